"""Spacing control: primitives held at a target spacing along the edges, so that their number
follows the length of edge a scene holds rather than the initialisation's count (issue 43).

A spacing event (`DensityStrategy`, at `strategy.spacing_epochs`) does two things:

- `redundant`: of primitives whose centres are closer than the spacing and where the edge runs
  in directions within an angle of each other (they cover the same stretch of edge), the one
  ranked first stays and the others go: a greedy non-maximum suppression against the kept
  ones in a hash of cells of side the spacing, O(N) whatever the density. Two edges that meet
  at an angle keep both.
- `split_pieces`: an elongated primitive longer than the spacing (its largest scale above it) is
  cut into pieces along its major axis (`split_offsets` places them).

The edge's direction at a primitive is the principal axis of its nearest neighbours' centres
(`edge_directions`), not the primitive's own major axis: trained primitives are nearly round
(their largest scale 1.1-1.3 times the second, measured on `quick` runs), and a round one's
major axis points anywhere. Along an edge of length L covered densely, L / (1 to 2 spacings)
primitives stay. The edge vote's start is thinned by the same suppression, on distance alone
(`edgedog.init.edge_vote.thin_to_spacing`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

CENTRAL_SHARE = (1.0, 99.0)
"""Percentiles of the centres along each axis that bound the primitives' extent (the outliers
left off the edges do not count)."""


def spacing_length(means: np.ndarray, spacing: float, relative: bool) -> float:
    """The spacing in scene units: `spacing` itself, or with `relative` that share of the largest
    side of the box holding the central 98 % of the centres (N, 3) along each axis (0 for fewer
    than two primitives)."""
    if not relative:
        return spacing
    if len(means) < 2:
        return 0.0
    low, high = np.percentile(means, CENTRAL_SHARE, axis=0)
    return spacing * float((high - low).max())


def cell_indices(means: np.ndarray, side: float) -> np.ndarray:
    """(N, 3) int64 index of the cell of side `side` holding each centre of `means` (N, 3),
    counted from the lowest corner of their box (small whatever the coordinates' origin)."""
    return np.floor((means - means.min(axis=0)) / side).astype(np.int64)


def edge_directions(means: np.ndarray, neighbours: int, spacing: float) -> np.ndarray:
    """(N, 3) unit direction of the edge at each centre of `means` (N, 3), on the scale of the
    spacing whatever the density: the centres are averaged in cells of side spacing / 2, and
    each cell's direction is the principal axis of its own and its `neighbours` nearest cells'
    averages (one KD-tree query, one 3x3 eigenproblem per cell), given to its centres."""
    n = len(means)
    if n < 2 or spacing <= 0:
        return np.tile(np.array([1.0, 0.0, 0.0]), (n, 1))
    _, cell, members = np.unique(cell_indices(means, spacing / 2), axis=0, return_inverse=True,
                                 return_counts=True)
    cell = cell.reshape(-1)
    averages = np.stack([np.bincount(cell, weights=means[:, k]) for k in range(3)], axis=1) / members[:, None]
    if len(averages) < 2:
        return np.tile(np.array([1.0, 0.0, 0.0]), (n, 1))
    _, found = cKDTree(averages).query(averages, k=min(neighbours + 1, len(averages)))
    local = averages[found] - averages[found].mean(axis=1, keepdims=True)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    return vectors[:, :, -1][cell]


def redundant(means: np.ndarray, axes: np.ndarray, rank: np.ndarray, spacing: float,
              max_angle: float) -> np.ndarray:
    """(N,) bool: the primitives to remove so that no two kept ones cover the same stretch of edge.

    Two primitives conflict when their centres are closer than `spacing` and their `axes` lie
    within `max_angle` degrees of each other (either sign). In decreasing `rank`, a primitive
    stays unless a kept one conflicts with it (a greedy non-maximum suppression): every removed
    primitive has a kept one at least as highly ranked within the spacing. The kept ones are
    found in a hash of cells of side `spacing` (the 27 cells around a centre): since they are
    a spacing apart along an edge, each cell holds a few, and the cost is O(N) whatever the
    density.

    Args:
        means: (N, 3) centres; axes: (N, 3) unit directions of the edge at them
            (`edge_directions`); rank: (N,) higher stays first (ties: the lower index).
    """
    n = len(means)
    removed = np.zeros(n, dtype=bool)
    if n < 2 or spacing <= 0:
        return removed
    cells = [tuple(c) for c in cell_indices(means, spacing).tolist()]
    points, directions = means.tolist(), axes.tolist()
    around = [(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)]
    limit, least_cos = spacing * spacing, math.cos(math.radians(max_angle))
    kept: dict[tuple[int, int, int], list[int]] = {}
    for i in np.argsort(-rank, kind="stable").tolist():
        (cx, cy, cz), (px, py, pz), (ax, ay, az) = cells[i], points[i], directions[i]
        conflict = False
        for dx, dy, dz in around:
            for j in kept.get((cx + dx, cy + dy, cz + dz), ()):
                qx, qy, qz = points[j]
                bx, by, bz = directions[j]
                if ((px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2 < limit
                        and abs(ax * bx + ay * by + az * bz) >= least_cos):
                    conflict = True
                    break
            if conflict:
                break
        if conflict:
            removed[i] = True
        else:
            kept.setdefault(cells[i], []).append(i)
    return removed


ELONGATED = 2.0
"""A primitive is cut only when its largest scale is at least this many times its second: the
major axis of a round one is no edge direction, and its size is no length of edge."""


def split_pieces(scales: np.ndarray, spacing: float, most: int, room: int) -> np.ndarray:
    """(N,) pieces each primitive is cut into: ceil(largest scale / spacing), at most `most`, for
    an `ELONGATED` one; 1 for one no longer than `spacing` or not elongated. The longest are cut
    first while the pieces add at most `room` primitives; the others stay whole.

    Args:
        scales: (N, 3) each primitive's scales (scene units).
    """
    pieces = np.ones(len(scales), dtype=np.int64)
    if spacing <= 0 or not len(scales):
        return pieces
    ordered = np.sort(scales, axis=1)
    largest_scale = ordered[:, 2]
    wanted = np.clip(np.ceil(largest_scale / spacing), 1, most).astype(np.int64)
    wanted[largest_scale < ELONGATED * ordered[:, 1]] = 1
    order = np.argsort(-largest_scale, kind="stable")
    extra = np.cumsum(wanted[order] - 1)
    fits = order[extra <= room]
    pieces[fits] = wanted[fits]
    return pieces


def split_offsets(pieces: np.ndarray) -> np.ndarray:
    """(sum(pieces),) each piece's offset along its source's major axis, in units of the source's
    largest scale s: a primitive cut into m pieces puts them at s (2j + 1 - m) / m, j = 0..m-1,
    evenly over [-s, s], each with largest scale s / m. Sources in order, their pieces together."""
    if not len(pieces):
        return np.zeros(0)
    return np.concatenate([(2 * np.arange(m) + 1 - m) / m for m in pieces.tolist()])
