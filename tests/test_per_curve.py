"""`edgedog eval --per-curve`: ground-truth curves with their identity (type, dihedral sign, kind)
and the diagnosis of a prediction built from the ground truth itself with one curve taken out."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import build123d as bd
import numpy as np
import pytest

from edgedog.cli import main
from edgedog.curve_files import EdgeCurves, write_edges
from edgedog.diagnosis import assign_points, ground_truth_curves
from edgedog.groundtruth import abc_curves, ground_truth_for, read_points_ply
from edgedog.primitives import PrimitiveArrays, write_ply, write_point_columns
from edgedog.synthetic.brep import part_from_solid
from edgedog.synthetic.features import sample_curve
from edgedog.synthetic.shapes import make_part

REMOVED = 3
"""The ground-truth curve the prediction leaves out (a convex edge of the L-bracket)."""


def _write_run(folder: Path, scene: Path, drop_primitives: bool) -> Path:
    """A run folder whose curves are the scene's ground-truth curves but REMOVED, with primitives
    every 5 mm along every curve: along REMOVED none (`drop_primitives`), or faint ones (opacity
    0.05) that edge_points.ply leaves out, as the opacity filter would."""
    part = make_part("l-bracket")
    folder.mkdir()
    kept = [sample_curve(c) for i, c in enumerate(part.curves) if i != REMOVED]
    lines = np.array([[c.a, c.b] for i, c in enumerate(part.curves) if i != REMOVED])
    write_edges(folder / "curves.json", EdgeCurves(lines=lines))
    faint = [] if drop_primitives else [sample_curve(part.curves[REMOVED])]
    centres = np.concatenate(kept + faint)
    count = len(centres)
    opacity = np.r_[np.full(sum(map(len, kept)), 0.9), np.full(count - sum(map(len, kept)), 0.05)]
    write_ply(folder / "primitives.ply", PrimitiveArrays(
        means=centres.astype(np.float32), scales=np.tile(np.float32([0.004, 0.001, 0.001]), (count, 1)),
        quats=np.tile(np.float32([1, 0, 0, 0]), (count, 1)), opacity=opacity.astype(np.float32),
        k_raw=np.zeros((count, 2), np.float32)))
    edge = np.concatenate(kept)
    write_point_columns(folder / "edge_points.ply", {"x": edge[:, 0], "y": edge[:, 1], "z": edge[:, 2]})
    (folder / "log.json").write_text(json.dumps({"scene": str(scene), "detector": "exact",
                                                 "config": {"maps": {"downscale": 1}}, "events": []}))
    (folder / "extract.json").write_text(json.dumps({"config": {"min_opacity": 0.2}}))
    return folder


def _per_curve(run: Path, scene: Path, out: Path) -> dict:
    assert main(["eval", str(run), "--scene", str(scene), "--per-curve", "--json", str(out)]) == 0
    return json.loads(out.read_text())["per_curve"]


@pytest.mark.parametrize("drop_primitives, cause", [(True, "no primitive formed"),
                                                    (False, "dropped at extraction")])
def test_the_removed_curve_and_only_it_is_missed_with_its_cause(bracket_scene, tmp_path, drop_primitives,
                                                                 cause):
    run = _write_run(tmp_path / "run", bracket_scene, drop_primitives)
    report = _per_curve(run, bracket_scene, tmp_path / "eval.json")
    missed = [c for c in report["curves"] if c["missed"]]
    assert [c["id"] for c in missed] == [REMOVED]
    assert missed[0]["cause"].startswith(cause), missed[0]["cause"]
    if not drop_primitives:
        assert "by the opacity filter" in missed[0]["cause"]
    assert missed[0]["views_seeing"] >= 2 and missed[0]["drawn"] > 0.1  # seen and drawn: lost later
    found = [c for c in report["curves"] if not c["missed"]]
    assert all(c["recall"]["10"] == 100.0 for c in found)
    assert report["false_curve_count"] == 0


def test_the_l_brackets_inner_corner_is_its_one_concave_curve(bracket_scene, tmp_path):
    part = make_part("l-bracket")
    inner = [i for i, c in enumerate(part.curves) if c.dihedral == "concave"]
    assert len(inner) == 1 and sum(c.dihedral == "convex" for c in part.curves) == len(part.curves) - 1
    # the inner corner runs across the profile at the foot's height
    low = min(c.a[2] for c in part.curves)
    a, b = part.curves[inner[0]].a, part.curves[inner[0]].b
    assert np.isclose(a[2] - low, part.dimensions["foot"], atol=1e-6) and np.isclose(a[0], b[0])
    assert np.isclose(a[2], b[2]) and not np.isclose(a[1], b[1])
    written = json.loads(next((bracket_scene / "gt").glob("*_curves.json")).read_text())["curves"]
    assert [c["dihedral"] for c in written] == [c.dihedral for c in part.curves]
    report = _per_curve(_write_run(tmp_path / "run", bracket_scene, True), bracket_scene, tmp_path / "e.json")
    kinds = {c["id"]: c["kind"] for c in report["curves"]}
    assert kinds[inner[0]] == "concave"
    assert {"outline", "concave"} <= set(kinds.values()) <= {"outline", "convex", "concave"}
    assert report["recall_by_kind"]["concave"]["curves"] == 1


def test_a_pocket_has_concave_edges_at_its_floor_and_walls():
    block = bd.Box(1, 0.8, 0.4, align=(bd.Align.MIN,) * 3)
    on_floor = (bd.Align.CENTER, bd.Align.CENTER, bd.Align.MIN)
    pocket = bd.Pos(0.5, 0.4, 0.25) * bd.Box(0.4, 0.3, 0.2, align=on_floor)
    part = part_from_solid("pocket", block - pocket, {})
    concave = [c for c in part.curves if c.dihedral == "concave"]
    assert len(part.curves) == 24 and len(concave) == 8
    floor = min(c.a[2] for c in concave)
    assert sum(np.isclose(c.a[2], floor) and np.isclose(c.b[2], floor) for c in concave) == 4  # the floor's
    assert sum(not np.isclose(c.a[2], c.b[2]) for c in concave) == 4  # the walls' corners


def test_ground_truth_without_curve_information_is_one_line(bracket_scene, tmp_path, capsys):
    bare = shutil.copytree(bracket_scene, tmp_path / "bare")  # a scene of points only
    for curves in (bare / "gt").glob("*_curves.json"):
        curves.unlink()
    ply = next((bare / "gt").glob("*_0.005.ply"))
    pred = tmp_path / "pred.obj"
    write_edges(pred, EdgeCurves(lines=np.array([[[0.2, 0.2, 0.2], [0.6, 0.2, 0.2]]])))
    out = str(tmp_path / "e.json")
    assert main(["eval", str(pred), "--scene", str(bare), "--per-curve", "--json", out]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and "without curve information" in error and "_curves.json" in error
    assert main(["eval", str(pred), "--gt", str(ply), "--per-curve", "--json", out]) == 2
    assert "--per-curve needs --scene" in capsys.readouterr().err


def test_abc_curves_from_the_mesh_and_from_the_features_file_alone(abc_nef_scene_dir, abc_emap_scene_dir):
    nef = ground_truth_for(abc_nef_scene_dir)
    curves = abc_curves(nef)
    assert len(curves) == 32 and {c.type for c in curves} == {"line", "circle", "bspline"}
    assert {c.dihedral for c in curves} == {"convex"}  # a solid with no inner corner
    points = nef.load()
    assert (assign_points(points, curves) >= 0).all()
    assert ground_truth_curves(nef, abc_nef_scene_dir).mesh is not None
    emap = ground_truth_for(abc_emap_scene_dir)
    curves = abc_curves(emap)  # no mesh: lines and circles from their parameters
    assert len(curves) == 33 and {c.dihedral for c in curves} == {"unknown"}
    points = read_points_ply(emap.sampled_ply)
    owner = assign_points(points, curves)
    assert (owner >= 0).all() and len(np.unique(owner)) == 33
    for curve in curves:  # the two faces along each curve, for signing it from the maps
        tangent = curve.polyline[len(curve.polyline) // 2 + 1] - curve.polyline[len(curve.polyline) // 2 - 1]
        assert curve.wedge.shape == (2, 3) and np.allclose(np.linalg.norm(curve.wedge, axis=1), 1)
        assert np.allclose(curve.wedge @ tangent, 0, atol=1e-6)
