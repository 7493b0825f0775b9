"""The shading test of extraction: a fitted curve is an edge when the faces on either side of it
keep their grey value across the views that draw it.

A sharp edge separates two faces, each of which a fixed light shades by its own normal: every
view that draws the edge shows the same two grey values on its two sides (or the background,
where the edge is an outline). The occluding contour of a curved face is no such curve: each
view draws it where the surface turns away from that view, so the surface beside it faces a
different way in each view and its grey value changes from view to view; training still
triangulates these contours into curves. The contour filter (`edgedog.curves.contours`) judges
them by the visual hull's normals, which are the object's only where a silhouette touches it;
this test needs no surface, and so also reaches the contours of fillets and of the faces inside
holes and pockets.

Sides are told apart in 3D, not in the image: for a curve point p with tangent t seen from a
camera at c, the side of the plane through c spanned by t and p - c, so that a face appears on
the same side in every view that sees both faces of the edge. Each view that draws the curve
gives each side a grey value per piece of the curve (the median over the piece's points: a
fixed stretch of a face keeps its grey value in every view, also a curved face beside a
circular edge). A side is consistent where most of these values lie within
`shading_tolerance` of their piece's median over the views; values on the background (outside
the view's mask) are left out, since an outline's far side changes with what lies behind it.
A curve is dropped when either side is inconsistent and it is a suspect: its points are seen
at grazing incidence on the visual hull by some of the views that draw them (`curve_grazing`,
the contour filter's test at a share below that filter's own limit).

Limits (measured on the CAD designs, docs/RESULTS.md): the images must be renders or photos of
a matte object under a fixed light, as ABC-NEF's and the built-in scenes' are; a face that no
light reaches keeps one grey value whatever its normal, so contours there are not caught; and
an outline whose far side is the part itself (walls seen behind walls) or whose face some views
see at grazing incidence (a strip narrower than `SIDE_PIXELS`) also changes from view to view,
which is why only the suspects are judged. Under ABC-NEF's soft light a curved face's grey value
changes little with its normal (0.11 from darkest to brightest around a vertical cylinder, at
most 0.05 between directions 30 degrees apart), so what the test catches of a contour is mostly
its far side, the part behind it. Scenes without masks are not judged.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import map_coordinates

from edgedog.curve_files import EdgeCurves, curve_polylines
from edgedog.curves.contours import DRAWN_VALUE, HullSurface, grazing_shares, window_max
from edgedog.metrics import points_along
from edgedog.scenes import Scene
from edgedog.scenes.camera import Camera

SAMPLES = 32
"""Points along a curve (evenly by arc length) where the views are read."""
PIECES = 8
"""Consecutive pieces of a curve (`SAMPLES` / `PIECES` points each) whose grey values are compared
between views: the median over a piece's points is robust to a point whose side reading lands on
the edge's own anti-aliased pixels or across a neighbouring edge, while a piece stays short
enough that the curved face beside a circular edge keeps one grey value along it."""
SIDE_PIXELS = 2.0
"""Pixels from the curve's projection at which each side's grey value is read: past the
anti-aliased pixels of the edge itself, within the strip of a face seen at an angle."""
DRAWN_SHARE = 0.75
"""A view draws a curve where this share of its points lands on drawn pixels (`window_max` at
least `DRAWN_VALUE`); a view that draws only part of it (the rest hidden, or another edge's
pixels crossing it) is not read."""
MIN_SIDE_VIEWS = 3
"""A point of a side that fewer views draw and see on the object is not judged (nothing to compare)."""
MAX_VIEWS = 256
"""Views read at most (evenly spread): the values held grow with curves x views."""


def curve_samples(curves: EdgeCurves) -> np.ndarray:
    """(C, SAMPLES, 3) points evenly spaced by arc length along each curve (lines, then Béziers,
    then polylines), ends included: where both tests read the curve."""
    fractions = np.linspace(0.0, 1.0, SAMPLES)
    chains = [points_along(chain, fractions) for chain in curve_polylines(curves)]
    return np.array(chains, dtype=np.float64).reshape(-1, SAMPLES, 3)


def side_offsets(camera: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions (K, 2) of curve points (K, 3) in `camera` and the unit image directions
    (K, 2) towards their positive side: the side of the plane through the camera centre spanned
    by the curve's tangent and the ray, on which n = t x (p - c) points."""
    uv, _ = camera.project(points)
    tangent = np.gradient(points, axis=0)
    normal = np.cross(tangent, points - camera.center)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-18)
    along = np.gradient(uv, axis=0)
    along /= np.maximum(np.linalg.norm(along, axis=1, keepdims=True), 1e-12)
    across = np.stack([-along[:, 1], along[:, 0]], axis=1)
    step = 1e-3 * np.linalg.norm(points - camera.center, axis=1, keepdims=True)
    towards, _ = camera.project(points + step * normal)
    flip = np.sum((towards - uv) * across, axis=1) < 0
    across[flip] *= -1
    return uv, across


def view_sides(camera: Camera, grey: np.ndarray, drawn: np.ndarray, mask: np.ndarray,
               points: np.ndarray) -> np.ndarray:
    """(K, 2) the grey value `SIDE_PIXELS` to the positive and to the negative side of each of a
    curve's points (K, 3) in one view; NaN where the side falls on the background, and
    everywhere when the view does not draw the curve (`DRAWN_SHARE`). `grey`: (H, W) float in
    [0, 1]; `drawn`, `mask`: (H, W) bool."""
    sides = np.full((len(points), 2), np.nan)
    pixels, inside = camera.pixels(points)
    if not inside.all() or drawn[pixels[:, 1], pixels[:, 0]].mean() < DRAWN_SHARE:
        return sides
    uv, across = side_offsets(camera, points)
    height, width = grey.shape
    for k, sign in enumerate((1.0, -1.0)):
        at = uv + sign * SIDE_PIXELS * across
        rows = np.clip(np.rint(at[:, 1]).astype(np.int64), 0, height - 1)
        cols = np.clip(np.rint(at[:, 0]).astype(np.int64), 0, width - 1)
        values = map_coordinates(grey, [at[:, 1], at[:, 0]], order=1, mode="nearest")
        sides[:, k] = np.where(mask[rows, cols], values, np.nan)
    return sides


def piece_values(values: np.ndarray) -> np.ndarray:
    """(V, PIECES) the median of a side's grey values (V, SAMPLES) over each piece's points that
    are seen on the object, NaN for a piece of which fewer than half are."""
    pieces = values.reshape(len(values), PIECES, SAMPLES // PIECES)
    seen = np.isfinite(pieces).sum(axis=2)
    medians = np.full(seen.shape, np.nan)
    enough = seen * 2 >= SAMPLES // PIECES
    medians[enough] = np.nanmedian(pieces[enough], axis=1)
    return medians


def consistent_share(values: np.ndarray, tolerance: float) -> float:
    """The share of a side's grey values (V, P) (views by pieces of a curve; NaN: not seen on
    the object) within `tolerance` of their piece's median over the views, over the pieces that
    at least `MIN_SIDE_VIEWS` views see (NaN when none does)."""
    counted = np.isfinite(values)
    judged = counted.sum(axis=0) >= MIN_SIDE_VIEWS
    if not judged.any():
        return float("nan")
    values, counted = values[:, judged], counted[:, judged]
    median = np.nanmedian(values, axis=0)
    close = np.abs(values - median) <= tolerance
    return float((close & counted).sum() / counted.sum())


def judged_views(count: int) -> np.ndarray:
    """Indices of at most `MAX_VIEWS` views, evenly spread over the `count` views."""
    return np.unique(np.linspace(0, count - 1, min(count, MAX_VIEWS)).round().astype(np.int64))


def curve_grazing(samples: np.ndarray, surface: HullSurface, detector: str, max_cosine: float,
                  probe: float) -> np.ndarray:
    """(C,) for each curve of `samples` (C, SAMPLES, 3), the share of the views drawing its points
    that see them at grazing incidence on the visual hull of `surface`, on average over its
    points (`contours.grazing_shares`, with the contour filter's `max_cosine` and `probe`): the
    shading and drawing-plane tests judge the curves at or above their own share. NaN on a
    scene without masks, so that no share picks a curve there."""
    if not len(samples) or surface.grid is None:
        return np.full(len(samples), np.nan)
    points = samples.reshape(-1, 3)
    shares = grazing_shares(points, surface.normals(points, probe), surface.scene, detector, max_cosine)
    return shares.reshape(len(samples), SAMPLES).mean(axis=1)


def shading_shares(samples: np.ndarray, scene: Scene, detector: str, masks: list[np.ndarray],
                   tolerance: float) -> np.ndarray:
    """(C,) for each curve of `samples` (C, SAMPLES, 3), the lower of its two sides'
    `consistent_share` over the views that draw it (at most `MAX_VIEWS` of the scene's);
    NaN where no piece of either side is seen by `MIN_SIDE_VIEWS` views. No view is read
    without curves. `masks`: each view's (H, W) bool object mask."""
    views = judged_views(len(scene)) if len(samples) else np.zeros(0, np.int64)
    sides = np.full((len(samples), len(views), SAMPLES, 2), np.nan)
    for row, view in enumerate(views):
        camera, grey = scene.camera(view), scene.load_image(view).mean(axis=2)
        drawn = window_max(scene.load_edge_map(view, detector)) >= DRAWN_VALUE
        for c, points in enumerate(samples):
            sides[c, row] = view_sides(camera, grey, drawn, masks[view], points)
    shares = [np.fmin(consistent_share(piece_values(sides[c, :, :, 0]), tolerance),
                      consistent_share(piece_values(sides[c, :, :, 1]), tolerance))
              for c in range(len(samples))]
    return np.array(shares, dtype=np.float64).reshape(len(samples))
