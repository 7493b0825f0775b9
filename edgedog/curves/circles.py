"""Circle completion: the circles of holes and bosses that few views see, found by sliding the
circles the curves already hold along their axes.

A blind hole's floor, a counterbore's step and a boss's foot are circles on the axis of a circle
the views all see (the hole's or the boss's rim), of the same radius, and seen only by the few
views that look down the axis: the rest of the part hides them, so no primitive forms on them.
Those few views still draw them. A circle fitted to a chain of the curves (`found_circles`) is
moved along its axis in steps of `sweep.STEP` of the scene size, up to `circle_reach` either
way, and each position is scored by what the maps draw there that no curve explains
(`sweep.offset_scores`: each view counting only where it looks across the cylinder through the
circle). A peak of that score, placed where the maps themselves peak around it (`sweep.placed`:
the maps' thick lines make the score a plateau along the axis), is a circle when, there:

- it lies inside every view's widened mask (the visual hull), all but `sweep.OUTSIDE_SHARE` of it;
- `circle_cover` of its points are drawn (their summed edge value over the views at least
  `sweep.DRAWN_SUM`), and `circle_views_cover` of them by two views or more: one view's ellipse
  fits a circle at any depth along its line of sight, two views' agree at one;
- most of it lies away from the curves.

A circle of another radius on the same axis (a counterbore's hole) is not looked for. Scenes
without masks get nothing, as for the lines.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from edgedog.curves import sweep
from edgedog.curves.completion import NOVELTY, Evidence
from edgedog.curves.config import ExtractConfig
from edgedog.curves.grouping import Chain

MIN_VERTICES = 8
"""Fewest vertices of a chain that a circle is fitted to."""
MAX_GAP = 90.0
"""Degrees: the largest gap between a chain's vertices around the fitted centre; a chain with a
larger one is an arc (or a bend between lines), not a closed circle."""
MAX_RADIUS = 0.5
"""Largest radius of a found circle, of the scene size."""
SAMPLES = 64
"""Points around a circle where the views are read."""
QUARTER = 4.0 / 3.0 * np.tan(np.pi / 8.0)
"""Handle length, of the radius, of a cubic Bézier that draws a quarter circle."""


@dataclass(frozen=True)
class Circle:
    """A 3D circle: centre (3,), unit axes u, v (3,) spanning its plane, radius."""

    centre: np.ndarray
    u: np.ndarray
    v: np.ndarray
    radius: float
    closed = True

    @property
    def normal(self) -> np.ndarray:
        """(3,) unit normal of the circle's plane."""
        return np.cross(self.u, self.v)

    def points(self, count: int = SAMPLES, offsets: np.ndarray | None = None) -> np.ndarray:
        """(count, 3) evenly spaced points, or (T, count, 3) those of the circle moved by each of
        `offsets` (T,) along its normal."""
        angle = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
        ring = self.centre + self.radius * (np.cos(angle)[:, None] * self.u + np.sin(angle)[:, None] * self.v)
        return ring if offsets is None else ring[None] + np.asarray(offsets)[:, None, None] * self.normal

    def swept(self, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T, SAMPLES, 3) the circle moved by each of `offsets` (T,) along its normal, and the
        unit normals of the cylinder it sweeps there (radial)."""
        rings = self.points(SAMPLES, offsets)
        centres = self.centre + np.asarray(offsets)[:, None] * self.normal
        return rings, (rings - centres[:, None]) / self.radius

    def moved(self, offset: float) -> Circle:
        return Circle(self.centre + offset * self.normal, self.u, self.v, self.radius)

    def beziers(self) -> np.ndarray:
        """(4, 4, 3) four cubic Béziers, a quarter circle each, end to end."""
        angle = np.arange(5) * np.pi / 2
        radial = np.cos(angle)[:, None] * self.u + np.sin(angle)[:, None] * self.v
        tangent = -np.sin(angle)[:, None] * self.u + np.cos(angle)[:, None] * self.v
        ends = self.centre + self.radius * radial
        handle = QUARTER * self.radius * tangent
        return np.stack([ends[:-1], ends[:-1] + handle[:-1], ends[1:] - handle[1:], ends[1:]], axis=1)


def fit_circle(points: np.ndarray) -> tuple[Circle, float, float]:
    """The circle fitted to points (M >= 3, 3): their best plane, then an algebraic circle fit in
    it; with the RMS distance of the points to the circle in the plane and the largest gap in
    degrees between them around its centre."""
    mean = points.mean(axis=0)
    _, _, axes = np.linalg.svd(points - mean, full_matrices=False)
    u, v = axes[0], axes[1]
    flat = np.stack([(points - mean) @ u, (points - mean) @ v], axis=1)
    solution = np.linalg.lstsq(np.c_[2 * flat, np.ones(len(flat))], (flat**2).sum(axis=1), rcond=None)[0]
    centre = solution[:2]
    radius = float(np.sqrt(max(solution[2] + centre @ centre, 0.0)))
    offsets = flat - centre
    rms = float(np.sqrt(np.mean((np.linalg.norm(offsets, axis=1) - radius) ** 2)))
    angles = np.sort(np.arctan2(offsets[:, 1], offsets[:, 0]))
    gaps = np.diff(np.r_[angles, angles[0] + 2 * np.pi])
    return Circle(mean + centre[0] * u + centre[1] * v, u, v, radius), rms, float(np.degrees(gaps.max()))


def found_circles(chains: list[Chain], tolerance: float, size: float) -> list[Circle]:
    """The chains (of at least MIN_VERTICES) that are whole circles: within `tolerance` (RMS) of
    their fitted circle, no gap over MAX_GAP around it, a radius under MAX_RADIUS of `size`."""
    circles = []
    for chain in chains:
        if len(chain.points) < MIN_VERTICES:
            continue
        circle, rms, gap = fit_circle(chain.points)
        if rms <= tolerance and gap <= MAX_GAP and 0 < circle.radius <= MAX_RADIUS * size:
            circles.append(circle)
    return circles


def complete_circles(circles: list[Circle], evidence: Evidence, maps: list[sweep.ViewMaps], size: float,
                     config: ExtractConfig) -> np.ndarray:
    """(B, 4, 3) the Béziers of the circles the curves of `evidence` miss on the axes of
    `circles` (see the module's doc), with `config`'s `circle_*` settings; `maps` are the views'
    `sweep.view_maps`, `size` the scene size the relative lengths refer to. A peak beside a circle
    already added (from this circle's axis or another's on it) is that circle again."""
    step = sweep.STEP * size
    reach = round(config.circle_reach / sweep.STEP)
    offsets = np.arange(-reach, reach + 1) * step
    existing = cKDTree(evidence.existing) if len(evidence.existing) else None
    added: list[Circle] = []
    earlier: cKDTree | None = None  # the points of the circles added
    for circle in circles:
        scores = sweep.offset_scores(circle, evidence, offsets, maps)
        value = np.where(scores.outside, 0.0, scores.value)
        strong = (scores.cover >= config.circle_cover) & (scores.cover_two >= config.circle_views_cover)
        for index in sweep.peaks(value):
            found = circle.moved(sweep.placed(circle, evidence, offsets[index], step, maps))
            points = found.points()
            if (strong[index] and sweep.away(points, existing, NOVELTY * size)
                    and sweep.away(points, earlier, 2 * NOVELTY * size)):
                added.append(found)
                earlier = cKDTree(np.concatenate([c.points() for c in added]))
    return np.concatenate([c.beziers() for c in added]) if added else np.empty((0, 4, 3))
