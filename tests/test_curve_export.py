"""Writing curves (EMAP JSON, OBJ, PLY) and reading them back; `edgedog export`."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from plyfile import PlyData
from scipy.spatial import cKDTree

from edgedog.bezier import bezier_points
from edgedog.curve_files import EdgeCurves, curve_polylines, read_edges, write_edges, write_json
from edgedog.errors import InputError
from edgedog.metrics import evaluate
from tests.helpers.cli_runner import edgedog

LINES = np.array([[[0.1, 0.2, 0.3], [0.5, 0.2, 0.3]], [[0.5, 0.2, 0.3], [0.5, 0.6, 0.1]]])
BEZIERS = np.array([[[0.0, 0.0, 0.0], [0.1, 0.3, 0.0], [0.3, 0.3, 0.1], [0.4, 0.0, 0.1]],
                    [[0.4, 0.0, 0.1], [0.45, -0.1, 0.1], [0.6, -0.1, 0.2], [0.7, 0.1, 0.3]]])
CURVES = EdgeCurves(lines=LINES, beziers=BEZIERS)


def distance_to_curves(points: np.ndarray, curves: EdgeCurves) -> np.ndarray:
    """Distance (N,) from each point (N, 3) to a dense sampling of the curves."""
    dense = np.concatenate([np.linspace(a, b, 2000) for a, b in curves.lines]
                           + [bezier_points(c, np.linspace(0, 1, 20000)) for c in curves.beziers])
    return cKDTree(dense).query(points)[0]


def test_json_round_trip_is_exact(tmp_path):
    write_edges(tmp_path / "curves.json", CURVES)
    data = json.loads((tmp_path / "curves.json").read_text())
    assert len(data["lines_end_pts"][0]) == 6 and np.shape(data["curves_ctl_pts"][0]) == (4, 3)
    back = read_edges(tmp_path / "curves.json")
    np.testing.assert_array_equal(back.lines, LINES)
    np.testing.assert_array_equal(back.beziers, BEZIERS)


def test_json_scores_exactly_like_the_curves(tmp_path):
    gt = np.concatenate([curve_polylines(CURVES)[0], bezier_points(BEZIERS[0], np.linspace(0, 1, 300))])
    write_edges(tmp_path / "curves.json", CURVES)
    ours = evaluate(CURVES.sample(), gt)
    assert evaluate(read_edges(tmp_path / "curves.json").sample(), gt) == ours


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_obj_and_ply_round_trip_within_tolerance(tmp_path, suffix):
    path = write_edges(tmp_path / f"curves{suffix}", CURVES)
    back = read_edges(path)
    assert len(back.polylines) == CURVES.num_curves
    for polyline, line in zip(back.polylines[:2], LINES):
        np.testing.assert_allclose(polyline, line, atol=1e-12)
    for polyline, ctrl in zip(back.polylines[2:], BEZIERS):
        np.testing.assert_allclose(polyline[[0, -1]], ctrl[[0, -1]], atol=1e-12)
    # Samples of the written chains lie on the Béziers, and the chains are as long.
    assert distance_to_curves(back.sample(0.001), CURVES).max() < 2e-4
    samples, original = back.sample(), CURVES.sample()
    assert abs(len(samples) - len(original)) <= CURVES.num_curves


def test_ply_has_vertex_and_edge_elements(tmp_path):
    write_edges(tmp_path / "curves.ply", CURVES)
    ply = PlyData.read(str(tmp_path / "curves.ply"))
    chains = curve_polylines(CURVES)
    assert ply["vertex"].count == sum(len(c) for c in chains)
    assert ply["edge"].count == sum(len(c) - 1 for c in chains)
    assert {"vertex1", "vertex2"} == set(ply["edge"].data.dtype.names)


def test_obj_has_one_object_per_curve(tmp_path):
    write_edges(tmp_path / "curves.obj", CURVES)
    records = [line.split() for line in (tmp_path / "curves.obj").read_text().splitlines()]
    objects = [r for r in records if r[0] == "o"]
    polylines = [r for r in records if r[0] == "l"]
    vertices = [r for r in records if r[0] == "v"]
    assert len(objects) == len(polylines) == CURVES.num_curves
    assert [len(r) - 1 for r in polylines] == [len(c) for c in curve_polylines(CURVES)]
    assert max(int(i) for r in polylines for i in r[1:]) == len(vertices)


def test_trimesh_reads_the_ply_as_paths_and_the_obj_vertices(tmp_path):
    """What CloudCompare or Blender users see, read by trimesh: the PLY as one path per
    curve; the OBJ's vertices (trimesh's OBJ reader takes no `l` elements; Blender and
    MeshLab do, and test_obj_has_one_object_per_curve checks them)."""
    import trimesh

    chains = curve_polylines(CURVES)
    write_edges(tmp_path / "curves.ply", CURVES)
    write_edges(tmp_path / "curves.obj", CURVES)
    paths = trimesh.load(str(tmp_path / "curves.ply"))
    assert isinstance(paths, trimesh.path.Path3D) and len(paths.entities) == len(chains)
    for entity, chain in zip(paths.entities, chains):
        np.testing.assert_allclose(paths.vertices[entity.points], chain, atol=1e-6)
    cloud = trimesh.load(str(tmp_path / "curves.obj"))
    np.testing.assert_allclose(cloud.vertices, np.concatenate(chains), atol=1e-9)


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_point_clouds_round_trip(tmp_path, suffix):
    points = np.random.default_rng(0).uniform(size=(30, 3))
    back = read_edges(write_edges(tmp_path / f"points{suffix}", EdgeCurves(points=points)))
    assert back.num_curves == 0
    np.testing.assert_allclose(back.points, points, atol=1e-12)


def test_writers_refuse_what_the_format_cannot_hold(tmp_path):
    with pytest.raises(ValueError, match="only lines and cubic"):
        write_json(tmp_path / "x.json", EdgeCurves(polylines=[LINES[0]]))
    with pytest.raises(ValueError, match="not both"):
        write_edges(tmp_path / "x.obj", EdgeCurves(lines=LINES, points=LINES[0]))
    with pytest.raises(InputError, match="unsupported"):
        write_edges(tmp_path / "x.stl", CURVES)


# --- edgedog export -------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["obj", "ply", "json"])
def test_export_formats(tmp_path, fmt):
    write_edges(tmp_path / "curves.json", CURVES)
    result = edgedog("export", tmp_path, "--format", fmt)
    assert result.returncode == 0, result.stderr
    back = read_edges(tmp_path / f"curves_world.{fmt}")
    assert back.num_curves == CURVES.num_curves
    assert distance_to_curves(back.sample(), CURVES).max() < 2e-4


def write_emap_scene(root, world_to_gt):
    """A small EMAP scene: one 8x8 view, and a world-to-ground-truth transform."""
    (root / "color").mkdir(parents=True)
    cv2.imwrite(str(root / "color" / "0_colors.png"), np.zeros((8, 8, 3), np.uint8))
    frame = {"rgb_path": "0_colors.png", "camtoworld": np.eye(4).tolist(),
             "intrinsics": [[4.0, 0, 3.5], [0, 4.0, 3.5], [0, 0, 1]]}
    meta = {"height": 8, "width": 8, "worldtogt": world_to_gt.tolist(), "frames": [frame]}
    (root / "meta_data.json").write_text(json.dumps(meta))


def test_export_in_the_ground_truth_frame(tmp_path):
    world_to_gt = np.array([[0, -0.5, 0, 0.5], [0.5, 0, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1]])
    write_emap_scene(tmp_path / "scene", world_to_gt)
    run = tmp_path / "run"
    write_edges(run / "curves.json", CURVES)
    (run / "log.json").write_text(json.dumps({"scene": str(tmp_path / "scene"), "detector": "x"}))
    for fmt in ("json", "obj"):
        result = edgedog("export", run, "--format", fmt, "--frame", "gt", "--out", tmp_path / f"gt.{fmt}")
        assert result.returncode == 0, result.stderr
    expected = CURVES.transformed(world_to_gt)
    back = read_edges(tmp_path / "gt.json")
    np.testing.assert_allclose(back.lines, expected.lines, atol=1e-12)
    np.testing.assert_allclose(back.beziers, expected.beziers, atol=1e-12)
    assert distance_to_curves(read_edges(tmp_path / "gt.obj").sample(), expected).max() < 2e-4


def test_export_errors_are_one_line(tmp_path):
    result = edgedog("export", tmp_path, "--format", "obj")
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "no curves yet" in result.stderr
    write_edges(tmp_path / "curves.json", CURVES)
    result = edgedog("export", tmp_path, "--format", "obj", "--out", tmp_path / "x.ply")
    assert result.returncode == 2 and "must end in .obj" in result.stderr
