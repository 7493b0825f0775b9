"""Checks and helpers the scene loaders share."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from edgedog.errors import InputError
from edgedog.scenes.camera import Camera, intrinsics_problem, pose_problem

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".exr", ".webp")


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


def checked_camera(K: np.ndarray, w2c: np.ndarray, width: int, height: int,
                   path: Path, what: str) -> Camera:
    """Build a Camera after checking that intrinsics and pose are usable."""
    problem = intrinsics_problem(K) or pose_problem(w2c)
    if problem:
        raise InputError(path, f"{what}: {problem}")
    if width <= 0 or height <= 0:
        raise InputError(path, f"{what}: image size {width}x{height} is not positive")
    return Camera(K=K, w2c=w2c, width=int(width), height=int(height))


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
