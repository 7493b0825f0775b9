"""NeRF/Blender scenes: `transforms_<split>.json` with OpenGL camera-to-world matrices.

Also the ABC-NEF variant: there `file_path` names the pseudo-edge map (`train/0_colors`) and
the colour image lives in the sibling folder `train_img/`. Those maps are PiDiNet's unless the
transforms file names their detector in an `edge_detector` entry (as edgedog's own scenes do).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from edgedog.errors import InputError
from edgedog.files import read_json
from edgedog.scenes.camera import intrinsics, w2c_from_opengl_c2w
from edgedog.scenes.common import (
    bounds_from_cameras,
    check_view_count,
    checked_camera,
    edge_folders,
    edge_maps_for,
    find_image,
    majority_size,
    matrix,
    metadata_errors,
    resolved,
)
from edgedog.scenes.scene import Scene, View

NEF_DETECTOR = "pidinet"
"""The detector of the maps that ABC-NEF ships in `train/`, when the file names none."""


def is_nerf(root: Path) -> bool:
    return (root / "transforms_train.json").is_file()


def _resolve(root: Path, file_path: str, transforms: Path) -> Path:
    """A frame's `file_path` (suffix optional) -> existing file."""
    path = resolved(root / file_path)  # an absolute file_path stays as it is
    if path.is_file():
        return path
    found = find_image(path.parent, path.name)
    if found is None:
        raise InputError(transforms, f"frame file {file_path!r} not found (looked in {path.parent})")
    return found


def _intrinsics(meta: dict[str, Any], frame: dict[str, Any], width: int, height: int,
                transforms: Path, where: str) -> np.ndarray:
    """Per-frame `camera_intrinsics`, else fl_x/fl_y/cx/cy, else `camera_angle_x`."""
    if "camera_intrinsics" in frame:
        return matrix(frame["camera_intrinsics"], (3, 3), transforms, f"{where} camera_intrinsics")
    merged = {**meta, **frame}
    if "fl_x" in merged:
        fx = float(merged["fl_x"])
        fy = float(merged.get("fl_y", fx))
    elif "camera_angle_x" in merged:
        fx = _focal_from_angle(merged["camera_angle_x"], width, transforms, where)
        fy = _focal_from_angle(merged["camera_angle_y"], height, transforms, where) \
            if "camera_angle_y" in merged else fx
    else:
        raise InputError(transforms, f"{where}: no camera_angle_x, fl_x or camera_intrinsics")
    # Pixel centres at integers: the optical centre of a W-wide image is (W - 1) / 2.
    cx = float(merged.get("cx", (width - 1) / 2))
    cy = float(merged.get("cy", (height - 1) / 2))
    return intrinsics(fx, fy, cx, cy)


def _focal_from_angle(angle: Any, pixels: int, transforms: Path, where: str) -> float:
    """Focal length in pixels from a full field-of-view angle in radians."""
    if not 0 < float(angle) < math.pi:
        raise InputError(transforms, f"{where}: field of view {angle} is not in (0, pi) radians")
    return 0.5 * pixels / math.tan(0.5 * float(angle))


def load_nerf(root: Path, split: str = "train") -> Scene:
    """Load a NeRF/Blender scene folder."""
    transforms = root / f"transforms_{split}.json"
    meta = read_json(transforms)
    frames = meta.get("frames") if isinstance(meta, dict) else None
    if not frames:
        raise InputError(transforms, "no 'frames' list")
    check_view_count(len(frames), transforms)
    with metadata_errors(transforms):
        views = _views(root, transforms, meta)
    return Scene(
        root=root,
        format="nerf",
        views=views,
        bounds=bounds_from_cameras([v.camera for v in views]),
    )


def _views(root: Path, transforms: Path, meta: dict[str, Any]) -> list[View]:
    folders = edge_folders(root)
    files = [_frame_files(root, transforms, meta, frame, f"frame {number}", folders)
             for number, frame in enumerate(meta["frames"])]
    if "w" in meta and "h" in meta:
        size = (int(meta["w"]), int(meta["h"]))
    else:  # all frames share one size: most images' (an odd image is named when the scene loads)
        size = majority_size([image for _, image, _ in files], transforms)
    views = []
    for number, (frame, (listed, image_path, edges)) in enumerate(zip(meta["frames"], files)):
        where = f"frame {number}"
        c2w = matrix(frame["transform_matrix"], (4, 4), transforms, f"{where} transform_matrix")
        K = _intrinsics(meta, frame, *size, transforms, where)
        camera = checked_camera(K, c2w, *size, transforms, where, to_w2c=w2c_from_opengl_c2w)
        views.append(View(name=listed.stem, camera=camera, image_path=image_path, edge_paths=edges))
    return views


def _frame_files(root: Path, transforms: Path, meta: dict[str, Any], frame: dict[str, Any], where: str,
                 folders: dict[str, Path]) -> tuple[Path, Path, dict[str, Path]]:
    """(the file `file_path` names, the view's image, its edge maps {detector: file}, those of
    the scene's `edge_<Detector>/` folders included).

    In the ABC-NEF layout the named file is an edge map and the image lies in the sibling
    folder `<folder>_img/` under the same name.
    """
    if "file_path" not in frame or "transform_matrix" not in frame:
        raise InputError(transforms, f"{where} lacks file_path or transform_matrix")
    listed = _resolve(root, frame["file_path"], transforms)
    image_folder = listed.parent.with_name(listed.parent.name + "_img")
    if image_folder.is_dir():
        image_path = find_image(image_folder, listed.stem)
        if image_path is None:
            raise InputError(image_folder, f"no image {listed.stem}.* for {where}")
        edges = {str(meta.get("edge_detector", NEF_DETECTOR)).lower(): listed}
    elif os.path.lexists(image_folder):  # a file, a broken link or a loop: not plain NeRF either
        raise InputError(image_folder, "is not a folder (a file, a broken symlink or a symlink loop), "
                                       "where an ABC-NEF scene keeps its images")
    else:
        image_path, edges = listed, {}
    return listed, image_path, {**edges, **edge_maps_for(listed.stem, folders)}
