"""COLMAP scenes: a sparse model (`sparse/0/` or `sparse/`, .bin or .txt) read with pycolmap,
and the photos in `images/`. The SfM points are kept for initialisation.

Pinhole cameras (PINHOLE, SIMPLE_PINHOLE) load as they are; distorted ones (SIMPLE_RADIAL,
RADIAL, OPENCV, FULL_OPENCV, OPENCV_FISHEYE) in OpenCV's terms, undistorted when the scene loads
(`edgedog.scenes.undistort`). Other models are refused: run `colmap image_undistorter` first.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from edgedog.errors import InputError
from edgedog.scenes.camera import intrinsics
from edgedog.scenes.colmap_binary import check_binary_model
from edgedog.scenes.common import (
    bounds_from_cameras,
    check_view_count,
    checked_camera,
    edge_folders,
    edge_maps_for,
    metadata_errors,
)
from edgedog.scenes.distortion import Distortion
from edgedog.scenes.scene import Scene, View

MODEL_FILES = ("cameras", "images", "points3D")
COLMAP_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
"""Image files COLMAP reads."""


@contextmanager
def colmap_log_level(level: int = 1) -> Iterator[None]:
    """Show only COLMAP log messages at `level` and above (0 info, 1 warning, 2 error) inside."""
    import pycolmap

    old = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = level
    try:
        yield
    finally:
        pycolmap.logging.minloglevel = old


def sparse_folder(root: Path) -> Path | None:
    """The folder that holds the sparse model's files, or None."""
    for folder in (root / "sparse" / "0", root / "sparse", root):
        if all((folder / f"{n}.bin").is_file() or (folder / f"{n}.txt").is_file() for n in MODEL_FILES):
            return folder
    return None


def is_colmap(root: Path) -> bool:
    return sparse_folder(root) is not None


# COLMAP model -> (OpenCV's distortion model or None, the parameters' names in COLMAP's order).
CAMERA_MODELS = {
    "SIMPLE_PINHOLE": (None, ("f", "cx", "cy")),
    "PINHOLE": (None, ("fx", "fy", "cx", "cy")),
    "SIMPLE_RADIAL": ("opencv", ("f", "cx", "cy", "k1")),
    "RADIAL": ("opencv", ("f", "cx", "cy", "k1", "k2")),
    "OPENCV": ("opencv", ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2")),
    "FULL_OPENCV": ("opencv", ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")),
    "OPENCV_FISHEYE": ("fisheye", ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")),
}
OPENCV_ORDER = {"opencv": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
                "fisheye": ("k1", "k2", "k3", "k4")}
"""The coefficients of OpenCV's distortion vector of each model, in its order (those a COLMAP
model lacks are zero)."""


def _intrinsics(camera, model_path: Path) -> tuple[np.ndarray, Distortion | None]:
    """pycolmap camera -> ((3, 3) K in edgedog's convention, its distortion or None), or an
    InputError for a model OpenCV cannot undistort (pycolmap refuses parameters that are not
    finite when it reads the model)."""
    name = camera.model.name
    if name not in CAMERA_MODELS:
        raise InputError(model_path, f"camera {camera.camera_id} uses the model {name}, which edgedog cannot "
                                     f"undistort ({', '.join(CAMERA_MODELS)}); undistort the images first "
                                     "(colmap image_undistorter --output_type COLMAP) and load that folder")
    model, names = CAMERA_MODELS[name]
    values = dict(zip(names, map(float, camera.params)))
    fx, fy = values.get("fx", values.get("f")), values.get("fy", values.get("f"))
    # COLMAP puts the centre of the top-left pixel at (0.5, 0.5); edgedog puts it at (0, 0).
    K = intrinsics(fx, fy, values["cx"] - 0.5, values["cy"] - 0.5)
    if model is None:
        return K, None
    order = OPENCV_ORDER[model][:8 if "k5" in values else 4]  # OpenCV takes 4, 5 or 8
    distortion = Distortion(model, tuple(values.get(k, 0.0) for k in order))
    return K, None if distortion.is_identity else distortion


def load_colmap(root: Path) -> Scene:
    """Load a COLMAP project folder."""
    import pycolmap  # heavy: imported only when a COLMAP scene is opened

    model_path = sparse_folder(root)
    if model_path is None:
        raise InputError(root, "no COLMAP sparse model (cameras, images, points3D)")
    check_binary_model(model_path)  # pycolmap loops for ever on a count the file cannot hold
    try:
        model = pycolmap.Reconstruction(str(model_path))
        image_ids = sorted(model.reg_image_ids())  # checks that frames name existing images
    except Exception as exc:  # pycolmap raises ValueError, IndexError (unknown ids), RuntimeError...
        first_line = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise InputError(model_path, f"unreadable COLMAP model ({first_line})") from None
    image_folder = root / "images"
    folders = edge_folders(root)
    check_view_count(len(image_ids), model_path)
    with metadata_errors(model_path):
        views = [_view(model, image_id, model_path, image_folder, folders) for image_id in image_ids]
    if not views:
        raise InputError(model_path, "the model has no registered images")
    points = np.array([p.xyz for p in model.points3D.values()], dtype=np.float64).reshape(-1, 3)
    colors = np.array([p.color for p in model.points3D.values()], dtype=np.uint8).reshape(-1, 3)
    if not np.all(np.isfinite(points)):
        raise InputError(model_path, "points3D contains NaN or Inf coordinates")
    return Scene(root=root, format="colmap", views=views, bounds=points_bounds(points, views),
                 sfm_points=points, sfm_colors=colors)


def _view(model, image_id: int, model_path: Path, image_folder: Path, folders: dict[str, Path]) -> View:
    """The view of one registered image of a pycolmap.Reconstruction."""
    image = model.image(image_id)
    camera = model.camera(image.camera_id)
    K, distortion = _intrinsics(camera, model_path)
    w2c = np.eye(4)
    w2c[:3, :4] = image.cam_from_world().matrix()
    where = f"image {image.name}"
    cam = checked_camera(K, w2c, camera.width, camera.height, model_path, where)
    # The name keeps the image's sub-folder: rigs store cam1/0001.png beside cam2/0001.png.
    name = Path(image.name).with_suffix("").as_posix()
    return View(name, cam, image_folder / image.name, edge_maps_for(name, folders), distortion=distortion)


def points_bounds(points: np.ndarray, views: list[View], padding: float = 0.1) -> np.ndarray:
    """(2, 3) robust box of the SfM points (1st to 99th percentile, padded by 10 %).

    With fewer than 10 points, falls back to the cameras' common view region.
    """
    if len(points) < 10:
        return bounds_from_cameras([v.camera for v in views])
    lo, hi = np.percentile(points, [1, 99], axis=0)
    pad = (hi - lo) * padding
    return np.stack([lo - pad, hi + pad])
