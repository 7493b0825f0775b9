"""Chains -> the curves they follow: broken curves joined, short isolated chains dropped as
noise, and chains split where their curve ends (at corners and junctions)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from edgedog.curves.grouping import Chain
from edgedog.curves.junctions import end_clusters


def turning_angles(points: np.ndarray, closed: bool, window: int) -> np.ndarray:
    """Degrees (M,) between the chords `window` vertices behind and ahead of each vertex of a
    chain (M, 3); 0 where an open chain has too few vertices on either side."""
    m = len(points)
    index = np.arange(m)
    behind, ahead = index - window, index + window
    if closed:
        behind, ahead = behind % m, ahead % m
    inner = (behind >= 0) & (ahead < m)
    a = points[index[inner]] - points[behind[inner]]
    b = points[ahead[inner]] - points[index[inner]]
    cos = np.sum(a * b, axis=1) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-18)
    angles = np.zeros(m)
    angles[inner] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return angles


def _cut(chain: Chain, cuts: list[int]) -> list[Chain]:
    """Cut a chain at vertex indices (each cut vertex ends one piece and starts the next)."""
    cuts = sorted(set(cuts))
    if not cuts:
        return [chain]
    p = chain.points
    if chain.closed:  # start at the first cut: the loop opens into pieces between cuts
        p = np.roll(p, -cuts[0], axis=0)
        p = np.vstack([p, p[:1]])
        cuts = [c - cuts[0] for c in cuts] + [len(p) - 1]
    else:
        cuts = [0] + [c for c in cuts if 0 < c < len(p) - 1] + [len(p) - 1]
    return [Chain(p[a:b + 1]) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def split_at_corners(chain: Chain, max_turn: float, window: int = 2) -> list[Chain]:
    """Split a chain where it turns by more than `max_turn` degrees over `window` vertices.

    The cut is the vertex of largest turn in its neighbourhood, so a corner spread over a few
    vertices is cut once.
    """
    angles = turning_angles(chain.points, chain.closed, window)
    m = len(angles)
    cuts: list[int] = []
    for i in np.argsort(-angles, kind="stable"):
        if angles[i] <= max_turn:
            break
        near = [abs(i - c) if not chain.closed else min(abs(i - c), m - abs(i - c)) for c in cuts]
        if all(d > window for d in near):
            cuts.append(int(i))
    return _cut(chain, cuts)


def split_at_junctions(chains: list[Chain], radius: float, window: int = 3) -> list[Chain]:
    """Split chains where another chain ends against their interior (a T or Y junction).

    An open chain's end that points at a vertex of another chain (within `radius` of the end's
    tangent ray, at most twice `radius` ahead) cuts that chain there, unless the vertex is
    within twice `radius` of that chain's own ends (a corner, which snapping joins).
    """
    if len(chains) < 2:
        return chains
    owner = np.concatenate([np.full(len(c.points), k) for k, c in enumerate(chains)])
    position = np.concatenate([np.arange(len(c.points)) for c in chains])
    vertices = np.concatenate([c.points for c in chains])
    tree = cKDTree(vertices)
    cuts: list[list[int]] = [[] for _ in chains]
    for k, chain in enumerate(chains):
        if chain.closed:
            continue
        for end, tangent in zip(chain.points[[0, -1]], _end_tangents(chain, window)):
            near = np.asarray(tree.query_ball_point(end, 2 * radius), dtype=np.int64)
            near = near[owner[near] != k]
            ahead = (vertices[near] - end) @ tangent
            off_ray = np.linalg.norm(vertices[near] - end - np.outer(ahead, tangent), axis=1)
            near = near[(ahead > -radius) & (off_ray < radius)]
            if not len(near):
                continue
            hit = near[np.argmin(np.linalg.norm(vertices[near] - end, axis=1))]
            other = chains[owner[hit]]
            from_ends = np.linalg.norm(other.points[[0, -1]] - vertices[hit], axis=1)
            if other.closed or np.all(from_ends > 2 * radius):
                cuts[owner[hit]].append(int(position[hit]))
    return [piece for chain, cut in zip(chains, cuts) for piece in _cut(chain, cut)]


def _end_tangents(chain: Chain, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit tangents (3,) at the first and last vertex, from chords over `window` vertices."""
    p = chain.points
    w = min(window, len(p) - 1)
    start, end = p[0] - p[w], p[-1] - p[-1 - w]
    return start / max(np.linalg.norm(start), 1e-18), end / max(np.linalg.norm(end), 1e-18)


def join_chains(chains: list[Chain], max_gap: float, min_cos: float, window: int = 3) -> list[Chain]:
    """Join open chains whose ends face each other across a gap: a curve broken by a missing
    stretch of points becomes one chain again, and a chain whose ends meet closes into a loop.

    Two ends can join when they are within `max_gap` and their outward tangents point at each
    other and along the gap (cosines above `min_cos`); the shortest such gap is joined first.
    """
    chains = list(chains)
    while True:
        ends = [(k, side) for k, c in enumerate(chains) if not c.closed for side in (0, 1)]
        if len(ends) < 2:
            return chains
        tips = np.array([chains[k].points[0 if side == 0 else -1] for k, side in ends])
        tangents = np.array([_end_tangents(chains[k], window)[side] for k, side in ends])
        i, j = cKDTree(tips).query_pairs(max_gap, output_type="ndarray").T
        gap = np.linalg.norm(tips[j] - tips[i], axis=1)
        u = (tips[j] - tips[i]) / np.maximum(gap, 1e-18)[:, None]
        facing = (np.sum(tangents[i] * -tangents[j], axis=1) > min_cos) \
            & ((gap < 1e-12) | ((np.sum(u * tangents[i], axis=1) > min_cos)
                                & (np.sum(-u * tangents[j], axis=1) > min_cos)))
        if not facing.any():
            return chains
        best = np.flatnonzero(facing)[np.argmin(gap[facing])]
        (ka, sa), (kb, sb) = ends[i[best]], ends[j[best]]
        pa = chains[ka].points if sa == 1 else chains[ka].points[::-1]  # ends at the joined tip
        if ka == kb:
            chains[ka] = Chain(pa, closed=True)
            continue
        pb = chains[kb].points if sb == 0 else chains[kb].points[::-1]  # starts at the joined tip
        chains[ka] = Chain(np.vstack([pa, pb]))
        del chains[kb]


def drop_isolated(chains: list[Chain], min_vertices: int, radius: float) -> list[Chain]:
    """Drop chains of fewer than `min_vertices` vertices, unless one of their ends meets an end of
    a longer chain within `radius` (as `junctions.end_clusters` decides for curve ends).

    Alone, a short chain is noise; between two junctions of the forest, or as a short edge between
    two corners of the object (sparse points give it few vertices), it is part of the network,
    and dropping it would leave a gap.
    """
    if not chains:
        return chains
    labels = end_clusters([chain.points for chain in chains], radius).reshape(-1, 2)
    long_ = np.array([len(chain.points) >= min_vertices for chain in chains])
    anchored = np.isin(labels, labels[long_]).any(axis=1)
    return [chain for chain, keep in zip(chains, long_ | anchored) if keep]
