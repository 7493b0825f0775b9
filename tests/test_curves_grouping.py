"""Spur pruning of the spanning forest: side branches go, a path through each junction stays."""

from __future__ import annotations

import numpy as np

from edgedog.curves.grouping import prune_spurs


def _links(*paths: list[int]) -> np.ndarray:
    """(E, 2) links along each path of vertex indices."""
    return np.array([pair for path in paths for pair in zip(path[:-1], path[1:])], dtype=np.int64)


def _as_set(edges: np.ndarray) -> set[tuple[int, int]]:
    return {tuple(sorted(map(int, e))) for e in edges}


def test_a_side_branch_of_a_long_curve_is_pruned():
    # A straight curve of 11 vertices along x with a two-link twig off its middle.
    vertices = np.array([[i, 0, 0] for i in range(11)] + [[5, 1, 0], [5, 2, 0]], float)
    curve = list(range(11))
    kept = prune_spurs(_links(curve, [5, 11, 12]), vertices, 4)
    assert _as_set(kept) == _as_set(_links(curve))


def test_at_a_frayed_end_the_twig_that_continues_the_curve_is_kept():
    # Vertices 0-9 along x; at vertex 9 the tube frays into a twig straight on (10, 11) and one
    # bent off (12, 13): the straight one is the curve's end.
    vertices = np.array([[i, 0, 0] for i in range(12)] + [[10, 1, 0], [11, 2, 0]], float)
    curve = list(range(10))
    kept = prune_spurs(_links(curve, [9, 12, 13], [9, 10, 11]), vertices, 4)
    assert _as_set(kept) == _as_set(_links(list(range(12))))


def test_a_short_edge_joined_as_a_star_stays_a_path():
    # Four vertices of a short edge (along y), the forest joining three of them to the fourth.
    vertices = np.array([[0, 0, 0], [0, 1, 0], [0, -1, 0], [0, 2, 0]], float)
    kept = prune_spurs(_links([0, 1, 3], [0, 2]), vertices, 4)
    # The two longest branches stay (1-3 and one of the single links): one path of four.
    assert len(kept) == 3
    degree = np.bincount(kept.ravel(), minlength=4)
    assert sorted(degree.tolist()) == [1, 1, 2, 2]


def test_pruning_repeats_until_no_spur_is_left_and_keeps_a_lone_path():
    vertices = np.array([[i, 0, 0] for i in range(3)], float)
    path = _links([0, 1, 2])
    assert _as_set(prune_spurs(path, vertices, 4)) == _as_set(path)
