"""Slide completion (extract.complete_slides): lines are slid along the directions the part's lines
run in, and on a block with a pocket the pocket's floor, left out of the curves, is found by
sliding the rim's lines down; a line floating in the pocket's opening, which the views that see it
do not draw, is refused; nothing is added where every edge is there or the maps draw nothing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.builtin.writer import write_scene
from edgedog.curve_files import EdgeCurves
from edgedog.curves.circles import Circle
from edgedog.curves.completion import ViewEvidence, gather_evidence
from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import HullSurface
from edgedog.curves.extract import scene_size
from edgedog.curves.slides import complete_slides, line_directions, ridge_drawn, seen_undrawn, slides
from edgedog.curves.sweep import view_maps
from edgedog.scenes import load_scene
from edgedog.synthetic.cameras import orbit_cameras
from edgedog.synthetic.family import family_part
from edgedog.synthetic.features import sample_curve

POCKET_DESIGN = 0
"""block + pocket + small hole"""


def test_directions_are_grouped_by_angle_and_ordered_by_length():
    x, y, z = np.eye(3)
    lines = np.array([[0 * x, 0.5 * x], [y, y + 0.4 * x], [0 * x, 0.3 * z],
                      [0 * x, 0.2 * (y + 0.01 * x)], [0 * x, 0.01 * y]])
    directions = line_directions(lines, min_length=0.05)
    assert directions.shape == (3, 3)
    assert np.allclose(np.abs(directions[0]), x)  # 0.9 long in all
    assert np.allclose(np.abs(directions[1]), z)  # 0.3
    assert abs(directions[2] @ y) > 0.99  # 0.2: the short one along y gives no direction of its own


def test_a_line_slides_only_across_itself():
    x, y, z = np.eye(3)
    lines = np.array([[0 * x, 0.5 * x], [0 * x, 0.4 * y], [0 * x, 0.3 * z]])
    found = slides(lines, size=1.0)
    assert len(found) == 6  # each line along the two other directions
    for slide in found:
        along = slide.ends[1] - slide.ends[0]
        assert abs(slide.slide @ along) < 1e-9 and np.isclose(np.linalg.norm(slide.slide), 1.0)


def _circle_of(curve) -> Circle:
    u = np.asarray(curve.e1) / np.linalg.norm(curve.e1)
    v = np.asarray(curve.e2) / np.linalg.norm(curve.e2)
    return Circle(np.asarray(curve.center, float), u, v, float(np.linalg.norm(curve.e1)))


@pytest.fixture(scope="module")
def pocket(tmp_path_factory):
    """The pocket design's scene, 50 views at 800 px with exact maps; the curves without the
    pocket's concave lines (its floor and its corners, which no primitive forms on), every
    curve, the floor's lines, the corners' lines, and the size."""
    part = family_part(POCKET_DESIGN)
    folder = tmp_path_factory.mktemp("slides") / "pocket"
    scene = load_scene(write_scene(folder, part, views=50, size=800, detector="exact"))
    lines = [c for c in part.curves if c.type == "line"]
    rim = max(max(c.a[2], c.b[2]) for c in lines)
    floor = np.array([[c.a, c.b] for c in lines
                      if c.dihedral == "concave" and abs(c.a[2] - c.b[2]) < 1e-6 and c.a[2] < rim - 1e-3])
    corners = np.array([[c.a, c.b] for c in lines if c.dihedral == "concave" and abs(c.a[2] - c.b[2]) > 1e-3])
    beziers = np.concatenate([_circle_of(c).beziers() for c in part.curves if c.type == "circle"])
    others = EdgeCurves(lines=[[c.a, c.b] for c in lines if c.dihedral != "concave"], beziers=beziers)
    every = EdgeCurves(lines=[[c.a, c.b] for c in lines], beziers=beziers)
    size = scene_size(np.concatenate([sample_curve(c) for c in part.curves]))
    return scene, others, every, floor, corners, size


def _complete(scene, curves: EdgeCurves, size: float) -> np.ndarray:
    config = ExtractConfig(contour_hull_cells=64, complete_slides=True)
    surface = HullSurface(scene, config.contour_hull_cells)
    evidence = gather_evidence(curves, surface, "exact", size, config)
    if evidence is None:
        return np.empty((0, 2, 3))
    maps = [view_maps(view.edge_map) for view in evidence.views]
    return complete_slides(curves.lines, evidence, maps, surface, "exact", size, config)


def _distance(lines: np.ndarray, to: np.ndarray) -> np.ndarray:
    """(A,) largest distance of each line of `lines` (A, 2, 3) from the nearest line of `to`."""
    w = np.linspace(0, 1, 20)[None, :, None]
    points = lines[:, :1] * (1 - w) + lines[:, 1:] * w  # (A, 20, 3)
    ends = to[:, 0]
    along = to[:, 1] - to[:, 0]
    t = np.clip(np.einsum("apbi,bi->apb", points[:, :, None] - ends, along) / (along**2).sum(-1), 0, 1)
    nearest = ends + t[..., None] * along
    return np.linalg.norm(points[:, :, None] - nearest, axis=-1).min(axis=2).max(axis=1)


def test_the_pockets_floor_comes_back_from_its_rim(pocket):
    scene, others, every, floor, corners, size = pocket
    added = _complete(scene, others, size)
    assert len(floor) == 4
    # Three of the four: the fourth, under the wall that the views looking into the pocket face
    # least, is drawn by two views or more on half of it only (slide_views_cover).
    assert (_distance(floor, added) < 0.005 * size).sum() >= 3
    # The lines joining the rim's ends to the floor's ends: two of the pocket's corners.
    assert len(corners) == 4 and (_distance(corners, added) < 0.005 * size).sum() >= 2
    assert (_distance(added, every.lines) < 0.005 * size).all()  # and nothing off the edges


def test_nothing_is_added_where_every_line_is_found(pocket):
    scene, others, every, floor, corners, size = pocket
    assert _complete(scene, every, size).shape == (0, 2, 3)


def test_empty_edge_maps_add_no_line(pocket, monkeypatch):
    scene, others, every, floor, corners, size = pocket
    blank = np.zeros((scene.camera(0).height, scene.camera(0).width), np.float32)
    monkeypatch.setattr(scene, "load_edge_map", lambda index, detector=None: blank)
    assert _complete(scene, others, size).shape == (0, 2, 3)


def test_a_line_in_the_pockets_opening_is_seen_and_left_undrawn(pocket):
    """Halfway across the pocket's opening, level with the rim: the views from above see it clear
    of the hull and draw nothing there. The floor under it is inside the hull: no view surely
    sees it, so nothing speaks against it."""
    scene, others, every, floor, corners, size = pocket
    config = ExtractConfig(contour_hull_cells=64)
    surface = HullSurface(scene, config.contour_hull_cells)
    evidence = gather_evidence(others, surface, "exact", size, config)
    rim = max(floor, key=lambda line: line[0][1])
    opposite = min(floor, key=lambda line: line[0][1])
    lift = np.array([0.0, 0.0, max(c[2] for line in every.lines for c in line) - rim[0][2]])
    opening = (rim + opposite) / 2 + lift
    assert seen_undrawn(opening, evidence, surface)
    assert not seen_undrawn(rim, evidence, surface)


def test_curves_a_completion_added_explain_their_pixels(pocket):
    scene, others, every, floor, corners, size = pocket
    config = ExtractConfig(contour_hull_cells=64)
    evidence = gather_evidence(others, HullSurface(scene, config.contour_hull_cells), "exact", size, config)
    points = np.linspace(floor[0][0], floor[0][1], 200)
    found = evidence.explained_by(points, config.completion_explained)
    assert len(found.existing) == len(evidence.existing) + len(points)
    before = after = 0
    for view, now in zip(evidence.views, found.views):
        pixels, inside = view.camera.pixels(points)
        before += view.unexplained[pixels[inside, 1], pixels[inside, 0]].sum()
        after += now.unexplained[pixels[inside, 1], pixels[inside, 0]].sum()
        assert not (now.unexplained & ~view.unexplained).any()  # nothing becomes unexplained
    assert before > 0 and after == 0


def test_a_line_is_drawn_on_its_maps_ridge_and_not_beside_it():
    camera = orbit_cameras(8, 400)[2]
    line = np.array([[0.35, 0.45, 0.5], [0.65, 0.55, 0.5]])
    edge_map = np.zeros((camera.height, camera.width), np.float32)
    uv = np.rint(camera.project(line)[0]).astype(np.int32)
    cv2.line(edge_map, tuple(uv[0]), tuple(uv[1]), 1.0, 5)
    edge_map = cv2.GaussianBlur(edge_map, (0, 0), 1.0)
    view = ViewEvidence(camera, edge_map, edge_map > 0.3, edge_map > 0.3, np.ones_like(edge_map, bool),
                        np.empty((0, 4)))
    along = uv[1] - uv[0]
    across = np.array([-along[1], along[0]]) / np.linalg.norm(along)
    beside = line + 0.0  # moved 5 px across in the image, at the line's depth
    for k in range(2):
        depth = (camera.R @ line[k] + camera.t)[2]
        beside[k] = line[k] + 5 * depth / camera.K[0, 0] * (camera.R.T @ np.r_[across, 0.0])
    assert ridge_drawn([view], line)[0]
    assert not ridge_drawn([view], beside)[0]
