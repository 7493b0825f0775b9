"""The built-in parts, modelled with the CAD kernel (build123d): each design draws its sizes
(longest side about 1) from a generator and returns the solid with those sizes.

Profiles drawn in the xy plane and extruded along z are turned upright where they are side
views (`_stand_up`); chamfers and fillets are the kernel's.
"""

from __future__ import annotations

from collections.abc import Callable

import build123d as bd
import numpy as np

Design = tuple[bd.Part, dict[str, float]]
MIN = (bd.Align.MIN, bd.Align.MIN, bd.Align.MIN)
ON_FLOOR = (bd.Align.CENTER, bd.Align.CENTER, bd.Align.MIN)


def _prism(vertices: list[tuple[float, float]], length: float) -> bd.Part:
    """The polygon through (x, y) `vertices` extruded from z = 0 to `length`."""
    return bd.extrude(bd.Polygon(*vertices, align=None), amount=length)


def _stand_up(part: bd.Part) -> bd.Part:
    """A profile extruded along z, turned to stand on the xy plane: +90 degrees about x
    (y -> z, z -> -y)."""
    return bd.Rot(90, 0, 0) * part


def box_between(lo: np.ndarray, hi: np.ndarray) -> bd.Part:
    """The axis-aligned box with corners `lo` and `hi` (3,)."""
    return bd.Pos(*lo) * bd.Box(*(hi - lo), align=MIN)


def _box(rng: np.random.Generator) -> Design:
    depth, height = rng.uniform(0.45, 0.9), rng.uniform(0.3, 0.7)
    return bd.Box(1, depth, height, align=MIN), {"width": 1.0, "depth": depth, "height": height}


def _l_bracket(rng: np.random.Generator) -> Design:
    """An L profile (a foot and an upright) extruded, then stood up."""
    rise, foot, upright = rng.uniform(0.5, 0.9), rng.uniform(0.1, 0.22), rng.uniform(0.1, 0.22)
    length = rng.uniform(0.4, 0.8)
    profile = [(0, 0), (1, 0), (1, foot), (upright, foot), (upright, rise), (0, rise)]
    dims = {"width": 1.0, "height": rise, "foot": foot, "upright": upright, "length": length}
    return _stand_up(_prism(profile, length)), dims


def _scatter_circles(rng: np.random.Generator, count: int, width: float, depth: float,
                     radii: tuple[float, float], clearance: float) -> list[tuple[float, float, float]]:
    """Up to `count` circles (x, y, r) inside the rectangle [0, width] x [0, depth], keeping
    `clearance` from its sides and from each other (rejection sampling)."""
    circles: list[tuple[float, float, float]] = []
    for _ in range(200):
        r = rng.uniform(*radii)
        margin = r + clearance
        x, y = rng.uniform(margin, width - margin), rng.uniform(margin, depth - margin)
        if all(np.hypot(x - a, y - b) > r + c + clearance for a, b, c in circles):
            circles.append((x, y, r))
        if len(circles) == count:
            break
    return circles


def _plate_with_holes(rng: np.random.Generator) -> Design:
    depth, thickness = rng.uniform(0.6, 0.9), rng.uniform(0.08, 0.16)
    holes = _scatter_circles(rng, int(rng.integers(2, 5)), 1.0, depth, (0.05, 0.12), 0.06)
    dims = {"width": 1.0, "depth": depth, "thickness": thickness}
    plate = bd.Box(1, depth, thickness, align=MIN)
    for k, (x, y, r) in enumerate(holes):
        dims |= {f"hole{k}_x": x, f"hole{k}_y": y, f"hole{k}_radius": r}
        plate -= bd.Pos(x, y, 0) * bd.Cylinder(r, thickness, align=ON_FLOOR)
    return plate, dims


def _stepped_block(rng: np.random.Generator) -> Design:
    """A staircase profile of 2 or 3 steps (treads and rises of comparable sizes) extruded,
    then stood up."""
    steps = int(rng.integers(2, 4))
    treads, rises = rng.uniform(0.6, 1.4, steps), rng.uniform(0.6, 1.4, steps)
    ends = np.r_[1.0, 1.0 - np.cumsum(treads / treads.sum())[:-1]]  # right end of each step
    heights = np.cumsum(rises) / rises.sum() * rng.uniform(0.5, 0.9)
    length = rng.uniform(0.4, 0.8)
    vertices = [(0.0, 0.0), (1.0, 0.0)]
    for k in range(steps):
        vertices.append((ends[k], heights[k]))
        vertices.append((ends[k + 1] if k + 1 < steps else 0.0, heights[k]))
    dims = {"width": 1.0, "length": length}
    dims |= {f"step{k}_end": float(ends[k]) for k in range(steps)}
    dims |= {f"step{k}_height": float(heights[k]) for k in range(steps)}
    return _stand_up(_prism(vertices, length)), dims


def _cylinder(rng: np.random.Generator) -> Design:
    height = rng.uniform(0.4, 1.2)
    return bd.Cylinder(0.5, height, align=ON_FLOOR), {"diameter": 1.0, "height": height}


def _vertical_edges(part: bd.Part) -> bd.ShapeList:
    return part.edges().filter_by(bd.Axis.Z)


def _chamfered_block(rng: np.random.Generator) -> Design:
    """A block whose four vertical edges are cut at 45 degrees."""
    depth, height, cut = rng.uniform(0.5, 0.9), rng.uniform(0.3, 0.6), rng.uniform(0.08, 0.18)
    block = bd.Box(1, depth, height, align=MIN)
    return bd.chamfer(_vertical_edges(block), cut), {"width": 1.0, "depth": depth, "height": height,
                                                     "chamfer": cut}


def _filleted_block(rng: np.random.Generator) -> Design:
    """A block whose four vertical edges are rounded: tangent fillets, so no vertical sharp
    edges, only the quarter circles where the fillets meet the top and bottom faces."""
    depth, height, radius = rng.uniform(0.5, 0.9), rng.uniform(0.3, 0.6), rng.uniform(0.1, 0.2)
    block = bd.Box(1, depth, height, align=MIN)
    return bd.fillet(_vertical_edges(block), radius), {"width": 1.0, "depth": depth, "height": height,
                                                       "fillet": radius}


def _boss(rng: np.random.Generator) -> Design:
    """A block with a cylindrical boss standing on its top face."""
    depth, height = rng.uniform(0.6, 0.9), rng.uniform(0.2, 0.4)
    (x, y, radius), = _scatter_circles(rng, 1, 1.0, depth, (0.12, 0.22), 0.06)
    boss_height = rng.uniform(0.2, 0.45)
    part = bd.Box(1, depth, height, align=MIN) + bd.Pos(x, y, height) * bd.Cylinder(radius, boss_height,
                                                                                      align=ON_FLOOR)
    dims = {"width": 1.0, "depth": depth, "height": height, "boss_x": x, "boss_y": y, "boss_radius": radius,
            "boss_height": boss_height}
    return part, dims


DESIGNS: dict[str, Callable[[np.random.Generator], Design]] = {
    "box": _box,
    "l-bracket": _l_bracket,
    "plate-holes": _plate_with_holes,
    "stepped-block": _stepped_block,
    "cylinder": _cylinder,
    "chamfered-block": _chamfered_block,
    "filleted-block": _filleted_block,
    "boss": _boss,
}
"""The designs of `edgedog.synthetic.shapes.SHAPES`, by the same names."""
