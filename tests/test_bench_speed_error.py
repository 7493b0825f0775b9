"""`edgedog bench speed-error`: rows per budget, seed and evaluation (runs of a batch, in this
process), the summary files, reuse, resume, evaluation that leaves training unchanged, seeds, and
one-line errors."""

from __future__ import annotations

import csv
import dataclasses
import shutil
import sys

import cv2
import pytest

from edgedog.batch.executors import SequentialExecutor
from edgedog.batch.outcome import SKIPPED
from edgedog.bench import speed_error
from edgedog.bench.speed_error import (
    SUMMARY,
    evaluation_epochs,
    parse_budgets,
    run_speed_error,
)
from edgedog.cli import main
from edgedog.errors import InputError
from edgedog.files import read_json

# A few epochs at 100 px, duplication early and the optimiser on every group from the start, so
# that the box has scored curves after two epochs.
TINY = ["epochs=6", "downscale=4", "init_method=uniform", "init_side=0.8", "opacity_from_epoch=0",
        "scales_from_epoch=0", "duplicate_epochs=1,2"]
BUDGETS = "preview-d4,preview-50"  # 6 and 3 epochs


def without_seconds(points) -> list[dict]:
    """Evaluation points as dicts, less the wall time, which differs between runs."""
    return [{k: v for k, v in dataclasses.asdict(p).items() if k != "seconds"} for p in points]


def speed(scene, out, budgets: str, overrides=TINY, evals: int = 2, seeds=(0,)):
    """The bench's result, its runs one after another in this process."""
    return run_speed_error(scene, out, parse_budgets(budgets), overrides, SequentialExecutor(), evals, seeds)


@pytest.fixture(scope="module")
def bench(builtin_scene_dir, tmp_path_factory):
    """The two tiny budgets trained and evaluated twice each; (out folder, results, run folders)."""
    out = tmp_path_factory.mktemp("speed_error")
    result = speed(builtin_scene_dir, out, BUDGETS)
    return out, result.results, [out / o.spec.name for o in result.batch.outcomes]


@pytest.fixture
def no_ray(monkeypatch):
    """Ray not installed: the command runs the bench in this process."""
    monkeypatch.setitem(sys.modules, "ray", None)


def test_budgets_and_evaluation_epochs():
    assert [b.name for b in parse_budgets("preview-d4, fast,preview-d4")] == ["preview-d4", "fast"]
    epochs = [b.config([]).schedule.epochs for b in parse_budgets("preview,preview-50,fast,full")]
    assert epochs == [100, 50, 200, 400]
    d4 = parse_budgets("preview-d4")[0].config(["downscale=8", "epochs=30"])
    assert (d4.maps.downscale, d4.schedule.epochs) == (4, 30)  # the budget's own change wins over --set
    assert parse_budgets("preview-50")[0].config(["epochs=30"]).schedule.epochs == 15
    whole = parse_budgets("preview-d1")[0].config(["downscale=2"])
    assert whole.maps.downscale == 1 and whole.schedule.epochs == 100
    assert evaluation_epochs(100, 5) == [20, 40, 60, 80, 100]
    assert evaluation_epochs(3, 5) == [1, 2, 3]


@pytest.mark.slow
def test_rows_scores_and_summary_files(bench):
    out, results, runs = bench
    with open(out / "speed_error.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert {row["seed"] for row in rows} == {"0"}
    assert [(r["budget"], int(r["epoch"])) for r in rows] == [("preview-d4", 3), ("preview-d4", 6),
                                                               ("preview-50", 2), ("preview-50", 3)]
    for budget in ("preview-d4", "preview-50"):
        seconds = [float(r["seconds"]) for r in rows if r["budget"] == budget]
        assert 0 < seconds[0] < seconds[1]
    for row in rows:
        assert int(row["primitives"]) > 0
        if row["acc_mm"] == "":  # no curve yet: the points are scored all the same
            assert int(row["curves"]) == 0 and int(row["epoch"]) < 3
            continue
        acc, comp, chamfer = (float(row[k]) for k in ("acc_mm", "comp_mm", "chamfer_mm"))
        assert 0 < acc < 50 and 0 < comp < 500 and chamfer == pytest.approx((acc + comp) / 2)
        fscores = [float(row[f"fscore_{mm}mm"]) for mm in (5, 10, 20)]
        assert 0 <= fscores[0] <= fscores[1] <= fscores[2] <= 100
        assert 0 < float(row["points_fscore_10mm"]) <= 100
    assert all(int(rows[i]["curves"]) > 0 for i in (1, 3))  # each budget ends with scored curves
    table = (out / "speed_error.md").read_text()
    assert table.count("| preview-d4 | 0 | 100x100 | 6/6 |") == 2
    assert table.count("| preview-50 | 0 | 100x100 |") == 3
    image = cv2.imread(str(out / "speed_error.png"))
    assert image is not None and image.shape[0] > 300 and image.shape[1] > 600
    coloured = (image.max(axis=2).astype(int) - image.min(axis=2)) > 60  # the budgets' lines
    assert coloured.sum() > 200 and image.std() > 10
    assert runs[0].name.startswith("box_preview_preview-d4_") and runs[0].name.endswith("_seed0")
    assert read_json(runs[0] / "log.json")["final_primitives"] == results[0].points[-1].primitives
    assert len(read_json(out / "batch.json")["configurations"]) == 2


@pytest.mark.slow
def test_a_second_invocation_reuses_every_budget(bench, builtin_scene_dir, monkeypatch, capsys, no_ray):
    out = bench[0]
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*/checkpoint.pt")}

    def no_training(*args, **kwargs):
        raise AssertionError("a finished budget was trained again")

    monkeypatch.setattr("edgedog.train.trainer.Trainer", no_training)
    args = ["bench", "speed-error", str(builtin_scene_dir), "--out", str(out), "--budgets", BUDGETS,
            "--evals", "2", "--quiet"] + [a for kv in TINY for a in ("--set", kv)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "| preview-50 | 0 | 100x100 | 3/3 |" in printed and str(out / SUMMARY[2]) in printed
    assert stamps and stamps == {p: p.stat().st_mtime_ns for p in out.glob("*/checkpoint.pt")}


class Killed(Exception):
    pass


@pytest.mark.slow
def test_a_killed_bench_resumes_to_the_rows_of_an_uninterrupted_one(bench, builtin_scene_dir, monkeypatch,
                                                                    tmp_path):
    evaluate = speed_error.evaluate

    def evaluate_then_die_mid_epoch(trainer, scene):
        point = evaluate(trainer, scene)
        step, steps = trainer.step, []

        def step_until_killed():
            if len(steps) == 10:
                raise Killed
            steps.append(step())

        trainer.step = step_until_killed
        return point

    monkeypatch.setattr(speed_error, "evaluate", evaluate_then_die_mid_epoch)
    with pytest.raises(Killed):
        speed(builtin_scene_dir, tmp_path, "preview-50")
    (saved,) = tmp_path.glob("*/speed_error.json")
    assert [p["epoch"] for p in read_json(saved)["points"]] == [2]
    assert not (tmp_path / SUMMARY[0]).exists()
    monkeypatch.undo()
    resumed = speed(builtin_scene_dir, tmp_path, "preview-50")
    assert [o.state for o in resumed.batch.outcomes] == ["resume"]
    assert without_seconds(resumed.results[0].points) == without_seconds(bench[1][1].points)


@pytest.mark.slow
def test_evaluating_along_the_way_leaves_training_unchanged(bench, builtin_scene_dir, tmp_path):
    once = speed(builtin_scene_dir, tmp_path, "preview-50", evals=1)
    assert without_seconds(once.results[0].points) == without_seconds(bench[1][1].points[-1:])


def test_seeds_are_runs_of_their_own_and_a_finished_bench_is_read_back(small_box_scene, tmp_path):
    first = speed(small_box_scene, tmp_path, "preview-50", evals=1, seeds=(0, 1))
    assert [(r.budget, r.seed) for r in first.results] == [("preview-50", 0), ("preview-50", 1)]
    assert [o.spec.name[-6:] for o in first.batch.outcomes] == ["_seed0", "_seed1"]
    assert first.results[0].points[0].epoch == first.results[0].epochs == 3
    with open(tmp_path / "speed_error.csv", newline="") as file:
        assert [row["seed"] for row in csv.DictReader(file)] == ["0", "1"]
    (configuration,) = read_json(tmp_path / "batch.json")["configurations"]
    assert configuration["seeds"] == "0 1" and configuration["runs"] == 2
    again = speed(small_box_scene, tmp_path, "preview-50", evals=1, seeds=(0, 1))
    assert [o.state for o in again.batch.outcomes] == [SKIPPED, SKIPPED] and again.results == first.results


@pytest.mark.slow
def test_bad_input_is_one_line(builtin_scene_dir, bench, tmp_path, capsys, no_ray):
    def error(*extra) -> str:
        try:
            code = main(["bench", "speed-error", *map(str, extra), "--quiet"])
        except SystemExit as exit:  # argparse's errors (an option out of its range)
            code = exit.code
        assert code == 2
        message = capsys.readouterr().err
        assert message.startswith("edgedog: error: ") and message.count("\n") == 1
        return message

    assert "--budgets must list some of preview-d4" in error(builtin_scene_dir, "--out", tmp_path / "a",
                                                           "--budgets", "fast,turbo")
    for evals in ("0", "1001", "1000000000"):  # 10**9 used to spin in a loop over the evaluations
        assert f"--evals: must be an integer in [1, 1000], got '{evals}'" in error(
            builtin_scene_dir, "--out", tmp_path / "a", "--evals", evals)
    bare = tmp_path / "no_gt"
    shutil.copytree(builtin_scene_dir, bare, ignore=shutil.ignore_patterns("gt"))
    assert "needs a scene with ground truth" in error(bare, "--out", tmp_path / "b",
                                                      "--budgets", "preview-d4")
    assert not (tmp_path / "b").exists()
    with pytest.raises(InputError, match="holds evaluations at epochs"):
        speed(builtin_scene_dir, bench[0], "preview-d4", evals=3)
