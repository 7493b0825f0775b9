"""The drawing-plane test (edgedog.curves.drawing_plane): the spread of the drawing views off
their best plane is near 0 for a contour (views looking along one tangent plane), about 1/3
for an edge drawn from all around, NaN for a point too few views draw; a curve takes the median
of its points."""

from __future__ import annotations

import numpy as np
import pytest

from edgedog.curves.drawing_plane import MIN_DRAWING_VIEWS, curve_spreads, drawing_spread
from edgedog.synthetic.cameras import TARGET, orbit_cameras

SIZE = 48
NORMAL = np.array([1.0, 0.0, 0.0])


class DrawnBy:
    """A scene whose view i draws every pixel when `draws(direction to its camera)` holds, and
    none otherwise (what `drawing_spread` reads of a scene)."""

    def __init__(self, draws):
        self.cameras = orbit_cameras(80, SIZE)
        self.draws = draws

    def __len__(self) -> int:
        return len(self.cameras)

    def camera(self, index: int):
        return self.cameras[index]

    def load_edge_map(self, index: int, detector: str) -> np.ndarray:
        direction = self.cameras[index].center - TARGET
        value = float(self.draws(direction / np.linalg.norm(direction)))
        return np.full((SIZE, SIZE), value, np.float32)


def contour(direction: np.ndarray) -> bool:
    """The views that look along the tangent plane x = 0.5 (within 10 degrees)."""
    return abs(direction @ NORMAL) < np.sin(np.radians(10))


def test_a_contour_spreads_little_and_an_edge_from_all_around_a_third():
    points = TARGET[None]
    assert drawing_spread(points, DrawnBy(contour), "maps")[0] < 0.02
    assert drawing_spread(points, DrawnBy(lambda d: True), "maps")[0] == pytest.approx(1 / 3, abs=0.03)
    # a convex edge between faces x+ and y+: the views of either face (3/4 of the sphere)
    assert drawing_spread(points, DrawnBy(lambda d: d[0] > 0 or d[1] > 0), "maps")[0] > 0.15


def test_too_few_drawing_views_give_no_spread():
    views = DrawnBy(lambda d: True).cameras
    few = [view.center for view in views[:MIN_DRAWING_VIEWS - 1]]

    def drawn_by_few(direction: np.ndarray) -> bool:
        return any(np.allclose(direction, (c - TARGET) / np.linalg.norm(c - TARGET)) for c in few)

    assert np.isnan(drawing_spread(TARGET[None], DrawnBy(drawn_by_few), "maps")[0])
    assert drawing_spread(np.zeros((0, 3)), DrawnBy(contour), "maps").shape == (0,)


def test_a_curve_takes_the_median_of_its_points():
    # two curves of three points: both drawn like a contour; the scene's maps do not depend on the
    # point, so every point of a curve has the same spread
    samples = np.stack([TARGET + np.array([0.0, 0.0, dz]) for dz in (-0.1, 0.0, 0.1)])[None].repeat(2, axis=0)
    spreads = curve_spreads(samples, DrawnBy(contour), "maps")
    assert spreads.shape == (2,)
    assert (spreads < 0.02).all()
    assert np.isnan(curve_spreads(samples, DrawnBy(lambda d: False), "maps")).all()
