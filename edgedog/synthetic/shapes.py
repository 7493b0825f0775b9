"""The catalogue of built-in CAD parts: procedural meshes with their exact sharp feature curves.

Every part is one or a few prisms (see `prism`), drawn with seeded dimensions, turned upright
where its profile is a side view, and normalised like an ABC object: scaled so that the
longest side of its bounding box is 1 and centred at (0.5, 0.5, 0.5). The parts are modelled
directly in that ground-truth frame, so the protocol's spacing (GT_SPACING) is 5 mm there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from edgedog.errors import ConfigError
from edgedog.groundtruth import GT_SPACING
from edgedog.synthetic.features import Curve, sample_curves
from edgedog.synthetic.prism import (
    Mesh,
    Prism,
    circle,
    polygon,
    rectangle,
    rounded_rectangle,
)

# Turns a profile drawn in the xy plane and extruded along z into a side view standing on
# the xy plane: a rotation of +90 degrees about x (y -> z, z -> -y).
STAND_UP = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])


@dataclass(frozen=True)
class Part:
    """A built-in part in the ground-truth frame.

    Attributes:
        name: the shape's name.
        dimensions: the seeded sizes (and positions from the part's corner), in ground-truth
            units (1 = 1000 mm).
        mesh: its closed triangle mesh.
        curves: its exact sharp feature curves.
    """

    name: str
    dimensions: dict[str, float]
    mesh: Mesh
    curves: tuple[Curve, ...]

    def ground_truth(self, spacing: float = GT_SPACING) -> np.ndarray:
        """(N, 3) the curves sampled by the ABC protocol."""
        return sample_curves(self.curves, spacing)


def assemble(name: str, prisms: list[Prism], dimensions: dict[str, float],
             transform: np.ndarray | None = None, normalise: bool = True) -> Part:
    """Join prisms into a part, apply `transform` (4, 4), then normalise into [0, 1]^3."""
    transform = np.eye(4) if transform is None else transform
    mesh = Mesh.concatenate([p.mesh() for p in prisms]).transformed(transform)
    curves = [c.transformed(transform) for p in prisms for c in p.curves()]
    scale = 1.0
    if normalise:
        corners = mesh.positions.reshape(-1, 3)
        lo, hi = corners.min(0), corners.max(0)
        scale = 1.0 / (hi - lo).max()
        frame = np.diag([scale, scale, scale, 1.0])
        frame[:3, 3] = 0.5 - (lo + hi) / 2 * scale
        mesh, curves = mesh.transformed(frame), [c.transformed(frame) for c in curves]
    return Part(name, {k: round(v * scale, 6) for k, v in dimensions.items()}, mesh, tuple(curves))


# --- the shapes: each draws its dimensions (longest side about 1) from a generator -----------

Design = tuple[list[Prism], dict[str, float]]


def _box(rng: np.random.Generator) -> Design:
    depth, height = rng.uniform(0.45, 0.9), rng.uniform(0.3, 0.7)
    return [Prism(rectangle(0, 0, 1, depth), 0, height)], {"width": 1.0, "depth": depth, "height": height}


def _l_bracket(rng: np.random.Generator) -> Design:
    """An L profile (a foot and an upright) extruded, then stood up."""
    rise, foot, upright = rng.uniform(0.5, 0.9), rng.uniform(0.1, 0.22), rng.uniform(0.1, 0.22)
    length = rng.uniform(0.4, 0.8)
    profile = polygon([(0, 0), (1, 0), (1, foot), (upright, foot), (upright, rise), (0, rise)])
    dims = {"width": 1.0, "height": rise, "foot": foot, "upright": upright, "length": length}
    return [Prism(profile, 0, length)], dims


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
    for k, (x, y, r) in enumerate(holes):
        dims |= {f"hole{k}_x": x, f"hole{k}_y": y, f"hole{k}_radius": r}
    prism = Prism(rectangle(0, 0, 1, depth), 0, thickness, holes=tuple(circle(x, y, r) for x, y, r in holes))
    return [prism], dims


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
    return [Prism(polygon(vertices), 0, length)], dims


def _cylinder(rng: np.random.Generator) -> Design:
    radius, height = 0.5, rng.uniform(0.4, 1.2)
    return [Prism(circle(0, 0, radius), 0, height)], {"diameter": 1.0, "height": height}


def _chamfered_block(rng: np.random.Generator) -> Design:
    """A block whose four vertical edges are cut at 45 degrees."""
    depth, height, cut = rng.uniform(0.5, 0.9), rng.uniform(0.3, 0.6), rng.uniform(0.08, 0.18)
    outline = polygon([(cut, 0), (1 - cut, 0), (1, cut), (1, depth - cut), (1 - cut, depth), (cut, depth),
                       (0, depth - cut), (0, cut)])
    return [Prism(outline, 0, height)], {"width": 1.0, "depth": depth, "height": height, "chamfer": cut}


def _filleted_block(rng: np.random.Generator) -> Design:
    """A block whose four vertical edges are rounded: tangent fillets, so no vertical feature
    lines, only the quarter circles where the fillets meet the top and bottom faces."""
    depth, height, radius = rng.uniform(0.5, 0.9), rng.uniform(0.3, 0.6), rng.uniform(0.1, 0.2)
    outline = rounded_rectangle(0, 0, 1, depth, radius)
    return [Prism(outline, 0, height)], {"width": 1.0, "depth": depth, "height": height, "fillet": radius}


def _boss(rng: np.random.Generator) -> Design:
    """A block with a cylindrical boss standing on its top face."""
    depth, height = rng.uniform(0.6, 0.9), rng.uniform(0.2, 0.4)
    (x, y, radius), = _scatter_circles(rng, 1, 1.0, depth, (0.12, 0.22), 0.06)
    boss_height = rng.uniform(0.2, 0.45)
    top = circle(x, y, radius)
    prisms = [Prism(rectangle(0, 0, 1, depth), 0, height, covered=(top,)),
              Prism(top, height, height + boss_height, bottom=False)]
    dims = {"width": 1.0, "depth": depth, "height": height, "boss_x": x, "boss_y": y, "boss_radius": radius,
            "boss_height": boss_height}
    return prisms, dims


@dataclass(frozen=True)
class Shape:
    """A catalogue entry: how to draw the part, whether its profile is a side view."""

    design: Callable[[np.random.Generator], Design]
    standing: bool
    description: str


SHAPES = {
    "box": Shape(_box, False, "rectangular block"),
    "l-bracket": Shape(_l_bracket, True, "L-shaped angle bracket"),
    "plate-holes": Shape(_plate_with_holes, False, "plate with 2 to 4 round through holes"),
    "stepped-block": Shape(_stepped_block, True, "staircase block of 2 or 3 steps"),
    "cylinder": Shape(_cylinder, False, "round cylinder"),
    "chamfered-block": Shape(_chamfered_block, False, "block with chamfered vertical edges"),
    "filleted-block": Shape(_filleted_block, False, "block with filleted vertical edges"),
    "boss": Shape(_boss, False, "block with a cylindrical boss on top"),
}


def make_part(name: str, seed: int = 0) -> Part:
    """The part `name` with dimensions drawn from `seed`."""
    if name not in SHAPES:
        raise ConfigError(f"unknown shape {name!r}; choose from {', '.join(SHAPES)}")
    shape = SHAPES[name]
    prisms, dimensions = shape.design(np.random.default_rng(seed))
    return assemble(name, prisms, dimensions, STAND_UP if shape.standing else None)
