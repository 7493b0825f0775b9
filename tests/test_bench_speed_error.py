"""`edgedog bench speed-error`: rows per budget and evaluation, the summary files, reuse, resume,
evaluation that leaves training unchanged, and one-line errors."""

from __future__ import annotations

import csv
import dataclasses
import shutil

import cv2
import pytest

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


@pytest.fixture(scope="module")
def bench(builtin_scene_dir, tmp_path_factory):
    """The two tiny budgets trained and evaluated twice each; (out folder, results)."""
    out = tmp_path_factory.mktemp("speed_error")
    return out, run_speed_error(builtin_scene_dir, out, parse_budgets(BUDGETS), TINY, evals=2, progress=False)


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
    out, results = bench
    with open(out / "speed_error.csv", newline="") as file:
        rows = list(csv.DictReader(file))
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
    assert table.count("| preview-d4 | 100x100 | 6/6 |") == 2 and table.count("| preview-50 | 100x100 |") == 3
    image = cv2.imread(str(out / "speed_error.png"))
    assert image is not None and image.shape[0] > 300 and image.shape[1] > 600
    coloured = (image.max(axis=2).astype(int) - image.min(axis=2)) > 60  # the budgets' lines
    assert coloured.sum() > 200 and image.std() > 10
    assert read_json(out / "preview-d4" / "log.json")["final_primitives"] == results[0].points[-1].primitives


@pytest.mark.slow
def test_a_second_invocation_reuses_every_budget(bench, builtin_scene_dir, monkeypatch, capsys):
    out, results = bench
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*/checkpoint.pt")}

    def no_training(*args, **kwargs):
        raise AssertionError("a finished budget was trained again")

    monkeypatch.setattr("edgedog.train.trainer.Trainer", no_training)
    args = ["bench", "speed-error", str(builtin_scene_dir), "--out", str(out), "--budgets", BUDGETS,
            "--evals", "2", "--quiet"] + [a for kv in TINY for a in ("--set", kv)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "| preview-50 | 100x100 | 3/3 |" in printed and str(out / SUMMARY[2]) in printed
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
    budgets = parse_budgets("preview-50")
    with pytest.raises(Killed):
        run_speed_error(builtin_scene_dir, tmp_path, budgets, TINY, evals=2, progress=False)
    assert [p["epoch"] for p in read_json(tmp_path / "preview-50" / "speed_error.json")["points"]] == [2]
    monkeypatch.undo()
    resumed = run_speed_error(builtin_scene_dir, tmp_path, budgets, TINY, evals=2, progress=False)
    assert without_seconds(resumed[0].points) == without_seconds(bench[1][1].points)


@pytest.mark.slow
def test_evaluating_along_the_way_leaves_training_unchanged(bench, builtin_scene_dir, tmp_path):
    budgets = parse_budgets("preview-50")
    once = run_speed_error(builtin_scene_dir, tmp_path, budgets, TINY, evals=1, progress=False)
    assert without_seconds(once[0].points) == without_seconds(bench[1][1].points[-1:])


@pytest.mark.slow
def test_bad_input_is_one_line(builtin_scene_dir, bench, tmp_path, capsys):
    def error(*extra) -> str:
        assert main(["bench", "speed-error", *map(str, extra), "--quiet"]) == 2
        message = capsys.readouterr().err
        assert message.startswith("edgedog: error: ") and message.count("\n") == 1
        return message

    assert "--budgets must list some of preview-d4" in error(builtin_scene_dir, "--out", tmp_path / "a",
                                                           "--budgets", "fast,turbo")
    assert "--evals must be at least 1" in error(builtin_scene_dir, "--out", tmp_path / "a", "--evals", "0")
    bare = tmp_path / "no_gt"
    shutil.copytree(builtin_scene_dir, bare, ignore=shutil.ignore_patterns("gt"))
    assert "needs a scene with ground truth" in error(bare, "--out", tmp_path / "b",
                                                      "--budgets", "preview-d4")
    assert not (tmp_path / "b" / "preview-d4" / "checkpoint.pt").exists()
    d4 = parse_budgets("preview-d4")
    with pytest.raises(InputError, match="holds evaluations at epochs"):
        run_speed_error(builtin_scene_dir, bench[0], d4, TINY, evals=3, progress=False)
    with pytest.raises(InputError, match="another scene or configuration"):
        run_speed_error(builtin_scene_dir, bench[0], d4, TINY[1:], progress=False)
