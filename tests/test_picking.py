"""The studio's inspection maths without a window: picking in the 3D view (screen-space distances
to segments and primitive centres, with the view camera's conventions), the enlarged inspector's
zoom, pan and pixel readout, and the per-primitive Fisher scores."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from edgedog.app.inspection import FisherScores, Inspector, fisher_scores, snapshot_primitives
from edgedog.app.picking import (
    PrimitivePick,
    chain_segments,
    clip_near,
    curve_kind,
    panel_pixel,
    pick_points,
    pick_segments,
    pixel_point,
    segment_distances,
    to_camera,
)
from edgedog.app.zoom import MAX_ZOOM, ImageZoom, pixel_at
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.gl.camera import ViewCamera
from edgedog.renderer.primitives import RasterCamera
from edgedog.renderer.rasterize import fisher_information

from edgedog.train.trainer import Snapshot

NEAR = 0.01
WIDTH, HEIGHT = 200, 100


def camera():
    """At y = -4 looking at the origin along +y, z up; f = 100 px: world x is image right, world z
    image up, and the origin projects to the centre pixel ((W - 1) / 2, (H - 1) / 2)."""
    return ViewCamera.looking_at((0, -4, 0), (0, 0, 0), (0, 0, 1), WIDTH, HEIGHT,
                                 2 * np.arctan(HEIGHT / 2 / 100)).camera()


CENTRE = ((WIDTH - 1) / 2, (HEIGHT - 1) / 2)


def test_the_view_camera_projects_with_opencv_axes_and_integer_pixel_centres():
    view = camera()
    assert view.K[0, 0] == pytest.approx(100) and view.K[1, 1] == pytest.approx(100)
    np.testing.assert_allclose(to_camera(view, np.zeros(3)), [0, 0, 4])
    # 0.4 right and 0.2 up at distance 4: 10 px right and 5 px up (rows grow downwards).
    hit = pick_points(view, np.array([[0.4, 0, 0.2]]), (CENTRE[0] + 10, CENTRE[1] - 5), NEAR)
    assert hit is not None and hit.index == 0 and hit.distance == pytest.approx(0, abs=1e-9)
    assert hit.depth == pytest.approx(4)


def test_a_click_picks_the_segment_within_the_tolerance_by_its_pixel_distance():
    view = camera()
    # A horizontal segment 0.2 above the origin: 5 px above the centre, from x - 20 px to x + 20 px.
    segments = np.array([[[-0.8, 0, 0.2], [0.8, 0, 0.2]]])
    hit = pick_segments(view, segments, np.array([7]), (CENTRE[0] + 3, CENTRE[1] - 5 + 4), NEAR)
    assert hit.index == 7 and hit.distance == pytest.approx(4) and hit.depth == pytest.approx(4)
    beyond = (CENTRE[0] + 20 + 3, CENTRE[1] - 5 + 4)  # 4 px below and 3 px past the end: 5 px
    assert pick_segments(view, segments, np.array([7]), beyond, NEAR).distance == pytest.approx(5)
    assert pick_segments(view, segments, np.array([7]), (CENTRE[0], CENTRE[1] + 5), NEAR) is None  # 10 px


def test_the_nearest_on_screen_wins_and_the_front_one_among_equally_near():
    view = camera()
    # Two segments crossing the same pixel, one behind the other; a third 3 px off.
    segments = np.array([[[-1, 2, 0], [1, 2, 0]], [[-1, 0, 0], [1, 0, 0]], [[-1, 0, 0.12], [1, 0, 0.12]]])
    hit = pick_segments(view, segments, np.arange(3), CENTRE, NEAR)
    assert hit.index == 1 and hit.depth == pytest.approx(4)
    hit = pick_segments(view, segments, np.arange(3), (CENTRE[0], CENTRE[1] - 2.5), NEAR)
    assert hit.index == 2  # 0.5 px from it, 2.5 px from the others
    points = np.array([[0, 3, 0], [0, 0, 0], [0.02, -1, 0]])  # the last: 0.67 px off, nearer the camera
    assert pick_points(view, points, CENTRE, NEAR).index == 1
    assert pick_points(view, points, (CENTRE[0] + 0.67, CENTRE[1]), NEAR).index == 2


def test_segments_are_clipped_at_the_near_plane_and_points_behind_are_never_picked():
    view = camera()
    # From behind the camera (y = -6) to the origin's plane, 0.2 right: clipped at z = near.
    through = np.array([[[0.2, -6, 0], [0.2, 0, 0]]])
    local, keep = clip_near(to_camera(view, through), NEAR)
    assert keep.tolist() == [True]
    assert local[0, 0, 2] == pytest.approx(NEAR) and local[0, 1, 2] == pytest.approx(4)
    assert pick_segments(view, through, np.array([0]), (CENTRE[0] + 5, CENTRE[1]), NEAR).index == 0
    behind = np.array([[[-1, -5, 0], [1, -5, 0]]])
    assert not clip_near(to_camera(view, behind), NEAR)[1].any()
    assert pick_segments(view, behind, np.array([0]), CENTRE, NEAR) is None
    assert pick_points(view, np.array([[0, -8, 0]]), CENTRE, NEAR) is None


def test_segment_distances_and_chains():
    distances, s = segment_distances(np.array([1.0, 1.0]), np.array([[0.0, 0.0], [3.0, 3.0]]),
                                     np.array([[2.0, 0.0], [3.0, 3.0]]))
    np.testing.assert_allclose(distances, [1.0, np.sqrt(8)])
    np.testing.assert_allclose(s, [0.5, 0.0])
    segments, owners = chain_segments([np.zeros((3, 3)), np.ones((2, 3))])
    assert segments.shape == (3, 2, 3) and owners.tolist() == [0, 0, 1]
    assert [curve_kind(i, 2, 1) for i in range(4)] == ["line", "line", "Bezier", "polyline"]


def test_the_mouse_maps_to_view_pixels_with_the_framebuffer_scale():
    # The panel's top-left corner is the first pixel's outer corner: pixel coordinate -0.5.
    assert panel_pixel((100, 50), (100, 50), (1, 1)) == (-0.5, -0.5)
    assert panel_pixel((110, 60), (100, 50), (2, 2)) == (19.5, 19.5)
    assert pixel_point(panel_pixel((123.25, 77.5), (100, 50), (2, 1)), (100, 50), (2, 1)) == (123.25, 77.5)


def test_a_fitted_inspector_reads_out_the_pixel_under_the_mouse():
    values = np.arange(12, dtype=np.float32).reshape(3, 4)  # row y, column x: value 4 y + x
    inspector = Inspector("depth", np.zeros((3, 4, 4), np.uint8), "viridis", 0, 11, values=values)
    zoom = ImageZoom(enlarged="depth")
    placement = zoom.placement((4, 3), (0, 0, 400, 600))  # fits the width: 100 points a pixel
    assert placement.scale == 100 and placement.corners(4, 3) == ((0, 150), (400, 450))
    assert pixel_at(placement, 250, 160, 4, 3) == (2, 0) and inspector.readout(2, 0) == "value 2"
    assert pixel_at(placement, 399, 449, 4, 3) == (3, 2) and inspector.readout(3, 2) == "value 11"
    assert pixel_at(placement, 250, 140, 4, 3) is None  # above the image
    image = Inspector("image", np.array([[[10, 20, 30, 255]]], np.uint8))
    assert image.readout(0, 0) == "RGB 10 20 30"


def test_zooming_keeps_the_point_under_the_mouse_and_panning_follows_the_drag():
    zoom, image, area = ImageZoom(), (40, 20), (0, 0, 400, 200)  # 10 points a pixel when fitted
    zoom.enlarge("U")
    under = zoom.placement(image, area).to_image(300, 50)
    zoom.zoom_at(3, 300, 50, image, area)
    placement = zoom.placement(image, area)
    assert zoom.zoom == pytest.approx(1.25 ** 3) and placement.scale == pytest.approx(10 * 1.25 ** 3)
    np.testing.assert_allclose(placement.to_image(300, 50), under)
    zoom.pan(25, -10, image, area)  # the image moves with the mouse
    np.testing.assert_allclose(zoom.placement(image, area).to_image(325, 40), under)
    zoom.zoom_at(100, 300, 50, image, area)
    assert zoom.zoom == MAX_ZOOM
    zoom.pan(1e6, 1e6, image, area)  # the middle stays on the image
    assert zoom.centre == (-0.5, -0.5)
    zoom.zoom_at(-100, 0, 0, image, area)  # back to the fit, centred
    assert zoom.zoom == 1 and zoom.centre is None
    zoom.pan(50, 50, image, area)
    assert zoom.centre is None
    zoom.enlarge(None)
    assert zoom.enlarged is None


def snapshot(n: int = 40, dirs: np.ndarray | None = None) -> Snapshot:
    generator = np.random.default_rng(3)
    quats = generator.normal(size=(n, 4))
    return Snapshot(0, 0, 0.0, generator.uniform(-0.3, 0.3, (n, 3)), generator.uniform(0.01, 0.05, (n, 3)),
                    quats, generator.uniform(0.2, 0.9, n), generator.normal(size=(n, 2)), np.zeros((0, 3)),
                    opacity_dirs=dirs)


def test_fisher_scores_are_the_pruning_score_over_the_training_views():
    views = [ViewCamera.looking_at(eye, (0, 0, 0), (0, 0, 1), 48, 32).camera()
             for eye in ((0, -2, 0.3), (2, 0, 0.5), (-1.5, 1.5, 1))]
    raster = RasterConfig()
    shot = snapshot()
    expected = fisher_information(snapshot_primitives(shot), [RasterCamera.from_camera(v) for v in views],
                                  raster).numpy()
    scores = fisher_scores(shot, views, raster)
    assert (scores > 0).any()
    np.testing.assert_allclose(scores, expected, rtol=1e-6)
    # A view-dependent opacity with b = 0 sees the same opacity from every view.
    np.testing.assert_allclose(fisher_scores(snapshot(dirs=np.zeros((40, 3))), views, raster), expected,
                               rtol=1e-4, atol=1e-6)
    assert fisher_scores(snapshot(0), views, raster).shape == (0,)


def test_a_picked_primitive_takes_the_fisher_score_of_its_snapshots_primitives():
    pick = PrimitivePick(2, 10, (1, 4), 3, "L0", (0, 0, 0), (0.1, 0.01, 0.01), 0.5, (0, 0), (1, 0.5))
    assert "Fisher U computing" in pick.text
    scores = np.array([1.0, 2.0, 3.0])
    assert pick.scored(FisherScores((1, 6), 12, scores)).fisher == 3.0  # the same run and count
    assert pick.scored(FisherScores((2, 1), 12, scores)).fisher is None  # another run
    assert pick.scored(FisherScores((1, 6), 12, np.ones(4))).fisher is None  # pruned or grown since
    assert torch.is_tensor(snapshot_primitives(snapshot()).means)
