"""Cubic Bézier evaluation in matrix form (the form least-squares fitting needs)."""

from __future__ import annotations

import numpy as np


def bernstein(t: np.ndarray) -> np.ndarray:
    """Cubic Bernstein basis (n, 4) at parameters t (n,): points = bernstein(t) @ ctrl (4, 3)."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    u = 1.0 - t
    return np.hstack([u**3, 3 * u**2 * t, 3 * u * t**2, t**3])


def bezier_points(ctrl: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Points (n, 3) of the cubic with control points ctrl (4, 3) at t (n,)."""
    return bernstein(t) @ ctrl


def bezier_derivatives(ctrl: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives (n, 3) each of the cubic ctrl (4, 3) at t (n,)."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    d1 = 3.0 * np.diff(ctrl, axis=0)  # (3, 3): hodograph control points
    d2 = 2.0 * np.diff(d1, axis=0)  # (2, 3)
    u = 1.0 - t
    first = u**2 * d1[0] + 2 * u * t * d1[1] + t**2 * d1[2]
    second = u * d2[0] + t * d2[1]
    return first, second
