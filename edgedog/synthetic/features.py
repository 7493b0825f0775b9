"""Exact feature curves of the parts: straight segments, circular arcs, and any other curve of
the CAD kernel (ellipses, B-splines) as points it placed densely along the arc length. Each curve
carries the sign of the dihedral angle at its edge (`DIHEDRALS`), written into the scene's
`gt/<scene>_curves.json` with its geometry (`to_json`, read back by `curve_from_json`).

Ground truth is sampled from these curves, not from their tessellation, with the ABC
protocol's rule applied along each curve's arc length: n = floor(length / spacing) samples at
equal arc-length steps, both ends included (for a segment these are `metrics.sample_line`'s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgedog.errors import InputError
from edgedog.groundtruth import GT_SPACING
from edgedog.metrics import points_along

DIHEDRALS = ("convex", "concave", "unknown")
"""Sign of the dihedral angle at an edge: the material's wedge is under 180 degrees (convex) or
over it (concave); unknown where no faces were given (an ABC mesh read as segments)."""


@dataclass(frozen=True)
class Line:
    """The segment from `a` to `b`, each (3,); `dihedral` is one of DIHEDRALS."""

    a: np.ndarray
    b: np.ndarray
    dihedral: str = "unknown"

    type = "line"

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.b - self.a))

    def at(self, t: np.ndarray) -> np.ndarray:
        """(n,) parameters in [0, 1] -> (n, 3) points."""
        return self.a + np.asarray(t, float)[:, None] * (self.b - self.a)

    def to_json(self) -> dict:
        return {"type": "line", "dihedral": self.dihedral, "a": self.a.tolist(), "b": self.b.tolist()}


@dataclass(frozen=True)
class Arc:
    """The arc `center + cos(theta) e1 + sin(theta) e2`, theta from `start` to `stop` (radians).

    `e1` and `e2` (3,) are orthogonal and as long as the radius; stop < start runs clockwise
    about e1 x e2, and |stop - start| = 2 pi is a full circle. `dihedral` is one of DIHEDRALS.
    """

    center: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    start: float
    stop: float
    dihedral: str = "unknown"

    type = "circle"

    @property
    def radius(self) -> float:
        return float(np.linalg.norm(self.e1))

    @property
    def length(self) -> float:
        return self.radius * abs(self.stop - self.start)

    def _angles(self, t: np.ndarray) -> np.ndarray:
        return self.start + np.asarray(t, float) * (self.stop - self.start)

    def at(self, t: np.ndarray) -> np.ndarray:
        """(n,) parameters in [0, 1] -> (n, 3) points."""
        theta = self._angles(t)[:, None]
        return self.center + np.cos(theta) * self.e1 + np.sin(theta) * self.e2

    def to_json(self) -> dict:
        return {"type": "arc", "dihedral": self.dihedral, "center": self.center.tolist(),
                "e1": self.e1.tolist(), "e2": self.e2.tolist(), "start": self.start, "stop": self.stop}


@dataclass(frozen=True)
class Traced:
    """Any other curve (an ellipse, a B-spline): `points` (n, 3) that the CAD kernel placed at
    equal arc-length steps, so finely (`edgedog.synthetic.sharp.TRACE_STEP`) that the polyline
    through them stays within a micrometre of the curve; t runs along the polyline's length.

    Attributes:
        kind: the kernel's curve type, lower case ("ellipse", "bspline", ...).
        dihedral: one of DIHEDRALS.
    """

    kind: str
    points: np.ndarray
    dihedral: str = "unknown"

    @property
    def type(self) -> str:
        """The curve's type for reports: ellipse, bspline, or other (the kernel's other kinds)."""
        return self.kind if self.kind in ("ellipse", "bspline") else "other"

    @property
    def length(self) -> float:
        return float(self._lengths()[-1])

    def _lengths(self) -> np.ndarray:
        """(n,) arc length from the first point to each point."""
        return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(self.points, axis=0), axis=1))]

    def at(self, t: np.ndarray) -> np.ndarray:
        """(n,) parameters in [0, 1] -> (n, 3) points, t proportional to the arc length."""
        return points_along(self.points, t)

    def to_json(self) -> dict:
        return {"type": self.kind, "dihedral": self.dihedral, "points": self.points.tolist()}


Curve = Line | Arc | Traced


def curve_from_json(record: dict, path) -> Curve:
    """The curve of one `to_json` record of the file `path`; a record written before curves
    carried their dihedral reads as "unknown". InputError naming `path` for a malformed record."""
    try:
        dihedral = record.get("dihedral", "unknown")
        if dihedral not in DIHEDRALS:
            raise ValueError(dihedral)
        if record["type"] == "line":
            curve = Line(np.asarray(record["a"], float).reshape(3), np.asarray(record["b"], float).reshape(3),
                         dihedral)
        elif record["type"] == "arc":
            curve = Arc(*(np.asarray(record[key], float).reshape(3) for key in ("center", "e1", "e2")),
                        float(record["start"]), float(record["stop"]), dihedral)
        else:
            curve = Traced(str(record["type"]), np.asarray(record["points"], float).reshape(-1, 3), dihedral)
    except (AttributeError, KeyError, TypeError, ValueError):
        raise InputError(path, "a curve record is not a line, an arc or a traced curve with points") from None
    if curve.length <= 0 or not np.isfinite(curve.length):
        raise InputError(path, "a curve of no length, or with NaN or infinite coordinates")
    return curve


def sample_curve(curve: Curve, spacing: float = GT_SPACING) -> np.ndarray:
    """(n, 3) samples: n = floor(length / spacing) at equal steps, ends included."""
    return curve.at(np.linspace(0.0, 1.0, int(curve.length // spacing)))


def sample_curves(curves: list[Curve] | tuple[Curve, ...], spacing: float = GT_SPACING) -> np.ndarray:
    """(N, 3) all curves' samples, curve after curve."""
    return np.concatenate([sample_curve(c, spacing) for c in curves])
