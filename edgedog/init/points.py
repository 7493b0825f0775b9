"""The initial point cloud a model starts from, and the per-point scale heuristic."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

METHODS = ("triangulated", "uniform", "sfm-points", "edge-vote")


@dataclass
class InitialPoints:
    """Where the Gaussians start.

    Attributes:
        positions: (N, 3) float64 world coordinates.
        scales: (N,) float64 initial isotropic scale (standard deviation) per point, world units.
        method: "triangulated" | "uniform" | "sfm-points" | "edge-vote".
        report: JSON-ready facts about how the points were made: counts, thresholds, and, when
            an automatic choice fell back to another method, why.
        sight: (N, 3) float64 or None: for each point, the mean unit direction toward the views
            that saw it ('edge-vote'), from which a view-dependent opacity can start.
    """

    positions: np.ndarray
    scales: np.ndarray
    method: str
    report: dict[str, Any] = field(default_factory=dict)
    sight: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.positions = np.asarray(self.positions, dtype=np.float64).reshape(-1, 3)
        self.scales = np.asarray(self.scales, dtype=np.float64).reshape(-1)
        if len(self.scales) != len(self.positions):
            raise ValueError(f"{len(self.scales)} scales for {len(self.positions)} points")
        if self.sight is not None:
            self.sight = np.asarray(self.sight, dtype=np.float64).reshape(-1, 3)
            if len(self.sight) != len(self.positions) or not np.all(np.isfinite(self.sight)):
                raise ValueError(f"sight must be {len(self.positions)} finite directions")
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")

    def __len__(self) -> int:
        return len(self.positions)


def nearest_neighbour_scales(points: np.ndarray, k: int = 3, lo: float = 0.0,
                             hi: float = np.inf) -> np.ndarray:
    """Mean distance of each point to its `k` nearest neighbours, clipped to [lo, hi].

    Args:
        points: (N, 3) positions.
        k: neighbours averaged (fewer when the cloud has fewer than k + 1 points).
        lo, hi: clip range; duplicates (distance 0) get `lo`.
    Returns:
        (N,) float64. A single point has no neighbour: it gets `lo` if positive, else `hi` if
        finite (and a ValueError when neither gives a usable scale).
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if k < 1:
        raise ValueError(f"k must be at least 1, got {k}")
    if lo > hi:
        raise ValueError(f"lo ({lo}) is larger than hi ({hi})")
    n = len(points)
    if n == 0:
        return np.zeros(0)
    neighbours = min(k, n - 1)
    if neighbours == 0:
        if lo > 0:
            return np.full(n, float(lo))
        if np.isfinite(hi):
            return np.full(n, float(hi))
        raise ValueError("one point has no neighbour to take a scale from; give lo or hi")
    # The nearest hit of each query is the point itself (distance 0): ask for one more.
    distances, _ = cKDTree(points).query(points, k=neighbours + 1)
    return np.clip(distances[:, 1:].mean(axis=1), lo, hi)
