"""The studio: its training thread, session, inspectors, curve export, scripted driver, and the
window itself under a virtual X server."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from edgedog.app.extraction import export_path, extract_snapshot
from edgedog.app.inspection import inspect_view, snapshot_primitives
from edgedog.app.script import ScriptDriver, assign, matches
from edgedog.app.session import Session
from edgedog.app.state import Display, UIState
from edgedog.app.view3d import View3D
from edgedog.app.worker import (
    FAILED,
    FINISHED,
    LIVE_EVENT,
    PAUSED,
    STOPPED,
    TRAINING,
    Published,
    TrainingWorker,
)
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.gl.context import GLUnavailableError, offscreen_context
from edgedog.renderer.primitives import RasterCamera
from edgedog.renderer.rasterize import rasterize

from edgedog.builtin.scene import BOX_MAX, BOX_MIN, ground_truth_points, write_box_scene
from edgedog.curve_files import read_edges
from edgedog.errors import InputError
from edgedog.scenes import load_scene
from edgedog.train import losses
from edgedog.train.config import preset, with_settings
from edgedog.train.run_folder import RUN_CONFIG, RunLock, read_run
from edgedog.train.trainer import CHECKPOINT, Controls, Snapshot, Trainer


def wait_for(condition, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


@pytest.fixture(scope="module")
def small_box(tmp_path_factory) -> Path:
    """The exact box at 8 views of 96 px: a few seconds of training show something."""
    return write_box_scene(tmp_path_factory.mktemp("studio") / "box", views=8, size=96)


BOX_CENTRE = (BOX_MIN + BOX_MAX) / 2


def small_config(**changes):
    return with_settings(preset("preview"), {"init.count": 300, **changes})


# --- the training thread, with a stand-in trainer --------------------------------------------

class BoundaryControls(Controls):
    """Controls that fail the test if changed while a step runs."""

    def __init__(self, trainer, *args):
        super().__init__(*args)
        self.trainer = trainer

    def update(self, **changes) -> None:
        assert not self.trainer.in_step, "controls changed during a step"
        super().update(**changes)


class FakeTrainer:
    """What the worker drives: steps that take `step_seconds` and record the controls they read."""

    def __init__(self, steps: int = 10_000, step_seconds: float = 0.002, fail_at: int | None = None):
        self.config = with_settings(preset("preview"), {"epochs": steps})
        self.controls = BoundaryControls(self, 0.9, "exp")
        self.step_seconds, self.fail_at = step_seconds, fail_at
        self.step_index, self.in_step, self.seen, self.outputs, self.events = 0, False, [], 0, []
        self.detector, self.raster, self.out, self.cameras = "exact", RasterConfig(), Path("run"), [None]

    @property
    def done(self) -> bool:
        return self.step_index >= self.config.schedule.epochs

    @property
    def epoch(self) -> int:
        return self.step_index

    def step(self) -> None:
        self.in_step = True
        self.seen.append(self.controls.read()[:2])
        time.sleep(self.step_seconds)
        if self.step_index == self.fail_at:
            raise RuntimeError("the loss is NaN")
        self.step_index += 1
        self.in_step = False

    @property
    def last_loss(self) -> float:
        return 1.0 / self.step_index

    def snapshot(self, loss: float = float("nan")) -> Snapshot:
        n = 4
        return Snapshot(self.step_index, self.step_index, loss, np.zeros((n, 3)), np.ones((n, 3)),
                        np.tile([1.0, 0, 0, 0], (n, 1)), np.ones(n), np.zeros((n, 2)), np.zeros((0, 3)))

    def write_outputs(self) -> None:
        self.outputs += 1


def test_the_worker_publishes_snapshots_and_a_series():
    trainer = FakeTrainer()
    worker = TrainingWorker(lambda: iter([trainer]), run=3, publish_every=0.02)
    worker.start()
    wait_for(lambda: worker.latest is not None and worker.latest.version >= 4)
    first = worker.latest
    wait_for(lambda: worker.latest.version > first.version)
    assert worker.stop()
    latest = worker.latest
    assert latest.key == (3, latest.version) and latest.snapshot.step > first.snapshot.step
    assert worker.info.detector == "exact" and worker.info.epochs == 10_000
    series = worker.series()
    assert series.shape[1] == 3 and len(series) >= 3 and np.all(np.diff(series[:, 0]) > 0)
    assert worker.steps == trainer.step_index and worker.steps_per_second > 0


def test_control_changes_apply_between_steps():
    trainer = FakeTrainer()
    worker = TrainingWorker(lambda: iter([trainer]))
    worker.start()
    wait_for(lambda: trainer.step_index > 5)
    worker.update_controls(keep_ratio=0.6, weighting="one_minus")
    wait_for(lambda: ("one_minus" in [w for _, w in trainer.seen]))
    seen = list(trainer.seen)
    switch = seen.index((0.6, "one_minus"))
    # Every step before the switch saw the old settings, every one after it the new ones.
    assert set(seen[:switch]) == {(0.9, "exp")} and set(seen[switch:]) == {(0.6, "one_minus")}
    assert worker.trainer_controls() == {"keep_ratio": 0.6, "weighting": "one_minus", "paused": False}
    # The live change is one of the run's events (log.json), at the step it applied from.
    (event,) = trainer.events
    assert event == {"event": LIVE_EVENT, "epoch": switch, "step": switch, "keep_ratio": 0.6,
                     "weighting": "one_minus"}
    worker.update_controls(paused=True)
    wait_for(lambda: worker.phase == PAUSED)
    paused_at = trainer.step_index
    time.sleep(0.1)
    assert trainer.step_index == paused_at
    worker.update_controls(paused=False)
    wait_for(lambda: trainer.step_index > paused_at and worker.phase == TRAINING)
    assert worker.stop()


def test_a_trainer_exception_is_kept_for_the_window():
    worker = TrainingWorker(lambda: iter([FakeTrainer(fail_at=7)]))
    worker.start()
    wait_for(lambda: not worker.alive)
    assert worker.phase == FAILED
    assert worker.error == "RuntimeError: the loss is NaN"
    assert "in step" in worker.traceback and worker.latest is not None


def test_a_failing_set_up_is_kept_too():
    def broken():
        raise FileNotFoundError("no edge maps")
        yield

    worker = TrainingWorker(broken)
    worker.start()
    wait_for(lambda: not worker.alive)
    assert worker.phase == FAILED and worker.error == "FileNotFoundError: no edge maps"
    assert worker.latest is None and worker.trainer_controls() is None


def test_stop_ends_the_thread_within_a_second_without_writing_outputs():
    trainer = FakeTrainer(step_seconds=0.2)
    worker = TrainingWorker(lambda: iter([trainer]))
    worker.start()
    wait_for(lambda: trainer.step_index >= 1)
    started = time.perf_counter()
    assert worker.stop(timeout=1.0)
    assert time.perf_counter() - started < 1.0
    assert worker.phase == STOPPED and trainer.outputs == 0 and not trainer.in_step


def test_a_finished_run_writes_its_outputs_once_then_finishes():
    trainer = FakeTrainer(steps=20)
    finished = []
    worker = TrainingWorker(lambda: iter([trainer]), finish=finished.append)
    worker.start()
    wait_for(lambda: not worker.alive)
    assert worker.phase == FINISHED and trainer.outputs == 1 and finished == [trainer]
    assert worker.latest.snapshot.step == 20  # the final state is always published


def test_the_trainers_of_a_layered_run_train_one_after_the_other():
    layers = [FakeTrainer(steps=5), FakeTrainer(steps=7)]
    worker = TrainingWorker(lambda: iter(layers))
    worker.start()
    wait_for(lambda: not worker.alive)
    assert worker.phase == FINISHED and [t.outputs for t in layers] == [1, 1]
    assert worker.steps == 12 and worker.latest.snapshot.step == 7


# --- the real trainer in the worker ----------------------------------------------------------

def test_stopping_a_real_run_keeps_a_checkpoint_it_resumes_from(small_box, tmp_path):
    config = small_config(epochs=1000, checkpoint_every=2)
    scene = load_scene(small_box, downscale=config.maps.downscale)
    worker = TrainingWorker(lambda: iter([Trainer(scene, config, tmp_path, progress=False)]))
    worker.start()
    wait_for(lambda: (tmp_path / CHECKPOINT).is_file() and worker.steps > 40, timeout=30)
    assert worker.stop(1.0)
    resumed = Trainer(scene, config, tmp_path, progress=False)
    assert resumed.step_index > 0 and resumed.step_index % (2 * len(scene)) == 0
    assert not (tmp_path / "log.json").exists()  # outputs are written only by a finished run


# --- session ---------------------------------------------------------------------------------

def test_a_finished_run_has_the_files_of_edgedog_train_and_reopens_as_it_ended(small_box, tmp_path):
    session = Session.open(small_box, tmp_path / "runs", "preview", ["init_count=200", "epochs=2"])
    assert session.config.init.count == 200 and session.ground_truth.shape[1] == 3
    worker = session.start("preview", session.config)
    wait_for(lambda: not worker.alive, timeout=60)
    assert worker.phase == FINISHED, worker.error
    first = session.run_dir
    assert read_run(first).config == session.config
    for name in ("log.json", "primitives.ply", "points.ply", "curves.json", "curves.obj", "extract.json"):
        assert (first / name).is_file(), name
    report = json.loads((first / "extract.json").read_text())
    assert "metrics" in report and "ground_truth" in report  # the box has ground truth: scored
    assert session.stop(None)
    RunLock.acquire(first).release()  # the finished run's lock was released
    reopened = Session.open(first)
    saved = reopened.saved
    assert not reopened.resumable and reopened.worker is saved and reopened.run_dir == first
    log = json.loads((first / "log.json").read_text())
    assert len(saved.latest.snapshot.means) == log["final_primitives"] and saved.latest.snapshot.loss > 0
    assert saved.series().shape == (2, 3) and saved.steps == 2 * 8
    assert saved.extraction.curves.num_curves == read_edges(first / "curves.json").num_curves
    assert saved.extraction.counts == report["counts"]
    reopened.start("preview", reopened.config)  # a finished run is never trained again: a new folder
    assert reopened.run_dir != first and reopened.stop(None)


def test_a_stopped_run_resumes_in_its_folder_which_it_locks(small_box, tmp_path):
    session = Session.open(small_box, tmp_path / "runs", "preview",
                           ["init_count=200", "epochs=1000", "checkpoint_every=1"])
    worker = session.start("preview", session.config)
    folder = session.run_dir
    with pytest.raises(InputError, match="in use by another edgedog process"):
        RunLock.acquire(folder)  # held from the start
    wait_for(lambda: (folder / CHECKPOINT).is_file(), timeout=60)
    assert session.stop(None) and worker.phase == STOPPED
    RunLock.acquire(folder).release()  # released once the worker ended
    reopened = Session.open(folder)
    assert reopened.resumable and reopened.runs_root == folder.parent
    assert reopened.config == session.config and reopened.preset == "preview"
    # Shown at its last checkpoint, with the history the checkpoint stores.
    saved, checkpoint = reopened.saved, torch.load(folder / CHECKPOINT, weights_only=True)
    assert reopened.worker is saved and saved.phase == STOPPED and reopened.run_dir == folder
    assert saved.latest.snapshot.step == checkpoint["step_index"] == saved.steps
    assert len(saved.latest.snapshot.means) == checkpoint["model"]["means"].shape[0]
    history = saved.series()
    assert len(history) == len(checkpoint["history"]) > 0 and saved.latest.elapsed == checkpoint["seconds"]
    with RunLock.acquire(folder):
        with pytest.raises(InputError, match="in use"):
            reopened.start("preview", reopened.config)  # another process trains into it
    resumed = reopened.start("preview", reopened.config)
    assert resumed.latest.snapshot is saved.latest.snapshot  # shown until the first publication
    wait_for(lambda: resumed.info is not None and len(resumed.series()) > len(history), timeout=30)
    assert reopened.run_dir == folder and resumed.info.resumed_at_step == checkpoint["step_index"]
    series = resumed.series()  # the plots go on from the checkpoint's history
    assert (series[:len(history)] == history).all() and series[len(history):, 0].min() > history[-1, 0]
    reopened.start("preview", reopened.config, fresh=True)
    assert reopened.run_dir != folder and reopened.stop(None)


def test_a_start_stopped_before_its_first_checkpoint_leaves_no_folder(small_box, tmp_path):
    session = Session.open(small_box, tmp_path / "runs", "preview", ["init_count=200"])
    session.start("preview", session.config)
    folder = session.run_dir
    assert (folder / RUN_CONFIG).is_file()
    assert session.stop(None)
    assert not folder.exists()


def test_a_run_folder_with_a_bad_config_is_one_error(tmp_path):
    (tmp_path / RUN_CONFIG).write_text("[]")
    with pytest.raises(Exception, match="expected 'scene' and 'config'"):
        Session.open(tmp_path)


def test_restart_settings_make_the_config_and_live_ones_go_with_it():
    state = UIState.for_config("preview", preset("preview"))
    state.restart.kernel, state.restart.epochs, state.restart.k_init = "gaussian", 7, (0.5, -0.5)
    state.live.keep_ratio, state.live.weighting = 0.6, "up"
    config = state.restart.apply(preset("preview"), state.live)
    assert (config.model.kernel, config.schedule.epochs, config.init.k, config.strategy.keep_ratio,
            config.loss.weighting) == ("gaussian", 7, (0.5, -0.5), 0.6, "up")


# --- inspectors and curves -------------------------------------------------------------------

def test_inspectors_are_the_trainers_own_maps(small_box, tmp_path):
    scene = load_scene(small_box, downscale=2)
    trainer = Trainer(scene, small_config(), tmp_path, progress=False)
    snapshot = trainer.snapshot()
    panels = inspect_view(snapshot, scene, 3, trainer.detector, trainer.raster, "one_minus", True)
    assert [p.name for p in panels] == ["image", "edge map", "render", "depth", "U", "w = 1 - U"]
    assert all(p.rgba.shape == (48, 48, 4) and p.rgba.dtype == np.uint8 for p in panels)
    with torch.no_grad():
        out = rasterize(trainer.model.primitives(), trainer.cameras[3], trainer.raster)
    expected_up = losses.depth_uncertainty(out.depth)
    assert panels[3].hi == pytest.approx(float(out.depth.max()), rel=1e-4)
    assert panels[5].lo == pytest.approx(float(1 - expected_up.max()), abs=1e-4)
    assert inspect_view(None, scene, 3, None, None, "exp", True)[0].name == "image"


def test_snapshot_primitives_round_trip_the_activations(small_box, tmp_path):
    scene = load_scene(small_box, downscale=2)
    trainer = Trainer(scene, small_config(), tmp_path, progress=False)
    prims = snapshot_primitives(trainer.snapshot())
    camera = RasterCamera.from_camera(scene.camera(0))
    with torch.no_grad():
        mine = rasterize(prims, camera, trainer.raster).image
        theirs = rasterize(trainer.model.primitives(), camera, trainer.raster).image
    torch.testing.assert_close(mine, theirs, atol=1e-5, rtol=1e-4)


def test_curves_of_a_snapshot_on_the_true_edges_score_and_export(small_box, tmp_path):
    scene = load_scene(small_box)
    points = ground_truth_points()
    n = len(points)
    snapshot = Snapshot(1234, 5, 0.0, points, np.full((n, 3), 0.004), np.tile([1.0, 0, 0, 0], (n, 1)),
                        np.full(n, 0.9), np.zeros((n, 2)), np.zeros((0, 3)))
    result = extract_snapshot(snapshot, 12.5, scene, "exact", tmp_path, ["obj", "json", "ply"])
    assert len(result.curves.lines) >= 12 and result.fscore[10] > 90
    assert result.written == tuple(export_path(tmp_path, 1234, fmt) for fmt in ("obj", "json", "ply"))
    for path in result.written:
        assert read_edges(path).num_curves == result.curves.num_curves


# --- the 3D view (offscreen) ----------------------------------------------------------------

@pytest.fixture
def view3d():
    try:
        ctx = offscreen_context()
    except GLUnavailableError as error:
        pytest.skip(f"no headless OpenGL: {error}")
    view = View3D(ctx, 160, 120)
    yield view
    view.release()
    ctx.release()


def test_the_view_frames_the_scene_and_follows_layers_and_colours(small_box, tmp_path, view3d):
    scene = load_scene(small_box, downscale=2)
    session = Session.open(small_box, tmp_path)
    view3d.set_scene(scene.cameras, scene.bounds, session.ground_truth)
    np.testing.assert_allclose(view3d.centre, BOX_CENTRE, atol=0.05)  # where the orbit looks
    trainer = Trainer(scene, small_config(), tmp_path / "run", progress=False)
    published = Published(1, 1, trainer.snapshot(), 0.0)
    display = Display()
    view3d.sync(published, trainer.raster, display, 0, None)
    assert view3d.render() and view3d.drawn == len(published.snapshot.means)
    assert not view3d.render()  # nothing changed: nothing re-drawn
    assert view3d.target.read()[..., :3].max() > 0
    display.layers["L0"] = False
    view3d.sync(published, trainer.raster, display, 0, None)
    assert view3d.render() and view3d.drawn == 0
    display.layers["L0"], display.color_by = True, "DoG t"
    view3d.sync(published, trainer.raster, display, 0, None)
    assert view3d.color_range == pytest.approx((0.5, 0.5))  # k = 0 everywhere: t = 1/2
    view3d.snap(2)
    np.testing.assert_allclose(view3d.camera.camera().R, scene.camera(2).R)
    assert view3d.render(every=0.0)
    view3d.orbit(5.0, 0.0)  # the view's own rate: not again within `every` seconds of a render
    assert not view3d.render(every=60.0) and view3d.render(every=0.0)


# --- the scripted driver ---------------------------------------------------------------------

def test_expectations_and_assignments():
    assert matches(0.7000000001, 0.7) and not matches(0.71, 0.7) and matches("up", "up")
    assert matches(3, [">", 2]) and not matches(None, [">", 2]) and matches(0, ["<=", 0])
    state = UIState.for_config("preview", preset("preview"))
    assign(state, "live.keep_ratio", 0.5)
    assign(state, "display.layers.L0", False)
    assert state.live.keep_ratio == 0.5 and state.display.layers == {"L0": False}
    with pytest.raises(AttributeError):
        assign(state, "live.nonsense", 1)


def test_a_missed_expectation_fails_the_script_and_closes():
    clock = iter(range(100)).__next__
    studio = type("Studio", (), {})()
    studio.state = UIState.for_config("preview", preset("preview"))
    studio.probe = lambda: {"phase": "starting"}
    driver = ScriptDriver({"actions": [{"expect": {"phase": "training"}, "timeout": 3}]}, clock=clock)
    for _ in range(5):
        driver.tick(studio)
    assert driver.failure and "expected {'phase': 'training'}" in driver.failure
    assert [r.name for r in studio.state.take_requests()] == ["close"]


# --- the window ------------------------------------------------------------------------------

def studio(*args, env=None, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "edgedog", "studio", *map(str, args)], env=env, cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def test_without_a_display_the_error_is_one_line(small_box):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = studio(small_box, env=env)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "edgedog train SCENE --out RUN" in result.stderr


@pytest.mark.xvfb
@pytest.mark.slow
def test_the_window_trains_follows_the_ui_exports_and_closes(small_box, xvfb_display, tmp_path):
    shot = tmp_path / "studio.png"
    actions = [
        {"request": "start"},
        {"expect": {"phase": "training", "version": [">=", 3]}, "timeout": 60},
        {"wait": 2},
        {"set": {"live.keep_ratio": 0.7, "live.weighting": "one_minus"}},
        {"expect": {"controls.keep_ratio": 0.7, "controls.weighting": "one_minus"}, "timeout": 5},
        {"expect": {"splats_drawn": [">", 0], "inspectors": 6}, "timeout": 10},
        {"set": {"display.layers.L0": False}},
        {"expect": {"splats_drawn": 0}, "timeout": 5},
        {"set": {"display.layers.L0": True}},
        {"expect": {"splats_drawn": [">", 0]}, "timeout": 5},
        {"request": "export", "format": "obj"},
        {"expect": {"extracting": False}, "timeout": 60},
        {"request": "screenshot", "path": str(shot)},
        {"request": "close"},
    ]
    report = tmp_path / "report.json"
    (tmp_path / "script.json").write_text(json.dumps({"report": str(report), "actions": actions}))
    env = {**os.environ, "DISPLAY": xvfb_display}
    result = studio(small_box, "--runs", tmp_path / "runs", "--script", tmp_path / "script.json",
                    "--preset", "preview", "--set", "epochs=5000", "--set", "init_count=300",
                    "--set", "checkpoint_every=10", "--set", "fisher_every=100",
                    "--size", "1280x800", env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    outcome = json.loads(report.read_text())
    assert outcome["ok"], outcome["failure"]
    probe = outcome["probe"]
    assert probe["phase"] == "stopped" and probe["error"] is None  # closed mid-training
    assert outcome["stop_seconds"] < 1.0
    if probe["curves"]:  # an export of no curves writes nothing and says so
        exported = Path(probe["export_paths"][0])
        assert exported.suffix == ".obj" and exported.parent == Path(probe["run_dir"]) / "exports"
        assert read_edges(exported).num_curves == probe["curves"]
    else:
        assert probe["status"].endswith("nothing exported (obj): no curves in this snapshot")
    image = cv2.imread(str(shot))
    assert image.shape == (800, 1280, 3) and image.std() > 10
    # The checkpoint left behind is whole: a new trainer resumes from it.
    run = read_run(Path(probe["run_dir"]))
    resumed = Trainer(load_scene(run.scene, downscale=run.config.maps.downscale), run.config, run.path,
                      progress=False)
    assert resumed.step_index > 0
