"""Hand-built test scenes of each format (a few 16x16 images) and their camera rigs."""

from __future__ import annotations

import json
import math
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

SIZE = 16  # width and height of the hand-made images
ANGLE_X = 0.8  # camera_angle_x of the hand-made NeRF scenes


def look_at_gl(position, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(4, 4) OpenGL camera-to-world (looks down -Z, +Y up) at `position` looking at `target`."""
    position, target = np.asarray(position, float), np.asarray(target, float)
    forward = target - position
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = right, true_up, -forward, position
    return c2w


def circle_c2ws(count: int, target=(0.0, 0.0, 0.0), radius: float = 3.0,
                height: float = 1.0) -> list[np.ndarray]:
    """OpenGL camera-to-world matrices of cameras on a circle around `target`, looking at it."""
    target = np.asarray(target, float)
    return [
        look_at_gl(target + [radius * math.cos(a), radius * math.sin(a), height], target)
        for a in np.linspace(0.3, 0.3 + 2 * math.pi, count, endpoint=False)
    ]


def write_png(path: Path, width: int = SIZE, height: int = SIZE, channels: int = 3) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(zlib.crc32(path.name.encode()))
    image = rng.integers(0, 256, (height, width, channels), dtype=np.uint8)
    assert cv2.imwrite(str(path), image)
    return path


def write_json(path: Path, data) -> Path:
    path.write_text(json.dumps(data, indent=1), encoding="utf-8")  # allows NaN, as Python does
    return path


def make_nerf(root: Path, frames: int = 3) -> Path:
    """A valid NeRF/Blender scene: `train/r_<i>.png` and transforms_train.json."""
    root.mkdir(parents=True, exist_ok=True)
    meta = {"camera_angle_x": ANGLE_X, "frames": []}
    for i, c2w in enumerate(circle_c2ws(frames)):
        write_png(root / "train" / f"r_{i}.png")
        meta["frames"].append({"file_path": f"./train/r_{i}", "transform_matrix": c2w.tolist()})
    write_json(root / "transforms_train.json", meta)
    return root


def nerf_meta(root: Path) -> dict:
    return json.loads((root / "transforms_train.json").read_text())


def make_emap(root: Path, frames: int = 2) -> Path:
    """A valid EMAP scene: color/<i>_colors.png and meta_data.json (OpenCV camera-to-world)."""
    root.mkdir(parents=True, exist_ok=True)
    K = [[20.0, 0.0, (SIZE - 1) / 2], [0.0, 20.0, (SIZE - 1) / 2], [0.0, 0.0, 1.0]]
    meta = {"camera_model": "OPENCV", "height": SIZE, "width": SIZE, "frames": []}
    for i, c2w_gl in enumerate(circle_c2ws(frames)):
        write_png(root / "color" / f"{i}_colors.png")
        c2w_cv = c2w_gl @ np.diag([1.0, -1.0, -1.0, 1.0])
        meta["frames"].append(
            {"rgb_path": f"{i}_colors.png", "camtoworld": c2w_cv.tolist(), "intrinsics": K}
        )
    write_json(root / "meta_data.json", meta)
    return root


def projection(c2w_gl: np.ndarray, focal: float = 20.0) -> np.ndarray:
    """(4, 4) NeuS world_mat: K [R | t] padded with a last row [0, 0, 0, 1]."""
    K = np.array([[focal, 0, (SIZE - 1) / 2], [0, focal, (SIZE - 1) / 2], [0, 0, 1]])
    w2c = np.linalg.inv(c2w_gl @ np.diag([1.0, -1.0, -1.0, 1.0]))
    P = np.eye(4)
    P[:3, :4] = K @ w2c[:3, :4]
    return P


def make_neus(root: Path, frames: int = 2, skip_key: str | None = None) -> Path:
    """A valid NeuS scene: image/<i>.png, mask/<i>.png and cameras_sphere.npz."""
    root.mkdir(parents=True, exist_ok=True)
    arrays = {}
    for i, c2w in enumerate(circle_c2ws(frames)):
        write_png(root / "image" / f"{i:03d}.png")
        write_png(root / "mask" / f"{i:03d}.png", channels=1)
        arrays[f"world_mat_{i}"] = projection(c2w)
        arrays[f"scale_mat_{i}"] = np.eye(4)
    arrays.pop(skip_key, None)
    np.savez(root / "cameras_sphere.npz", **arrays)
    return root


def make_colmap(root: Path, model: str = "PINHOLE", params=None) -> Path:
    """A COLMAP project: images/a.png and a text model in sparse/0 (one camera, one image)."""
    pycolmap = pytest.importorskip("pycolmap")
    rec = pycolmap.Reconstruction()
    camera = pycolmap.Camera.create_from_model_name(1, model, 20.0, SIZE, SIZE)
    if params is not None:
        camera.params = np.asarray(params, dtype=np.float64)
    rec.add_camera_with_trivial_rig(camera)
    rotation = pycolmap.Rotation3d(np.eye(3))
    rec.add_image_with_trivial_frame(
        pycolmap.Image(name="a.png", camera_id=1, image_id=1),
        pycolmap.Rigid3d(rotation, np.array([0.0, 0.0, 3.0])),
    )
    rec.add_point3D(np.array([0.1, 0.2, 0.3]), pycolmap.Track(), np.array([10, 20, 30], np.uint8))
    write_png(root / "images" / "a.png")
    (root / "sparse" / "0").mkdir(parents=True)
    rec.write_text(str(root / "sparse" / "0"))
    return root
