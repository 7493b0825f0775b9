"""Spacing control: primitives held at a target spacing along the edges, so that their number
follows the length of edge a scene holds rather than the initialisation's count (issue 43).

A spacing event (`DensityStrategy`, at `strategy.spacing_epochs`) does two things:

- `redundant`: of primitives whose centres are closer than the spacing and whose major axes
  lie within an angle of each other (they cover the same stretch of edge), the one ranked
  first stays and the others go: a greedy non-maximum suppression over each primitive's k
  nearest neighbours from a KD-tree, O(N k log N) whatever the density, repeated on the
  survivors where more than k crowd within the spacing. Two edges that meet at an angle keep
  both.
- `split_pieces`: an elongated primitive longer than the spacing (its largest scale above it) is
  cut into pieces along its major axis (`split_offsets` places them).

Along an edge of length L covered densely, about L / spacing primitives stay.
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


MAX_ROUNDS = 8
"""Suppression rounds at most: each round's survivors are a few times sparser than its input, so
after two or three a primitive's nearest neighbours reach past the spacing."""


def redundant(means: np.ndarray, axes: np.ndarray, rank: np.ndarray, spacing: float, max_angle: float,
              neighbours: int) -> np.ndarray:
    """(N,) bool: the primitives to remove so that no two kept ones cover the same stretch of edge.

    Two primitives conflict when their centres are closer than `spacing` and their major axes
    lie within `max_angle` degrees of each other (either sign). Each primitive looks only at its
    `neighbours` nearest centres (one KD-tree query: bounded cost whatever the density); in
    decreasing `rank`, one that no kept primitive conflicts with stays and removes the undecided
    ones it conflicts with. Where more than `neighbours` crowd within the spacing, the survivors
    go through the same round again (at most `MAX_ROUNDS`), until a round removes none.

    Args:
        means: (N, 3) centres; axes: (N, 3) unit major axes; rank: (N,) higher stays first
            (ties: the lower index).
    """
    alive = np.arange(len(means))
    for _ in range(MAX_ROUNDS):
        gone = _suppressed(means[alive], axes[alive], rank[alive], spacing, max_angle, neighbours)
        if not gone.any():
            break
        alive = alive[~gone]
    removed = np.ones(len(means), dtype=bool)
    removed[alive] = False
    return removed


def _suppressed(means: np.ndarray, axes: np.ndarray, rank: np.ndarray, spacing: float, max_angle: float,
                neighbours: int) -> np.ndarray:
    """(N,) bool: one round of `redundant` over each primitive's `neighbours` nearest centres."""
    n = len(means)
    if n < 2 or spacing <= 0:
        return np.zeros(n, dtype=bool)
    tree = cKDTree(means)
    distances, found = tree.query(means, k=min(neighbours + 1, n), distance_upper_bound=spacing)
    inside = (found < n) & (distances < spacing) & (found != np.arange(n)[:, None])
    others = np.where(inside, found, 0)
    cosines = np.abs(np.einsum("nd,nkd->nk", axes, axes[others]))
    conflicts = inside & (cosines >= math.cos(math.radians(max_angle)))
    lists = [row[mask].tolist() for row, mask in zip(others, conflicts)]
    undecided, kept, removed = 0, 1, 2
    state = bytearray(n)
    for i in np.argsort(-rank, kind="stable").tolist():
        if state[i] == removed:
            continue
        if any(state[j] == kept for j in lists[i]):
            state[i] = removed
            continue
        state[i] = kept
        for j in lists[i]:
            if state[j] == undecided:
                state[j] = removed
    return np.frombuffer(bytes(state), dtype=np.uint8) == removed


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
