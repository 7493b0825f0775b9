"""Stop when done (edgedog.train.convergence): the test on synthetic epochs, and the trainer
stopping a settled run (or its coarse stage), recording it, and resuming it as finished."""

from __future__ import annotations

import json

import pytest
import torch

from edgedog.train.config import ScheduleSettings
from edgedog.train.convergence import Convergence, fisher_change
from edgedog.train.lifecycle import trained_to_end
from edgedog.train.trainer import Trainer
from tests.helpers.tiny_runs import every_fifth_view, tiny_config

FROZEN = {"lr_means": 0.0, "lr_scales": 0.0, "lr_opacity": 0.0, "lr_quats": 0.0, "lr_k": 0.0}
"""Rates of a run that has nothing left to learn: every epoch ends where it started."""


def epochs(settings: ScheduleSettings, shifts: list[float], losses: list[float],
           events: set[int] = frozenset(), scores=lambda epoch: torch.ones(50)) -> list[dict]:
    """The records of `Convergence.update` over synthetic epochs: 50 centres each moved by
    `shifts[e]` along x in epoch e, whose mean loss is `losses[e]`, with a density event that
    adds a primitive at the end of the epochs in `events`; `scores(e)`: the Fisher scores then."""
    convergence, centres, records = Convergence(), torch.zeros(50, 3), []
    for epoch, (shift, loss) in enumerate(zip(shifts, losses)):
        centres = centres + torch.tensor([shift, 0.0, 0.0])
        after = torch.cat([centres, centres[:1]]) if epoch in events else centres
        records.append(convergence.update(settings, centres, loss, epoch in events, after,
                                          lambda: scores(epoch)[:len(after)]))
        centres = after
    return records


def test_a_settling_run_converges_after_the_patience():
    settings = ScheduleSettings(stop="run", stop_patience=3, stop_shift=1e-3, stop_loss_change=0.05)
    # Centres moving 8 mm, 4, 2, 1, 0.5, ... per epoch; the loss falling then flat.
    shifts = [0.008 * 0.5**e for e in range(10)]
    losses = [0.05, 0.03, 0.02, 0.016, 0.0155, 0.0152, 0.0153, 0.0152, 0.0151, 0.0152]
    records = epochs(settings, shifts, losses)
    # The shift is within 1 mm from epoch 3 on; the loss within 5 % of the mean of the 3 epochs
    # before from epoch 6 on (epoch 5: 0.0152 against 0.0172).
    assert [r["settled"] for r in records] == [0, 0, 0, 0, 0, 0, 1, 2, 3, 4]
    assert [r["converged"] for r in records].index(True) == 8
    assert records[0]["centre_shift"] is None and records[1]["centre_shift"] == pytest.approx(0.004)


def test_a_moving_or_changing_run_does_not_converge():
    settings = ScheduleSettings(stop="run", stop_patience=3, stop_shift=1e-3, stop_loss_change=0.05)
    flat, falling = [0.02] * 12, [0.02 * 0.9**e for e in range(12)]
    # Centres still drifting 2 mm per epoch; a loss still falling 10 % per epoch; primitives
    # added every third epoch (the streak starts again after each).
    for shifts, losses, events in (([0.002] * 12, flat, set()), ([0.0] * 12, falling, set()),
                                   ([0.0] * 12, flat, {2, 5, 8, 11})):
        records = epochs(settings, shifts, losses, events)
        assert not any(r["converged"] for r in records)
        assert max(r["settled"] for r in records) < 3
    # Primitives removed (a cull) do not interrupt the streak.
    removing, centres = Convergence(), torch.zeros(50, 3)
    for epoch in range(6):
        kept = centres[:-1] if epoch == 2 else centres
        record = removing.update(settings, centres, 0.02, False, kept, lambda: torch.ones(len(kept)))
        centres = kept
    assert record["settled"] == 5 and record["converged"]


def test_the_fisher_scores_must_settle_too():
    settings = ScheduleSettings(stop="run", stop_patience=2, stop_shift=1e-3, stop_loss_change=0.05,
                                stop_fisher_change=0.05)
    g = torch.Generator().manual_seed(0)
    wandering = [torch.rand(50, generator=g) for _ in range(8)]
    records = epochs(settings, [0.0] * 8, [0.02] * 8, scores=lambda e: wandering[e])
    assert not any(r["converged"] for r in records)
    assert all(r["fisher_change"] > 0.05 for r in records[3:])  # measured from the patience on
    steady = epochs(settings, [0.0] * 8, [0.02] * 8, scores=lambda e: torch.linspace(1, 2, 50) * (1 + e))
    # Settled at epochs 1 and 2: scores measured at 2, compared at 3 (the same shares: 0 moved).
    assert [r["converged"] for r in steady].index(True) == 3 and steady[3]["fisher_change"] == 0
    assert fisher_change(torch.tensor([1.0, 0.0]), torch.tensor([0.0, 2.0])) == 1.0


def stop_config(**changes):
    return tiny_config(**{"epochs": 8, "checkpoint_every": 4, "sampled_from_epoch": 100, "stop_patience": 3,
                          **changes})


def test_a_settled_run_stops_and_resumes_finished(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    trainer = Trainer(scene, stop_config(stop="run", **FROZEN), tmp_path / "run", progress=False)
    trainer.run()
    # Epoch 0 has no epoch before; epochs 1, 2, 3 are settled: the run ends after epoch 3 of 8.
    log = json.loads((tmp_path / "run" / "log.json").read_text())
    assert log["stopped"] == {"epoch": 3, "ceiling": 8, "reason": "converged"}
    assert [h["epoch"] for h in log["history"]] == [0, 1, 2, 3] and log["history"][3]["converged"]
    assert {"event": "converged", "ended": "run", "epoch": 3} in log["events"]
    assert trained_to_end(log, 8) and trainer.step_index == 4 * len(scene)
    # Resumed, it is finished: no step, the same outputs.
    resumed = Trainer(scene, stop_config(stop="run", **FROZEN), tmp_path / "run", progress=False)
    assert resumed.done and resumed.step_index == 4 * len(scene) and resumed.stopped == log["stopped"]
    resumed.run()
    assert json.loads((tmp_path / "run" / "log.json").read_text())["history"] == log["history"]
    # Not before stop_from_epoch.
    later = Trainer(scene, stop_config(stop="run", stop_from_epoch=5, **FROZEN), tmp_path / "later",
                    progress=False)
    later.run()
    assert later.stopped["epoch"] == 5


def test_a_learning_run_does_not_stop(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    # The first epochs from a uniform start, at the default tolerances: the centres move 8 to 3.4
    # mm per epoch (more than 3 mm), none is settled, and the run trains to its end.
    trainer = Trainer(scene, stop_config(stop="run", epochs=5), tmp_path / "run", progress=False)
    trainer.run()
    log = json.loads((tmp_path / "run" / "log.json").read_text())
    assert log["stopped"] is None and len(log["history"]) == 5 and trained_to_end(log, 5)
    assert min(h["centre_shift"] for h in log["history"][1:]) > ScheduleSettings().stop_shift
    assert not any(h["settled"] for h in log["history"])


def test_a_settled_coarse_stage_ends_early(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    config = stop_config(stop="coarse", coarse_downscale=2, fine_from_epoch=6, **FROZEN)
    trainer = Trainer(scene, config, tmp_path / "run", progress=False)
    trainer.run()
    log = json.loads((tmp_path / "run" / "log.json").read_text())
    # The coarse stage settles after epoch 3: epochs 4 and 5 are left out, the fine stage trains.
    assert [h["epoch"] for h in log["history"]] == [0, 1, 2, 3, 6, 7] and log["stopped"] is None
    assert {"event": "converged", "ended": "coarse stage", "skipped_to": 6, "epoch": 3} in log["events"]
    assert trained_to_end(log, 8)
    # Not before coarse_stop_from_epoch: settled from epoch 3 on, it ends after epoch 4.
    config = stop_config(stop="coarse", coarse_downscale=2, fine_from_epoch=6, coarse_stop_from_epoch=4,
                         **FROZEN)
    later = Trainer(scene, config, tmp_path / "later", progress=False)
    later.run()
    assert [h["epoch"] for h in later.history] == [0, 1, 2, 3, 4, 6, 7]
    # 'both': then the fine stage settles too (from epoch 9 on, of 12), and the run ends from
    # stop_from_epoch on (which the coarse stage does not wait for).
    config = stop_config(stop="both", epochs=12, coarse_downscale=2, fine_from_epoch=6, stop_from_epoch=10,
                         **FROZEN)
    both = Trainer(scene, config, tmp_path / "both", progress=False)
    both.run()
    assert [h["epoch"] for h in both.history] == [0, 1, 2, 3, 6, 7, 8, 9, 10]
    assert both.stopped == {"epoch": 10, "ceiling": 12, "reason": "converged"}


def test_off_leaves_the_outputs_as_they_were(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    Trainer(scene, stop_config(epochs=3, **FROZEN), tmp_path / "run", progress=False).run()
    log = json.loads((tmp_path / "run" / "log.json").read_text())
    assert "stopped" not in log and set(log["history"][0]) == {"epoch", "loss", "primitives_before_events",
                                                                "primitives", "seconds"}


def test_a_run_folder_stopped_when_converged_is_finished(builtin_scene_dir, tmp_path):
    from edgedog.scenes import load_scene
    from edgedog.train.lifecycle import FINISHED, REUSE, is_finished, plan_run
    from edgedog.train.run_folder import RunFolder, write_run

    config = stop_config(stop="run", **FROZEN)
    run = RunFolder(tmp_path / "run", load_scene(builtin_scene_dir).root, "preview", config)
    write_run(run)
    Trainer(every_fifth_view(builtin_scene_dir), config, run.path, progress=False).run()
    assert json.loads((run.path / "log.json").read_text())["stopped"]["epoch"] == 3
    assert is_finished(run.path)
    assert plan_run(run.path, builtin_scene_dir, "preview", config, REUSE).state == FINISHED
