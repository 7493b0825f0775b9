"""The search that circle and slide completion share: a found curve moved step by step along one
direction, each position scored by what the edge maps draw there and no curve explains.

An edge that few views see is often a copy of one that every view sees, moved along one
direction: a blind hole's floor on its rim's axis, a pocket's floor under its rim, a concave
corner beside a wall's top edge. The moved curve sweeps a surface (a cylinder, a plane). At
each offset a view reads the curve's projection on its map: it counts at a point where the point
lands on a pixel that is drawn and that no curve explains (`ViewEvidence.unexplained`), the
map's line there runs along the projection (`MAX_RIDGE_ANGLE`: a curved face's contour crossing
it does not count) and the view looks across the swept surface (`MIN_ACROSS`: a view in the
surface's tangent plane sees every offset at one place). The search is one-dimensional, so
chance agreements between views are rare where a free triangulation would find many.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np
from scipy.spatial import cKDTree

from edgedog.curves.completion import Evidence
from edgedog.curves.contours import window_max

STEP = 0.001
"""Step of the search, of the scene size (about a pixel on the CAD scenes)."""
DRAWN_SUM = 0.5
"""A point of a moved curve is drawn where the edge values of the views at its unexplained
pixels sum to at least this."""
MIN_ACROSS = np.sin(np.radians(10.0))
"""A view counts at a point only where its direction from the point leaves the swept surface by
at least this (the cosine to the surface's normal there): a view in the surface's tangent plane
sees every offset at the same place (a cylinder's contour, a wall seen edge-on), and cannot tell
one depth from another."""
MAX_RIDGE_ANGLE = 30.0
"""Degrees: a view draws a point of a moved curve where the map's line there runs within this of
the curve's projection. A cylinder's contour is a band across the flat ellipses of the circles
on it that low views see; its line runs along the axis, not along them."""
RIDGE_WINDOW = 7
"""Pixels: the window of the structure tensor that gives the direction of the maps' lines."""
PLACE_STEPS = 15
"""Steps either way of a peak of the score within which a copy is placed (`placed`): the thick
lines of the maps make the score a plateau of offsets up to about this wide."""
OUTSIDE_SHARE = 0.1
"""A moved curve is off the object where more of its points than this fall outside one view's
widened mask (a circle that another hole cuts is partly over the void)."""


class Swept(Protocol):
    """A curve that can be moved along one direction."""

    closed: bool
    """Whether its samples go round (a circle) or run from end to end (a line)."""

    def swept(self, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The curve moved by each of `offsets` (T,): (T, S, 3) samples along it, and the unit
        normals of the swept surface at them, (T, S, 3) or broadcastable to it."""


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
    """Each offset's (T,) score: `value`, the edge values summed over the views at the curve's
    unexplained pixels; `cover`, the share of its points drawn (DRAWN_SUM); `cover_two`, the share
    drawn by two views or more; `outside`, whether more than OUTSIDE_SHARE of its points fall
    outside one view's widened mask."""

    value: np.ndarray
    cover: np.ndarray
    cover_two: np.ndarray
    outside: np.ndarray


def bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(...) the values of an (H, W) image at sub-pixel points uv (..., 2) inside it, interpolated
    between the four nearest pixel centres."""
    height, width = image.shape
    x = np.clip(uv[..., 0], 0, width - 1.001)
    y = np.clip(uv[..., 1], 0, height - 1.001)
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    fx, fy = x - x0, y - y0
    top = image[y0, x0] * (1 - fx) + image[y0, x0 + 1] * fx
    bottom = image[y0 + 1, x0] * (1 - fx) + image[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bottom * fy


def offset_scores(curve: Swept, evidence: Evidence, offsets: np.ndarray, maps: list[ViewMaps],
                  sharp: bool = False) -> OffsetScores:
    """Score `curve` moved by each of `offsets` (T,), reading every view whose image holds the
    whole moved curve (its `ViewMaps` in `maps`): a view counts at a point where it draws the
    curve (see the module's doc). The value read is the map's largest within a pixel (a thick
    line: a plateau of offsets, what finding a copy needs), or with `sharp` the map's own,
    interpolated at the projection (its ridge: what placing a copy needs). Memory O(T S)
    whatever the number of views."""
    points, normals = curve.swept(offsets)  # (T, S, 3)
    shape, flat = points.shape[:2], points.reshape(-1, 3)
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
        if curve.closed:
            tangent = np.roll(uv, -1, axis=1) - np.roll(uv, 1, axis=1)
        else:
            tangent = np.gradient(uv, axis=1)
        direction = np.degrees(np.arctan2(tangent[..., 1], tangent[..., 0])) % 180.0
        turn = np.abs(direction - view_map.ridge[y, x])
        along = np.minimum(turn, 180.0 - turn) <= MAX_RIDGE_ANGLE
        towards = view.camera.center - points
        towards /= np.maximum(np.linalg.norm(towards, axis=2, keepdims=True), 1e-12)
        across = np.abs((towards * normals).sum(axis=2)) >= MIN_ACROSS
        on = view.unexplained[y, x] & whole[:, None] & along & across
        value = bilinear(view.edge_map, uv) if sharp else view_map.value[y, x] / 255.0
        values += np.where(on, value, 0.0)
        drawing += on & (value > 0)
    drawn = values >= DRAWN_SUM
    two = (drawn & (drawing >= 2)).mean(axis=1)
    return OffsetScores(values.sum(axis=1), drawn.mean(axis=1), two, outside)


def placed(curve: Swept, evidence: Evidence, peak: float, step: float, maps: list[ViewMaps]) -> float:
    """The offset within `PLACE_STEPS` steps of `step` either way of `peak` (an offset where the
    plateau score peaks) where the views' maps themselves peak (`offset_scores` with `sharp`),
    refined between steps: the middle of the thick lines the views draw, not the step at which
    the score happens to peak on its plateau (a circle's copy landed 2 to 10 mm off a floor that
    way)."""
    offsets = peak + np.arange(-PLACE_STEPS, PLACE_STEPS + 1) * step
    value = offset_scores(curve, evidence, offsets, maps, sharp=True).value
    index = int(np.argmax(value))
    if 0 < index < len(offsets) - 1:
        return float(offsets[index] + vertex(value, index) * step)
    return float(offsets[index])


def peaks(value: np.ndarray) -> np.ndarray:
    """Indices of the strict local maxima of `value` (T,) above zero, highest first."""
    inner = np.arange(1, len(value) - 1)
    peak = inner[(value[inner] > 0) & (value[inner] >= value[inner - 1]) & (value[inner] > value[inner + 1])]
    return peak[np.argsort(-value[peak], kind="stable")]


def vertex(value: np.ndarray, index: int) -> float:
    """Sub-step position of a peak at `index`: the vertex of the parabola through it and its
    neighbours, in steps from `index`."""
    left, middle, right = value[index - 1], value[index], value[index + 1]
    curvature = left - 2 * middle + right
    return 0.0 if curvature >= 0 else float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))


def away(points: np.ndarray, others: cKDTree | None, radius: float) -> bool:
    """Whether most of points (M, 3) lie farther than `radius` from every point of `others` (a
    tree of them; None: there are none)."""
    return others is None or np.mean(others.query(points)[0] > radius) >= 0.5
