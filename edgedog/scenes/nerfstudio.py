"""nerfstudio scenes: `transforms.json` as `ns-process-data` and capture apps write it.

- Intrinsics `fl_x fl_y cx cy w h`, given once for all frames or per frame (a frame's own win).
  nerfstudio, like COLMAP, puts the top-left pixel's centre at (0.5, 0.5); edgedog at (0, 0).
- `camera_model`: PINHOLE, SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL and OPENCV are nerfstudio's
  perspective camera, with its distortion `k1 k2 k3 p1 p2` when given (OpenCV's model);
  OPENCV_FISHEYE is OpenCV's fisheye with `k1 k2 k3 k4`. Distorted views are undistorted when
  the scene loads (`edgedog.scenes.undistort`). nerfstudio's perspective k4 (an r^8 term) has
  no OpenCV counterpart and is refused rather than dropped.
- `transform_matrix`: camera-to-world, OpenGL convention, as in NeRF's files.
- `applied_transform` (3x4): what nerfstudio applied to the capture's world; its inverse is the
  scene's `world_to_gt`, so ground truth stays in the capture's frame.
- `mask_path`: the frame's object mask; `depth_file_path` is ignored.
- `images_2/`, `images_4/`, `images_8/` (and `masks_N/`): nerfstudio's downscaled copies; a frame
  whose full-resolution file is absent is read from the first copy found, its intrinsics scaled
  to it. Edge maps in `edge_<Detector>/` folders, named after the images, as in other formats.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from edgedog.errors import InputError
from edgedog.files import read_json
from edgedog.scenes.camera import intrinsics, w2c_from_opengl_c2w
from edgedog.scenes.common import (
    ALLOW_OUTSIDE,
    bounds_from_cameras,
    check_view_count,
    checked_camera,
    edge_folders,
    edge_maps_for,
    matrix,
    metadata_errors,
    outside_files_allowed,
    resolved,
)
from edgedog.scenes.distortion import Distortion, distortion_problem
from edgedog.scenes.images import image_info
from edgedog.scenes.scene import Scene, View

TRANSFORMS = "transforms.json"
PERSPECTIVE_MODELS = ("PINHOLE", "SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV")
FISHEYE_MODEL = "OPENCV_FISHEYE"
INTRINSICS = ("fl_x", "fl_y", "cx", "cy", "w", "h")
DOWNSCALES = (2, 4, 8)
"""The factors of nerfstudio's downscaled copies (`images_2/` ...), tried in this order."""


def is_nerfstudio(root: Path) -> bool:
    return (root / TRANSFORMS).is_file()


def load_nerfstudio(root: Path) -> Scene:
    """Load a nerfstudio scene folder (see the module's docstring)."""
    transforms = root / TRANSFORMS
    meta = read_json(transforms)
    frames = meta.get("frames") if isinstance(meta, dict) else None
    if not frames or not isinstance(frames, list):
        raise InputError(transforms, "no 'frames' list")
    check_view_count(len(frames), transforms)
    folders = edge_folders(root)
    with metadata_errors(transforms):
        views = [_view(root, transforms, meta, frame, f"frame {number}", folders)
                 for number, frame in enumerate(frames)]
        world_to_gt = _world_to_gt(meta, transforms)
    return Scene(root=root, format="nerfstudio", views=views,
                 bounds=bounds_from_cameras([v.camera for v in views]), world_to_gt=world_to_gt)


def _view(root: Path, transforms: Path, meta: dict[str, Any], frame: Any, where: str,
          folders: dict[str, Path]) -> View:
    if not isinstance(frame, dict):
        raise InputError(transforms, f"{where}: not an object with file_path and transform_matrix")
    for key in ("file_path", "transform_matrix"):
        if key not in frame:
            raise InputError(transforms, f"{where}: no {key}")
    merged = {**meta, **frame}
    missing = [name for name in INTRINSICS if name not in merged]
    if missing:
        raise InputError(transforms, f"{where}: no {', '.join(missing)} (nerfstudio's intrinsics, given "
                                     "for all frames or per frame)")
    fx, fy, cx, cy = (float(merged[name]) for name in INTRINSICS[:4])
    width, height = int(merged["w"]), int(merged["h"])
    c2w = matrix(frame["transform_matrix"], (4, 4), transforms, f"{where} transform_matrix")
    camera = checked_camera(intrinsics(fx, fy, cx - 0.5, cy - 0.5), c2w, width, height, transforms, where,
                            to_w2c=w2c_from_opengl_c2w)
    distortion = _distortion(merged, transforms, where)
    image, factor = _frame_file(root, transforms, frame["file_path"], where, "file_path")
    mask = None
    if frame.get("mask_path") is not None:
        mask, _ = _frame_file(root, transforms, frame["mask_path"], where, "mask_path", factor)
    if factor > 1:  # read from a downscaled copy: the camera of that copy's size
        info = image_info(image)
        camera = camera.scaled(info.width, info.height)
    return View(name=image.stem, camera=camera, image_path=image, mask_path=mask, distortion=distortion,
                edge_paths=edge_maps_for(image.stem, folders))


def _distortion(merged: dict[str, Any], transforms: Path, where: str) -> Distortion | None:
    """The frame's distortion in OpenCV's terms; None when it has none (all zero)."""
    model = str(merged.get("camera_model", "OPENCV"))
    k1, k2, k3, k4, p1, p2 = (float(merged.get(name, 0.0)) for name in ("k1", "k2", "k3", "k4", "p1", "p2"))
    problem = distortion_problem(("k1", "k2", "k3", "k4", "p1", "p2"), (k1, k2, k3, k4, p1, p2))
    if problem:
        raise InputError(transforms, f"{where}: distortion {problem}")
    if model in PERSPECTIVE_MODELS:
        if k4 != 0:
            raise InputError(transforms, f"{where}: camera_model {model} with k4={k4:g}: nerfstudio's r^8 "
                                         "radial term has no OpenCV counterpart")
        distortion = Distortion("opencv", (k1, k2, p1, p2, k3))
    elif model == FISHEYE_MODEL:
        if p1 or p2:
            raise InputError(transforms, f"{where}: camera_model {model} takes no tangential distortion "
                                         f"(p1={p1:g}, p2={p2:g})")
        distortion = Distortion("fisheye", (k1, k2, k3, k4))
    else:
        raise InputError(transforms, f"{where}: unknown camera_model {model!r}; expected one of "
                                     f"{', '.join((*PERSPECTIVE_MODELS, FISHEYE_MODEL))}")
    return None if distortion.is_identity else distortion


def _frame_file(root: Path, transforms: Path, listed: Any, where: str, key: str,
                factor: int | None = None) -> tuple[Path, int]:
    """(the file a frame's `key` names, 1) or, when that is absent, (its downscaled copy, the
    factor): the first of `DOWNSCALES`, or `factor` when given (a mask follows its image)."""
    if not isinstance(listed, str) or not listed:
        raise InputError(transforms, f"{where}: {key} is not a file name")
    path = resolved(root / listed)
    if not path.is_relative_to(root) and not outside_files_allowed():
        raise InputError(transforms, f"{where}: {key} {listed!r} lies outside the scene folder (set "
                                     f"{ALLOW_OUTSIDE}=1 to allow it)")
    candidates = [(path, 1)] if factor in (None, 1) else []
    candidates += [(path.parent.with_name(f"{path.parent.name}_{d}") / path.name, d)
                   for d in DOWNSCALES if factor in (None, d)]
    for candidate, scale in candidates:
        if candidate.is_file():
            return candidate, scale
    raise InputError(transforms, f"{where}: {key} {listed!r} not found")


def _world_to_gt(meta: dict[str, Any], transforms: Path) -> np.ndarray:
    """(4, 4) the inverse of `applied_transform` (identity without one)."""
    if "applied_transform" not in meta:
        return np.eye(4)
    applied = np.eye(4)
    applied[:3] = matrix(meta["applied_transform"], (3, 4), transforms, "applied_transform")
    if not np.all(np.isfinite(applied)) or abs(np.linalg.det(applied[:3, :3])) < 1e-9:
        raise InputError(transforms, "applied_transform is not an invertible, finite 3x4 transform")
    return np.linalg.inv(applied)
