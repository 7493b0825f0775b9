"""Circle completion (extract.complete_circles): circles are fitted to chains and told from bends
and arcs, drawn as four Béziers, and on a block with a blind hole the hole's floor, left out of
the curves, is found by sliding the rim's circle down its axis; nothing is added where every
edge is there or the maps draw nothing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.builtin.writer import write_scene
from edgedog.curve_files import EdgeCurves
from edgedog.curves.circles import Circle, complete_circles, fit_circle, found_circles
from edgedog.curves.completion import Evidence, ViewEvidence, gather_evidence
from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import HullSurface
from edgedog.curves.extract import scene_size
from edgedog.curves.grouping import Chain
from edgedog.curves.sweep import offset_scores, view_maps
from edgedog.metrics import sample_cubic_bezier
from edgedog.scenes import load_scene
from edgedog.synthetic.cameras import TARGET, orbit_cameras
from edgedog.synthetic.family import family_part
from edgedog.synthetic.features import sample_curve

BLIND_HOLE_DESIGN = 6
"""L section + through hole + blind hole"""


def _circle_of(curve) -> Circle:
    """A part's circle curve as a `Circle`."""
    u = np.asarray(curve.e1) / np.linalg.norm(curve.e1)
    v = np.asarray(curve.e2) / np.linalg.norm(curve.e2)
    return Circle(np.asarray(curve.center, float), u, v, float(np.linalg.norm(curve.e1)))


def test_a_noisy_circle_is_fitted_and_a_bend_or_an_arc_is_no_circle():
    rng = np.random.default_rng(0)
    truth = Circle(np.array([0.3, -0.2, 0.5]), np.array([1.0, 0, 0]), np.array([0, 0.6, 0.8]), 0.07)
    points = truth.points(40) + rng.normal(0, 0.0005, (40, 3))
    circle, rms, gap = fit_circle(points)
    assert np.linalg.norm(circle.centre - truth.centre) < 0.001
    assert abs(circle.radius - truth.radius) < 0.001
    assert abs(abs(circle.normal @ truth.normal) - 1) < 1e-4
    assert rms < 0.001 and gap < 20
    bend = np.r_[np.linspace([0, 0, 0], [0.1, 0, 0], 10), np.linspace([0.1, 0.01, 0], [0.1, 0.1, 0], 10)]
    arc = truth.points(40)[:15]  # a third of the circle
    kept = found_circles([Chain(points), Chain(bend), Chain(arc), Chain(points[:5])], 0.002, 1.0)
    assert len(kept) == 1 and np.linalg.norm(kept[0].centre - truth.centre) < 0.001


def test_the_four_beziers_draw_the_circle():
    circle = Circle(np.array([0.1, 0.2, 0.3]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]), 0.05)
    beziers = circle.beziers()
    assert beziers.shape == (4, 4, 3)
    points = np.concatenate([sample_cubic_bezier(b, 0.001) for b in beziers])
    assert np.abs(np.linalg.norm(points - circle.centre, axis=1) - circle.radius).max() < 0.0002
    assert np.allclose(beziers[1:, 0], beziers[:-1, 3]) and np.allclose(beziers[0, 0], beziers[-1, 3])


def _drawn(camera, polylines: list[np.ndarray], width: int) -> ViewEvidence:
    """A view whose map draws the projections of 3D polylines (M, 3) at `width` px, every drawn
    pixel unexplained, and the whole image inside the mask."""
    edge_map = np.zeros((camera.height, camera.width), np.float32)
    for line in polylines:
        uv = np.rint(camera.project(line)[0]).astype(np.int32)
        cv2.polylines(edge_map, [uv.reshape(-1, 1, 2)], False, 1.0, width)
    drawn = edge_map > 0
    return ViewEvidence(camera, edge_map, drawn, drawn, np.ones_like(drawn), np.empty((0, 4)))


def test_a_cylinders_contours_draw_no_circle_on_it_while_the_circle_drawn_is_one():
    """The contours of a cylinder cross the flat ellipse of every circle on it that a low view
    sees: summed over the views they cover the circle, but run along the axis, not along it."""
    ring = Circle(TARGET, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), 0.1)
    cameras = [c for c in orbit_cameras(40, 400) if abs(c.forward[2]) < 0.5]  # low views
    contours, circles = [], []
    for camera in cameras:
        points = ring.points(720)
        towards = camera.center - points
        grazing = np.einsum("ni,ni->n", towards, points - ring.centre)
        ends = np.nonzero(np.sign(grazing) != np.sign(np.roll(grazing, 1)))[0]
        lines = [np.stack([points[e] - [0, 0, 0.15], points[e] + [0, 0, 0.15]]) for e in ends]
        contours.append(_drawn(camera, lines, 6))
        circles.append(_drawn(camera, [np.r_[points, points[:1]]], 3))
    offsets = np.array([-0.002, 0.0, 0.002])
    for views, drawn in ((contours, False), (circles, True)):
        maps = [view_maps(view.edge_map) for view in views]
        scores = offset_scores(ring, Evidence(views, np.empty((0, 3))), offsets, maps)
        assert (scores.cover[1] >= 0.9) == drawn, scores.cover


@pytest.fixture(scope="module")
def blind_hole(tmp_path_factory):
    """The blind-hole design's scene, 50 views at 800 px with exact maps (at 400 px the floor lies
    within the explained 4 px of its rim in the views that see it); every curve but the blind
    hole's floor (lines, circles as Béziers), every curve, the floor, its rim and the size."""
    part = family_part(BLIND_HOLE_DESIGN)
    folder = tmp_path_factory.mktemp("circles") / "blind-hole"
    scene = load_scene(write_scene(folder, part, views=50, size=800, detector="exact"))
    floor = next(c for c in part.curves if c.type == "circle" and c.dihedral == "concave")
    rim = next(c for c in part.curves if c.type == "circle" and c is not floor
               and np.allclose(c.center[:2], floor.center[:2]))
    lines = [[c.a, c.b] for c in part.curves if c.type == "line"]
    beziers = [_circle_of(c).beziers() for c in part.curves if c.type == "circle" and c is not floor]
    others = EdgeCurves(lines=lines, beziers=np.concatenate(beziers))
    every = EdgeCurves(lines=lines, beziers=np.concatenate([*beziers, _circle_of(floor).beziers()]))
    size = scene_size(np.concatenate([sample_curve(c) for c in part.curves]))
    return scene, others, every, _circle_of(floor), _circle_of(rim), size


def _complete(scene, curves: EdgeCurves, axes: list[Circle], size: float) -> np.ndarray:
    config = ExtractConfig(contour_hull_cells=64)
    evidence = gather_evidence(curves, HullSurface(scene, config.contour_hull_cells), "exact", size, config)
    if evidence is None:
        return np.empty((0, 4, 3))
    maps = [view_maps(view.edge_map) for view in evidence.views]
    return complete_circles(axes, evidence, maps, size, config)


def test_the_blind_holes_floor_comes_back_from_its_rim_and_nothing_else(blind_hole):
    scene, others, every, floor, rim, size = blind_hole
    added = _complete(scene, others, [rim], size)
    assert added.shape == (4, 4, 3)  # one circle
    points = np.concatenate([sample_cubic_bezier(b, 0.002) for b in added])
    assert np.linalg.norm(points[:, None] - floor.points(200)[None], axis=2).min(axis=1).max() < 0.005 * size


def test_nothing_is_added_where_every_circle_is_found(blind_hole):
    scene, others, every, floor, rim, size = blind_hole
    assert _complete(scene, every, [rim], size).shape == (0, 4, 3)


def test_empty_edge_maps_add_no_circle(blind_hole, monkeypatch):
    scene, others, every, floor, rim, size = blind_hole
    blank = np.zeros((scene.camera(0).height, scene.camera(0).width), np.float32)
    monkeypatch.setattr(scene, "load_edge_map", lambda index, detector=None: blank)
    assert _complete(scene, others, [rim], size).shape == (0, 4, 3)
