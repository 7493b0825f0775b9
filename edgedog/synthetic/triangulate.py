"""Triangulation of a planar polygon with holes by ear clipping: the flat faces of the parts.

Each hole is joined to the outer boundary by a two-way bridge (a zero-width cut), which leaves
one weakly simple polygon to clip ears from. Quadratic in the vertex count, fine for the few
hundred vertices of a cap.
"""

from __future__ import annotations

import numpy as np

EPS = 1e-12


def signed_area(loop: np.ndarray) -> float:
    """Area of a closed (N, 2) loop, positive when counter-clockwise."""
    x, y = loop.T
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z of (a - o) x (b - o); broadcasts over leading axes."""
    a, b = a - o, b - o
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def triangulate(outer: np.ndarray, holes: list[np.ndarray] | tuple[np.ndarray, ...] = ()) -> np.ndarray:
    """Triangles covering `outer` minus `holes`.

    Args:
        outer: (N, 2) boundary loop (not closed), either orientation.
        holes: (M_k, 2) loops strictly inside `outer`, disjoint from each other.
    Returns:
        (T, 3) int64 indices into np.concatenate([outer, *holes]), counter-clockwise.
    """
    points = np.concatenate([outer, *holes]).astype(np.float64)
    starts = np.cumsum([0, len(outer), *[len(h) for h in holes]])
    loops = [list(range(a, b)) for a, b in zip(starts[:-1], starts[1:])]
    # The region lies left of every boundary: outer counter-clockwise, holes clockwise.
    for number, loop in enumerate(loops):
        if (signed_area(points[loop]) > 0) != (number == 0):
            loop.reverse()
    polygon, holes_left = loops[0], sorted(loops[1:], key=lambda h: -points[h, 0].max())
    while holes_left:
        hole = holes_left.pop(0)
        polygon = _bridge(points, polygon, hole, holes_left)
    return np.array(_clip_ears(points, polygon), dtype=np.int64).reshape(-1, 3)


def _edges(loops: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
    """(E,) first and (E,) second vertex indices of every edge of the closed loops."""
    first = np.concatenate(loops)
    second = np.concatenate([np.roll(loop, -1) for loop in loops])
    return first, second


def _bridge(points: np.ndarray, polygon: list[int], hole: list[int], others: list[list[int]]) -> list[int]:
    """Splice `hole` into `polygon` through a cut from the hole's rightmost vertex M to the
    nearest polygon vertex right of M that it sees. One exists: the holes are taken from
    right to left, so the ray from M towards +x meets the polygon, and a visible vertex lies
    in the triangle it spans (the classic argument for this cut)."""
    m = hole[int(np.argmax(points[hole, 0]))]
    M = points[m]
    first, second = _edges([polygon, hole, *others])
    A, B = points[first], points[second]
    candidates = [k for k in range(len(polygon)) if points[polygon[k], 0] > M[0]]
    for k in sorted(candidates, key=lambda k: np.linalg.norm(points[polygon[k]] - M)):
        C = points[polygon[k]]
        # Edges that touch the cut's ends (by position: bridges duplicate vertices) cannot block it.
        free = ~((A == M).all(1) | (B == M).all(1) | (A == C).all(1) | (B == C).all(1))
        d1, d2 = _cross(M, C, A[free]), _cross(M, C, B[free])
        d3, d4 = _cross(A[free], B[free], M), _cross(A[free], B[free], C)
        if not np.any((d1 * d2 <= EPS) & (d3 * d4 <= EPS)):
            start = hole.index(m)
            return polygon[:k + 1] + hole[start:] + hole[:start] + [m] + polygon[k:]
    raise RuntimeError("triangulation: a hole cannot be joined to the boundary (does it overlap?)")


def _clip_ears(points: np.ndarray, polygon: list[int]) -> list[tuple[int, int, int]]:
    """Ear clipping of a weakly simple counter-clockwise polygon (vertex indices, repeats allowed)."""
    polygon, triangles, i, misses = list(polygon), [], 0, 0
    while len(polygon) > 3:
        n = len(polygon)
        a, b, c = polygon[(i - 1) % n], polygon[i % n], polygon[(i + 1) % n]
        if _is_ear(points, polygon, a, b, c):
            triangles.append((a, b, c))
            del polygon[i % n]
            i, misses = (i - 1) % len(polygon), 0
        else:
            i, misses = (i + 1) % n, misses + 1
            if misses > n:
                raise RuntimeError("triangulation: no ear left (self-intersecting outline?)")
    triangles.append(tuple(polygon))
    return triangles


def _is_ear(points: np.ndarray, polygon: list[int], a: int, b: int, c: int) -> bool:
    """Whether a-b-c turns left and no other vertex lies in or on the triangle."""
    A, B, C = points[a], points[b], points[c]
    if _cross(A, B, C) <= EPS:
        return False
    P = points[polygon]
    inside = (_cross(A, B, P) >= -EPS) & (_cross(B, C, P) >= -EPS) & (_cross(C, A, P) >= -EPS)
    corner = (P == A).all(1) | (P == B).all(1) | (P == C).all(1)
    return not np.any(inside & ~corner)
