"""Where pieces meet: merging collinear lines and snapping ends to shared junction points.

Pieces are (2, 3) lines or (4, 3) cubic Béziers (see `fitting`). Each has two ends: end 0 is its
first control point, end 1 its last.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

# Weight of the ends' centroid against the tangent lines when solving for a junction point:
# small, it only decides the position along tangents that are all parallel.
_CENTROID_WEIGHT = 0.1


def _ends(pieces: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """End points (2P, 3) and unit outward tangents (2P, 3); row 2p + e is end e of piece p."""
    points, tangents = [], []
    for piece in pieces:
        for end, inner in ((piece[0], piece[1:]), (piece[-1], piece[-2::-1])):
            # The nearest control point that differs from the end gives the tangent.
            away = end - inner
            length = np.linalg.norm(away, axis=1)
            k = int(np.argmax(length > 1e-12 * max(length.max(), 1e-300)))
            points.append(end)
            tangents.append(away[k] / max(length[k], 1e-300))
    return np.asarray(points).reshape(-1, 3), np.asarray(tangents).reshape(-1, 3)


def end_clusters(pieces: list[np.ndarray], radius: float) -> np.ndarray:
    """Cluster label (2P,) of each end; ends that meet share one, transitively.

    Two ends meet when they are within `radius`, or, up to twice that apart, when their
    tangents extended forwards pass within `radius` of each other at most twice `radius`
    beyond the ends: two curves that both stop short of a corner still meet at it. The two
    ends of one piece are never joined directly, so a short piece is not folded up.
    """
    points, tangents = _ends(pieces)
    pairs = cKDTree(points).query_pairs(2 * radius, output_type="ndarray")
    pairs = pairs[pairs[:, 0] // 2 != pairs[:, 1] // 2]
    i, j = pairs[:, 0], pairs[:, 1]
    w = points[i] - points[j]
    cos = np.sum(tangents[i] * tangents[j], axis=1)
    wi, wj = np.sum(tangents[i] * w, axis=1), np.sum(tangents[j] * w, axis=1)
    parallel = 1.0 - cos**2 < 1e-6
    s = np.where(parallel, 0.0, (cos * wj - wi) / np.where(parallel, 1.0, 1.0 - cos**2))
    u = wj + s * cos  # closest points: points[i] + s t_i and points[j] + u t_j
    gap = np.linalg.norm(w + s[:, None] * tangents[i] - u[:, None] * tangents[j], axis=1)
    reach = (s > -radius) & (s < 2 * radius) & (u > -radius) & (u < 2 * radius)
    meet = (np.linalg.norm(w, axis=1) < radius) | (~parallel & reach & (gap < radius))
    n = len(points)
    graph = coo_matrix((np.ones(meet.sum()), (i[meet], j[meet])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _distance_to_line(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    axis = (b - a) / max(np.linalg.norm(b - a), 1e-18)
    rel = points - a
    return np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)


def merge_collinear(pieces: list[np.ndarray], radius: float, tolerance: float) -> list[np.ndarray]:
    """Join two lines that meet end to end (and nothing else meets there) when one line holds
    all four endpoints within `tolerance`; repeated until no pair qualifies."""
    pieces = list(pieces)
    merged = True
    while merged:
        merged = False
        labels = end_clusters(pieces, radius)
        for label in np.unique(labels):
            ends = np.flatnonzero(labels == label)
            if len(ends) != 2:
                continue
            (p, e), (q, f) = divmod(ends[0], 2), divmod(ends[1], 2)
            if len(pieces[p]) != 2 or len(pieces[q]) != 2:
                continue
            far_a, far_b = pieces[p][1 - e], pieces[q][1 - f]
            if np.all(_distance_to_line(np.vstack([pieces[p], pieces[q]]), far_a, far_b) <= tolerance):
                pieces[p] = np.stack([far_a, far_b])
                del pieces[q]
                merged = True
                break  # labels are stale once a piece is gone
    return pieces


def junction_point(points: np.ndarray, tangents: np.ndarray) -> np.ndarray:
    """The point (3,) nearest, in least squares, to the lines through ends (n, 3) along their
    tangents (n, 3), pulled slightly to the ends' centroid; the corner of two lines that both
    stop short of it, or the crossing of three curves at a T."""
    projector = np.eye(3)[None] - tangents[:, :, None] * tangents[:, None, :]
    lhs = projector.sum(axis=0) + _CENTROID_WEIGHT * len(points) * np.eye(3)
    rhs = np.einsum("nij,nj->i", projector, points) + _CENTROID_WEIGHT * points.sum(axis=0)
    return np.linalg.solve(lhs, rhs)


def snap_ends(pieces: list[np.ndarray], radius: float) -> list[np.ndarray]:
    """Move the ends of pieces that meet within `radius` onto one junction point each.

    A Bézier's inner control point moves with its end, so its tangent there is unchanged. A
    junction point farther than `radius` from the ends' centroid (nearly parallel tangents
    that do not meet) is replaced by the centroid.
    """
    pieces = [piece.copy() for piece in pieces]
    points, tangents = _ends(pieces)
    labels = end_clusters(pieces, radius)
    for label in np.unique(labels):
        ends = np.flatnonzero(labels == label)
        # Snapping a piece's two ends together would fold it up: leave such clusters alone.
        if len(ends) < 2 or len(np.unique(ends // 2)) < len(ends):
            continue
        centroid = points[ends].mean(axis=0)
        target = junction_point(points[ends], tangents[ends])
        if np.linalg.norm(target - centroid) > radius:
            target = centroid
        for end in ends:
            piece, side = divmod(end, 2)
            tip, inner = (0, 1) if side == 0 else (-1, -2)
            shift = target - pieces[piece][tip]
            pieces[piece][tip] = target
            if len(pieces[piece]) == 4:
                pieces[piece][inner] += shift
    return pieces
