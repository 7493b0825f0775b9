"""`edgedog bench edge-length`: a scene's ground-truth edge length (curves file, points alone),
reading run and batch folders, the primitives-per-length ratio's median and spread, and the
command's files and errors, on tiny made-up scenes and runs (nothing trains)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from edgedog.bench import edge_length as bench
from edgedog.bench.edge_length import (
    RunPoint,
    edge_length,
    markdown,
    parse_variants,
    read_runs,
    record,
    run_folders,
    scene_points,
    summaries,
)
from edgedog.cli import main
from edgedog.errors import ConfigError
from edgedog.files import read_json
from edgedog.groundtruth import GT_SPACING


def write_points(path, count: int) -> None:
    points = np.zeros(count, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    points["x"] = np.linspace(0.0, 1.0, count)
    PlyData([PlyElement.describe(points, "vertex")]).write(str(path))


def make_scene(root, name: str, segments: list[float] | None, points: int = 10, shape: str = ""):
    """A generated scene's ground truth: `points` sampled points and, unless `segments` is None,
    a curves file of straight segments of those lengths along x, one above the other."""
    scene = root / name
    (scene / "gt").mkdir(parents=True)
    write_points(scene / "gt" / f"{name}_{GT_SPACING}.ply", points)
    if segments is not None:
        curves = [{"type": "line", "dihedral": "convex", "a": [0.0, 0.1 * i, 0.0],
                   "b": [length, 0.1 * i, 0.0]} for i, length in enumerate(segments)]
        (scene / "gt" / f"{name}_curves.json").write_text(json.dumps({"frame": "gt", "curves": curves}))
    if shape:
        (scene / "edgedog_scene.json").write_text(json.dumps({"shape": shape}))
    return scene


def make_run(folder, scene, primitives: int, seconds: float):
    folder.mkdir(parents=True)
    (folder / "config.json").write_text("{}")
    (folder / "log.json").write_text(json.dumps({"scene": str(scene), "final_primitives": primitives,
                                                 "train_seconds": seconds}))
    return folder


def point(variant: str, scene: str, length: float, primitives: int, seconds: float = 10.0) -> RunPoint:
    return RunPoint(variant, f"runs/{scene}", f"/scenes/{scene}", scene, "", length, "curves", primitives,
                    seconds)


def test_edge_length_from_the_curves_file_else_from_the_points(tmp_path):
    with_curves = make_scene(tmp_path, "part-a", [0.5, 0.25, 1.0], points=7, shape="block")
    found = edge_length(with_curves)
    assert found.length == pytest.approx(1.75)
    assert (found.source, found.curves) == ("curves", 3)
    points_only = make_scene(tmp_path, "part-b", None, points=40)
    found = edge_length(points_only)
    assert found.length == pytest.approx(40 * GT_SPACING)
    assert (found.source, found.curves) == ("points", None)


def test_a_scene_without_ground_truth_is_an_input_error(tmp_path):
    (tmp_path / "bare").mkdir()
    with pytest.raises(Exception, match="no ground truth"):
        edge_length(tmp_path / "bare")


def test_runs_of_a_batch_folder_and_a_single_run_are_read_unfinished_ones_left_out(tmp_path):
    short = make_scene(tmp_path / "scenes", "short", [1.0], shape="block+pocket")
    long = make_scene(tmp_path / "scenes", "long", [1.0, 2.0])
    batch = tmp_path / "batch"
    make_run(batch / "short_quick_seed0", short, 100, 20.0)
    make_run(batch / "long_quick_seed0", long, 300, 50.0)
    unfinished = make_run(batch / "long_quick_seed1", long, 999, 1.0)
    (batch / "batch.json").write_text("{}")
    (batch / "not-a-run").mkdir()
    single = make_run(tmp_path / "vote-long", long, 450, 70.0)
    assert run_folders(batch) == [batch / "long_quick_seed0", batch / "long_quick_seed1",
                                  batch / "short_quick_seed0"]
    assert run_folders(single) == [single]

    points, notes = read_runs([("default", batch), ("vote", single)], finished=lambda run: run != unfinished)
    assert [(p.variant, p.scene_name, p.length, p.primitives, p.train_seconds) for p in points] == [
        ("default", "long", pytest.approx(3.0), 300, 50.0),
        ("default", "short", pytest.approx(1.0), 100, 20.0),
        ("vote", "long", pytest.approx(3.0), 450, 70.0)]
    assert points[1].design == "block+pocket" and points[0].design == ""
    assert notes == [f"default: {unfinished} is not finished; left out"]


def test_the_ratio_its_median_and_spread_per_variant():
    points = [point("a", "s1", 1.0, 100), point("a", "s2", 2.0, 200), point("a", "s4", 4.0, 600),
              point("a", "s4", 4.0, 400),  # a second run of s4: the scene's mean, 500
              point("b", "s1", 1.0, 1000, 5.0), point("b", "s2", 2.0, 1000, 5.0),
              point("b", "s4", 4.0, 1000, 5.0)]
    scenes = scene_points(points)
    a = [s for s in scenes if s.variant == "a"]
    assert [(s.scene_name, s.runs, s.primitives, s.ratio) for s in a] == [
        ("s1", 1, 100, 100), ("s2", 1, 200, 100), ("s4", 2, 500, 125)]
    assert [s.share for s in a] == pytest.approx([1.0, 1.0, 1.25])
    first, second = summaries(scenes)
    assert (first.variant, first.scenes) == ("a", 3)
    assert (first.ratio_median, first.ratio_min, first.ratio_max) == (100, 100, 125)
    assert (first.share_min, first.share_max, first.within_band) == (1.0, 1.25, 3)
    # One count for all on lengths 1, 2, 4: shares 2, 1, 0.5 of the median: one within the band.
    assert first.constant_within_band == 1
    assert first.primitives_r > 0.95 and first.primitives_slope > 0
    # A constant count: ratios 1000, 500, 250, median 500; only s2 within +-30 %; no correlation.
    assert (second.ratio_median, second.share_min, second.share_max) == (500, 0.5, 2.0)
    assert second.within_band == 1 and second.median_primitives == 1000
    assert second.primitives_slope == pytest.approx(0.0, abs=1e-9) and second.primitives_r is None
    assert second.seconds_r is None


def test_one_length_has_no_line_and_the_band_edge_counts_as_within():
    scenes = scene_points([point("a", "s1", 2.0, 100), point("a", "s2", 2.0, 130), point("a", "s3", 2.0, 70)])
    summary, = summaries(scenes)
    assert summary.within_band == 3  # shares 1.0, 1.3 and 0.7: on the band's edges
    assert (summary.primitives_slope, summary.primitives_r, summary.seconds_slope) == (None, None, None)


def test_record_and_markdown():
    result = record([point("default", "s1", 1.0, 100), point("default", "s2", 2.0, 220)], ["a note"])
    assert [v["variant"] for v in result["variants"]] == ["default"]
    assert json.loads(json.dumps(result)) == result  # plain JSON
    text = markdown(result)
    assert "| s2 | default | 2.00 | 1 | 220 | 10 | 110 | 105 % |" in text
    assert "| default | 2 | 105 | 100 - 110 | 95 - 105 % | 2 of 2 | 1 of 2 |" in text
    assert "note: a note" in text


def test_variants_are_name_equals_folder():
    assert parse_variants(["default=runs/a", " vote = runs/b "]) == [("default", bench.Path("runs/a")),
                                                                      ("vote", bench.Path("runs/b"))]
    for bad in ("runs/a", "=runs/a", "default="):
        with pytest.raises(ConfigError, match="NAME=FOLDER"):
            parse_variants([bad])


def test_the_command_writes_the_record_table_and_figure(tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")
    import edgedog.train.lifecycle as lifecycle

    monkeypatch.setattr(lifecycle, "is_finished", lambda run: True)
    short = make_scene(tmp_path / "scenes", "short", [1.0], shape="block")
    long = make_scene(tmp_path / "scenes", "00000099", [1.0, 2.0])
    make_run(tmp_path / "batch" / "short_quick_seed0", short, 100, 20.0)
    make_run(tmp_path / "batch" / "long_quick_seed0", long, 280, 50.0)
    make_run(tmp_path / "vote", long, 450, 70.0)
    out, figure = tmp_path / "out", tmp_path / "docs" / "edge_length.png"
    figure.parent.mkdir()
    args = ["bench", "edge-length", "--runs", f"default={tmp_path / 'batch'}",
            "--runs", f"vote={tmp_path / 'vote'}", "--out", str(out), "--figure", str(figure)]
    assert main(args) == 0
    written = read_json(out / "edge_length.json")
    assert [(s["variant"], s["scene_name"]) for s in written["scenes"]] == [
        ("default", "short"), ("default", "00000099"), ("vote", "00000099")]
    assert (out / "edge_length.md").read_text().startswith("| scene | variant |")
    for png in (out / "edge_length.png", figure):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "wrote" in capsys.readouterr().out
    assert main(args) == 2  # the figure exists: --force replaces it
    assert "already exists" in capsys.readouterr().err
    assert main([*args, "--force"]) == 0


def test_no_finished_run_is_one_line(tmp_path, capsys):
    scene = make_scene(tmp_path / "scenes", "short", [1.0])
    make_run(tmp_path / "batch" / "short_quick_seed0", scene, 100, 20.0)  # no run of ours: not finished
    args = ["bench", "edge-length", "--runs", f"default={tmp_path / 'batch'}", "--out", str(tmp_path / "out")]
    assert main(args) == 2
    error = capsys.readouterr().err
    assert "no finished run" in error and "not finished" in error
    assert not (tmp_path / "out").exists()
