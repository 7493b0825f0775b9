"""Exact feature curves of the built-in parts: straight segments and circular arcs in 3D.

Ground truth is sampled from these curves, not from their tessellation, with the ABC
protocol's rule applied along each curve's arc length: n = floor(length / spacing) samples at
equal parameter steps, both ends included (for a segment these are `metrics.sample_line`'s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgedog.groundtruth import GT_SPACING


def _affine(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ matrix[:3, :3].T + matrix[:3, 3]


@dataclass(frozen=True)
class Line:
    """The segment from `a` to `b`, each (3,)."""

    a: np.ndarray
    b: np.ndarray

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.b - self.a))

    def at(self, t: np.ndarray) -> np.ndarray:
        """(n,) parameters in [0, 1] -> (n, 3) points."""
        return self.a + np.asarray(t, float)[:, None] * (self.b - self.a)

    def tangent(self, t: np.ndarray) -> np.ndarray:
        """(n,) parameters -> (n, 3) unit tangents in the direction of increasing t."""
        direction = (self.b - self.a) / self.length
        return np.broadcast_to(direction, (len(np.atleast_1d(t)), 3)).copy()

    def transformed(self, matrix: np.ndarray) -> Line:
        """The curve under a (4, 4) similarity transform."""
        a, b = _affine(matrix, np.stack([self.a, self.b]))
        return Line(a, b)

    def to_json(self) -> dict:
        return {"type": "line", "a": self.a.tolist(), "b": self.b.tolist()}


@dataclass(frozen=True)
class Arc:
    """The arc `center + cos(theta) e1 + sin(theta) e2`, theta from `start` to `stop` (radians).

    `e1` and `e2` (3,) are orthogonal and as long as the radius; stop < start runs clockwise
    about e1 x e2, and |stop - start| = 2 pi is a full circle.
    """

    center: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    start: float
    stop: float

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

    def tangent(self, t: np.ndarray) -> np.ndarray:
        """(n,) parameters -> (n, 3) unit tangents in the direction of increasing t."""
        theta = self._angles(t)[:, None]
        sense = np.sign(self.stop - self.start)
        return sense * (-np.sin(theta) * self.e1 + np.cos(theta) * self.e2) / self.radius

    def transformed(self, matrix: np.ndarray) -> Arc:
        """The curve under a (4, 4) similarity transform (e1, e2 stay orthogonal and equally long)."""
        center = _affine(matrix, self.center[None])[0]
        return Arc(center, matrix[:3, :3] @ self.e1, matrix[:3, :3] @ self.e2, self.start, self.stop)

    def to_json(self) -> dict:
        return {"type": "arc", "center": self.center.tolist(), "e1": self.e1.tolist(),
                "e2": self.e2.tolist(), "start": self.start, "stop": self.stop}


Curve = Line | Arc


def sample_curve(curve: Curve, spacing: float = GT_SPACING) -> np.ndarray:
    """(n, 3) samples: n = floor(length / spacing) at equal steps, ends included."""
    return curve.at(np.linspace(0.0, 1.0, int(curve.length // spacing)))


def sample_curves(curves: list[Curve] | tuple[Curve, ...], spacing: float = GT_SPACING) -> np.ndarray:
    """(N, 3) all curves' samples, curve after curve."""
    return np.concatenate([sample_curve(c, spacing) for c in curves])
