"""Camera rigs for the hand-built test scenes."""

from __future__ import annotations

import math

import numpy as np


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
