"""Chains -> parametric pieces: RANSAC lines where straight, cubic Béziers elsewhere.

A piece is an array of control points: (2, 3) for a line segment, (4, 3) for a cubic Bézier.
"""

from __future__ import annotations

import numpy as np

from edgedog.bezier import bernstein, bezier_derivatives
from edgedog.curves.grouping import Chain

MIN_SPLIT_VERTICES = 4
"""Each half of a split keeps at least this many vertices (a cubic needs 4 to be determined)."""


def chord_parameters(points: np.ndarray) -> np.ndarray:
    """Chord-length parameters (M,) in [0, 1] of ordered points (M, 3)."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    return cum / cum[-1] if cum[-1] > 0 else np.linspace(0.0, 1.0, len(points))


def fit_bezier(points: np.ndarray, newton_steps: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares cubic Bézier (4, 3) from the first to the last of ordered points (M >= 4, 3),
    and each point's distance (M,) to it.

    The ends are pinned to the first and last point, so the pieces of a split chain meet; the
    inner control points are solved from chord-length parameters, and each Newton step moves
    every parameter to the foot of its point on the current curve before solving again.
    """
    t = chord_parameters(points)
    ends = points[[0, -1]]
    for step in range(newton_steps + 1):
        basis = bernstein(t)
        inner = np.linalg.lstsq(basis[:, 1:3], points - basis[:, [0, 3]] @ ends, rcond=None)[0]
        ctrl = np.vstack([ends[0], inner, ends[1]])
        residual = basis @ ctrl - points
        if step == newton_steps:
            break
        first, second = bezier_derivatives(ctrl, t)
        slope = np.sum(first * first + residual * second, axis=1)
        update = np.sum(residual * first, axis=1) / np.where(np.abs(slope) > 1e-12, slope, np.inf)
        t = np.clip(t - update, 0.0, 1.0)
    return ctrl, np.linalg.norm(residual, axis=1)


def line_through(points: np.ndarray) -> np.ndarray:
    """Total-least-squares segment (2, 3) spanning the projections of points (M, 3)."""
    centre = points.mean(axis=0)
    axis = np.linalg.svd(points - centre, full_matrices=False)[2][0] if len(points) > 2 \
        else points[-1] - points[0]
    axis = axis / max(np.linalg.norm(axis), 1e-18)
    s = (points - centre) @ axis
    # Keep the chain's orientation: the segment starts at the end nearest the first vertex.
    if s[0] > s[-1]:
        axis, s = -axis, -s
    return centre + np.outer([s.min(), s.max()], axis)


def ransac_line(points: np.ndarray, tolerance: float, max_outlier_share: float,
                rng: np.random.Generator, trials: int = 64) -> np.ndarray | None:
    """A segment (2, 3) when one line holds all but `max_outlier_share` of the points (M, 3)
    within `tolerance`, refitted to those inliers; None when the points are not straight."""
    m = len(points)
    if m < 3:
        return line_through(points)
    pairs = np.array([(a, b) for a in range(m) for b in range(a + 1, m)]) if m <= 12 \
        else rng.integers(0, m, size=(trials, 2))
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    a, b = points[pairs[:, 0]], points[pairs[:, 1]]
    axis = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True).clip(1e-18)
    offset = points[None] - a[:, None]  # (T, M, 3)
    along = np.einsum("tmc,tc->tm", offset, axis)
    distance = np.linalg.norm(offset - along[..., None] * axis[:, None], axis=2)
    inliers = distance < tolerance
    best = inliers[np.argmax(inliers.sum(axis=1))]
    if best.sum() < (1.0 - max_outlier_share) * m:
        return None
    line = line_through(points[best])
    # The refit moves the line: it must still hold the inliers.
    axis = line[1] - line[0]
    axis /= max(np.linalg.norm(axis), 1e-18)
    rel = points[best] - line[0]
    if np.max(np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)) > 1.5 * tolerance:
        return None
    return line


def fit_open(points: np.ndarray, line_tolerance: float, bezier_tolerance: float,
             max_outlier_share: float, rng: np.random.Generator) -> list[np.ndarray]:
    """Pieces along an open chain (M, 3), in order: a line if straight, else a Bézier whose RMS
    distance is under `bezier_tolerance`, else the chain is split at its worst point and each
    half is fitted the same way."""
    if len(points) < MIN_SPLIT_VERTICES:
        return [line_through(points)]
    line = ransac_line(points, line_tolerance, max_outlier_share, rng)
    if line is not None:
        return [line]
    ctrl, distance = fit_bezier(points)
    if np.sqrt(np.mean(distance**2)) <= bezier_tolerance or len(points) < 2 * MIN_SPLIT_VERTICES - 1:
        return [ctrl]
    lo, hi = MIN_SPLIT_VERTICES - 1, len(points) - MIN_SPLIT_VERTICES
    cut = int(np.clip(np.argmax(distance), max(lo, len(points) // 4), min(hi, 3 * len(points) // 4)))
    return (fit_open(points[:cut + 1], line_tolerance, bezier_tolerance, max_outlier_share, rng)
            + fit_open(points[cut:], line_tolerance, bezier_tolerance, max_outlier_share, rng))


def fit_chain(chain: Chain, line_tolerance: float, bezier_tolerance: float, max_outlier_share: float,
              rng: np.random.Generator) -> list[np.ndarray]:
    """Pieces along a chain; a closed chain is opened into two halves that share their ends."""
    p = chain.points
    args = (line_tolerance, bezier_tolerance, max_outlier_share, rng)
    if not chain.closed:
        return fit_open(p, *args)
    half = len(p) // 2
    return fit_open(p[:half + 1], *args) + fit_open(np.vstack([p[half:], p[:1]]), *args)
