"""The run object: a run of one layer and a layered run opened, trained, resumed, extracted and
closed through one API (`edgedog.train.run`)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from edgedog.errors import InputError
from edgedog.train import lifecycle
from edgedog.train.config import preset, with_settings
from edgedog.train.layered import REPORT as LAYERS_REPORT
from edgedog.train.levels import resolve_levels
from edgedog.train.lifecycle import CONTINUE, FINISHED, NEW, RESUME, START, is_finished, plan_run
from edgedog.train.run import open_run
from edgedog.train.run_folder import RUN_CONFIG, RunLock

LEVELS = resolve_levels(["L0", "L1"], ["L0=canny:150,300", "L1=canny:30,90"])
CONFIG = with_settings(preset("preview"), {"epochs": 2, "init.count": 300, "checkpoint_every": 1})


def plans(scene: Path, root: Path, policy: str = START) -> dict:
    """A run of one layer and a layered run of LEVELS, planned under `policy` in `root`."""
    return {"single": plan_run(root / "single", scene, "preview", CONFIG, policy),
            "layered": plan_run(root / "layered", scene, "preview", CONFIG, policy, LEVELS)}


def top_primitives(layers) -> bytes:
    """primitives.ply of the top layer: the whole model."""
    return (layers[-1].path / "primitives.ply").read_bytes()


@pytest.fixture(scope="module")
def trained(small_box_scene, tmp_path_factory) -> dict:
    """Both runs trained to their end with `Run.train` and extracted: name -> (result, layers)."""
    root = tmp_path_factory.mktemp("trained")
    done = {}
    for name, plan in plans(small_box_scene, root).items():
        with open_run(plan.check(), progress=False) as run:
            run.train()
            done[name] = (run.finish(), run.layers)
    return done


def test_one_api_for_a_stack_of_one_and_of_two(trained):
    single, layered = trained["single"], trained["layered"]
    assert [layer.path.name for layer in single[1]] == ["single"]
    assert [layer.path.name for layer in layered[1]] == ["L0", "L1"]
    for result, layers in (single, layered):
        assert result.plan.state == NEW and all(is_finished(layer.path) for layer in layers)
        assert result.log["history"]
        RunLock.acquire(result.plan.run.path).release()  # closed: the lock is free
    assert "counts" in single[0].report
    assert set(layered[0].report["selections"]) == {"L0", "L1", "L0+L1"}
    assert (layered[0].plan.run.path / LAYERS_REPORT).is_file()
    assert layered[0].log["config"]["layers"]["layer"] == 1 and layered[0].log["lower_primitives"] > 0


def test_stepping_gives_what_training_gives(trained, small_box_scene, tmp_path):
    """`Run.step` across the layers (the next layer built when the one below ends) and
    `Run.train(until=...)` reach the same primitives as `Run.train`."""
    for name, plan in plans(small_box_scene, tmp_path).items():
        with open_run(plan.check(), progress=False) as run:
            run.train(until=1)
            first = run.current()
            assert first.epoch == 1 and first.config.layers.layer == 0 and not first.done
            steps = 0
            while not run.done:
                run.step()
                steps += 1
            assert steps > 0 and run.trainer.config.layers.layer == len(run.layers) - 1
            with pytest.raises(ValueError, match="every layer is trained"):
                run.step()
            run.finish()
        assert top_primitives(run.layers) == top_primitives(trained[name][1]), name


def test_an_interrupted_layered_run_resumes_to_the_uninterrupted_result(trained, small_box_scene, tmp_path):
    """A layered run left in L1 after its first checkpoint (as a kill leaves it), continued
    with CONTINUE, ends with the primitives of the run trained in one go."""
    plan = plans(small_box_scene, tmp_path)["layered"]
    with open_run(plan.check(), progress=False) as run:
        run.train(until=1)
        assert run.current().config.layers.layer == 0
        while run.current().config.layers.layer == 0 or run.current().epoch < 1:
            run.step()
    resumed = plan_run(plan.run.path, small_box_scene, policy=CONTINUE)
    assert resumed.state == RESUME and resumed.step > 0 and resumed.run == plan.run
    announced = []
    with open_run(resumed.check(), progress=False) as run:
        run.train(on_trainer=announced.append)
        result = run.finish()
    assert [trainer.config.layers.layer for trainer in announced] == [1]  # L0 is reused
    assert result.plan.state == RESUME and "L0+L1" in result.report["selections"]
    assert top_primitives(run.layers) == top_primitives(trained["layered"][1])


def test_finished_runs_are_reused_or_continued_alike(trained, small_box_scene):
    for name, (result, layers) in trained.items():
        path = result.plan.run.path
        stamp = (layers[-1].path / "checkpoint.pt").stat().st_mtime_ns
        levels = () if name == "single" else LEVELS
        reused = plan_run(path, small_box_scene, "preview", CONFIG, lifecycle.REUSE, levels)
        assert reused.state == FINISHED and reused.extracted, name
        with open_run(reused, progress=False) as run:
            run.train()
            again = run.finish()
        assert not run.trained and again.report == json.loads(json.dumps(result.report)), name
        continued = plan_run(path, small_box_scene, policy=CONTINUE)
        assert continued.state == FINISHED and continued.run == result.plan.run, name
        with open_run(continued, progress=False) as run:
            run.train()
            run.finish()
        assert run.trained and (layers[-1].path / "checkpoint.pt").stat().st_mtime_ns == stamp, name


def test_the_plan_carries_its_scene(small_box_scene, tmp_path, monkeypatch):
    plan = plans(small_box_scene, tmp_path)["layered"].check()

    def reload(*args):
        raise AssertionError("the scene was loaded again")

    monkeypatch.setattr(lifecycle, "load_run_scene", reload)
    monkeypatch.setattr("edgedog.train.run.load_run_scene", reload)
    with open_run(plan, progress=False) as run:
        assert run.scene is plan.scene


def test_a_new_run_closed_before_its_first_checkpoint_leaves_nothing(small_box_scene, tmp_path):
    for name, plan in plans(small_box_scene, tmp_path).items():
        with open_run(plan.check(), progress=False) as run:
            assert (plan.run.path / (RUN_CONFIG if name == "single" else "layers.json")).is_file()
            with pytest.raises(InputError, match="in use by another edgedog process"):
                RunLock.acquire(plan.run.path)
            run.current()  # the first layer's trainer set up, nothing trained
        assert not plan.run.path.exists(), name
