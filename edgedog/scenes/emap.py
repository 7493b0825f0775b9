"""EMAP scenes: `meta_data.json` with OpenCV camera-to-world matrices and per-frame intrinsics.

Layout: `color/<i>_colors.png`, `edge_DexiNed/`, `edge_PidiNet/` (the same file names),
`meta_data.json` with `height`, `width`, `frames`, `scene_box`, and `worldtogt`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from edgedog.errors import InputError
from edgedog.files import read_json
from edgedog.scenes.camera import rigid_inverse
from edgedog.scenes.common import (
    check_view_count,
    checked_camera,
    edge_folders,
    edge_maps_for,
    find_image,
    matrix,
    metadata_errors,
)
from edgedog.scenes.scene import Scene, View
from edgedog.world import MAX_COORDINATE


def is_emap(root: Path) -> bool:
    return (root / "meta_data.json").is_file()


def load_emap(root: Path) -> Scene:
    """Load an EMAP scene folder."""
    meta_path = root / "meta_data.json"
    meta = read_json(meta_path)
    if not isinstance(meta, dict) or not meta.get("frames"):
        raise InputError(meta_path, "no 'frames' list")
    if "height" not in meta or "width" not in meta:
        raise InputError(meta_path, "no image 'height' and 'width'")
    if meta.get("camera_model", "OPENCV") not in ("OPENCV", "PINHOLE"):
        raise InputError(meta_path, f"unsupported camera_model {meta['camera_model']!r}")
    with metadata_errors(meta_path):
        check_view_count(len(meta["frames"]), meta_path)
        views = _views(root, meta_path, meta)
        world_to_gt = matrix(meta.get("worldtogt", np.eye(4).tolist()), (4, 4), meta_path, "worldtogt")
        aabb = matrix(meta.get("scene_box", {}).get("aabb", [[-1] * 3, [1] * 3]), (2, 3), meta_path,
                      "scene_box.aabb")
    problem = _similarity_problem(world_to_gt) or _box_problem(aabb)
    if problem:
        raise InputError(meta_path, problem)
    return Scene(
        root=root,
        format="emap",
        views=views,
        bounds=aabb,
        world_to_gt=world_to_gt,
    )


def _views(root: Path, meta_path: Path, meta: dict) -> list[View]:
    width, height = int(meta["width"]), int(meta["height"])
    folders = edge_folders(root)
    views = []
    for number, frame in enumerate(meta["frames"]):
        where = f"frame {number}"
        missing = [k for k in ("rgb_path", "camtoworld", "intrinsics") if k not in frame]
        if missing:
            raise InputError(meta_path, f"{where} lacks {', '.join(missing)}")
        stem = Path(frame["rgb_path"]).stem
        image_path = find_image(root / "color", stem) or root / "color" / frame["rgb_path"]
        c2w = matrix(frame["camtoworld"], (4, 4), meta_path, f"{where} camtoworld")
        K = matrix(frame["intrinsics"], (3, 3), meta_path, f"{where} intrinsics")
        camera = checked_camera(K, c2w, width, height, meta_path, where, to_w2c=rigid_inverse)
        views.append(View(stem, camera, image_path, edge_maps_for(stem, folders)))
    return views


def _similarity_problem(world_to_gt: np.ndarray) -> str | None:
    """Why `worldtogt` cannot map predictions into the ground-truth frame (it is a scale and a
    shift, possibly a rotation: finite, last row 0 0 0 1, invertible), or None."""
    if not np.all(np.isfinite(world_to_gt)):
        return "worldtogt contains NaN or Inf"
    if not np.allclose(world_to_gt[3], [0.0, 0.0, 0.0, 1.0], rtol=0, atol=1e-6):
        return f"worldtogt's last row is {world_to_gt[3].tolist()}, expected [0, 0, 0, 1]"
    if abs(np.linalg.det(world_to_gt[:3, :3])) < 1e-12:
        return "worldtogt is not invertible"
    return None


def _box_problem(aabb: np.ndarray) -> str | None:
    """Why `scene_box.aabb` (2, 3) [min, max] is not a box around the object, or None."""
    if not np.all(np.isfinite(aabb)) or not np.all(aabb[0] < aabb[1]):
        return f"scene_box.aabb {aabb.tolist()} is not [min, max] with finite min < max"
    if np.abs(aabb).max() > MAX_COORDINATE:
        return f"scene_box.aabb {aabb.tolist()} reaches beyond {MAX_COORDINATE:.0e} units"
    return None
