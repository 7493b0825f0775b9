"""Circle completion: the circles of holes and bosses that few views see, found by sliding the
circles the curves already hold along their axes.

A blind hole's floor, a counterbore's step and a boss's foot are circles on the axis of a circle
the views all see (the hole's or the boss's rim), of the same radius, and seen only by the few
views that look down the axis: the rest of the part hides them, so no primitive forms on them.
Those few views still draw them. A circle fitted to a chain of the curves (`found_circles`) is
moved along its axis in steps of `STEP` of the scene size, up to `circle_reach` either way, and
each position is scored by what the maps draw there that no curve explains (`view_evidence`'s
unexplained pixels, weighted by the edge value, summed over the views), each view counting only
where it looks across the cylinder through the circle (`MIN_ACROSS`). A peak of that score is
a circle when, there:

- it lies inside every view's widened mask (the visual hull), all but `OUTSIDE_SHARE` of it;
- `circle_cover` of its points are drawn (their summed edge value over the views at least
  `DRAWN_SUM`), and `circle_views_cover` of them by two views or more: one view's ellipse fits a
  circle at any depth along its line of sight, two views' agree at one;
- most of it lies away from the curves.

The search is one-dimensional per circle, so chance agreements are rare where a free
triangulation of arcs would find many; a circle of another radius on the same axis (a
counterbore's hole) is not looked for. Scenes without masks get nothing, as for the lines.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from edgedog.curves.completion import NOVELTY, Evidence
from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import window_max
from edgedog.curves.grouping import Chain

MIN_VERTICES = 8
"""Fewest vertices of a chain that a circle is fitted to."""
MAX_GAP = 90.0
"""Degrees: the largest gap between a chain's vertices around the fitted centre; a chain with a
larger one is an arc (or a bend between lines), not a closed circle."""
MAX_RADIUS = 0.5
"""Largest radius of a found circle, of the scene size."""
STEP = 0.001
"""Step of the search along the axis, of the scene size (about a pixel on the CAD scenes)."""
SAMPLES = 64
"""Points around a circle where the views are read."""
DRAWN_SUM = 0.5
"""A point of a circle is drawn where the edge values of the views at its unexplained pixels
sum to at least this."""
MIN_ACROSS = np.sin(np.radians(10.0))
"""A view counts at a point of a moved circle only where its direction from the point leaves the
cylinder through the circle by at least this (the cosine to the circle's radial direction): a
view in the cylinder's tangent plane there sees every circle on it at the same place (the
cylinder's contour, or along the axis its wall), and cannot tell one depth from another."""
MAX_RIDGE_ANGLE = 30.0
"""Degrees: a view draws a point of a moved circle where the map's line there runs within this of
the circle's projection. A cylinder's contour is a band across the flat ellipses of the circles
on it that low views see; its line runs along the axis, not along them."""
RIDGE_WINDOW = 7
"""Pixels: the window of the structure tensor that gives the direction of the maps' lines."""
OUTSIDE_SHARE = 0.1
"""A moved circle is off the object where more of its points than this fall outside one view's
widened mask (a circle that another hole cuts is partly over the void)."""
QUARTER = 4.0 / 3.0 * np.tan(np.pi / 8.0)
"""Handle length, of the radius, of a cubic Bézier that draws a quarter circle."""


@dataclass(frozen=True)
class Circle:
    """A 3D circle: centre (3,), unit axes u, v (3,) spanning its plane, radius."""

    centre: np.ndarray
    u: np.ndarray
    v: np.ndarray
    radius: float

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


@dataclass(frozen=True)
class ViewMaps:
    """What the search reads of one view besides its `ViewEvidence`: value, (H, W) uint8 the edge
    map's `window_max` x 255 (a point a pixel off its line still reads it); ridge, (H, W) uint8
    the direction of the map's lines in degrees [0, 180) (from its structure tensor)."""

    value: np.ndarray
    ridge: np.ndarray


def view_maps(edge_map: np.ndarray) -> ViewMaps:
    """`ViewMaps` of an (H, W) float edge map in [0, 1]."""
    edge_map = edge_map.astype(np.float32)
    gx, gy = cv2.Sobel(edge_map, cv2.CV_32F, 1, 0), cv2.Sobel(edge_map, cv2.CV_32F, 0, 1)
    window = (RIDGE_WINDOW, RIDGE_WINDOW)
    jxx, jxy, jyy = (cv2.blur(a, window) for a in (gx * gx, gx * gy, gy * gy))
    across = 0.5 * np.arctan2(2 * jxy, jxx - jyy)  # the dominant gradient's direction
    ridge = np.degrees(across + np.pi / 2) % 180.0
    value = np.rint(window_max(edge_map) * 255).clip(0, 255).astype(np.uint8)
    return ViewMaps(value, np.rint(ridge).astype(np.uint8) % 180)


@dataclass(frozen=True)
class OffsetScores:
    """Each offset's (T,) score: `value`, the edge values summed over the views at the circle's
    unexplained pixels; `cover`, the share of its points drawn (DRAWN_SUM); `cover_two`, the share
    drawn by two views or more; `outside`, whether more than OUTSIDE_SHARE of its points fall
    outside one view's widened mask."""

    value: np.ndarray
    cover: np.ndarray
    cover_two: np.ndarray
    outside: np.ndarray


def offset_scores(circle: Circle, evidence: Evidence, offsets: np.ndarray,
                  maps: list[ViewMaps]) -> OffsetScores:
    """Score the circle moved by each of `offsets` (T,) along its normal, reading every view
    whose image holds the whole moved circle (its `ViewMaps` in `maps`). A view counts at a point
    where it draws the circle: the point lies on an unexplained pixel, the map's line there runs
    along the circle's projection (`MAX_RIDGE_ANGLE`) and the view looks across the cylinder
    through the circle (`MIN_ACROSS`). Memory O(T SAMPLES) whatever the number of views."""
    rings = circle.points(SAMPLES, offsets)  # (T, S, 3)
    shape, flat = rings.shape[:2], rings.reshape(-1, 3)
    radial = (rings - (circle.centre + offsets[:, None] * circle.normal)[:, None]) / circle.radius
    values = np.zeros(shape)
    drawing = np.zeros(shape, np.int64)
    outside = np.zeros(len(offsets), bool)
    for view, view_map in zip(evidence.views, maps):
        uv, depth = view.camera.project(flat)
        pixels, inside = view.camera.nearest_pixels(uv, depth)
        whole = inside.reshape(shape).all(axis=1)
        x = np.where(inside, pixels[:, 0], 0).reshape(shape)
        y = np.where(inside, pixels[:, 1], 0).reshape(shape)
        outside |= whole & ((~view.hull[y, x]).mean(axis=1) > OUTSIDE_SHARE)
        uv = np.nan_to_num(uv).reshape(*shape, 2)
        tangent = np.roll(uv, -1, axis=1) - np.roll(uv, 1, axis=1)  # the ring is closed
        direction = np.degrees(np.arctan2(tangent[..., 1], tangent[..., 0])) % 180.0
        turn = np.abs(direction - view_map.ridge[y, x])
        along = np.minimum(turn, 180.0 - turn) <= MAX_RIDGE_ANGLE
        towards = view.camera.center - rings
        towards /= np.maximum(np.linalg.norm(towards, axis=2, keepdims=True), 1e-12)
        across = np.abs(np.einsum("tsi,tsi->ts", towards, radial)) >= MIN_ACROSS
        on = view.unexplained[y, x] & whole[:, None] & along & across
        value = view_map.value[y, x] / 255.0
        values += np.where(on, value, 0.0)
        drawing += on & (value > 0)
    drawn = values >= DRAWN_SUM
    two = (drawn & (drawing >= 2)).mean(axis=1)
    return OffsetScores(values.sum(axis=1), drawn.mean(axis=1), two, outside)


def _peaks(value: np.ndarray) -> np.ndarray:
    """Indices of the strict local maxima of `value` (T,) above zero, highest first."""
    inner = np.arange(1, len(value) - 1)
    peak = inner[(value[inner] > 0) & (value[inner] >= value[inner - 1]) & (value[inner] > value[inner + 1])]
    return peak[np.argsort(-value[peak], kind="stable")]


def _vertex(value: np.ndarray, index: int) -> float:
    """Sub-step position of a peak at `index`: the vertex of the parabola through it and its
    neighbours, in steps from `index`."""
    left, middle, right = value[index - 1], value[index], value[index + 1]
    curvature = left - 2 * middle + right
    return 0.0 if curvature >= 0 else float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))


def _away(points: np.ndarray, others: cKDTree | None, radius: float) -> bool:
    """Whether most of points (M, 3) lie farther than `radius` from every point of `others` (a
    tree of them; None: there are none)."""
    return others is None or np.mean(others.query(points)[0] > radius) >= 0.5


def complete_circles(circles: list[Circle], evidence: Evidence, size: float,
                     config: ExtractConfig) -> np.ndarray:
    """(B, 4, 3) the Béziers of the circles the curves of `evidence` miss on the axes of
    `circles` (see the module's doc), with `config`'s `circle_*` settings; `size` is the scene
    size the relative lengths refer to. A peak beside a circle already added (from this circle's
    axis or another's on it) is that circle again."""
    step = STEP * size
    reach = round(config.circle_reach / STEP)
    offsets = np.arange(-reach, reach + 1) * step
    maps = [view_maps(view.edge_map) for view in evidence.views] if circles else []
    existing = cKDTree(evidence.existing) if len(evidence.existing) else None
    added: list[Circle] = []
    earlier: cKDTree | None = None  # the points of the circles added
    for circle in circles:
        scores = offset_scores(circle, evidence, offsets, maps)
        value = np.where(scores.outside, 0.0, scores.value)
        strong = (scores.cover >= config.circle_cover) & (scores.cover_two >= config.circle_views_cover)
        for index in _peaks(value):
            found = circle.moved(offsets[index] + _vertex(value, index) * step)
            points = found.points()
            if (strong[index] and _away(points, existing, NOVELTY * size)
                    and _away(points, earlier, 2 * NOVELTY * size)):
                added.append(found)
                earlier = cKDTree(np.concatenate([c.points() for c in added]))
    return np.concatenate([c.beziers() for c in added]) if added else np.empty((0, 4, 3))
