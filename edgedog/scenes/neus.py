"""NeuS/IDR scenes (DTU, BlendedMVS): `cameras_sphere.npz`, `image/`, `mask/`.

For view i the projection is P = world_mat_i @ scale_mat_i; scale_mat maps the unit sphere,
which holds the object, to the original world, so the scene's world frame is that sphere.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import cv2
import numpy as np

from edgedog.errors import InputError
from edgedog.scenes.camera import Camera
from edgedog.scenes.common import (
    IMAGE_SUFFIXES,
    check_view_count,
    checked_camera,
    edge_folders,
    edge_maps_for,
    majority_size,
    matrix,
)
from edgedog.scenes.scene import Scene, View

CAMERAS_FILE = "cameras_sphere.npz"
MAX_ARRAY_BYTES = 1 << 20
"""Largest array of the cameras archive, unpacked: its matrices are 4x4 (128 bytes); a bigger
entry is not a camera, and a small archive may unpack to gigabytes."""


def is_neus(root: Path) -> bool:
    return (root / CAMERAS_FILE).is_file()


def decompose_projection(P: np.ndarray, width: int, height: int, path: Path, what: str) -> Camera:
    """A 3x4 projection K [R | t], defined up to scale, -> Camera (K[2, 2] = 1, positive focals)."""
    if not np.all(np.isfinite(P)):
        raise InputError(path, f"{what}: projection contains NaN or Inf")
    # -P is the same camera as P: fix the sign so that the decomposed R is a proper rotation.
    P = P[:3, :4] * np.sign(np.linalg.det(P[:3, :3]))
    K, R, center_h = cv2.decomposeProjectionMatrix(P)[:3]
    if abs(center_h[3, 0]) < 1e-12:
        raise InputError(path, f"{what}: projection has its camera centre at infinity")
    K = K / K[2, 2]
    # The RQ decomposition leaves the signs of K's diagonal free: move them into R.
    signs = np.diag(np.sign(np.diag(K)))
    K, R = K @ signs, signs @ R
    center = center_h[:3, 0] / center_h[3, 0]
    w2c = np.eye(4)
    w2c[:3, :3] = R
    w2c[:3, 3] = -R @ center
    return checked_camera(K, w2c, width, height, path, what)


def _sorted_images(folder: Path) -> list[Path]:
    return sorted(p for p in folder.glob("*") if p.suffix.lower() in IMAGE_SUFFIXES)


def load_neus(root: Path) -> Scene:
    """Load a NeuS/IDR scene folder."""
    cameras_path = root / CAMERAS_FILE
    images = _sorted_images(root / "image")
    if not images:
        raise InputError(root / "image", "no images found")
    check_view_count(len(images), root / "image")
    masks = _sorted_images(root / "mask")
    if masks and len(masks) != len(images):
        raise InputError(root / "mask", f"{len(masks)} masks for {len(images)} images")
    cameras = _read_cameras(cameras_path, len(images))
    width, height = majority_size(images, root / "image")
    folders = edge_folders(root)
    views = []
    for i, image_path in enumerate(images):
        key = f"world_mat_{i}"
        if key not in cameras:
            raise InputError(cameras_path, f"no {key} for image {image_path.name}")
        world = matrix(cameras[key], (4, 4), cameras_path, key)
        scale = matrix(cameras.get(f"scale_mat_{i}", np.eye(4)), (4, 4), cameras_path, f"scale_mat_{i}")
        camera = decompose_projection(world @ scale, width, height, cameras_path, key)
        views.append(View(image_path.stem, camera, image_path, edge_maps_for(image_path.stem, folders),
                          masks[i] if masks else None))
    return Scene(root=root, format="neus", views=views,
                 bounds=np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]]))


def _read_cameras(path: Path, count: int) -> dict[str, np.ndarray]:
    """The `world_mat_<i>` and `scale_mat_<i>` arrays of the first `count` views.

    The archive is data, never code: numpy refuses its object arrays (allow_pickle=False), and
    an entry that unpacks to more than MAX_ARRAY_BYTES is refused before it is read.
    """
    if not zipfile.is_zipfile(path):
        raise InputError(path, "not a .npz (zip) archive")
    wanted = {f"{kind}_{i}" for kind in ("world_mat", "scale_mat") for i in range(count)}
    try:
        with zipfile.ZipFile(path) as archive:
            sizes = {entry.filename.removesuffix(".npy"): entry.file_size for entry in archive.infolist()}
        too_big = sorted(key for key in wanted & sizes.keys() if sizes[key] > MAX_ARRAY_BYTES)
        if not too_big:
            with np.load(path, allow_pickle=False) as archive:
                return {key: archive[key] for key in archive.files if key in wanted}
    except Exception as exc:  # numpy and zipfile raise several types for a damaged archive
        raise InputError(path, f"damaged .npz archive ({type(exc).__name__}: {exc})") from None
    raise InputError(path, f"{too_big[0]} unpacks to {sizes[too_big[0]]} bytes, far more than a 4x4 matrix")
