"""A seeded procedural family of ABC-like parts for the CAD benchmark, modelled with the CAD kernel.

Each design is a recipe: a base and the features cut into or added onto it. The prismatic bases
(a block, L, U and T sections, three thin walls meeting in a corner) each expose one flat
rectangular face looking up, the work face, where the features go: pockets, through and blind
holes, counterbores, slots, bosses, ribs, steps and a small hole beside a large feature; their
outer vertical edges may be chamfered (sharp) or filleted (not sharp). The other designs are
revolved (circular edges, grooves, bores, bolt circles) or lofted and spline-walled (ellipse and
B-spline edges). `DESIGNS` lists them; `family_part(index, seed)` builds one with sizes drawn
from the seed, normalised like an ABC object.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import build123d as bd
import numpy as np

from edgedog.errors import ConfigError
from edgedog.synthetic.brep import part_from_solid
from edgedog.synthetic.shapes import Part

MIN = (bd.Align.MIN,) * 3
CENTRED = (bd.Align.CENTER, bd.Align.CENTER, bd.Align.MIN)
SMALL_HOLE = 0.012
"""Radius of the small hole placed beside a large feature (12 mm across on a normalised part)."""


@dataclass(frozen=True)
class WorkFace:
    """A flat rectangle [x0, x1] x [y0, y1] at height z looking up, over `depth` of material."""

    x0: float
    y0: float
    x1: float
    y1: float
    z: float
    depth: float

    @property
    def size(self) -> float:
        return min(self.x1 - self.x0, self.y1 - self.y0)

    def spot(self, rng: np.random.Generator, clearance: float) -> tuple[float, float]:
        """A random (x, y) at least `clearance` inside the rectangle (on its middle line where it
        is narrower than that)."""
        def along(lo: float, hi: float) -> float:
            return rng.uniform(lo + clearance, hi - clearance) if hi - lo > 2 * clearance else (lo + hi) / 2
        return along(self.x0, self.x1), along(self.y0, self.y1)


# --- prismatic bases: a solid and its work face ----------------------------------------------

def _section(profile: list[tuple[float, float]], length: float) -> bd.Part:
    """A profile in the xz plane (x, z pairs) extruded along +y by `length`."""
    return bd.extrude(bd.Plane.XZ * bd.Polygon(*profile, align=None), amount=-length)


def _block(rng: np.random.Generator) -> tuple[bd.Part, WorkFace]:
    depth, height = rng.uniform(0.5, 0.9), rng.uniform(0.25, 0.5)
    return bd.Box(1, depth, height, align=MIN), WorkFace(0, 0, 1, depth, height, height)


def _l_section(rng: np.random.Generator) -> tuple[bd.Part, WorkFace]:
    """A foot and an upright: the foot's top meets the upright in a concave edge."""
    foot, upright, rise, length = (rng.uniform(0.15, 0.25), rng.uniform(0.12, 0.25), rng.uniform(0.5, 0.8),
                                   rng.uniform(0.5, 0.8))
    part = _section([(0, 0), (1, 0), (1, foot), (upright, foot), (upright, rise), (0, rise)], length)
    return part, WorkFace(upright, 0, 1, length, foot, foot)


def _u_section(rng: np.random.Generator) -> tuple[bd.Part, WorkFace]:
    """A channel: a floor between two walls, two concave edges along it."""
    floor, wall, rise, length = (rng.uniform(0.15, 0.25), rng.uniform(0.08, 0.15), rng.uniform(0.4, 0.7),
                                 rng.uniform(0.5, 0.9))
    part = _section([(0, 0), (1, 0), (1, rise), (1 - wall, rise), (1 - wall, floor), (wall, floor),
                     (wall, rise), (0, rise)], length)
    return part, WorkFace(wall, 0, 1 - wall, length, floor, floor)


def _t_section(rng: np.random.Generator) -> tuple[bd.Part, WorkFace]:
    """A wide stem under a flange that overhangs it on both sides: concave edges under the
    flange, seen only from below."""
    stem, flange, height, length = (rng.uniform(0.35, 0.5), rng.uniform(0.12, 0.2), rng.uniform(0.5, 0.7),
                                    rng.uniform(0.5, 0.8))
    a, b = (1 - stem) / 2, (1 + stem) / 2
    part = _section([(a, 0), (b, 0), (b, height - flange), (1, height - flange), (1, height), (0, height),
                     (0, height - flange), (a, height - flange)], length)
    return part, WorkFace(0, 0, 1, length, height, flange)


def _corner_walls(rng: np.random.Generator) -> tuple[bd.Part, WorkFace]:
    """Three thin walls meeting in a corner (a floor and two sides): concave edges that few
    views see, as in ABC-NEF's held-out object."""
    wall, depth, rise = rng.uniform(0.04, 0.08), rng.uniform(0.6, 1.0), rng.uniform(0.4, 0.8)
    part = (bd.Box(1, depth, wall, align=MIN) + bd.Box(wall, depth, rise, align=MIN)
            + bd.Box(1, wall, rise, align=MIN))
    return part, WorkFace(wall, wall, 1, depth, wall, wall)


BASES: dict[str, Callable[[np.random.Generator], tuple[bd.Part, WorkFace]]] = {
    "block": _block, "l-section": _l_section, "u-section": _u_section, "t-section": _t_section,
    "corner-walls": _corner_walls,
}


# --- features on the work face -------------------------------------------------------------

def _down(face: WorkFace, x: float, y: float, depth: float, shape: bd.Part) -> bd.Part:
    """`shape` (standing on z = 0, centred on the origin) placed at (x, y) with its base `depth`
    below the work face. Cutters are made a hair taller than the cut, so that no face of the
    cutter lies on a face of the part (coplanar faces make the kernel's booleans fragile)."""
    return bd.Pos(x, y, face.z - depth) * shape


def _pocket(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    w, d = rng.uniform(0.3, 0.5) * (face.x1 - face.x0), rng.uniform(0.3, 0.5) * (face.y1 - face.y0)
    x, y = face.spot(rng, max(w, d) / 2 + 0.03)
    depth = rng.uniform(0.3, 0.6) * face.depth
    return part - _down(face, x, y, depth, bd.Box(w, d, depth + 1e-3, align=CENTRED))


def _hole(part: bd.Part, face: WorkFace, rng: np.random.Generator, through: bool) -> bd.Part:
    r = rng.uniform(0.04, 0.1) * min(1.0, face.size / 0.3)
    x, y = face.spot(rng, r + 0.03)
    depth = face.depth + 0.01 if through else rng.uniform(0.3, 0.7) * face.depth
    return part - _down(face, x, y, depth, bd.Cylinder(r, depth + 1e-3 + 0.01 * through, align=CENTRED))


def _through_hole(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    return _hole(part, face, rng, through=True)


def _blind_hole(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    return _hole(part, face, rng, through=False)


def _counterbore(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    r = rng.uniform(0.03, 0.06) * min(1.0, face.size / 0.3)
    x, y = face.spot(rng, 2 * r + 0.03)
    bore = rng.uniform(0.3, 0.5) * face.depth
    part -= _down(face, x, y, face.depth + 0.01, bd.Cylinder(r, face.depth + 0.02, align=CENTRED))
    return part - _down(face, x, y, bore, bd.Cylinder(2 * r, bore + 1e-3, align=CENTRED))


def _slot(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    width = rng.uniform(0.05, 0.1) * min(1.0, face.size / 0.3)
    length = rng.uniform(2.5, 4) * width
    x, y = face.spot(rng, length / 2 + 0.03)
    depth = rng.uniform(0.4, 0.8) * face.depth
    return part - _down(face, x, y, depth, bd.extrude(bd.SlotOverall(length, width), amount=depth + 1e-3))


def _boss(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    r = rng.uniform(0.06, 0.12) * min(1.0, face.size / 0.3)
    x, y = face.spot(rng, r + 0.03)
    return part + bd.Pos(x, y, face.z) * bd.Cylinder(r, rng.uniform(0.1, 0.25), align=CENTRED)


def _rib(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    """A thin wall standing on the work face across its whole width."""
    thickness, height = rng.uniform(0.03, 0.06), rng.uniform(0.1, 0.2)
    x, _ = face.spot(rng, thickness + 0.05)
    span = face.y1 - face.y0
    return part + bd.Pos(x, (face.y0 + face.y1) / 2, face.z) * bd.Box(thickness, span, height, align=CENTRED)


def _step(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    """A step down across the work face's far end (exactly: walls beside the face stay whole)."""
    run, drop = rng.uniform(0.15, 0.3) * (face.x1 - face.x0), rng.uniform(0.3, 0.6) * face.depth
    cutter = bd.Box(run, face.y1 - face.y0, drop + 0.01, align=MIN)
    return part - bd.Pos(face.x1 - run, face.y0, face.z - drop) * cutter


def _small_hole(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    """A small through hole near a corner of the work face, beside whatever is larger."""
    x, y = face.x0 + 3 * SMALL_HOLE, face.y0 + 3 * SMALL_HOLE
    hole = bd.Cylinder(SMALL_HOLE, face.depth + 0.02, align=CENTRED)
    return part - _down(face, x, y, face.depth + 0.01, hole)


def _outer_vertical_edges(part: bd.Part) -> bd.ShapeList:
    """The vertical edges at the corners of the part's bounding box in plan."""
    box = part.bounding_box()

    def at_corner(edge) -> bool:
        x, y = edge.center().X, edge.center().Y
        return min(abs(x - box.min.X), abs(x - box.max.X)) < 1e-6 and min(abs(y - box.min.Y),
                                                                              abs(y - box.max.Y)) < 1e-6
    return part.edges().filter_by(bd.Axis.Z).filter_by(at_corner)


def _chamfer(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    return bd.chamfer(_outer_vertical_edges(part), rng.uniform(0.03, 0.08))


def _fillet(part: bd.Part, face: WorkFace, rng: np.random.Generator) -> bd.Part:
    return bd.fillet(_outer_vertical_edges(part), rng.uniform(0.03, 0.08))


FEATURES: dict[str, Callable[[bd.Part, WorkFace, np.random.Generator], bd.Part]] = {
    "pocket": _pocket, "through-hole": _through_hole, "blind-hole": _blind_hole, "counterbore": _counterbore,
    "slot": _slot, "boss": _boss, "rib": _rib, "step": _step, "small-hole": _small_hole,
    "chamfer": _chamfer, "fillet": _fillet,
}
EDGE_TREATMENTS = ("chamfer", "fillet")
"""Applied first, on the base's outer corners, before anything is cut into it."""
FEATURE_SETS = [("pocket", "small-hole"), ("through-hole", "blind-hole"), ("counterbore", "chamfer"),
                ("slot", "fillet"), ("boss", "through-hole"), ("rib",), ("step", "blind-hole", "chamfer")]


# --- revolved and lofted designs -----------------------------------------------------------

def _revolved(profile: list[tuple[float, float]]) -> bd.Part:
    """A profile of (radius, z) pairs turned about the z axis."""
    return bd.revolve(bd.Plane.XZ * bd.Polygon(*profile, align=None), axis=bd.Axis.Z)


def _stepped_shaft(rng: np.random.Generator) -> bd.Part:
    radii = np.sort(rng.uniform(0.15, 0.5, 3))[::-1]
    heights = np.cumsum(rng.uniform(0.2, 0.4, 3))
    profile = [(0, 0), (radii[0], 0), (radii[0], heights[0]), (radii[1], heights[0]), (radii[1], heights[1]),
               (radii[2], heights[1]), (radii[2], heights[2]), (0, heights[2])]
    return bd.chamfer(_revolved(profile).edges().sort_by(bd.Axis.Z)[-1], 0.03)


def _flanged_hub(rng: np.random.Generator) -> bd.Part:
    """A flange with a bolt circle, a hub on it, and a bore through both."""
    flange, hub, bore = rng.uniform(0.08, 0.15), rng.uniform(0.2, 0.3), rng.uniform(0.08, 0.14)
    height = rng.uniform(0.3, 0.5)
    part = bd.Cylinder(0.5, flange, align=CENTRED) + bd.Cylinder(hub, height, align=CENTRED)
    part -= bd.Pos(0, 0, -0.01) * bd.Cylinder(bore, height + 0.02, align=CENTRED)
    holes = int(rng.integers(4, 7))
    for location in bd.PolarLocations((0.5 + hub) / 2, holes):
        part -= location * bd.Pos(0, 0, -0.01) * bd.Cylinder(0.035, flange + 0.02, align=CENTRED)
    return part


def _pulley(rng: np.random.Generator) -> bd.Part:
    """A wheel with a V groove round its rim (concave circular edges) and a bore."""
    width, groove, bore = rng.uniform(0.25, 0.4), rng.uniform(0.06, 0.12), rng.uniform(0.06, 0.12)
    mid = width / 2
    profile = [(bore, 0), (0.5, 0), (0.5, mid - groove), (0.5 - groove, mid), (0.5, mid + groove),
               (0.5, width), (bore, width)]
    return _revolved(profile)


def _cup(rng: np.random.Generator) -> bd.Part:
    """A thin-walled cup (revolved), its rim chamfered: inner edges seen through the opening only."""
    wall, height = rng.uniform(0.03, 0.06), rng.uniform(0.5, 0.9)
    profile = [(0, 0), (0.5, 0), (0.5, height), (0.5 - wall, height), (0.5 - wall, wall), (0, wall)]
    cup = _revolved(profile)
    rim = cup.edges().filter_by(bd.GeomType.CIRCLE).sort_by(bd.Axis.Z)[-2:]
    return bd.chamfer(rim, wall / 3)


def _loft_rectangle_circle(rng: np.random.Generator) -> bd.Part:
    height, radius = rng.uniform(0.4, 0.8), rng.uniform(0.15, 0.3)
    bottom = bd.Plane.XY * bd.Rectangle(1, rng.uniform(0.6, 1.0))
    return bd.loft([bottom, bd.Plane.XY.offset(height) * bd.Circle(radius)])


def _loft_ellipse(rng: np.random.Generator) -> bd.Part:
    """A slanted elliptical tube: an ellipse lofted to a smaller one moved aside, with a bore."""
    height = rng.uniform(0.5, 0.9)
    a, b = rng.uniform(0.35, 0.5), rng.uniform(0.2, 0.3)
    top = bd.Plane.XY.offset(height) * bd.Pos(rng.uniform(0.05, 0.15), 0) * bd.Ellipse(a * 0.7, b * 0.7)
    body = bd.loft([bd.Plane.XY * bd.Ellipse(a, b), top])
    return body - bd.Pos(0, 0, -0.01) * bd.Cylinder(b * 0.4, height + 0.02, align=CENTRED)


def _spline_wall(rng: np.random.Generator) -> bd.Part:
    """A block whose front wall is a B-spline curve in plan, extruded: B-spline sharp edges."""
    depth, height = rng.uniform(0.4, 0.7), rng.uniform(0.3, 0.6)
    bulge = rng.uniform(0.1, 0.25, 3)
    points = [(1.0, 0.0), (0.75, -bulge[0]), (0.5, -bulge[1]), (0.25, -bulge[2]), (0.0, 0.0)]
    outline = [bd.Line((0, 0), (0, depth)), bd.Line((0, depth), (1, depth)), bd.Line((1, depth), (1, 0)),
               bd.Spline(*points)]
    return bd.extrude(bd.make_face(outline), amount=height)


OTHERS: dict[str, Callable[[np.random.Generator], bd.Part]] = {
    "stepped-shaft": _stepped_shaft, "flanged-hub": _flanged_hub, "pulley": _pulley, "cup": _cup,
    "loft-rectangle-circle": _loft_rectangle_circle, "loft-ellipse": _loft_ellipse,
    "spline-wall": _spline_wall,
}


@dataclass(frozen=True)
class Recipe:
    """One design: a base (of BASES or OTHERS) and, for a prismatic base, its features in order."""

    base: str
    features: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return "+".join((self.base, *self.features))


DESIGNS: tuple[Recipe, ...] = (tuple(Recipe(base, features) for features in FEATURE_SETS for base in BASES)
                               + tuple(Recipe(name) for name in OTHERS))
"""Every design of the family, in a fixed order: 5 bases x 7 feature sets, then 7 others."""


def family_solid(recipe: Recipe, rng: np.random.Generator) -> bd.Part:
    """The solid of `recipe` with sizes drawn from `rng` (longest side about 1)."""
    if recipe.base in OTHERS:
        return OTHERS[recipe.base](rng)
    part, face = BASES[recipe.base](rng)
    ordered = sorted(recipe.features, key=lambda name: name not in EDGE_TREATMENTS)
    for name in ordered:
        part = FEATURES[name](part, face, rng)
    return part


def family_part(index: int, seed: int = 0) -> Part:
    """Design `index` of DESIGNS with sizes drawn from `seed`, normalised into [0, 1]^3."""
    if not 0 <= index < len(DESIGNS):
        raise ConfigError(f"--family {index}: the family's designs are 0 to {len(DESIGNS) - 1}")
    recipe = DESIGNS[index]
    return part_from_solid(recipe.name, family_solid(recipe, np.random.default_rng([index, seed])), {})
