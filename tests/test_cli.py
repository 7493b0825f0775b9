"""The command line, run as a user runs it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from edgedog.builtin.scene import CORNERS, EDGES
from tests.helpers.cli_runner import edgedog


def test_info_describes_the_scene(builtin_scene_dir):
    result = edgedog("info", builtin_scene_dir, "--downscale", "2")
    assert result.returncode == 0, result.stderr
    assert "format        nerf" in result.stdout
    assert "50 at 200x200 (downscaled 2x)" in result.stdout
    assert "edge maps     exact" in result.stdout
    assert "from the images' alpha" in result.stdout
    assert "ground truth  10" in result.stdout  # 10xx edge points


def test_info_on_a_bad_folder_is_one_line_naming_it(tmp_path):
    result = edgedog("info", tmp_path)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1
    assert result.stderr.startswith(f"edgedog: error: {tmp_path}: not a scene folder")


def write_obj(path, polylines):
    lines, offset = [], 1
    for k, polyline in enumerate(polylines):
        lines.append(f"o curve_{k}")
        lines += [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in polyline]
        lines.append("l " + " ".join(str(offset + i) for i in range(len(polyline))))
        offset += len(polyline)
    path.write_text("\n".join(lines) + "\n")


def test_eval_of_the_true_edges_scores_perfectly(builtin_scene_dir, tmp_path):
    pred = tmp_path / "edges.obj"
    write_obj(pred, [CORNERS[[a, b]] for a, b in EDGES])
    result = edgedog("eval", pred, "--scene", builtin_scene_dir)
    assert result.returncode == 0, result.stderr
    metrics = json.loads((tmp_path / "edges.obj.eval.json").read_text())["metrics"]
    # Voxel means of samples on a straight edge stay on it: every threshold is met.
    for tau in (5, 10, 20):
        assert metrics[f"fscore_{tau}mm"] == 100.0
    assert metrics["acc_mm"] < 2.5 and metrics["comp_mm"] < 3.0
    assert "  5mm   100.00   100.00   100.00" in result.stdout


def test_eval_of_shifted_edges_with_explicit_gt_and_json_path(builtin_scene_dir, tmp_path):
    pred = tmp_path / "parametric_edges.json"
    shift = np.array([0.0, 0.0, 0.015])  # 15 mm up
    lines = [np.concatenate([CORNERS[a] + shift, CORNERS[b] + shift]).tolist() for a, b in EDGES]
    pred.write_text(json.dumps({"curves_ctl_pts": [], "lines_end_pts": lines}))
    gt = builtin_scene_dir / "gt" / "box_0.005.ply"
    out = tmp_path / "metrics.json"
    result = edgedog("eval", pred, "--gt", gt, "--json", out, "--no-voxel")
    assert result.returncode == 0, result.stderr
    metrics = json.loads(out.read_text())["metrics"]
    # Horizontal edges move 15 mm away; the four vertical ones slide along themselves.
    assert metrics["fscore_20mm"] == 100.0
    assert 0 < metrics["precision_10mm"] < 50
    assert 5 < metrics["acc_mm"] <= 15.0 + 1e-9


def test_eval_of_a_prediction_inside_a_scene_asks_for_json_elsewhere(builtin_scene_dir, tmp_path):
    """Its default metrics file would land in the scene folder, where nothing is ever written."""
    scene = tmp_path / "scene"
    scene.mkdir()
    (scene / "transforms_train.json").write_bytes((builtin_scene_dir / "transforms_train.json").read_bytes())
    pred = scene / "edges.obj"
    write_obj(pred, [CORNERS[[a, b]] for a, b in EDGES])
    before = sorted(scene.iterdir())
    result = edgedog("eval", pred, "--gt", builtin_scene_dir / "gt" / "box_0.005.ply")
    assert result.returncode != 0 and result.stderr.count("\n") == 1, result.stderr
    assert "edges.obj.eval.json: would lie inside a scene folder" in result.stderr
    assert "pass --json FILE outside it" in result.stderr
    assert sorted(scene.iterdir()) == before
    elsewhere = tmp_path / "metrics.json"
    assert edgedog("eval", pred, "--gt", builtin_scene_dir / "gt" / "box_0.005.ply", "--json",
                   elsewhere).returncode == 0 and elsewhere.is_file()


def test_eval_rejects_a_truncated_prediction(builtin_scene_dir, tmp_path):
    pred = tmp_path / "parametric_edges.json"
    pred.write_text('{"lines_end_pts": [[0, 0, 0, 1, 1')
    result = edgedog("eval", pred, "--scene", builtin_scene_dir)
    assert result.returncode == 2
    assert result.stderr.startswith(f"edgedog: error: {pred}: invalid JSON")
    assert result.stderr.count("\n") == 1


@pytest.mark.parametrize("args", [["--help"], ["info", "--help"], ["edges", "--help"], ["init", "--help"],
                                  ["sfm", "--help"], ["train", "--help"], ["eval", "--help"],
                                  ["bench", "raster", "--help"], ["bench", "ablation", "--help"],
                                  ["extract", "--help"], ["export", "--help"], ["make-scene", "--help"],
                                  ["demo", "--help"]])
def test_help(args):
    result = edgedog(*args)
    assert result.returncode == 0 and "usage: edgedog" in result.stdout


@pytest.mark.slow
def test_demo_trains_extracts_and_scores_the_builtin_part(tmp_path):
    from edgedog.train.config import preset
    from edgedog.train.run_folder import config_digest

    # A demo run left by an older version (named after the scene alone, other defaults) is not
    # in the way.
    older = tmp_path / "runs" / "demo-boss-canny"
    older.mkdir(parents=True)
    (older / "config.json").write_text(json.dumps({"scene": "elsewhere", "config": {"seed": 7}}))
    result = edgedog("demo", "--cache", tmp_path, "--quiet")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "scenes" / "boss-canny" / "transforms_train.json").is_file()
    run = tmp_path / "runs" / f"demo-boss-canny-{config_digest(preset('preview'))}"
    for name in ("curves.obj", "curves.ply", "curves.json", "primitives.ply", "log.json"):
        assert (run / name).is_file(), name
    report = json.loads((run / "extract.json").read_text())
    curves = report["metrics"]["curves"]
    assert "curves " in result.stdout and "F10" in result.stdout
    # `make demo` scores F10 about 90 on this part (89.9 with the view-dependent opacity); a guard.
    assert curves["fscore_10mm"] >= 85, curves
    assert 5 <= report["counts"]["lines"] + report["counts"]["beziers"] <= 80
    again = edgedog("demo", "--cache", tmp_path, "--quiet")
    assert again.returncode == 0 and "reusing the finished demo run" in again.stdout
    # A folder holding a run of another scene is refused, not resumed as if it were the demo.
    other = tmp_path / "other-run"
    other.mkdir()
    saved = json.loads((run / "config.json").read_text())
    (other / "config.json").write_text(json.dumps({**saved, "scene": str(tmp_path / "another-scene")}))
    refused = edgedog("demo", "--cache", tmp_path, "--out", other, "--quiet")
    assert refused.returncode != 0 and "holds a run of another scene" in refused.stderr
    assert not (other / "checkpoint.pt").exists()


def test_edges_computes_then_reuses_maps(builtin_scene_dir, tmp_path):
    import shutil

    scene = tmp_path / "box"
    shutil.copytree(builtin_scene_dir, scene)
    first = edgedog("edges", scene, "--detector", "canny", "--downscale", "2")
    assert first.returncode == 0, first.stderr
    assert "50 computed now" in first.stdout and "s per megapixel" in first.stdout
    second = edgedog("edges", scene, "--detector", "canny", "--downscale", "2")
    assert "0 computed now" in second.stdout
    provided = edgedog("edges", scene, "--detector", "exact")
    assert "using the scene's own 'exact' maps" in provided.stdout


def test_edges_rejects_an_unknown_detector(builtin_scene_dir):
    result = edgedog("edges", builtin_scene_dir, "--detector", "foo")
    assert result.returncode == 2
    assert result.stderr.startswith("edgedog: error: unknown detector 'foo'")
    assert result.stderr.count("\n") == 1


def test_init_reports_the_method_and_writes_points(builtin_scene_dir, tmp_path):
    from plyfile import PlyData

    out = tmp_path / "init.ply"
    result = edgedog("init", builtin_scene_dir, "--method", "uniform", "--uniform-count", "1234",
                     "--out", out)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout[: result.stdout.rindex("}") + 1])
    assert report["method"] == "uniform" and report["points"] == 1234 and report["reason"] == "requested"
    vertex = PlyData.read(str(out))["vertex"]
    assert len(vertex) == 1234 and (vertex["scale"] > 0).all()


@pytest.mark.slow
def test_train_writes_a_run_and_refuses_to_overwrite_it(builtin_scene_dir, tmp_path):
    run = tmp_path / "run"
    settings = ["--set", "epochs=2", "--set", "downscale=4", "--set", "init_count=200", "--quiet"]
    result = edgedog("train", builtin_scene_dir, "--out", run, "--preset", "preview", *settings)
    assert result.returncode == 0, result.stderr
    assert "trained" in result.stdout
    log = json.loads((run / "log.json").read_text())
    assert log["initial_primitives"] == 200 and len(log["history"]) == 2
    again = edgedog("train", builtin_scene_dir, "--out", run, *settings)
    assert again.returncode == 2 and "pass --resume" in again.stderr
    resumed = edgedog("train", builtin_scene_dir, "--out", run, "--resume", "--quiet")
    assert resumed.returncode == 0 and '"resumed_at_step": ' in resumed.stdout
    bad = edgedog("train", builtin_scene_dir, "--out", tmp_path / "other", "--set", "nonsense=1")
    assert bad.returncode == 2 and bad.stderr.startswith("edgedog: error: --set 'nonsense=1'")


def test_written_files_get_the_usual_permissions(tmp_path):
    import os

    from edgedog.files import atomic_write_json

    path = atomic_write_json(tmp_path / "x.json", {"a": 1})
    mask = os.umask(0)
    os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask
