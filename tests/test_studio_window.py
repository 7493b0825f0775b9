"""The studio window under a virtual X server, driven by scripts (edgedog.app.script) whose clicks,
drags and keys go through imgui's input queue as a mouse's and keyboard's do: the crashes and
dead controls of issue 29 stay fixed, and the window works at its smallest sizes."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import pytest

from edgedog.builtin.scene import write_box_scene

pytestmark = pytest.mark.xvfb

FAST = ["--set", "init_count=300", "--set", "checkpoint_every=1"]
"""Settings of the scripted runs: few primitives, a checkpoint every epoch."""
OPEN_QUESTION = "Stop this run and open {}? It keeps its last checkpoint."
STATUS_PIXELS = 40
"""The status line's height at the bottom of a screenshot, and then some."""


@pytest.fixture(scope="module")
def box(tmp_path_factory) -> Path:
    """The exact box at 8 views of 96 px: set up in a fraction of a second."""
    return write_box_scene(tmp_path_factory.mktemp("window") / "box", views=8, size=96)


def run_script(actions: list[dict], args: list, display: str, folder: Path, size: str = "1280x800"
               ) -> tuple[subprocess.CompletedProcess, dict]:
    """Run `edgedog studio ARGS` with the script; returns the process and its report."""
    report, script = folder / "report.json", folder / "script.json"
    script.write_text(json.dumps({"report": str(report), "actions": actions}))
    result = subprocess.run([sys.executable, "-m", "edgedog", "studio", *map(str, args), "--script", script,
                             "--size", size], env={**os.environ, "DISPLAY": display}, cwd=folder,
                            capture_output=True, text=True, timeout=180)
    outcome = json.loads(report.read_text()) if report.is_file() else {}
    return result, outcome


@pytest.fixture
def window_manager(xvfb_display) -> str:
    """The display with openbox managing its windows, so that xdotool's keys reach the focused
    window as a keyboard's do (skipped without openbox or xdotool)."""
    if shutil.which("openbox") is None or shutil.which("xdotool") is None:
        pytest.skip("openbox and xdotool are not installed")
    manager = subprocess.Popen(["openbox"], env={**os.environ, "DISPLAY": xvfb_display},
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield xvfb_display
    finally:
        manager.terminate()
        manager.wait()


def run_driven(actions: list[dict], args: list, display: str, folder: Path,
               drive: Callable[[str, dict, subprocess.Popen], None]
               ) -> tuple[subprocess.CompletedProcess, dict]:
    """As `run_script`, while `drive(window, env, studio)` gives the activated window real input
    (xdotool with `env`'s display). The script's expectations follow what the input does."""
    report, script = folder / "report.json", folder / "script.json"
    script.write_text(json.dumps({"report": str(report), "actions": actions}))
    env = {**os.environ, "DISPLAY": display}
    studio = subprocess.Popen([sys.executable, "-m", "edgedog", "studio", *map(str, args), "--script", script,
                               "--size", "1280x800"], env=env, cwd=folder, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    try:
        found = subprocess.run(["xdotool", "search", "--sync", "--name", "EdgeDoG Studio"], env=env,
                               capture_output=True, text=True, timeout=120)
        window = found.stdout.split()[0]
        subprocess.run(["xdotool", "windowactivate", "--sync", window], env=env, timeout=30)
        drive(window, env, studio)
        out, err = studio.communicate(timeout=180)
    finally:
        if studio.poll() is None:
            studio.kill()
            studio.wait()
    outcome = json.loads(report.read_text()) if report.is_file() else {}
    return subprocess.CompletedProcess(studio.args, studio.returncode, out, err), outcome


def run_with_keys(actions: list[dict], keys: list[str | float | Path], args: list, display: str, folder: Path
                  ) -> tuple[subprocess.CompletedProcess, dict]:
    """`run_driven` with xdotool typing `keys`: a key name (X's, e.g. "F1", "Escape", "ctrl+o"),
    seconds to wait, or a file to wait for (one the script writes with "save_rects" once the
    studio is ready for the keys that follow)."""
    def type_keys(window: str, env: dict, studio: subprocess.Popen) -> None:
        for key in keys:
            if isinstance(key, (int, float)):
                time.sleep(key)
            elif isinstance(key, Path):
                deadline = time.monotonic() + 120
                while not key.is_file() and studio.poll() is None and time.monotonic() < deadline:
                    time.sleep(0.1)
            elif studio.poll() is None:
                subprocess.run(["xdotool", "key", "--clearmodifiers", key], env=env, timeout=30)

    return run_driven(actions, args, display, folder, type_keys)


def assert_ok(result: subprocess.CompletedProcess, outcome: dict) -> dict:
    """The script ran to its end and the studio exited 0; returns the final probes."""
    assert result.returncode == 0, result.stderr[-3000:]
    assert outcome["ok"], outcome["failure"]
    return outcome["probe"]


def test_hiding_every_layer_under_each_colouring_keeps_the_window(box, xvfb_display, tmp_path):
    actions = [{"request": "start"}, {"expect": {"splats_drawn": [">", 0]}, "timeout": 60}]
    for mode in ("opacity", "DoG a", "DoG t"):
        actions += [{"set": {"display.color_by": mode, "display.layers.L0": False}},
                    {"expect": {"splats_drawn": 0}, "timeout": 5},
                    {"set": {"display.layers.L0": True}},
                    {"expect": {"splats_drawn": [">", 0]}, "timeout": 5}]
    result, outcome = run_script([*actions, {"request": "close"}], [box, "--runs", tmp_path / "runs", *FAST],
                                 xvfb_display, tmp_path)
    assert_ok(result, outcome)


def test_the_first_launch_makes_the_builtin_scene_and_opens(xvfb_display, tmp_path):
    # The scene is rendered through EGL in this process before GLFW's GLX window opens.
    result, outcome = run_script([{"expect": {"inspectors": 2}, "timeout": 30}, {"request": "close"}],
                                 ["--cache", tmp_path / "cache"], xvfb_display, tmp_path)
    assert "BadAccess" not in result.stderr
    probe = assert_ok(result, outcome)
    assert probe["title"].startswith("boss-canny - no run")


def test_closing_during_the_set_up_exits_cleanly_and_leaves_no_folder(builtin_scene_dir, xvfb_display,
                                                                     tmp_path):
    # 50 views of 400 px: the trainer's set-up (COLMAP features for the initial points) is under way.
    actions = [{"request": "start"}, {"wait": 0.3}, {"request": "close"}]
    result, outcome = run_script(actions, [builtin_scene_dir, "--runs", tmp_path / "runs"], xvfb_display,
                                 tmp_path)
    probe = assert_ok(result, outcome)
    assert probe["phase"] == "stopped" and probe["runs"] == 1
    assert not list((tmp_path / "runs").iterdir())  # the aborted start left nothing


def test_the_mouse_and_the_keys_drive_the_view_the_run_and_the_panels(box, xvfb_display, tmp_path):
    actions = [
        {"expect": {"view_at_home": True, "inspectors": 2}, "timeout": 20},
        {"drag": "3D view", "by": [150, 60]},
        {"expect": {"view_at_home": False}, "timeout": 5},
        {"click": "reset view"},
        {"expect": {"view_at_home": True}, "timeout": 5},
        {"drag": "3D view", "by": [-80, 30]},
        {"expect": {"view_at_home": False}, "timeout": 5},
        {"key": "r"},
        {"expect": {"view_at_home": True}, "timeout": 5},
        {"key": "3"},
        {"expect": {"view_index": 2, "view_at_home": False}, "timeout": 5},
        {"key": "space"},
        {"expect": {"phase": "training"}, "timeout": 60},
        {"key": "space"},
        {"expect": {"phase": "paused"}, "timeout": 5},
        {"key": "space"},
        {"expect": {"phase": "training"}, "timeout": 5},
        {"key": "f1"},
        {"expect": {"help": True}, "timeout": 5},
        {"key": "escape"},
        {"expect": {"help": False}, "timeout": 5},
        {"click": "Open..."},
        {"expect": {"dialog": str(box.parent)}, "timeout": 5},
        {"click": "Open"},  # the browser starts on the open scene's folder, the scene selected
        {"expect": {"dialog": None, "confirm": OPEN_QUESTION.format(box)}, "timeout": 10},
        {"key": "enter"},
        {"expect": {"confirm": None, "runs": 0, "status": f"opened {box}"}, "timeout": 10},
        {"key": "ctrl+o"},
        {"expect": {"dialog": str(box.parent)}, "timeout": 5},
        {"key": "escape"},
        {"expect": {"dialog": None}, "timeout": 5},
        {"key": "q"},
    ]
    result, outcome = run_script(actions, [box, "--runs", tmp_path / "runs", *FAST], xvfb_display, tmp_path)
    probe = assert_ok(result, outcome)
    assert probe["title"] == "box - no run - EdgeDoG Studio"  # the scene opened again: no run yet


def test_at_800x600_the_3d_view_keeps_a_third_of_the_width(box, xvfb_display, tmp_path):
    shot = tmp_path / "small.png"
    actions = [{"expect": {"inspectors": 2}, "timeout": 20}, {"wait": 0.5},
               {"request": "screenshot", "path": str(shot)}, {"request": "close"}]
    assert_ok(*run_script(actions, [box], xvfb_display, tmp_path, size="800x600"))
    image = cv2.imread(str(shot))
    assert image.shape == (600, 800, 3)
    # The view is the only black area (the panels are grey): columns black over most of its rows.
    band = image[60:300]
    view_columns = ((band.max(axis=2) == 0).mean(axis=0) > 0.5).sum()
    assert view_columns >= 800 / 3


def test_a_finished_run_opens_with_its_model_history_and_curves(box, xvfb_display, tmp_path):
    train = subprocess.run([sys.executable, "-m", "edgedog", "train", box, "--out", tmp_path / "run",
                            "--preset", "preview", "--set", "epochs=3", "--set", "init_count=300", "--quiet"],
                           capture_output=True, text=True, timeout=120)
    assert train.returncode == 0, train.stderr[-2000:]
    actions = [{"expect": {"phase": "finished", "splats_drawn": [">", 0], "series": 3, "curves": [">=", 0],
                           "steps": 3 * 8, "loss": [">", 0]}, "timeout": 20},
               {"request": "close"}]
    probe = assert_ok(*run_script(actions, [tmp_path / "run"], xvfb_display, tmp_path))
    assert probe["runs"] == 0 and probe["title"] == "box - run - EdgeDoG Studio"
    assert not (tmp_path / "run" / "exports").exists()  # opening wrote nothing


def interrupted_run(scene: Path, out: Path, layers: int = 1, epochs: int = 3, stop_at: int = 2) -> Path:
    """A run of `layers` layers of `epochs` epochs each (preview, 300 primitives, a checkpoint an
    epoch) stopped as a closed window stops one: its lower layers finished, its top layer at the
    checkpoint of epoch `stop_at`."""
    from edgedog.train.config import preset, with_overrides
    from edgedog.train.layers import layer_name
    from edgedog.train.levels import resolve_levels
    from edgedog.train.lifecycle import START, is_finished, load_run_scene, plan_run
    from edgedog.train.run import open_run

    config = with_overrides(preset("preview"), [f"epochs={epochs}", "init_count=300", "checkpoint_every=1"])
    levels = resolve_levels([layer_name(i) for i in range(layers)]) if layers > 1 else ()
    plan = plan_run(out, load_run_scene(scene, config), "preview", config, START, levels)
    with open_run(plan.check(), progress=False) as run:
        while not all(is_finished(layer.path) for layer in run.layers[:-1]) or run.current().epoch < stop_at:
            run.step()
    return out


@pytest.mark.parametrize("layers", [1, 2])
def test_an_interrupted_run_opens_at_its_checkpoint_and_resume_continues_its_plots(box, layers, xvfb_display,
                                                                                   tmp_path):
    # Issue 40, defect 4: an interrupted run opened as "no run", 0 splats and empty plots (a layered
    # run hid its finished L0) until Resume, and Resume started the plots empty.
    run = interrupted_run(box, tmp_path / "run", layers)
    names = [f"L{i}" for i in range(layers)]
    epochs = 3 * (layers - 1) + 2  # the finished layers' and the checkpoint's
    actions = [{"expect": {"phase": "stopped", "title": "box - run - EdgeDoG Studio", "layers": names,
                           "splats_drawn": [">", 0], "series": epochs, "loss": [">", 0],
                           "inspectors": 6}, "timeout": 30},
               {"mark": "opened"},
               {"request": "start"},
               {"expect": {"phase": "finished", "series": [">", epochs]}, "timeout": 120},
               {"request": "close"}]
    result, outcome = run_script(actions, [run], xvfb_display, tmp_path)
    probe = assert_ok(result, outcome)
    opened = outcome["marks"]["opened"]
    assert opened["run_dir"] == str(run / names[-1] if layers > 1 else run)
    assert opened["steps"] == epochs * 8 and opened["elapsed"] > 0
    assert probe["runs"] == 1 and probe["run_dir"] == opened["run_dir"]  # resumed in its folder
    assert probe["elapsed"] > opened["elapsed"]  # the time axis goes on


def test_too_small_a_window_is_refused_in_one_line(box):
    result = subprocess.run([sys.executable, "-m", "edgedog", "studio", str(box), "--size", "320x240"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "640x480" in result.stderr


def test_a_layered_run_trains_filters_its_curves_by_layer_exports_per_layer_and_reopens(box, xvfb_display,
                                                                                       tmp_path):
    train = [{"set": {"restart.layers": 2}}, {"request": "start"},
             {"expect": {"phase": "finished", "layers": ["L0", "L1"], "curves_selection": ""},
              "timeout": 120},
             {"set": {"display.layers.L1": False}},
             {"expect": {"curves_selection": "L0"}, "timeout": 60},  # the curves follow the layers shown
             {"key": "ctrl+e"},
             {"expect": {"extracting": False}, "timeout": 60},
             {"request": "close"}]
    probe = assert_ok(*run_script(train, [box, "--runs", tmp_path / "runs", "--preset", "preview",
                                          "--set", "epochs=2", *FAST], xvfb_display, tmp_path))
    run = Path(probe["run_dir"]).parent  # the top layer's folder is in the layered run's
    assert (run / "layers.json").is_file() and (run / "layers_report.json").is_file()
    for selection in ("L0", "L1", "L0+L1"):  # what `edgedog train --layers L0,L1` writes
        assert (run / "curves" / selection / "curves.json").is_file()
    # One snapshot, every format, the layers shown named as `edgedog export --layers` names them;
    # two epochs may leave L0 no curves: then no empty files, and the status says so.
    step = probe["steps"] // 2
    if probe["curves"]:
        assert sorted(Path(path).name for path in probe["export_paths"]) == [
            f"curves_step{step:06d}_L0.{fmt}" for fmt in ("json", "obj", "ply")]
    else:
        assert probe["status"] == (f"curves at step {step} (L0): 0 lines, 0 Beziers; nothing exported "
                                   "(ply, obj, json): no curves in this snapshot")
        assert probe["export_paths"] == [] and not (run / "exports").exists()
    reopen = [{"expect": {"phase": "finished", "layers": ["L0", "L1"], "curves_selection": "",
                          "splats_drawn": [">", 0]}, "timeout": 20},
              {"set": {"display.layers.L0": False}},
              {"expect": {"curves_selection": "L1"}, "timeout": 60},
              {"request": "close"}]
    probe = assert_ok(*run_script(reopen, [run], xvfb_display, tmp_path))
    assert probe["runs"] == 0 and probe["title"] == f"box - {run.name} - EdgeDoG Studio"


KEY_PAUSE = 2.0
"""Seconds between two real keys: a few frames even while the window draws slowly (training)."""


def test_real_keys_close_the_topmost_window_and_quitting_asks_first(box, window_manager, tmp_path):
    # Issue 40: after F1 then Esc, Ctrl+O must open the browser; Esc must close it and never quit;
    # Esc with nothing open and q while a run trains only ask (Esc: no).
    ready = tmp_path / "training.json"  # the keys wait for the run to train
    actions = [{"request": "start"}, {"expect": {"phase": "training"}, "timeout": 60},
               {"save_rects": str(ready)},
               {"expect": {"help": True}, "timeout": 60},
               {"expect": {"help": False}, "timeout": 20},
               {"expect": {"dialog": str(box.parent)}, "timeout": 20},
               {"expect": {"dialog": None, "confirm": None}, "timeout": 20},
               {"expect": {"confirm": "Stop training and quit? The run keeps its last checkpoint."},
                "timeout": 20},
               {"expect": {"confirm": None, "phase": "training"}, "timeout": 20},
               {"expect": {"confirm": [">", ""]}, "timeout": 20},  # q asks too
               {"expect": {"confirm": None, "phase": "training"}, "timeout": 20},
               {"mark": "answered"},
               {"request": "close"}]
    keys = [ready, KEY_PAUSE, "F1", KEY_PAUSE, "Escape", KEY_PAUSE, "ctrl+o", KEY_PAUSE, "Escape", KEY_PAUSE,
            "Escape", KEY_PAUSE, "Escape", KEY_PAUSE, "q", KEY_PAUSE, "Escape"]
    result, outcome = run_with_keys(actions, keys, [box, "--runs", tmp_path / "runs", "--set", "epochs=5000",
                                                    *FAST], window_manager, tmp_path)
    probe = assert_ok(result, outcome)
    assert probe["phase"] == "stopped" and "answered" in outcome["marks"]


def test_a_path_typed_right_after_ctrl_o_goes_into_the_browser(box, window_manager, tmp_path):
    # The browser's path field has the keys as it opens: a typed path replaces the one shown,
    # Enter goes there, and Esc still closes the browser.
    actions = [{"expect": {"dialog": str(box.parent)}, "timeout": 60},
               {"expect": {"dialog": "/tmp"}, "timeout": 30},
               {"expect": {"dialog": None}, "timeout": 30},
               {"request": "close"}]
    keys = [4.0, "ctrl+o", KEY_PAUSE, "slash", "t", "m", "p", "Return", KEY_PAUSE, "Escape"]
    probe = assert_ok(*run_with_keys(actions, keys, [box], window_manager, tmp_path))
    assert probe["typed_drawn"][-1][1] == 4  # every typed character was drawn


def test_restart_and_open_while_training_ask_and_a_stray_q_keeps_the_run(box, xvfb_display, tmp_path):
    restart = "Stop this run and train a new run folder? It keeps its last checkpoint."
    actions = [
        {"request": "start"},
        {"key": "q"},  # during the set-up, or just after: asked, not quit
        {"expect": {"confirm": "Stop training and quit? The run keeps its last checkpoint."}, "timeout": 10},
        {"key": "escape"},
        {"expect": {"confirm": None, "phase": "training", "steps": [">", 20]}, "timeout": 60},
        {"mark": "kept"},
        {"click": "Restart"},
        {"expect": {"confirm": restart}, "timeout": 10},
        {"key": "escape"},
        {"expect": {"confirm": None, "runs": 1, "phase": "training"}, "timeout": 10},
        {"request": "open", "path": str(box)},  # as a folder dropped on the window
        {"expect": {"confirm": OPEN_QUESTION.format(box)}, "timeout": 10},
        {"key": "escape"},
        {"expect": {"confirm": None, "runs": 1, "phase": "training"}, "timeout": 10},
        {"click": "Restart"},
        {"expect": {"confirm": restart}, "timeout": 10},
        {"key": "enter"},
        {"expect": {"confirm": None, "runs": 2}, "timeout": 10},
        {"request": "close"}]
    result, outcome = run_script(actions, [box, "--runs", tmp_path / "runs", "--set", "epochs=5000", *FAST],
                                 xvfb_display, tmp_path)
    assert assert_ok(result, outcome)["runs"] == 2
    assert (Path(outcome["marks"]["kept"]["run_dir"]) / "checkpoint.pt").is_file()  # the stray q lost nothing


def test_every_layer_combination_of_a_resumed_layered_run_draws(box, xvfb_display, tmp_path):
    # Issue 40, defect 2: a layered run stopped while L1 trains, reopened and resumed, trains only
    # L1; showing L0 alone needs L0's maps (Canny 150,300), never loaded by this process.
    first = [{"set": {"restart.layers": 2}}, {"request": "start"},
             {"expect": {"layers": ["L0", "L1"], "steps": [">", 600 * 8 + 2 * 8]}, "timeout": 300},
             {"request": "close"}]
    # 600 epochs a layer: stopped, and resumed below, with thousands of L1's steps to go. With 60, an
    # idle machine trained the 464 steps left between two frames (2 a second while training) and
    # the run had finished when the close came.
    probe = assert_ok(*run_script(first, [box, "--runs", tmp_path / "runs", "--set", "epochs=600", *FAST],
                                  xvfb_display, tmp_path))
    assert probe["phase"] == "stopped"
    run = Path(probe["run_dir"]).parent
    resume = [{"request": "start"}, {"expect": {"phase": "training"}, "timeout": 60}, {"request": "pause"},
              {"expect": {"phase": "paused", "layers": ["L0", "L1"], "inspected_layers": "L0+L1"},
               "timeout": 30}]
    for shown, drawn in (({"L0": True, "L1": False}, "L0"), ({"L0": False, "L1": True}, "L1"),
                         ({"L0": False, "L1": False}, ""), ({"L0": True, "L1": True}, "L0+L1")):
        resume += [{"set": {f"display.layers.{name}": on for name, on in shown.items()}},
                   {"expect": {"inspected_layers": drawn, "inspectors": 6}, "timeout": 30}]
    probe = assert_ok(*run_script([*resume, {"request": "close"}], [run], xvfb_display, tmp_path))
    assert probe["run_dir"] == str(run / "L1") and not probe["status"].startswith("inspectors:")


def test_at_1024x700_every_no_op_says_why_and_export_is_in_sight(box, xvfb_display, tmp_path):
    # Issue 40, item 5: Export and Extract with every layer hidden did nothing, silently; the
    # export paths ran off the status line; Export needed scrolling; the plots were squashed.
    hidden = "nothing to {}: every layer is hidden (tick one in 3D view)"
    actions = [{"request": "start"}, {"expect": {"phase": "training", "steps": [">", 120]}, "timeout": 90},
               {"request": "pause"}, {"expect": {"phase": "paused"}, "timeout": 10},
               {"set": {"display.layers.L0": False}},
               {"key": "ctrl+e"}, {"expect": {"status": hidden.format("export")}, "timeout": 5},
               {"click": "Extract now"}, {"expect": {"status": hidden.format("extract")}, "timeout": 5},
               {"key": "9"}, {"expect": {"status": "9: no such view, the scene has 8"}, "timeout": 5},
               {"set": {"display.layers.L0": True}},
               {"click": "Export"}, {"expect": {"curves": [">=", 0]}, "timeout": 60},
               {"request": "close"}]
    probe = assert_ok(*run_script(actions, [box, "--runs", tmp_path / "runs", "--preset", "preview", *FAST],
                                  xvfb_display, tmp_path, size="1024x700"))
    assert probe["plots_tabbed"]
    assert not {"Export", "Extract now", "PLY", "OBJ", "JSON"} & set(probe["cut_widgets"])
    if probe["curves"]:  # the status names the files in the run's exports folder
        first = Path(probe["export_paths"][0])
        assert probe["status"].endswith(f"; wrote exports/{first.name}, .obj, .json")
    else:
        assert probe["status"].endswith("nothing exported (ply, obj, json): no curves in this snapshot")


def test_help_opens_in_the_same_place_each_time(box, xvfb_display, tmp_path):
    # Issue 40, defect 8: its wrapped text made the help window open tall and elsewhere the first time.
    shots = [tmp_path / "help1.png", tmp_path / "help2.png"]
    actions = []
    for shot in shots:
        actions += [{"key": "f1"}, {"request": "screenshot", "path": str(shot)},  # its first frames
                    {"expect": {"help": True}, "timeout": 5}, {"key": "escape"},
                    {"expect": {"help": False}, "timeout": 5}]
    actions = [{"expect": {"inspectors": 2}, "timeout": 20}, *actions, {"request": "close"}]
    assert_ok(*run_script(actions, [box], xvfb_display, tmp_path))
    first, second = (cv2.imread(str(shot)) for shot in shots)
    assert (first[:-STATUS_PIXELS] == second[:-STATUS_PIXELS]).all()  # the status line reads out the fps


def test_computed_edge_maps_go_to_the_cache_given(box, xvfb_display, tmp_path):
    # Issue 40, defect 8: --cache was only the built-in scene's folder; computed maps went to the default.
    actions = [{"request": "start"}, {"expect": {"phase": "training"}, "timeout": 60}, {"request": "close"}]
    assert_ok(*run_script(actions, [box, "--runs", tmp_path / "runs", "--cache", tmp_path / "cache",
                                    "--set", "maps.detector=canny:100,200", *FAST], xvfb_display, tmp_path))
    assert any((tmp_path / "cache" / "edges").rglob("*.png"))
