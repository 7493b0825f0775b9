"""Extruded profiles: the triangle mesh and the sharp feature curves of a straight prism.

A profile is a closed outline in the plane z = 0 made of chained segments and arcs. A prism
extrudes it from z0 to z1, minus through holes. Its sharp edges are the outline and hole
curves at both ends (caps meet walls at 90 degrees) and the vertical lines at the outline's
corners. Where two pieces join tangentially (a fillet meeting a flat) the wall is smooth:
no vertical line there, as ABC counts only sharp edges as features.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgedog.synthetic.features import Arc, Curve, Line
from edgedog.synthetic.triangulate import triangulate

ARC_STEP = np.radians(5.0)
"""Largest angle one wall facet spans on an arc (sagitta under 0.1% of the radius)."""
TANGENT_COS = np.cos(np.radians(1.0))
"""Pieces that meet at less than this angle join smoothly (no corner, no feature line)."""


def _lift(z: float) -> np.ndarray:
    """(4, 4) translation by z along the z axis."""
    matrix = np.eye(4)
    matrix[2, 3] = z
    return matrix


def _outward(tangents: np.ndarray) -> np.ndarray:
    """(n, 3) unit tangents in the z = 0 plane -> (n, 2) normals to their right (outward of a
    counter-clockwise loop)."""
    return np.stack([tangents[:, 1], -tangents[:, 0]], axis=1)


@dataclass(frozen=True)
class Mesh:
    """A triangle soup with per-corner normals (sharp edges get one normal per face).

    Attributes:
        positions: (T, 3, 3) float64 corners of each triangle, counter-clockwise seen from outside.
        normals: (T, 3, 3) float64 unit normals at those corners.
    """

    positions: np.ndarray
    normals: np.ndarray

    @staticmethod
    def concatenate(meshes: list[Mesh]) -> Mesh:
        return Mesh(np.concatenate([m.positions for m in meshes]),
                    np.concatenate([m.normals for m in meshes]))

    def transformed(self, matrix: np.ndarray) -> Mesh:
        """The mesh under a (4, 4) similarity transform."""
        normals = self.normals @ matrix[:3, :3].T
        return Mesh(self.positions @ matrix[:3, :3].T + matrix[:3, 3],
                    normals / np.linalg.norm(normals, axis=-1, keepdims=True))


@dataclass(frozen=True)
class Outline:
    """A closed loop in the plane z = 0, counter-clockwise seen from +z.

    Attributes:
        pieces: chained Lines and Arcs (z = 0), each ending where the next one starts.
    """

    pieces: tuple[Curve, ...]

    def loop(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The tessellated loop.

        Returns:
            points: (N, 2) vertices, not closed.
            normal_in: (N, 2) outward normal of the wall facet arriving at each vertex.
            normal_out: (N, 2) outward normal of the wall facet leaving each vertex.
        """
        points, normal_in, normal_out = [], [], []
        for number, piece in enumerate(self.pieces):
            steps = int(np.ceil(abs(piece.stop - piece.start) / ARC_STEP)) if isinstance(piece, Arc) else 1
            t = np.arange(steps) / steps
            out = _outward(piece.tangent(t))
            arriving = out.copy()
            arriving[0] = _outward(self.pieces[number - 1].tangent(np.ones(1)))[0]
            points.append(piece.at(t)[:, :2])
            normal_in.append(arriving)
            normal_out.append(out)
        return np.concatenate(points), np.concatenate(normal_in), np.concatenate(normal_out)

    def corners(self) -> np.ndarray:
        """(C, 3) joints where the outline turns sharply (z = 0)."""
        joints = [piece.at(np.zeros(1))[0] for number, piece in enumerate(self.pieces)
                  if np.dot(self.pieces[number - 1].tangent(np.ones(1))[0], piece.tangent(np.zeros(1))[0])
                  < TANGENT_COS]
        return np.array(joints).reshape(-1, 3)

    def curves_at(self, z: float) -> list[Curve]:
        return [piece.transformed(_lift(z)) for piece in self.pieces]


def polygon(vertices: list[tuple[float, float]]) -> Outline:
    """A closed polygon through (x, y) vertices in counter-clockwise order."""
    corners = [np.array([x, y, 0.0]) for x, y in vertices]
    return Outline(tuple(Line(a, b) for a, b in zip(corners, corners[1:] + corners[:1])))


def rectangle(x0: float, y0: float, x1: float, y1: float) -> Outline:
    return polygon([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])


def circle(cx: float, cy: float, radius: float) -> Outline:
    return Outline((Arc(np.array([cx, cy, 0.0]), np.array([radius, 0.0, 0.0]), np.array([0.0, radius, 0.0]),
                        0.0, 2 * np.pi),))


def rounded_rectangle(x0: float, y0: float, x1: float, y1: float, radius: float) -> Outline:
    """A rectangle whose four corners are quarter circles of `radius`, tangent to the sides."""
    pieces: list[Curve] = []
    centres = [(x1 - radius, y0 + radius), (x1 - radius, y1 - radius), (x0 + radius, y1 - radius),
               (x0 + radius, y0 + radius)]
    for quarter, (cx, cy) in enumerate(centres):
        start = (quarter - 1) * np.pi / 2
        arc = Arc(np.array([cx, cy, 0.0]), np.array([radius, 0.0, 0.0]), np.array([0.0, radius, 0.0]),
                  start, start + np.pi / 2)
        if pieces:  # the side from the previous arc's end to this arc's start
            pieces.append(Line(pieces[-1].at(np.ones(1))[0], arc.at(np.zeros(1))[0]))
        pieces.append(arc)
    pieces.append(Line(pieces[-1].at(np.ones(1))[0], pieces[0].at(np.zeros(1))[0]))
    return Outline(tuple(pieces))


@dataclass(frozen=True)
class Prism:
    """An outline extruded from z0 to z1.

    Attributes:
        outline: the outer boundary.
        z0, z1: bottom and top heights, z0 < z1.
        holes: outlines (counter-clockwise) of through holes.
        covered: outlines of top-cap regions covered by a prism standing on this one: cut out
            of the top cap so that the two meshes join without inner faces.
        bottom: False when the prism stands on another one's top cap (no bottom cap).
    """

    outline: Outline
    z0: float
    z1: float
    holes: tuple[Outline, ...] = ()
    covered: tuple[Outline, ...] = ()
    bottom: bool = True

    def mesh(self) -> Mesh:
        """Walls (outer and hole) and caps: a closed surface together with the prisms it joins."""
        points, normal_in, normal_out = self.outline.loop()
        parts = [_wall(points, normal_in, normal_out, self.z0, self.z1)]
        hole_loops = [hole.loop() for hole in self.holes]
        for pts, n_in, n_out in hole_loops:  # traversed backwards, facing into the hole
            parts.append(_wall(pts[::-1], -n_out[::-1], -n_in[::-1], self.z0, self.z1))
        hole_points = [pts for pts, _, _ in hole_loops]
        parts.append(_cap(points, hole_points + [c.loop()[0] for c in self.covered], self.z1, up=True))
        if self.bottom:
            parts.append(_cap(points, hole_points, self.z0, up=False))
        return Mesh.concatenate(parts)

    def curves(self) -> list[Curve]:
        """The sharp feature curves: outlines at both heights and vertical lines at corners."""
        curves: list[Curve] = []
        for outline in (self.outline, *self.holes):
            curves += outline.curves_at(self.z0) + outline.curves_at(self.z1)
            curves += [Line(c + [0, 0, self.z0], c + [0, 0, self.z1]) for c in outline.corners()]
        return curves


def _wall(points: np.ndarray, normal_in: np.ndarray, normal_out: np.ndarray, z0: float, z1: float) -> Mesh:
    """Two triangles per edge of a closed loop (N, 2) between heights z0 and z1, facing right of
    the direction of travel; normal_in / normal_out (N, 2) as `Outline.loop` gives them."""
    nxt = np.roll(np.arange(len(points)), -1)
    a0, b0 = np.c_[points, np.full(len(points), z0)], np.c_[points[nxt], np.full(len(points), z0)]
    a1, b1 = a0 + [0, 0, z1 - z0], b0 + [0, 0, z1 - z0]
    na, nb = np.c_[normal_out, np.zeros(len(points))], np.c_[normal_in[nxt], np.zeros(len(points))]
    positions = np.concatenate([np.stack([a0, b0, b1], 1), np.stack([a0, b1, a1], 1)])
    normals = np.concatenate([np.stack([na, nb, nb], 1), np.stack([na, nb, na], 1)])
    return Mesh(positions, normals)


def _cap(outer: np.ndarray, holes: list[np.ndarray], z: float, up: bool) -> Mesh:
    """The flat face at height z: the loop `outer` (N, 2) minus the loops `holes` (M_k, 2),
    facing +z (`up`) or -z."""
    vertices = np.concatenate([outer, *holes])
    triangles = triangulate(outer, holes)
    if not up:
        triangles = triangles[:, ::-1]
    positions = np.concatenate([vertices, np.full((len(vertices), 1), z)], axis=1)[triangles]
    normals = np.broadcast_to([0.0, 0.0, 1.0 if up else -1.0], positions.shape).copy()
    return Mesh(positions, normals)
