"""Views of distorted cameras, undistorted once into the user cache.

A view with a `distortion` (nerfstudio's OPENCV and OPENCV_FISHEYE, COLMAP's SIMPLE_RADIAL,
RADIAL, OPENCV, FULL_OPENCV, OPENCV_FISHEYE) is never used as a pinhole: its image, mask and edge
maps are resampled through one OpenCV undistortion map each view (so they stay aligned) into

    <cache>/edges/<scene>-<path digest>/undistorted/<content>/<images|masks|maps/NAME>/<view>.png

and the view becomes a pinhole view of those files, with OpenCV's undistorted intrinsics.
`<content>` digests every distorted view's camera, distortion and files (path, size, time), so
files that changed since are undistorted again, and others are reused. Each file is written
atomically: an interrupted undistortion resumes where it stopped. Scene folders are never
written to.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from edgedog.errors import InputError
from edgedog.files import atomic_write, default_cache
from edgedog.scenes.camera import Camera, intrinsics_problem
from edgedog.scenes.distortion import undistort, undistorted_intrinsics, undistortion_maps
from edgedog.scenes.images import read_raw
from edgedog.scenes.scene import Scene, View


def scene_cache(root: Path) -> Path:
    """The user cache's folder of the scene folder `root` (edge maps, undistorted files): named
    after it and a digest of its path."""
    digest = hashlib.sha1(str(root).encode()).hexdigest()[:12]
    return default_cache() / "edges" / f"{root.name}-{digest}"


def undistort_scene(scene: Scene) -> Scene:
    """`scene` with every distorted view replaced by its undistorted pinhole view (see the
    module's docstring); the same scene when no view is distorted.

    A view's damaged image (`scene.damaged`) keeps its path: reading it fails naming it.
    """
    distorted = [index for index, view in enumerate(scene.views) if view.distortion is not None]
    if not distorted:
        return scene
    folder = scene_cache(scene.root) / "undistorted" / _content_key([scene.views[i] for i in distorted])
    views = list(scene.views)
    for index in distorted:
        views[index] = _undistorted_view(views[index], folder, scene.damaged)
    return dataclasses.replace(scene, views=views)


def _undistorted_view(view: View, folder: Path, damaged: dict[Path, str]) -> View:
    camera = view.camera
    new_K = undistorted_intrinsics(camera.K, view.distortion, camera.width, camera.height)
    problem = intrinsics_problem(new_K, camera.width, camera.height)
    if problem:  # a distortion so strong (or so odd) that no pinhole camera sees the whole image
        raise InputError(view.image_path, f"cannot be undistorted ({view.distortion.model} distortion "
                                          f"{view.distortion.coefficients}): the undistorted {problem}")
    size = (camera.width, camera.height)
    # Built only when a file is not in the cache yet (a scene loads many times, undistorts once).
    maps = functools.cache(lambda: undistortion_maps(camera.K, view.distortion, new_K, *size))

    def moved(path: Path | None, kind: str) -> Path | None:
        return None if path is None else _undistorted_file(path, folder / kind / view.name, maps, size)

    image = view.image_path if view.image_path in damaged else moved(view.image_path, "images")
    edges = {name: moved(path, f"maps/{name}") for name, path in view.edge_paths.items()}
    return dataclasses.replace(view, camera=Camera(K=new_K, w2c=camera.w2c, width=camera.width,
                                                   height=camera.height),
                               image_path=image, mask_path=moved(view.mask_path, "masks"), edge_paths=edges,
                               distortion=None)


def _undistorted_file(source: Path, stem: Path, maps: Callable[[], tuple[np.ndarray, np.ndarray]],
                      size: tuple[int, int]) -> Path:
    """`source` undistorted into `stem`.png (8 or 16 bit, as stored) or `stem`.tiff (float
    images) through `maps()` (see `undistortion_maps`), written unless it is there already;
    returns that file."""
    for suffix in (".png", ".tiff"):
        if (stem.parent / f"{stem.name}{suffix}").is_file():
            return stem.parent / f"{stem.name}{suffix}"
    image = undistort(read_raw(source, size), maps())
    target = stem.parent / f"{stem.name}{'.png' if np.issubdtype(image.dtype, np.integer) else '.tiff'}"
    if image.ndim == 3:  # read_raw gives RGB(A); OpenCV writes BGR(A)
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR if image.shape[2] == 3 else cv2.COLOR_RGBA2BGRA)
    ok, data = cv2.imencode(target.suffix, image)
    if not ok:
        raise RuntimeError(f"encoding failed for {target}")
    atomic_write(target, lambda file: file.write(data.tobytes()))
    return target


def _content_key(views: list[View]) -> str:
    """16 hex digits over the distorted views' names, cameras, distortions and files."""
    digest = hashlib.sha256()
    for view in views:
        camera = view.camera
        digest.update(f"{view.name}\0{view.distortion}\0{camera.width}x{camera.height}\0".encode())
        digest.update(np.asarray(camera.K, np.float64).tobytes())
        files = [view.image_path, view.mask_path, *(view.edge_paths[n] for n in sorted(view.edge_paths))]
        for path in (p for p in files if p is not None):
            stat = path.stat() if path.is_file() else None
            digest.update(f"{path}\0{stat and (stat.st_size, stat.st_mtime_ns)}\0".encode())
    return digest.hexdigest()[:16]
