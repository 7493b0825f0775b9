"""One run lifecycle: a plan (new / resume from step k / finished / refused) apart from its
execution, one meaning of "finished" for every caller, and runs whose results do not depend on
what ran before them in the process."""

from __future__ import annotations

import dataclasses
import json
import os
import pickle
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from edgedog.curves.config import ExtractConfig, to_dict
from edgedog.curves.report import REPORT
from edgedog.errors import InputError
from edgedog.scenes import load_scene
from edgedog.train import lifecycle
from edgedog.train import run as run_object
from edgedog.train.config import preset, with_settings
from edgedog.train.lifecycle import (
    CONTINUE,
    FINISHED,
    NEW,
    REFUSED,
    RESUME,
    REUSE,
    START,
    execute,
    is_finished,
    plan_run,
)
from edgedog.train.run_folder import LOCK_FILE, RunFolder, lock_holder, read_run, write_run
from edgedog.train.trainer import Trainer
from tests.helpers.bad_inputs import edgedog

SETTINGS = {"epochs": 2, "init.count": 300, "checkpoint_every": 1}
CLI_SETTINGS = [arg for key, value in SETTINGS.items() for arg in ("--set", f"{key}={value}")]


def config(**changes):
    return with_settings(preset("preview"), {**SETTINGS, **changes})


@pytest.fixture(scope="module")
def finished(small_box_scene, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("runs") / "finished"
    execute(plan_run(out, small_box_scene, "preview", config(), START), progress=False)
    return out


def _plain(value) -> bool:
    """Whether `value` is plain data: no open file, tensor or array anywhere in it."""
    if dataclasses.is_dataclass(value):
        return all(_plain(getattr(value, f.name)) for f in dataclasses.fields(value))
    if isinstance(value, (tuple, list)):
        return all(_plain(item) for item in value)
    return value is None or isinstance(value, (str, int, float, bool, Path))


def test_a_plan_writes_nothing_carries_its_scene_and_is_plain_data_besides(small_box_scene, tmp_path):
    out = tmp_path / "run"
    plan = plan_run(out, small_box_scene, "preview", config(), START)
    assert plan.state == NEW and plan.step == 0 and not out.exists()
    assert plan.run.scene_fingerprint and plan.run.scene == load_scene(small_box_scene).root
    assert plan.scene.root == plan.run.scene and len(plan.scene) == len(load_scene(small_box_scene))
    sent = pickle.loads(pickle.dumps(plan))  # to another process: the scene is loaded there
    assert sent == plan and sent.scene is None and _plain(sent)


def test_plans_of_a_finished_run(finished, small_box_scene):
    views = len(load_scene(small_box_scene))
    assert is_finished(finished)
    resumed = plan_run(finished, small_box_scene, policy=CONTINUE)
    assert resumed.state == FINISHED and resumed.step == SETTINGS["epochs"] * views and resumed.extracted
    assert resumed.run == read_run(finished)
    reused = plan_run(finished, small_box_scene, "preview", config(), REUSE)
    assert reused.state == FINISHED
    again = plan_run(finished, small_box_scene, "preview", config(), START)
    assert again.state == REFUSED and "pass --resume" in again.reason
    other = plan_run(finished, small_box_scene, "preview", config(seed=7), REUSE)
    assert other.state == REFUSED and "another scene or configuration" in other.reason
    with pytest.raises(InputError, match="another scene or configuration"):
        execute(other)


def test_a_report_of_other_extraction_settings_is_extracted_again(finished, small_box_scene, tmp_path):
    out = tmp_path / "copy"
    shutil.copytree(finished, out)
    report = json.loads((out / REPORT).read_text())
    report["config"]["filter_outliers"] = True  # as written before the setting was a choice
    (out / REPORT).write_text(json.dumps(report))
    stale = plan_run(out, small_box_scene, "preview", config(), REUSE)
    assert stale.state == FINISHED and not stale.extracted
    primitives = (out / "primitives.ply").read_bytes()
    result = execute(stale, progress=False)
    assert result.report["config"] == to_dict(ExtractConfig())
    assert json.loads((out / REPORT).read_text())["config"] == to_dict(ExtractConfig())
    assert (out / "primitives.ply").read_bytes() == primitives  # extracted, not trained again
    assert plan_run(out, small_box_scene, "preview", config(), REUSE).extracted
    (out / REPORT).write_text("{not json")
    assert not plan_run(out, small_box_scene, "preview", config(), REUSE).extracted


def test_a_run_of_one_layer_answers_the_record_api(finished, tmp_path):
    """`open_record` reads the run under its lock (taking none in a folder that records no run);
    its extraction writes what the run's own extraction wrote; `curves_of` finds its curves, and a
    folder of curves that records no run holds its own."""
    out = tmp_path / "copy"
    shutil.copytree(finished, out)
    (tmp_path / "curves").mkdir()
    assert (lifecycle.record_kind(out), lifecycle.record_kind(tmp_path)) == (lifecycle.SINGLE_RUN, "")
    assert lifecycle.curves_of(out) == (out, out)
    assert lifecycle.curves_of(tmp_path / "curves") == (tmp_path / "curves", tmp_path / "curves")
    with pytest.raises(InputError, match="--layers needs a layered run"):
        lifecycle.curves_of(out, "L0")
    with pytest.raises(InputError, match="is not an edgedog run folder"), lifecycle.open_record(tmp_path):
        pass
    assert not (tmp_path / LOCK_FILE).exists()
    written = {name: (out / name).read_bytes() for name in ("curves.json", "edge_points.ply", REPORT)}
    with lifecycle.open_record(out) as record:
        assert lock_holder(out) == str(os.getpid()) and record == read_run(out)
        record.extract(record.extraction_scene(ExtractConfig()), ExtractConfig())
    assert lock_holder(out) is None
    assert {name: (out / name).read_bytes() for name in written} == written


def test_refused_plans_say_why(small_box_scene, tmp_path):
    missing = plan_run(tmp_path / "nothing", small_box_scene, policy=CONTINUE)
    assert missing.state == REFUSED and "nothing to resume" in missing.reason
    (tmp_path / "theirs").mkdir()
    (tmp_path / "theirs" / "notes.txt").write_text("mine")
    theirs = plan_run(tmp_path / "theirs", small_box_scene, "preview", config(), REUSE)
    assert theirs.state == REFUSED and theirs.refused_path == tmp_path / "theirs"
    with pytest.raises(InputError, match="is not empty and is not an edgedog run folder"):
        theirs.check()


def test_an_interrupted_run_resumes_from_its_checkpoint_step(small_box_scene, finished, tmp_path):
    out = tmp_path / "run"
    plan = plan_run(out, small_box_scene, "preview", config(), REUSE)
    write_run(plan.run)
    scene = load_scene(small_box_scene, downscale=config().maps.downscale)
    trainer = Trainer(scene, config(), out, progress=False)
    while trainer.epoch < 1:  # the end of the first epoch saves a checkpoint
        trainer.step()
    resumed = plan_run(out, small_box_scene, "preview", config(), REUSE)
    assert resumed.state == RESUME and resumed.step == len(scene) and not resumed.extracted
    result = execute(resumed, progress=False)
    assert result.plan.state == RESUME and is_finished(out) and "counts" in result.report
    assert (out / "primitives.ply").read_bytes() == (finished / "primitives.ply").read_bytes()


def test_finished_means_one_thing(small_box_scene, tmp_path):
    """A log.json written mid-run (the speed bench's evaluations write one) is no finished run,
    for the benches, the demo, `train --resume`, layered runs and the studio alike."""
    out = tmp_path / "run"
    run = RunFolder(out, load_scene(small_box_scene).root, "preview", config())
    write_run(run)
    scene = load_scene(small_box_scene, downscale=run.config.maps.downscale)
    trainer = Trainer(scene, run.config, out, progress=False)
    while trainer.epoch < 1:
        trainer.step()
    trainer.write_outputs()
    assert (out / "log.json").is_file() and not is_finished(out)
    assert plan_run(out, small_box_scene, "preview", run.config, REUSE).state == RESUME
    assert plan_run(out, small_box_scene, policy=CONTINUE).state == RESUME
    from edgedog.app import saved_run

    assert saved_run.is_finished is run_object.is_finished is lifecycle.is_finished


def _primitives(out: Path) -> bytes:
    return (out / "primitives.ply").read_bytes()


def test_a_run_does_not_depend_on_what_ran_before_it_in_the_process(small_box_scene, tmp_path):
    """Two runs in one process, in either order and with the global generators disturbed, give
    the primitives of each run made alone in a fresh process."""
    fresh = {}
    for seed in (1, 2):
        fresh[seed] = tmp_path / f"fresh-{seed}"
        result = edgedog("train", small_box_scene, "--out", fresh[seed], "--preset", "preview", *CLI_SETTINGS,
                         "--set", f"seed={seed}", "--quiet")
        assert result.returncode == 0, result.stderr
    for order in ((1, 2), (2, 1)):
        for seed in order:
            torch.manual_seed(1000 + seed)
            np.random.seed(seed)
            torch.rand(17), np.random.rand(3)
            out = tmp_path / f"in-process-{order[0]}{order[1]}-{seed}"
            execute(plan_run(out, small_box_scene, "preview", config(seed=seed), START), progress=False)
            assert _primitives(out) == _primitives(fresh[seed]), (order, seed)
    assert _primitives(fresh[1]) != _primitives(fresh[2])
