"""The ABC-NEF edge evaluation protocol, as published with EMAP and reused by EdgeGaussians.

Predicted edges (lines, cubic Béziers, polylines) are sampled every ``SAMPLE_SPACING``
(n = floor(length / spacing) points, endpoints included), the predicted samples are averaged
per cell of a 256^3 voxel grid over [-1, 1]^3 (continued beyond it), and the result is
compared with ground-truth edge samples by nearest-neighbour distances:

* Accuracy: mean distance from each prediction point to the nearest GT point (mm).
* Completeness: mean distance from each GT point to the nearest prediction point (mm).
* Precision / recall at tau: share of prediction / GT points whose distance is < tau (%).
* F-score: harmonic mean of precision and recall (%).

Scenes are normalised to the unit cube, so "mm" means 1/1000 of a scene unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from edgedog.bezier import bezier_derivatives, bezier_points

SAMPLE_SPACING = 0.005
THRESHOLDS = (0.005, 0.01, 0.02)
VOXELS_PER_AXIS = 256
VOXEL_BOUNDS = (-1.0, 1.0)

MAX_SAMPLES = 10_000_000
"""Most points one file's curves may be sampled into (every 5 mm: 50 km of curves in a unit-sized
scene). An ABC object's ground truth has 10^4 to 10^5 samples and a dense prediction a few times
that; a file over the limit is broken or in other units, and sampling it would take gigabytes."""

# Gauss-Legendre rule for Bézier arc lengths: 8 nodes on each of 64 equal subintervals of t
# integrates |B'(t)| to ~1e-12 relative even for strongly curved control polygons.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_GL_SUBINTERVALS = 64


def sample_line(a: np.ndarray, b: np.ndarray, spacing: float = SAMPLE_SPACING) -> np.ndarray:
    """Sample the segment a-b (each (3,)) with EMAP's rule; returns (n, 3).

    n = floor(|b - a| / spacing) points at ``linspace(0, 1, n)``: both endpoints are included
    when n >= 2, and segments shorter than ``spacing`` give no points at all.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    n = int(np.linalg.norm(b - a) // spacing)
    t = np.linspace(0.0, 1.0, n)[:, None]
    return a + t * (b - a)


def sample_count(lengths: np.ndarray, spacing: float = SAMPLE_SPACING) -> float:
    """How many samples curves of these lengths (any shape) get: sum of floor(length / spacing),
    as a float so that absurd lengths do not overflow."""
    return float(np.sum(np.floor(np.asarray(lengths, dtype=np.float64) / spacing)))


def points_along(points: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """(n, 3) the points of a polyline (M, 3) at `fractions` (n,) of its arc length (0: its first
    vertex, 1: its last)."""
    lengths = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    at = np.asarray(fractions, dtype=np.float64) * lengths[-1]
    return np.stack([np.interp(at, lengths, points[:, k]) for k in range(3)], axis=1)


def sample_polyline(points: np.ndarray, spacing: float = SAMPLE_SPACING) -> np.ndarray:
    """Sample a polyline (M, 3) uniformly in arc length; returns (n, 3).

    n = floor(arclen / spacing) samples at ``linspace(0, arclen, n)``, so a two-point polyline
    gives exactly :func:`sample_line`'s points. Zero-length segments (repeated vertices) are
    harmless: they add no arc length.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) < 2:
        return np.empty((0, 3))
    seg_len = np.linalg.norm(np.diff(points, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    n = int(cum[-1] // spacing)
    s = np.linspace(0.0, cum[-1], n)
    # Segment holding each sample; side="right" - 1 skips zero-length segments, and the clip
    # puts s == arclen on the last segment.
    seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg_len) - 1)
    length = seg_len[seg]
    frac = np.divide(s - cum[seg], length, out=np.zeros_like(s), where=length > 0)
    return points[seg] + frac[:, None] * (points[seg + 1] - points[seg])


def _bezier_arclength(ctrl: np.ndarray) -> float:
    """Arc length of a cubic Bézier (4, 3) by composite Gauss-Legendre quadrature of |B'(t)|."""
    edges = np.linspace(0.0, 1.0, _GL_SUBINTERVALS + 1)
    half = 0.5 * np.diff(edges)
    t = ((edges[:-1] + edges[1:]) * 0.5)[:, None] + half[:, None] * _GL_NODES  # (S, 8)
    speed = np.linalg.norm(bezier_derivatives(ctrl, t.ravel())[0], axis=1)
    return float(np.sum(speed.reshape(_GL_SUBINTERVALS, -1) * _GL_WEIGHTS * half[:, None]))


def sample_cubic_bezier(ctrl: np.ndarray, spacing: float = SAMPLE_SPACING) -> np.ndarray:
    """Sample a cubic Bézier given by its control points (4, 3); returns (n, 3).

    n = floor(arclen / spacing) samples, uniform in the parameter t (not in arc length), as
    EMAP's evaluation does.
    """
    ctrl = np.asarray(ctrl, dtype=np.float64).reshape(4, 3)
    n = int(_bezier_arclength(ctrl) // spacing)
    return bezier_points(ctrl, np.linspace(0.0, 1.0, n))


def voxel_mean(
    points: np.ndarray,
    voxels_per_axis: int = VOXELS_PER_AXIS,
    bounds: tuple[float, float] = VOXEL_BOUNDS,
) -> np.ndarray:
    """Replace the points (N, 3) of each occupied voxel by their mean; returns (M, 3) float64.

    The grid has ``voxels_per_axis`` cells per axis over [lo, hi]^3 and continues beyond it: a
    point's cell is floor((p - lo) / size), and points outside the bounds are kept in cells of
    the extended grid, as point_cloud_utils' `downsample_point_cloud_on_voxel_grid` (which
    EMAP's evaluation calls) does. Non-finite points are dropped. Rows are ordered by cell.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]  # a NaN or Inf point has no cell
    lo, hi = bounds
    size = (hi - lo) / voxels_per_axis
    cell = np.floor((points - lo) / size).astype(np.int64)
    _, inverse, counts = np.unique(cell, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)  # NumPy 2.0.0 (allowed by pyproject) returns it 2-D along an axis
    sums = np.stack(
        [np.bincount(inverse, weights=points[:, k], minlength=len(counts)) for k in range(3)],
        axis=1,
    )
    return sums / counts[:, None]


def _mm(tau: float) -> int:
    """Threshold in scene units -> integer millimetres (0.005 -> 5)."""
    return int(round(tau * 1000))


@dataclass(frozen=True)
class EdgeMetrics:
    """Scores of one prediction against one ground truth.

    Distances are in mm; precision, recall and fscore map a threshold in mm (e.g. 5, 10, 20)
    to a percentage in [0, 100].
    """

    accuracy_mm: float
    completeness_mm: float
    precision: dict[int, float]
    recall: dict[int, float]
    fscore: dict[int, float]
    num_pred: int
    num_gt: int

    def to_dict(self) -> dict[str, float | int]:
        """Flat JSON-ready dict: acc_mm, comp_mm, precision_5mm, recall_5mm, fscore_5mm, ..."""
        out: dict[str, float | int] = {
            "acc_mm": self.accuracy_mm,
            "comp_mm": self.completeness_mm,
        }
        for mm in self.precision:
            out[f"precision_{mm}mm"] = self.precision[mm]
            out[f"recall_{mm}mm"] = self.recall[mm]
            out[f"fscore_{mm}mm"] = self.fscore[mm]
        out["num_pred"] = self.num_pred
        out["num_gt"] = self.num_gt
        return out

    def table(self) -> str:
        """Human-readable summary: a P/R/F row per threshold, then accuracy and completeness."""
        lines = [f"{'tau':>6}  {'P (%)':>7}  {'R (%)':>7}  {'F (%)':>7}"]
        for mm in self.precision:
            lines.append(
                f"{f'{mm}mm':>6}  {self.precision[mm]:7.2f}  {self.recall[mm]:7.2f}"
                f"  {self.fscore[mm]:7.2f}"
            )
        lines.append(f"Acc  {self.accuracy_mm:8.3f} mm  ({self.num_pred} pred points)")
        lines.append(f"Comp {self.completeness_mm:8.3f} mm  ({self.num_gt} GT points)")
        return "\n".join(lines)


def score_points(
    pred: np.ndarray, gt: np.ndarray, thresholds: tuple[float, ...] = THRESHOLDS
) -> EdgeMetrics:
    """Compare prediction points (N, 3) with GT points (M, 3), without any voxelisation.

    Raises ValueError when either set is empty (no distance can be defined).
    """
    pred = np.asarray(pred, dtype=np.float64).reshape(-1, 3)
    gt = np.asarray(gt, dtype=np.float64).reshape(-1, 3)
    if len(pred) == 0:
        raise ValueError("the prediction has no points to evaluate (no edges, or all too short)")
    if len(gt) == 0:
        raise ValueError("the ground truth has no points to evaluate")
    d_pred, _ = cKDTree(gt).query(pred, k=1)  # pred -> nearest GT
    d_gt, _ = cKDTree(pred).query(gt, k=1)  # GT -> nearest pred
    precision, recall, fscore = {}, {}, {}
    for tau in thresholds:
        p = 100.0 * float(np.mean(d_pred < tau))
        r = 100.0 * float(np.mean(d_gt < tau))
        mm = _mm(tau)
        precision[mm], recall[mm] = p, r
        fscore[mm] = 2.0 * p * r / (p + r) if p + r > 0 else 0.0
    return EdgeMetrics(
        accuracy_mm=1000.0 * float(np.mean(d_pred)),
        completeness_mm=1000.0 * float(np.mean(d_gt)),
        precision=precision,
        recall=recall,
        fscore=fscore,
        num_pred=len(pred),
        num_gt=len(gt),
    )


def evaluate(pred_points: np.ndarray, gt_points: np.ndarray, voxelize: bool = True) -> EdgeMetrics:
    """Score sampled prediction points (N, 3) against GT edge samples (M, 3).

    As in the protocol, only the prediction is voxel-averaged (this evens out predictions that
    pile many points on the same spot); the GT samples are used as they are.
    """
    pred = voxel_mean(pred_points) if voxelize else pred_points
    return score_points(pred, gt_points)
