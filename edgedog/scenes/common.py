"""Checks and helpers the scene loaders share."""

from __future__ import annotations

import dataclasses
import os
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from edgedog.errors import InputError
from edgedog.scenes.camera import Camera, intrinsics_problem, pose_problem
from edgedog.scenes.images import MAX_IMAGE_PIXELS, image_info
from edgedog.scenes.scene import Scene

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".exr", ".webp")

MAX_VIEWS = 10_000
"""Most views a scene may have: ten times the largest object captures (DTU has 49 to 64 views,
ABC-NEF 50); training keeps every view's edge map in memory."""

ALLOW_OUTSIDE = "EDGEDOG_ALLOW_OUTSIDE_FILES"
"""Environment variable: set to 1 to let a scene's metadata name files outside its folder."""


@contextmanager
def metadata_errors(path: Path) -> Iterator[None]:
    """Turn a wrongly typed value met while parsing `path` into an InputError naming it.

    Metadata is user data: `float("wide")`, a frame that is a number instead of an object, or
    a matrix of the wrong size must read as a problem of that file, not as a traceback.
    """
    try:
        yield
    except (TypeError, ValueError, KeyError, AttributeError, IndexError, ZeroDivisionError) as exc:
        kind = "missing entry" if isinstance(exc, KeyError) else "wrongly typed value"
        raise InputError(path, f"{kind} ({type(exc).__name__}: {exc})") from None


def matrix(value: Any, shape: tuple[int, ...], path: Path, what: str) -> np.ndarray:
    """A nested list -> float64 array of `shape`, or an InputError saying which entry is bad."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(path, f"{what} is not a numeric matrix") from None
    if array.shape != shape:
        raise InputError(path, f"{what} has shape {array.shape}, expected {shape}")
    return array


def checked_camera(K: np.ndarray, pose: np.ndarray, width: int, height: int, path: Path, what: str,
                   to_w2c: Callable[[np.ndarray], np.ndarray] | None = None) -> Camera:
    """Build a Camera after checking that its image size, intrinsics and pose are usable.

    Args:
        K: (3, 3) intrinsics for a `width` x `height` image.
        pose: (4, 4) the pose as the file gives it (checked as given: its last row counts).
        path, what: the file and the entry (e.g. "frame 3") an error names.
        to_w2c: turns `pose` into the world-to-camera matrix (default: it is one).
    """
    if not (0 < width and 0 < height and width * height <= MAX_IMAGE_PIXELS):
        raise InputError(path, f"{what}: image size {width}x{height} is not between 1 pixel and "
                               f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels")
    problem = intrinsics_problem(K, width, height) or pose_problem(pose)
    if problem:
        raise InputError(path, f"{what}: {problem}")
    w2c = pose if to_w2c is None else to_w2c(pose)
    return Camera(K=K, w2c=w2c, width=int(width), height=int(height))


def check_view_count(count: int, path: Path) -> None:
    """An InputError naming `path` when it lists more than MAX_VIEWS views."""
    if count > MAX_VIEWS:
        raise InputError(path, f"{count} views, more than the {MAX_VIEWS} a scene may have")


def resolved(path: Path) -> Path:
    """`path` with every symlink followed; a symlink loop is an InputError naming it."""
    try:
        return path.resolve()
    except (RuntimeError, OSError):  # Python 3.11 raises RuntimeError for a loop, later ones OSError
        raise InputError(path, "cannot be resolved: a symlink loop") from None


def outside_files_allowed() -> bool:
    return os.environ.get(ALLOW_OUTSIDE, "") not in ("", "0")


def confine_files(scene: Scene) -> None:
    """Refuse a scene whose images, masks or edge maps lie outside its folder once symlinks are
    followed (metadata may name any path: `/etc/passwd`, `../../x`), unless ALLOW_OUTSIDE is set.
    The scene's root is resolved already, so a symlinked scene folder itself is fine."""
    if outside_files_allowed():
        return
    for view in scene.views:
        files = [view.image_path, view.mask_path, *view.edge_paths.values()]
        for path in (p for p in files if p is not None):
            target = resolved(path)
            if not target.is_relative_to(scene.root):
                link = f" (that is {target})" if target != path else ""
                raise InputError(scene.root, f"view '{view.name}' names {path}{link}, which lies outside "
                                             f"the scene folder (set {ALLOW_OUTSIDE}=1 to allow it)")


def majority_size(paths: list[Path], source: Path) -> tuple[int, int]:
    """(width, height) of most of the images (read from their headers): the scene's image size
    when its metadata gives none. An image of another size is named by `inspect_images`."""
    sizes = Counter()
    for path in paths:
        try:
            info = image_info(path)
        except InputError:  # missing or damaged: `inspect_images` reports it
            continue
        sizes[info.width, info.height] += 1
    if not sizes:
        raise InputError(source, f"none of its {len(paths)} images can be read")
    return sizes.most_common(1)[0][0]


def inspect_images(scene: Scene) -> Scene:
    """The scene with each view's `alpha` known and its damaged images listed, after checking,
    from the files' headers (nothing is decoded), that every image exists and has its camera's
    size: an odd image is named here rather than the edge map it is later compared with.

    A damaged image (cut short, undecodable) does not stop the scene from loading: it fails
    with an InputError naming it when it is read, and `Scene.damaged` lists it (a scene that
    ships edge maps may train without ever reading its images).
    """
    views, damaged = [], {}
    for view in scene.views:
        if not view.image_path.is_file():
            raise InputError(view.image_path, f"image of view '{view.name}' not found")
        try:
            info = image_info(view.image_path)
        except InputError as error:
            damaged[view.image_path] = error.problem
            views.append(view)
            continue
        camera = view.camera
        if (info.width, info.height) != (camera.width, camera.height):
            raise InputError(view.image_path, f"image is {info.width}x{info.height} pixels but its camera "
                                              f"is {camera.width}x{camera.height} (the size the scene's "
                                              "metadata or most of its images give)")
        views.append(dataclasses.replace(view, alpha=info.alpha))
    return dataclasses.replace(scene, views=views, damaged=damaged)


def find_image(folder: Path, stem: str) -> Path | None:
    """The file `folder/stem.<image suffix>`, or None."""
    for suffix in IMAGE_SUFFIXES:
        candidate = folder / f"{stem}{suffix}"
        if candidate.is_file():
            return candidate
    return None


def edge_folders(root: Path) -> dict[str, Path]:
    """Edge-map folders `edge_<Detector>/` of a scene -> {detector name in lower case: folder}."""
    return {
        p.name[len("edge_"):].lower(): p
        for p in sorted(root.glob("edge_*"))
        if p.is_dir() and len(p.name) > len("edge_")
    }


def edge_maps_for(stem: str, folders: dict[str, Path]) -> dict[str, Path]:
    """The edge maps of one view: {detector: file} for the folders that hold `stem`."""
    found = {name: find_image(folder, stem) for name, folder in folders.items()}
    return {name: path for name, path in found.items() if path is not None}


def nearest_to_axes(cameras: list[Camera]) -> np.ndarray:
    """(3,) the point nearest (least squares) to all cameras' optical axes."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for cam in cameras:
        P = np.eye(3) - np.outer(cam.forward, cam.forward)  # projects onto the axis' normal
        A += P
        b += P @ cam.center
    return np.linalg.lstsq(A, b, rcond=None)[0]


def look_at_point(cameras: list[Camera]) -> np.ndarray | None:
    """(3,) the point an object-centric capture looks at, or None when the views do not share
    one: it must lie in front of every camera, within a quarter of its distance from every axis."""
    point = nearest_to_axes(cameras)
    for cam in cameras:
        offset = point - cam.center
        depth = float(np.dot(offset, cam.forward))
        if depth <= 0 or np.linalg.norm(offset - depth * cam.forward) > 0.25 * depth:
            return None
    return point


def bounds_from_cameras(cameras: list[Camera]) -> np.ndarray:
    """(2, 3) box around the region every camera sees, for object-centric captures.

    The centre is the point nearest (least squares) to all optical axes; the half-size is the
    radius of the largest sphere around it that fits inside every view's field of view.
    """
    center = nearest_to_axes(cameras)
    radii = []
    for cam in cameras:
        distance = float(np.dot(center - cam.center, cam.forward))
        half_fov = min(cam.width / (2 * cam.K[0, 0]), cam.height / (2 * cam.K[1, 1]))
        radii.append(distance * half_fov / np.sqrt(1 + half_fov**2))
    radius = max(min(radii), 1e-6)
    return np.stack([center - radius, center + radius])
