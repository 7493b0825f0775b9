"""`edgedog bench ablation`: the rows of the paper's Tables 3 and 4, shared runs, reuse."""

from __future__ import annotations

import pytest

from edgedog.bench.ablation import (
    COMPONENTS,
    WEIGHTING,
    component_rows,
    effective_config,
    markdown,
    run_ablation,
    run_name,
    weighting_rows,
)
from edgedog.files import read_json
from edgedog.settings import with_values
from edgedog.train.config import TrainConfig, preset, with_settings


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


@pytest.mark.slow
def test_weighting_table_trains_scores_and_reuses_its_runs(builtin_scene_dir, tmp_path):
    base = with_settings(preset("preview"), dict(
        downscale=4, epochs=4, init_count=300, duplicate_epochs=(1,), opacity_from_epoch=0,
        scales_from_epoch=0, cull_projection_epochs=(), cull_opacity_epochs=(), fisher_every=1,
        checkpoint_every=4, init_side=0.8))
    results = run_ablation(builtin_scene_dir, tmp_path, "preview", base, (WEIGHTING,), progress=False)
    assert [r["table"] for r in results] == [WEIGHTING] * 5
    runs = sorted(p.name for p in tmp_path.iterdir() if p.is_dir())
    assert len(runs) == 5 and "dog_nopix_fisher_outline-auto" in runs  # w = 1 is the run without the term
    assert results[0]["run"] == "dog_nopix_fisher_outline-auto"
    for r in results:
        assert r["primitives"] > 0 and r["train_seconds"] > 0
        assert r["points_fscore_10mm"] is not None and 0 <= r["points_fscore_10mm"] <= 100
    saved = read_json(tmp_path / "ablation.json")
    assert saved == results
    table = (tmp_path / "ablation.md").read_text()
    assert table.count("| w = ") == 5 and COMPONENTS not in table
    stamps = {run: (tmp_path / run / "log.json").stat().st_mtime_ns for run in runs}
    again = run_ablation(builtin_scene_dir, tmp_path, "preview", base, (WEIGHTING,), progress=False)
    assert again == results
    assert stamps == {run: (tmp_path / run / "log.json").stat().st_mtime_ns for run in runs}
    assert markdown(again) == table


def test_correction_rows_get_their_own_runs_and_a_skipped_row_says_why():
    from edgedog.bench.ablation import CORRECTIONS, correction_rows

    base = preset("preview")
    names = [run_name(effective_config(with_values(base, row.changes)))
             for row in correction_rows()]
    assert len(set(names)) == len(names) == 7 and names[0] == "dog_pix-exp_neg_fisher"  # no correction at all
    assert {"dog_pix-exp_neg_fisher_learned", "dog_pix-exp_neg_fisher_outline",
            "dog_pix-exp_neg_fisher_profile_outline"} <= set(names)
    table = markdown([{"table": CORRECTIONS, "label": "shift by the detector's calibration", "run": names[1],
                       "skipped": "no calibration of detector 'x'"}])
    assert "| shift by the detector's calibration | skipped: no calibration of detector 'x' |" in table


def test_rows_are_chosen_by_key_and_an_unknown_key_is_named():
    import pytest

    from edgedog.bench.ablation import CORRECTIONS, select_rows
    from edgedog.errors import ConfigError

    keys = [r.key for r in select_rows((COMPONENTS, WEIGHTING, CORRECTIONS))]
    assert keys[:8] == ["baseline", "dog", "pixel", "fisher", "dog+pixel", "dog+fisher", "pixel+fisher",
                        "full"]
    assert len(set(keys[8:13])) == 5 and len(set(keys[13:])) == 7
    chosen = select_rows((CORRECTIONS,), ("outline+profile", "raw"))
    assert [r.key for r in chosen] == ["raw", "outline+profile"]  # table order, not the order asked
    assert chosen[1].changes["maps.edge_profile"] == "profile"
    with pytest.raises(ConfigError, match="no row full in the tables corrections"):
        select_rows((CORRECTIONS,), ("full",))


def test_a_killed_bench_writes_no_tables_and_resumes_from_its_rows(builtin_scene_dir, tmp_path, monkeypatch):
    from edgedog.bench import ablation

    base = with_settings(preset("preview"), dict(downscale=4, epochs=2, init_count=300, duplicate_epochs=(),
                                                 cull_projection_epochs=(), cull_opacity_epochs=(),
                                                 init_side=0.8))
    rows, trained = ("one", "exp"), []

    def killed_at_the_second_row(run, progress):
        if trained:
            raise KeyboardInterrupt
        trained.append(run.path)
        return train_and_extract(run, progress)

    train_and_extract = ablation.train_and_extract
    monkeypatch.setattr(ablation, "train_and_extract", killed_at_the_second_row)
    with pytest.raises(KeyboardInterrupt):
        run_ablation(builtin_scene_dir, tmp_path, "preview", base, (WEIGHTING,), False, rows)
    assert len(trained) == 1 and not (tmp_path / "ablation.json").exists()
    stamp = (trained[0] / "log.json").stat().st_mtime_ns
    monkeypatch.undo()
    results = run_ablation(builtin_scene_dir, tmp_path, "preview", base, (WEIGHTING,), False, rows)
    assert read_json(tmp_path / "ablation.json") == results and len(results) == 2
    assert (trained[0] / "log.json").stat().st_mtime_ns == stamp  # the finished row is reused
