"""Tests of reading predicted edges (EMAP JSON, PLY, OBJ) into EdgeCurves."""

import json

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from edgedog.curve_files import EdgeCurves, read_edges
from edgedog.errors import InputError
from edgedog.metrics import sample_cubic_bezier, sample_line, sample_polyline

BEZIER = np.array([[0.0, 0.0, 0.0], [0.1, 0.2, 0.0], [0.3, 0.2, 0.1], [0.4, 0.0, 0.1]])
LINE = np.array([[-0.2, 0.1, 0.0], [0.3, 0.1, -0.05]])


def _write_ply(path, xyz, edges=None):
    vertex = np.array([tuple(p) for p in xyz], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    elements = [PlyElement.describe(vertex, "vertex")]
    if edges is not None:
        edge = np.array([tuple(e) for e in edges], dtype=[("vertex1", "i4"), ("vertex2", "i4")])
        elements.append(PlyElement.describe(edge, "edge"))
    PlyData(elements, text=False).write(str(path))


def _same_order_or_reversed(got, expected):
    return got.shape == expected.shape and (
        np.allclose(got, expected, atol=1e-12) or np.allclose(got[::-1], expected, atol=1e-12)
    )


# --- JSON ------------------------------------------------------------------------------------


@pytest.mark.parametrize("nested", [True, False])
def test_json_round_trip(tmp_path, nested):
    data = {
        "curves_ctl_pts": [BEZIER.tolist() if nested else BEZIER.ravel().tolist()],
        "lines_end_pts": [LINE.tolist() if nested else LINE.ravel().tolist()],
    }
    path = tmp_path / "parametric_edges.json"
    path.write_text(json.dumps(data))
    curves = read_edges(path)
    np.testing.assert_array_equal(curves.beziers, BEZIER[None])
    np.testing.assert_array_equal(curves.lines, LINE[None])
    assert curves.polylines == [] and curves.points.shape == (0, 3)
    assert curves.num_curves == 2 and not curves.is_empty
    expected = np.concatenate([sample_line(*LINE), sample_cubic_bezier(BEZIER)])
    np.testing.assert_array_equal(curves.sample(), expected)


def test_json_one_key_missing_or_empty(tmp_path):
    path = tmp_path / "lines_only.json"
    path.write_text(json.dumps({"lines_end_pts": [LINE.ravel().tolist()], "curves_ctl_pts": []}))
    curves = read_edges(path)
    assert curves.lines.shape == (1, 2, 3) and curves.beziers.shape == (0, 4, 3)
    path.write_text(json.dumps({"curves_ctl_pts": [BEZIER.tolist()]}))
    curves = read_edges(path)
    assert curves.lines.shape == (0, 2, 3) and curves.beziers.shape == (1, 4, 3)


# --- PLY -------------------------------------------------------------------------------------


def _open_and_square():
    t = np.linspace(0.0, 1.0, 51)
    open_xyz = np.stack([0.2 * t - 0.1, 0.02 * np.sin(3 * t), np.zeros_like(t)], axis=1)
    square = np.array([[0, 0, 0.2], [0.3, 0, 0.2], [0.3, 0.3, 0.2], [0, 0.3, 0.2]])
    xyz = np.concatenate([open_xyz, square])
    edges = [(i, i + 1) for i in range(50)]  # 50 segments, each shorter than 5 mm
    edges += [(51 + i, 51 + (i + 1) % 4) for i in range(4)]
    return xyz, edges, open_xyz, square


def test_ply_edges_become_polylines(tmp_path):
    xyz, edges, open_xyz, square = _open_and_square()
    path = tmp_path / "edges.ply"
    _write_ply(path, xyz, edges)
    curves = read_edges(path)
    assert curves.num_curves == 2 and curves.lines.shape == (0, 2, 3)
    open_poly, closed = sorted(curves.polylines, key=len, reverse=True)
    assert _same_order_or_reversed(open_poly, open_xyz)
    assert len(closed) == 5
    np.testing.assert_array_equal(closed[0], closed[-1])
    # Same cycle as the square, in either direction, from whichever corner.
    start = int(np.flatnonzero(np.all(square == closed[0], axis=1))[0])
    cycle = np.roll(square, -start, axis=0)
    assert np.allclose(closed[:4], cycle) or np.allclose(closed[1:][::-1], cycle)
    # Each segment alone would get no sample at all; the chain gets its full arc length.
    assert sum(len(sample_line(a, b)) for a, b in zip(open_xyz[:-1], open_xyz[1:])) == 0
    samples = curves.sample()
    n_open = len(sample_polyline(open_xyz))
    assert n_open > 35
    assert len(samples) == n_open + len(sample_polyline(np.vstack([square, square[:1]])))


def test_ply_edges_shuffled_and_flipped(tmp_path):
    xyz, edges, open_xyz, _ = _open_and_square()
    rng = np.random.default_rng(0)
    edges = [e[::-1] if rng.random() < 0.5 else e for e in edges]
    edges = [edges[i] for i in rng.permutation(len(edges))]
    path = tmp_path / "shuffled.ply"
    _write_ply(path, xyz, edges)
    polys = sorted(read_edges(path).polylines, key=len, reverse=True)
    assert [len(p) for p in polys] == [51, 5]
    assert _same_order_or_reversed(polys[0], open_xyz)


def test_ply_junction_splits_chains(tmp_path):
    # A "T": three arms meeting at vertex 0.
    xyz = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [-0.1, 0, 0], [0, 0.1, 0], [0, 0.2, 0]])
    _write_ply(tmp_path / "t.ply", xyz, [(0, 1), (1, 2), (0, 3), (0, 4), (4, 5)])
    polys = read_edges(tmp_path / "t.ply").polylines
    assert sorted(len(p) for p in polys) == [2, 3, 3]
    assert all(np.array_equal(p[0], xyz[0]) or np.array_equal(p[-1], xyz[0]) for p in polys)


def test_ply_points_only(tmp_path):
    rng = np.random.default_rng(1)
    xyz = rng.uniform(-1, 1, size=(20, 3))
    path = tmp_path / "cloud.ply"
    _write_ply(path, xyz)
    curves = read_edges(path)
    np.testing.assert_allclose(curves.points, xyz)
    assert curves.num_curves == 0 and not curves.is_empty
    np.testing.assert_allclose(curves.sample(), xyz)


# --- OBJ -------------------------------------------------------------------------------------


def test_obj_polylines(tmp_path):
    path = tmp_path / "edges.obj"
    path.write_text(
        "# exported edges\n"
        "o part\n"
        "g edges\n"
        "v 0 0 0\n"
        "v 0.1 0 0\n"
        "v 0.2 0.05 0\n"
        "vn 0 0 1\n"
        "vt 0.5 0.5\n"
        "l 1 2/1 3\n"
        "v 1 1 1\n"
        "v 1 1 1.5\n"
        "l -2 -1\n"
        "l 4\n"
        "s off\n"
    )
    curves = read_edges(path)
    assert len(curves.polylines) == 2 and curves.points.shape == (0, 3)
    np.testing.assert_array_equal(curves.polylines[0], [[0, 0, 0], [0.1, 0, 0], [0.2, 0.05, 0]])
    np.testing.assert_array_equal(curves.polylines[1], [[1, 1, 1], [1, 1, 1.5]])


def test_obj_vertices_only_are_points(tmp_path):
    path = tmp_path / "cloud.obj"
    path.write_text("v 0 0 0\nv 1 2 3\n")
    np.testing.assert_array_equal(read_edges(path).points, [[0, 0, 0], [1, 2, 3]])


# --- EdgeCurves ------------------------------------------------------------------------------


def test_transformed_and_defaults():
    empty = EdgeCurves()
    assert empty.is_empty and empty.num_curves == 0 and empty.sample().shape == (0, 3)
    c = EdgeCurves(
        lines=LINE[None], beziers=BEZIER[None], polylines=[LINE], points=np.ones((2, 3))
    )
    T = np.eye(4)
    T[:3, :3] = 2.0 * np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    T[:3, 3] = [0.1, 0.2, 0.3]
    moved = c.transformed(T)

    def f(x):
        return x @ T[:3, :3].T + T[:3, 3]

    np.testing.assert_allclose(moved.lines, f(c.lines))
    np.testing.assert_allclose(moved.beziers, f(c.beziers))
    np.testing.assert_allclose(moved.polylines[0], f(LINE))
    np.testing.assert_allclose(moved.points, f(c.points))
    np.testing.assert_array_equal(c.lines, LINE[None])  # the original is untouched


# --- malformed inputs ------------------------------------------------------------------------


def _assert_input_error(path, match):
    with pytest.raises(InputError, match=match) as info:
        read_edges(path)
    message = str(info.value)
    assert message.startswith(str(path))
    assert "\n" not in message


@pytest.mark.parametrize(
    "name, content, match",
    [
        ("truncated.json", '{"curves_ctl_pts": [[0, 0, 0, 1, 1', "invalid JSON"),
        ("short.json", json.dumps({"curves_ctl_pts": [list(range(11))]}), r"curves_ctl_pts\[0\]"),
        ("bad_line.json", json.dumps({"lines_end_pts": [[[0, 0], [1, 1]]]}), r"lines_end_pts\[0\]"),
        ("nan.json", '{"lines_end_pts": [[0, 0, 0, NaN, 1, 1]]}', "NaN"),
        ("nokeys.json", json.dumps({"edges": []}), "curves_ctl_pts"),
        ("list.json", "[1, 2, 3]", "curves_ctl_pts"),
        ("bad_index.obj", "v 0 0 0\nv 1 1 1\nl 1 3\n", "line 3.*out of range"),
        ("bad_neg.obj", "v 0 0 0\nl -1 -2\n", "out of range"),
        ("bad_vertex.obj", "v 0 0\n", "line 1"),
        ("garbage.ply", "this is not a ply file\n", "PLY"),
        ("edges.txt", "0 0 0 1 1 1\n", "unsupported"),
    ],
)
def test_malformed_inputs(tmp_path, name, content, match):
    path = tmp_path / name
    path.write_text(content)
    _assert_input_error(path, match)


def test_missing_file(tmp_path):
    _assert_input_error(tmp_path / "nope.json", "no such file")


def test_ply_edge_index_out_of_range(tmp_path):
    path = tmp_path / "bad_edges.ply"
    _write_ply(path, np.zeros((3, 3)), [(0, 1), (1, 7)])
    _assert_input_error(path, "out of range")


def test_kept_drops_by_the_order_lines_beziers_polylines():
    curves = EdgeCurves(lines=np.zeros((2, 2, 3)), beziers=np.ones((2, 4, 3)),
                        polylines=[np.full((3, 3), 2.0), np.full((4, 3), 3.0)], points=np.zeros((5, 3)))
    kept = curves.kept(~(np.array([0.1, np.nan, 0.9, 0.2, 0.3, 0.8]) < 0.4))  # NaN: kept
    assert len(kept.lines) == 1 and len(kept.beziers) == 1 and [len(p) for p in kept.polylines] == [4]
    assert len(kept.points) == 5  # free points are no curves: kept
