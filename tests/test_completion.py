"""Line completion (extract.complete_lines): two views' segments triangulate their 3D line, a line
found a centimetre off is refined onto the views' ridges, and on the L-bracket's scene the edge
taken out of the curves comes back, nothing else does, and nothing is added where every edge is
already there, the curves are empty or the maps draw nothing; two views that are one give no
line."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.builtin.writer import write_scene
from edgedog.curve_files import EdgeCurves
from edgedog.curves import contours
from edgedog.curves.completion import (
    ViewEvidence,
    complete_lines,
    gather_evidence,
    pair_candidates,
    refine,
    samples_along,
)
from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import HullSurface, scene_hull
from edgedog.curves.extract import extract_primitives, scene_size
from edgedog.primitives import EdgePrimitives
from edgedog.scenes import load_scene
from edgedog.synthetic.cameras import TARGET, orbit_cameras
from edgedog.synthetic.features import sample_curve
from edgedog.synthetic.shapes import make_part

SIZE = 400
SEGMENT = np.array([[TARGET[0] - 0.2, TARGET[1] + 0.05, TARGET[2] - 0.1],
                    [TARGET[0] + 0.2, TARGET[1] - 0.05, TARGET[2] + 0.1]])


def _evidence(camera, segment: np.ndarray) -> ViewEvidence:
    """A view whose map draws `segment`'s projection (a blurred 1 px line) and lists it."""
    uv, _ = camera.project(segment)
    edge_map = np.zeros((camera.height, camera.width), np.float32)
    cv2.line(edge_map, tuple(np.rint(uv[0]).astype(int)), tuple(np.rint(uv[1]).astype(int)), 1.0, 1)
    edge_map = cv2.GaussianBlur(edge_map, (5, 5), 0.8)
    edge_map /= edge_map.max()
    drawn = edge_map >= 0.3
    everywhere = np.ones_like(drawn)
    return ViewEvidence(camera, edge_map, drawn, drawn, everywhere, uv.reshape(1, 4))


def _two_views_apart(cameras, low: float, high: float) -> tuple[int, int]:
    forward = np.stack([c.forward for c in cameras])
    angles = np.degrees(np.arccos(np.clip(forward @ forward.T, -1, 1)))
    i, j = np.argwhere((angles > low) & (angles < high))[0]
    return int(i), int(j)


def test_two_views_segments_triangulate_their_3d_segment():
    cameras = orbit_cameras(24, SIZE)
    i, j = _two_views_apart(cameras, 25, 45)
    found = pair_candidates(_evidence(cameras[i], SEGMENT), _evidence(cameras[j], SEGMENT), 0.01)
    assert found.shape == (1, 2, 3)
    ends = found[0] if np.linalg.norm(found[0, 0] - SEGMENT[0]) < 0.1 else found[0, ::-1]
    assert np.abs(ends - SEGMENT).max() < 0.01  # rounded pixel ends: a few mm


def test_one_view_paired_with_itself_gives_nothing_and_no_nan():
    view = _evidence(orbit_cameras(24, SIZE)[0], SEGMENT)
    with np.errstate(all="raise"):  # parallel planes: no division by zero reaches the result
        assert pair_candidates(view, view, 0.01).shape == (0, 2, 3)


def test_a_line_a_centimetre_off_is_refined_onto_the_views_ridges():
    cameras = orbit_cameras(24, SIZE)
    views = [_evidence(camera, SEGMENT) for camera in cameras]
    seen = np.array([np.linalg.norm(np.cross(c.forward, SEGMENT[1] - SEGMENT[0])) > 0.2 for c in cameras])
    off = SEGMENT + np.array([0.0, 0.0, 0.01]) + np.array([0.004, 0.0, 0.0]) * np.array([[1], [-1]])
    refined = refine(views, off, seen)
    distance = np.linalg.norm(np.cross(samples_along(refined[None])[0] - SEGMENT[0], SEGMENT[1] - SEGMENT[0]),
                              axis=1) / np.linalg.norm(SEGMENT[1] - SEGMENT[0])
    assert distance.max() < 0.002
    assert refine(views, off, np.zeros(len(views), bool)) is off  # no view: left as it was


@pytest.fixture(scope="module")
def bracket(tmp_path_factory):
    """The L-bracket's scene, 24 views at 400 px with exact maps (at 160 px its inner corner draws
    no segment of 20 px clear of the other edges), its curves and its size."""
    part = make_part("l-bracket")
    folder = tmp_path_factory.mktemp("completion") / "bracket"
    scene = load_scene(write_scene(folder, part, views=24, size=400, detector="exact"))
    every = [[c.a, c.b] for c in part.curves]
    size = scene_size(np.concatenate([sample_curve(c) for c in part.curves]))
    return part, scene, every, size


def _complete(scene, curves: EdgeCurves, size: float) -> np.ndarray:
    config = ExtractConfig(completion_views=3, contour_hull_cells=64)
    surface = HullSurface(scene, config.contour_hull_cells)
    evidence = gather_evidence(curves, surface, "exact", size, config)
    if evidence is None:
        return np.empty((0, 2, 3))
    return complete_lines(evidence, surface, "exact", size, config)


@pytest.mark.parametrize("kind", ["concave", "convex"])
def test_the_edge_left_out_of_the_curves_comes_back_and_nothing_else(bracket, kind):
    part, scene, every, size = bracket
    removed = next(i for i, c in enumerate(part.curves) if c.dihedral == kind)
    curves = EdgeCurves(lines=[line for i, line in enumerate(every) if i != removed])
    added = _complete(scene, curves, size)
    assert len(added) >= 1
    truth = sample_curve(part.curves[removed])
    to_truth = np.linalg.norm(samples_along(added)[:, :, None] - truth[None, None], axis=3).min(axis=2)
    assert to_truth.max() < 0.01 * size  # every added line lies on the removed edge
    covered = np.linalg.norm(truth[:, None] - samples_along(added, 40).reshape(1, -1, 3), axis=2).min(axis=1)
    assert np.mean(covered < 0.01 * size) > 0.5


def test_nothing_is_added_where_every_edge_is_found_or_no_curve_is(bracket):
    part, scene, every, size = bracket
    assert len(_complete(scene, EdgeCurves(lines=every), size)) == 0
    assert len(_complete(scene, EdgeCurves(), size)) == 0


def test_empty_edge_maps_add_nothing(bracket, monkeypatch):
    part, scene, every, size = bracket
    blank = np.zeros((scene.camera(0).height, scene.camera(0).width), np.float32)
    monkeypatch.setattr(scene, "load_edge_map", lambda index, detector=None: blank)
    assert _complete(scene, EdgeCurves(lines=every[1:]), size).shape == (0, 2, 3)


def test_one_extraction_carves_the_hull_once(bracket, monkeypatch):
    """The contour filter and the completion's contour test share the extraction's hull, and the
    completion reads the masks the hull was carved from."""
    part, scene, every, size = bracket
    kept = [c for c in part.curves if c.dihedral != "concave"]
    points = np.concatenate([sample_curve(c) for c in kept])
    directions = np.concatenate([np.tile(c.b - c.a, (len(sample_curve(c)), 1)) for c in kept])
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    count = len(points)
    primitives = EdgePrimitives(points, directions, np.full(count, 3.0), np.ones(count), np.ones((count, 2)))
    carved, read, read_coverage = [], [], type(scene)._read_coverage
    monkeypatch.setattr(contours, "scene_hull", lambda *args: carved.append(args) or scene_hull(*args))
    monkeypatch.setattr(type(scene), "_read_coverage",
                        lambda self, index: read.append(index) or read_coverage(self, index))
    config = ExtractConfig(complete_lines=True, completion_views=3, contour_hull_cells=64,
                           filter_projection=False, filter_silhouette=False, filter_outliers="off")
    result = extract_primitives(primitives, config, scene, "exact")
    assert result.counts["completed_lines"] >= 1 and "after_contours" in result.counts
    assert len(carved) == 1
    assert len(read) == len(scene)  # each view's mask read from its file once
