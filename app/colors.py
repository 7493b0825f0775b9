"""Colour maps for the inspectors, their colour bars and the splats, and a palette for curves."""

from __future__ import annotations

import colorsys

import cv2
import numpy as np

COLORMAPS = {"gray": None, "viridis": cv2.COLORMAP_VIRIDIS, "magma": cv2.COLORMAP_MAGMA}
GOLDEN = 0.618033988749895


def colormap(values: np.ndarray, lo: float, hi: float, name: str = "viridis") -> np.ndarray:
    """(...) values -> (..., 3) uint8 RGB, `lo` and `hi` at the ends of the map; NaN is black.

    Without a range (hi <= lo, e.g. w(Up) = 1 everywhere) positive values take the map's top
    colour and the others its bottom one: a constant 1 is not drawn as 0.
    """
    values = np.asarray(values, np.float64)
    scaled = np.clip((values - lo) / (hi - lo), 0, 1) if hi > lo else (values > 0).astype(np.float64)
    levels = np.nan_to_num(scaled * 255).round().astype(np.uint8)
    if not levels.size:  # cv2.applyColorMap returns None for an empty array
        return np.zeros((*levels.shape, 3), np.uint8)
    if COLORMAPS[name] is None:
        rgb = np.repeat(levels[..., None], 3, axis=-1)
    else:
        rgb = cv2.applyColorMap(levels.reshape(-1, 1), COLORMAPS[name]).reshape(*levels.shape, 3)[..., ::-1]
    return np.where(np.isnan(values)[..., None], 0, rgb).astype(np.uint8)


def with_alpha(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 -> (H, W, 4) opaque RGBA."""
    return np.concatenate([rgb, np.full(rgb.shape[:-1] + (1,), 255, np.uint8)], axis=-1)


def colorbar(name: str, height: int = 256) -> np.ndarray:
    """(height, 1, 4) uint8 RGBA, the map's high end at the top."""
    return with_alpha(colormap(np.linspace(1, 0, height)[:, None], 0, 1, name))


def curve_palette(count: int) -> np.ndarray:
    """(count, 3) float RGB in [0, 1], bright hues spread by the golden ratio (neighbours differ)."""
    return np.array([colorsys.hsv_to_rgb((i * GOLDEN) % 1.0, 0.75, 1.0) for i in range(count)]).reshape(-1, 3)
