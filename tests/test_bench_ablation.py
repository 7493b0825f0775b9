"""`edgedog bench ablation`: the rows of the paper's Tables 3 and 4 as runs of a batch, shared runs,
seeds' mean and spread, reuse, and the path without Ray."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from edgedog.batch.executors import SequentialExecutor, choose_executor
from edgedog.batch.jobs import TrainAndExtract
from edgedog.batch.outcome import SKIPPED, RunOutcome
from edgedog.batch.runner import run_batch
from edgedog.batch.suite import RunSpec, config_changes, expand, load_suite
from edgedog.batch.table import TIMINGS, run_rows
from edgedog.bench.ablation import (
    COMPONENTS,
    CORRECTIONS,
    WEIGHTING,
    component_rows,
    correction_rows,
    effective_config,
    markdown,
    row_result,
    row_specs,
    run_ablation,
    run_name,
    select_rows,
    weighting_rows,
)
from edgedog.cli import main
from edgedog.errors import ConfigError
from edgedog.files import read_json
from edgedog.settings import with_values
from edgedog.train.config import PRESETS, TrainConfig, preset, with_overrides, with_settings

TINY = ["epochs=3", "init.count=300"]
"""Runs of a few seconds on the small box scene."""


def test_component_rows_cover_every_combination_once():
    rows = component_rows()
    combos = {(r.changes["model.kernel"], r.changes["loss.pixel_uncertainty"],
               r.changes["strategy.primitive_uncertainty"]) for r in rows}
    assert len(rows) == len(combos) == 8
    assert rows[0].changes == {"model.kernel": "gaussian", "loss.pixel_uncertainty": False,
                               "strategy.primitive_uncertainty": False}
    assert rows[-1].label == "full EdgeDoG" and rows[-1].changes["model.kernel"] == "dog"
    weightings = [r.changes["loss.weighting"] for r in weighting_rows()]
    assert weightings == ["one", "exp_neg", "one_minus", "up", "exp"]


def test_rows_that_train_identically_share_a_run():
    base = TrainConfig()
    full = effective_config(with_settings(base, dict(weighting="exp")))
    one = effective_config(with_settings(base, dict(weighting="one")))
    off = effective_config(with_settings(base, dict(pixel_uncertainty=False, weighting="up")))
    assert one == off != full
    assert run_name(one) == "dog_nopix_fisher_outline-auto"
    assert run_name(full) == "dog_pix-exp_fisher_outline-auto"
    baseline = effective_config(with_settings(base, dict(kernel="gaussian", k_init=(1.0, 0.0))))
    assert baseline.init.k == base.init.k  # k is unused by the Gaussian kernel


def test_rows_of_one_effective_config_name_the_same_runs_and_give_it(tmp_path):
    base = with_overrides(preset("preview"), TINY)
    one, dog_fisher, exp = select_rows((COMPONENTS, WEIGHTING), ("one", "dog+fisher", "exp"))
    specs = {row.key: row_specs(tmp_path, "preview", base, row, (0, 3)) for row in (one, dog_fisher, exp)}
    assert [s.name for s in specs["one"]] == [s.name for s in specs["dog+fisher"]]
    assert len({s.name for s in specs["one"] + specs["exp"]}) == 4
    assert [s.seed for s in specs["exp"]] == [0, 3] and specs["exp"][1].name.endswith("_seed3")
    for row in (one, exp):
        for spec in specs[row.key]:  # the overrides are text: they give the config exactly
            assert spec.config() == with_values(effective_config(with_values(base, row.changes)),
                                                {"run.seed": spec.seed})
    assert specs["exp"][0].changes == ("loss.weighting=exp",)
    assert set(specs["exp"][0].overrides) >= {"schedule.epochs=3", "init.count=300"}


@pytest.mark.parametrize("name", PRESETS)
def test_a_config_written_as_overrides_reads_back_as_itself(name):
    config = preset(name)
    assert with_overrides(TrainConfig(), config_changes(config, TrainConfig())) == config


def test_correction_rows_get_their_own_runs():
    base = preset("preview")
    names = [run_name(effective_config(with_values(base, row.changes))) for row in correction_rows()]
    assert len(set(names)) == len(names) == 7 and names[0] == "dog_pix-exp_neg_fisher"  # no correction at all
    assert {"dog_pix-exp_neg_fisher_learned", "dog_pix-exp_neg_fisher_outline",
            "dog_pix-exp_neg_fisher_profile_outline"} <= set(names)


def outcome(seed: int, f10: float | None = None, seconds: float = 1.0, error: str = "") -> RunOutcome:
    spec = RunSpec(f"c_seed{seed}", "c", Path("/scenes/box"), "preview", "row", (), (f"seed={seed}",), seed)
    if error:
        return RunOutcome(spec, "new", error=error)
    curves = None if f10 is None else {"fscore_10mm": f10, "acc_mm": 2.0}
    return RunOutcome(spec, "new", 0, {"train_seconds": seconds, "final_primitives": 100 + seed,
                                       "map_shift_px": [0.5, -0.25]},
                      {"metrics": {"curves": curves}, "counts": {"lines": 2, "beziers": 1}})


def test_a_row_reports_the_mean_and_spread_over_its_seeds_and_why_runs_failed():
    calibrated = select_rows((CORRECTIONS,), ("calibrated",))[0]
    two = row_result(calibrated, [outcome(0, 40.0, 10.0), outcome(1, 50.0, 14.0), outcome(2, error="boom")])
    assert (two["fscore_10mm_mean"], two["train_seconds_mean"], two["curves_mean"]) == (45.0, 12.0, 3)
    assert two["fscore_10mm_std"] == pytest.approx(50 ** 0.5) and two["curves_std"] == 0.0
    assert two["runs"] == ["c_seed0", "c_seed1", "c_seed2"] and two["errors"] == ["boom"]
    one = row_result(calibrated, [outcome(0, None)])
    assert one["fscore_10mm_mean"] is None and one["primitives_mean"] == 100 and one["primitives_std"] is None
    table = markdown([two])
    label = "shift by the detector's calibration"
    assert f"| {label} (1 of 3 runs failed: boom) | – | – | – | 45.0 ± 7.1 |" in table
    assert "| +0.50 ± 0.00, -0.25 ± 0.00 |" in table and "over seeds 0, 1, 2" in table
    single = markdown([one])
    assert "| – | – | – | – | – | – | – | – | 3 | 1 | 100 | +0.50, -0.25 | – |" in single
    assert "over seeds" not in single
    failed = markdown([row_result(calibrated, [outcome(0, error="no calibration of detector 'x'")])])
    assert f"| {label} | skipped: no calibration of detector 'x' |" in failed


def test_rows_are_chosen_by_key_and_an_unknown_key_is_named():
    keys = [r.key for r in select_rows((COMPONENTS, WEIGHTING, CORRECTIONS))]
    assert keys[:8] == ["baseline", "dog", "pixel", "fisher", "dog+pixel", "dog+fisher", "pixel+fisher",
                        "full"]
    assert len(set(keys[8:13])) == 5 and len(set(keys[13:])) == 7
    chosen = select_rows((CORRECTIONS,), ("outline+profile", "raw"))
    assert [r.key for r in chosen] == ["raw", "outline+profile"]  # table order, not the order asked
    assert chosen[1].changes["maps.edge_profile"] == "profile"
    with pytest.raises(ConfigError, match="no row full in the tables corrections"):
        select_rows((CORRECTIONS,), ("full",))


def test_without_ray_the_bench_runs_in_this_process_and_an_address_needs_ray(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    assert choose_executor(None, 2) == SequentialExecutor(2)
    with pytest.raises(ConfigError, match="^--address auto needs Ray, which is not installed: pip install"):
        choose_executor("auto", 1)


def ablation(scene: Path, out: Path, keys: tuple[str, ...], seeds: tuple[int, ...] = (0,)):
    rows = select_rows((COMPONENTS, WEIGHTING), keys)
    return run_ablation(scene, out, "preview", TINY, rows, seeds, SequentialExecutor())


def test_seeds_and_shared_runs_make_the_tables_and_a_rerun_trains_nothing(small_box_scene, tmp_path):
    out = tmp_path / "out"
    result = ablation(small_box_scene, out, ("dog+fisher", "one", "exp"), (0, 1))
    assert [outcome.state for outcome in result.batch.outcomes] == ["new"] * 4  # dog+fisher = one
    one, shared, exp = result.rows
    assert one["runs"] == shared["runs"] and one["runs"] != exp["runs"] and one["seeds"] == [0, 1]
    runs = {o.spec.name: o.log for o in result.batch.outcomes}
    primitives = [runs[name]["final_primitives"] for name in exp["runs"]]
    assert exp["primitives_mean"] == sum(primitives) / 2 and exp["primitives_std"] is not None
    assert read_json(out / "ablation.json") == result.rows
    table = (out / "ablation.md").read_text()
    assert table.count("| w = ") == 2 and "| + DoG + Fisher U |" in table and " ± " in table
    assert {path.name for path in result.batch.files} >= {"batch.md", "batch.csv", "ablation.md"}
    assert [row["run"] for row in read_json(out / "batch.json")["runs"]] == list(runs)
    stamps = {name: (out / name / "log.json").stat().st_mtime_ns for name in runs}
    again = ablation(small_box_scene, out, ("dog+fisher", "one", "exp"), (0, 1))
    assert [outcome.state for outcome in again.batch.outcomes] == [SKIPPED] * 4
    assert again.rows == result.rows and (out / "ablation.md").read_text() == table
    assert stamps == {name: (out / name / "log.json").stat().st_mtime_ns for name in runs}


def test_the_bench_runs_the_rows_as_a_suite_of_them_would(small_box_scene, tmp_path):
    bench = ablation(small_box_scene, tmp_path / "bench", ("one", "exp"))
    specs = [o.spec for o in bench.batch.outcomes]
    suite = tmp_path / "suite.yaml"
    rows = "".join(f"  {s.row}: [{', '.join(s.changes)}]\n" for s in specs)
    common = ", ".join(specs[0].overrides[:len(specs[0].overrides) - 1 - len(specs[0].changes)])
    suite.write_text(f"scenes: [{small_box_scene}]\npresets: [preview]\nset: [{common}]\nrows:\n{rows}")
    batch = run_batch(expand(load_suite(suite)), tmp_path / "batch", SequentialExecutor(), suite)
    assert [o.spec.name for o in batch.outcomes] == [s.name for s in specs]
    assert without_timings(batch.outcomes) == without_timings(bench.batch.outcomes)
    assert [h["loss"] for o in batch.outcomes for h in o.log["history"]] == \
        [h["loss"] for o in bench.batch.outcomes for h in o.log["history"]]


def without_timings(outcomes: list[RunOutcome]) -> list[dict]:
    return [{key: value for key, value in row.items() if key not in TIMINGS} for row in run_rows(outcomes)]


def test_a_killed_bench_writes_no_tables_and_resumes_from_its_runs(small_box_scene, tmp_path, monkeypatch):
    trained = []

    def killed_at_the_second_run(task, job):
        if trained:
            raise KeyboardInterrupt
        trained.append(job.plan.run.path)
        return run(task, job)

    run = TrainAndExtract.run
    monkeypatch.setattr(TrainAndExtract, "run", killed_at_the_second_run)
    with pytest.raises(KeyboardInterrupt):
        ablation(small_box_scene, tmp_path, ("one", "exp"))
    assert len(trained) == 1 and not (tmp_path / "ablation.json").exists()
    stamp = (trained[0] / "log.json").stat().st_mtime_ns
    monkeypatch.undo()
    result = ablation(small_box_scene, tmp_path, ("one", "exp"))
    assert read_json(tmp_path / "ablation.json") == result.rows and len(result.rows) == 2
    assert [o.state for o in result.batch.outcomes] == [SKIPPED, "new"]
    assert (trained[0] / "log.json").stat().st_mtime_ns == stamp  # the finished run is reused


def test_the_command_without_ray(small_box_scene, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)
    out = tmp_path / "out"
    args = ["bench", "ablation", str(small_box_scene), "--out", str(out), "--tables", "weighting", "--rows",
            "one,exp", "--seeds", "0,1", "--preset", "preview", "--quiet", "--set", TINY[0], "--set", TINY[1]]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "over seeds 0, 1" in printed and printed.count("| w = ") == 2
    assert str(out / "ablation.md") in printed
    assert len(read_json(out / "batch.json")["runs"]) == 4
    assert main(args[:-4] + ["--set", "seed=3"]) == 2
    assert "--set 'seed=3': give seeds with --seeds" in capsys.readouterr().err
