"""Oriented edge points -> ordered vertex chains, one per connected piece of curve.

The points of a trained model form a noisy tube around each edge, so a k-nearest-neighbour graph
of the raw points is a thick web, not a chain. Four steps turn it into chains:

1. smoothing: each point moves across its direction onto the centre of the nearby points that
   agree with that direction (points of a crossing edge do not pull it off its own edge);
2. thinning: the smoothed points are reduced to vertices about `spacing` apart;
3. linking: vertices are candidate neighbours when their directions and the vector between them
   agree; a minimum spanning forest of the candidates runs along each curve, with short side
   branches from the tube's width, which are pruned;
4. chaining: the forest is cut at its junctions into chains, and a chain whose two ends are
   candidate neighbours is a closed loop (a circle), not an open curve with a gap.

Corners and junctions that the direction test leaves connected are split in `topology`, which
also joins broken curves and drops the short chains that are noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import minimum_spanning_tree
from scipy.spatial import cKDTree

from edgedog.curve_files import chain_edges


@dataclass
class Chain:
    """Ordered vertices (M, 3) of one curve. A closed chain's last vertex links back to its first,
    which is not repeated."""

    points: np.ndarray
    closed: bool = False


def principal_axes(points: np.ndarray, neighbours: int) -> np.ndarray:
    """Unit principal axis (N, 3) of each point's `neighbours` nearest points (itself included)."""
    k = min(neighbours, len(points))
    _, idx = cKDTree(points).query(points, k=k)
    local = points[idx] - points[idx].mean(axis=1, keepdims=True)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    return vectors[:, :, 2]


SMOOTHING_NEIGHBOURS = 48
"""At most this many nearest points within the smoothing radius move each point."""
SMOOTHING_POOL = 20_000
"""Beyond this many points, the neighbours are drawn from a random subset of this size."""


def _weighted_sums(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Sum of rows of values (P, C) grouped by index (P,) into (n, C)."""
    return np.stack([np.bincount(index, weights=values[:, c], minlength=n)
                     for c in range(values.shape[1])], axis=1)


def smooth(points: np.ndarray, directions: np.ndarray, radius: float, min_cos: float,
           iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Move points (N, 3) across their directions (N, 3) onto the local centre line.

    Each iteration takes, for every point, itself and its nearest points within `radius` (at
    most `SMOOTHING_NEIGHBOURS`) whose direction agrees (|cos| > min_cos), replaces its
    direction by their weighted principal axis and moves it, only perpendicularly to that axis,
    to their weighted mean. Returns new points and directions.
    """
    n = len(points)
    # Dense runs: neighbours come from a fixed random pool, so that the nearest points still span
    # the radius and memory stays linear in N.
    pool = np.arange(n) if n <= SMOOTHING_POOL else \
        np.sort(np.random.default_rng(0).choice(n, SMOOTHING_POOL, replace=False))
    for _ in range(iterations):
        _, j = cKDTree(points[pool]).query(points, k=min(SMOOTHING_NEIGHBOURS, len(pool)),
                                           distance_upper_bound=radius)
        i = np.repeat(np.arange(n), j.shape[1])
        j = j.ravel()
        keep = j < len(pool)
        i, j = i[keep], pool[j[keep]]
        i, j = np.concatenate([i[i != j], np.arange(n)]), np.concatenate([j[i != j], np.arange(n)])
        keep = np.abs(np.sum(directions[i] * directions[j], axis=1)) > min_cos
        i, j = i[keep], j[keep]
        offset = points[j] - points[i]
        weight = np.exp(-2.0 * np.sum(offset**2, axis=1) / radius**2)  # Gaussian, sigma = radius / 2
        total = np.bincount(i, weights=weight, minlength=n)
        mean_offset = _weighted_sums(i, weight[:, None] * offset, n) / total[:, None]
        centred = offset - mean_offset[i]
        outer = (centred[:, :, None] * centred[:, None, :]).reshape(-1, 9)
        covariance = _weighted_sums(i, weight[:, None] * outer, n).reshape(n, 3, 3)
        axes = np.linalg.eigh(covariance)[1][:, :, 2]
        # A lone point (no agreeing neighbour) has a zero covariance: keep its direction.
        alone = np.bincount(i, minlength=n) < 3
        axes[alone] = directions[alone]
        across = mean_offset - np.sum(mean_offset * axes, axis=1, keepdims=True) * axes
        points, directions = points + across, axes
    return points, directions


def thin(points: np.ndarray, directions: np.ndarray, spacing: float,
         min_cos: float) -> tuple[np.ndarray, np.ndarray]:
    """Reduce points (N, 3) to vertices (K, 3) about `spacing` apart, with their directions (K, 3).

    Seeds are taken densest first; each seed covers the points within `spacing` and becomes the
    mean of those that agree with its direction.
    """
    tree = cKDTree(points)
    order = np.argsort(-tree.query_ball_point(points, spacing, return_length=True), kind="stable")
    covered = np.zeros(len(points), dtype=bool)
    vertices, axes = [], []
    for seed in order:
        if covered[seed]:
            continue
        ball = np.asarray(tree.query_ball_point(points[seed], spacing), dtype=np.int64)
        covered[ball] = True
        agree = ball[np.abs(directions[ball] @ directions[seed]) > min_cos]
        vertices.append(points[agree].mean(axis=0))
        axes.append(directions[seed])
    return np.asarray(vertices).reshape(-1, 3), np.asarray(axes).reshape(-1, 3)


def candidate_links(vertices: np.ndarray, directions: np.ndarray, max_distance: float, min_cos: float,
                    candidates: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (E, 2) of vertices (K, 3) that may be neighbours on one curve, and their lengths (E,).

    A pair qualifies when one is among the other's `candidates` nearest within `max_distance`
    and the two directions (K, 3) and the vector between the vertices are all parallel within
    |cos| > min_cos: points of a crossing or diverging edge are never linked.
    """
    n = len(vertices)
    if n < 2:
        return np.empty((0, 2), dtype=np.int64), np.empty(0)
    dist, idx = cKDTree(vertices).query(vertices, k=min(candidates + 1, n), distance_upper_bound=max_distance)
    i = np.repeat(np.arange(n), idx.shape[1] - 1)
    j, length = idx[:, 1:].ravel(), dist[:, 1:].ravel()  # column 0 is the vertex itself
    valid = j < n
    i, j, length = i[valid], j[valid], length[valid]
    u = (vertices[j] - vertices[i]) / np.maximum(length, 1e-18)[:, None]
    agree = ((np.abs(np.sum(u * directions[i], axis=1)) > min_cos)
             & (np.abs(np.sum(u * directions[j], axis=1)) > min_cos)
             & (np.abs(np.sum(directions[i] * directions[j], axis=1)) > min_cos))
    pairs, first = np.unique(np.sort(np.stack([i, j], axis=1)[agree], axis=1), axis=0, return_index=True)
    return pairs, length[agree][first]


def spanning_links(pairs: np.ndarray, lengths: np.ndarray, n: int) -> np.ndarray:
    """The links (E, 2) of a minimum spanning forest of the candidate graph over n vertices.

    In a noisy tube of vertices the forest is a main path with short side branches (pruned by
    `prune_spurs`); a ring of vertices loses exactly one link (restored by `chains_from_links`).
    """
    graph = coo_matrix((np.maximum(lengths, 1e-18), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    tree = minimum_spanning_tree(graph).tocoo()
    return np.stack([tree.row, tree.col], axis=1).astype(np.int64)


def prune_spurs(edges: np.ndarray, n: int, min_vertices: int) -> np.ndarray:
    """Remove side branches shorter than `min_vertices` links (from a leaf to the junction it
    hangs from) until none is left; returns the remaining links (E', 2)."""
    while True:
        degree = np.bincount(edges.ravel(), minlength=n)
        drop = set()
        for chain in chain_edges(edges, n):
            ends = degree[chain[[0, -1]]]
            if len(chain) - 1 < min_vertices and min(ends) == 1 and max(ends) >= 3:
                drop.update(tuple(sorted(pair)) for pair in zip(chain[:-1].tolist(), chain[1:].tolist()))
        if not drop:
            return edges
        edges = np.asarray([e for e in edges.tolist() if tuple(sorted(e)) not in drop],
                           dtype=np.int64).reshape(-1, 2)


def chains_from_links(vertices: np.ndarray, edges: np.ndarray, candidates: np.ndarray) -> list[Chain]:
    """Chains of vertices (K, 3) between ends and junctions of the forest links (E, 2), however
    short (`topology.drop_isolated` judges them once broken curves are joined); a chain whose
    two ends are a candidate pair (C, 2) is a closed loop."""
    closing = {tuple(pair) for pair in np.sort(candidates, axis=1).tolist()}
    chains = []
    for index in chain_edges(edges, len(vertices)):
        closed = len(index) > 2 and tuple(sorted((int(index[0]), int(index[-1])))) in closing
        chains.append(Chain(vertices[index], closed))
    return chains
