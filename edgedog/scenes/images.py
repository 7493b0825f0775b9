"""Reading images, edge maps and masks from disk, with size checks and downscaling."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from edgedog.errors import InputError

Background = tuple[float, float, float] | None
"""RGB in [0, 1] to composite RGBA images on, or None to drop the alpha channel."""


def read_raw(path: Path, expected_size: tuple[int, int] | None = None,
             also_allowed: tuple[int, int] | None = None) -> np.ndarray:
    """Decode an image file as stored (8 or 16 bit, 1, 3 or 4 channels; colour as RGB(A)).

    Args:
        path: the file.
        expected_size: (width, height) the scene's camera declares for it, checked when given.
        also_allowed: another accepted (width, height), e.g. the downscaled size of a cached map.
    Returns:
        (H, W) or (H, W, C) array of the file's dtype.
    """
    if not path.is_file():
        raise InputError(path, "file not found")
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise InputError(path, "cannot be decoded as an image")
    if expected_size is not None:
        height, width = image.shape[:2]
        if (width, height) not in (tuple(expected_size), also_allowed):
            raise InputError(
                path,
                f"image is {width}x{height} pixels but the camera expects "
                f"{expected_size[0]}x{expected_size[1]}",
            )
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2RGBA if image.shape[2] == 4 else cv2.COLOR_BGR2RGB
        image = cv2.cvtColor(image, code)
    return image


def to_unit_float(image: np.ndarray) -> np.ndarray:
    """Integer image -> float32 in [0, 1] (by the dtype's maximum)."""
    if np.issubdtype(image.dtype, np.integer):
        return image.astype(np.float32) / np.iinfo(image.dtype).max
    return image.astype(np.float32)


def to_u8(image: np.ndarray) -> np.ndarray:
    """Float image in [0, 1] -> uint8, rounded to nearest (values outside are clipped)."""
    return np.clip(image * 255.0 + 0.5, 0, 255).astype(np.uint8)


def resize_to(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """Area-averaging resize (no-op at the same size); keeps the channel layout."""
    if image.shape[1] == width and image.shape[0] == height:
        return image
    return cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)


def as_rgb(image: np.ndarray, background: Background) -> np.ndarray:
    """(H, W[, C]) float image -> (H, W, 3) RGB, compositing alpha on `background`."""
    if image.ndim == 2:
        return np.repeat(image[..., None], 3, axis=2)
    if image.shape[2] == 4:
        rgb, alpha = image[..., :3], image[..., 3:]
        if background is None:
            return np.ascontiguousarray(rgb)
        return rgb * alpha + np.asarray(background, np.float32) * (1.0 - alpha)
    return image[..., :3]


def as_gray(image: np.ndarray) -> np.ndarray:
    """(H, W[, C]) float image -> (H, W) single channel (mean of RGB; alpha ignored)."""
    if image.ndim == 2:
        return image
    return image[..., :3].mean(axis=2) if image.shape[2] >= 3 else image[..., 0]


def parse_background(text: str) -> Background:
    """'black' | 'white' | 'none' | 'R,G,B' (floats in [0, 1]) -> Background."""
    named = {"black": (0.0, 0.0, 0.0), "white": (1.0, 1.0, 1.0), "none": None}
    if text in named:
        return named[text]
    parts = text.split(",")
    try:
        rgb = tuple(float(p) for p in parts)
    except ValueError:
        rgb = ()
    if len(rgb) != 3 or not all(0.0 <= c <= 1.0 for c in rgb):
        raise ValueError(f"background must be black, white, none or R,G,B in [0, 1], got {text!r}")
    return rgb
