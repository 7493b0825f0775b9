"""The drawing-plane test of extraction: a fitted curve whose points are drawn only by views
lying near one plane through them is the occluding contour of a curved face, not an edge.

A view draws the contour of a smooth surface through a point p exactly when it looks along the
surface there: the direction d from p to its camera is perpendicular to the surface normal n at
p. Every view that draws a contour point therefore lies near the tangent plane through p (near
it, not on it: the maps' band is a few pixels wide, and a view slightly off still finds the line
it draws within reach). An edge is drawn by every view that sees it, from a region of directions
(the two faces' views), not a plane. The test needs no surface: the plane is the one the
drawing directions fit best, and how far they spread off it is the smallest eigenvalue of their
mean outer product d d^T (0 for directions in one plane, 1/3 for directions from all around).

What it cannot tell apart: an edge that only a narrow fan of views draws (a shallow chamfer
seen as a line from some sides only) spreads little off a plane too, so only the contour
filter's suspects are judged (some views draw them at grazing incidence on the visual hull,
`shading.curve_grazing`), and the limit is set where no edge of the CAD designs and the shared
ABC objects measured was below it (docs/notes). A narrow cone of views (an edge few views see)
fits a plane as well; those curves are kept only if they are not suspects.
"""

from __future__ import annotations

import numpy as np

from edgedog.curves.contours import DRAWN_VALUE, window_max
from edgedog.curves.shading import judged_views
from edgedog.scenes import Scene

MIN_DRAWING_VIEWS = 6
"""A point drawn by fewer views has no plane to speak of and is not counted."""


def drawing_spread(points: np.ndarray, scene: Scene, detector: str) -> np.ndarray:
    """(N,) for each point (N, 3): the smallest eigenvalue of the mean outer product of the unit
    directions from it to the cameras of the views whose `detector` maps draw it (`window_max`
    at least DRAWN_VALUE; at most `shading.MAX_VIEWS` views, evenly spread); NaN for a point
    that fewer than MIN_DRAWING_VIEWS views draw. Views are streamed: memory is O(N)."""
    moments = np.zeros((len(points), 3, 3))
    counts = np.zeros(len(points))
    for view in judged_views(len(scene)) if len(points) else []:
        camera = scene.camera(view)
        pixels, inside = camera.pixels(points)
        drawn = inside.copy()
        values = window_max(scene.load_edge_map(view, detector))
        drawn[inside] = values[pixels[inside, 1], pixels[inside, 0]] >= DRAWN_VALUE
        directions = camera.center - points[drawn]
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        moments[drawn] += directions[:, :, None] * directions[:, None, :]
        counts[drawn] += 1
    spread = np.linalg.eigvalsh(moments / np.maximum(counts, 1)[:, None, None])[:, 0]
    return np.where(counts >= MIN_DRAWING_VIEWS, spread, np.nan)


def curve_spreads(samples: np.ndarray, scene: Scene, detector: str) -> np.ndarray:
    """(C,) the median `drawing_spread` over each curve's points (C, S, 3) that enough views
    draw; NaN for a curve with none."""
    spread = drawing_spread(samples.reshape(-1, 3), scene, detector).reshape(samples.shape[:2])
    counted = np.isfinite(spread)
    return np.array([np.median(row[ok]) if ok.any() else np.nan for row, ok in zip(spread, counted)])
