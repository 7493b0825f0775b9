"""Photos to curves in the studio window under a virtual X server: a folder of photos opened is
offered structure from motion, its progress bar moves, its sparse points and cameras show, and
training starts; real keys and clicks (xdotool) open photos and cancel; a folder that cannot
register says how many photos did."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from edgedog.app.controls_panel import PROGRESS_COLOR

from edgedog.builtin.scene import DEFAULT_DETECTOR, DEFAULT_SHAPE, write_box_scene
from tests import test_studio_window as window_tests
from tests.test_app_sfm import DTU_VIEWS, write_dtu_photos, write_noise_photos
from tests.test_studio_window import assert_ok, run_script

pytestmark = pytest.mark.xvfb
window_manager = window_tests.window_manager
OFFER_BUTTON = "Recover cameras (SfM) (Enter)"
FAST = ["--set", "init_count=300", "--set", "maps.detector=canny"]
"""Training settings of the scripted runs: they only need to start."""


@pytest.fixture(scope="module")
def box(tmp_path_factory) -> Path:
    """The scene the studio opens on, before the photos."""
    return write_box_scene(tmp_path_factory.mktemp("sfm-window") / "box", views=8, size=96)


def wait_for_file(path: Path, studio: subprocess.Popen, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while not path.is_file():
        assert studio.poll() is None, studio.communicate()[1][-3000:]
        assert time.monotonic() < deadline, f"no {path.name}"
        time.sleep(0.1)


def leftovers(folder: Path) -> list[str]:
    """What `folder` holds (nothing when it was never made)."""
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def bar_pixels(shot: Path) -> int:
    """Pixels of the progress bar's fill colour in a screenshot."""
    image = cv2.imread(str(shot)).astype(int)  # BGR
    fill = np.round(np.array([PROGRESS_COLOR.z, PROGRESS_COLOR.y, PROGRESS_COLOR.x]) * 255)
    return int((np.abs(image - fill) <= 3).all(axis=2).sum())


@pytest.mark.shared_data
@pytest.mark.slow
def test_photos_open_into_sfm_whose_points_and_cameras_show_then_training_starts(box, xvfb_display, tmp_path):
    photos = write_dtu_photos(tmp_path / "photos")
    runs = tmp_path / "runs"
    progress_shot, points_shot = tmp_path / "sfm-progress.png", tmp_path / "sfm-points.png"
    actions = [{"set": {"sfm.max_image_size": 800}},
               {"request": "open", "path": str(photos)},
               {"expect": {"confirm": ["!=", None]}, "timeout": 30}, {"mark": "offered"},
               {"wait": 1},  # the question's window is drawn (a click as it appears is lost)
               {"click": OFFER_BUTTON},
               {"expect": {"sfm": "running", "sfm_fraction": [">", 0.0]}, "timeout": 30},
               {"request": "screenshot", "path": str(progress_shot)}, {"mark": "running"},
               {"expect": {"sfm": "done", "sfm_points": [">", 500]}, "timeout": 120},
               {"request": "screenshot", "path": str(points_shot)}, {"mark": "shown"},
               {"expect": {"phase": "training", "steps": [">", 0]}, "timeout": 120}, {"mark": "training"},
               {"request": "close"}]
    result, outcome = run_script(actions, [box, "--runs", runs, *FAST], xvfb_display, tmp_path)
    probe = assert_ok(result, outcome)
    marks = outcome["marks"]
    assert f"{photos} holds {len(DTU_VIEWS)} photos and no cameras" in marks["offered"]["confirm"]
    assert marks["offered"]["scene"] == str(box)
    assert marks["running"]["sfm_stage"] in ("matching", "mapping", "undistortion")
    scene = runs / "photos-sfm"
    assert marks["shown"]["scene"] == probe["scene"] == str(scene)
    assert sorted(p.name for p in scene.iterdir()) == ["images", "sparse"]
    assert [name for name in leftovers(runs) if name.startswith(".")] == []  # nothing partial
    assert probe["run_dir"].startswith(str(runs / "photos-sfm-"))
    assert bar_pixels(progress_shot) > 100 and bar_pixels(points_shot) == 0  # the bar, then none


@pytest.mark.shared_data
@pytest.mark.slow
def test_real_keys_and_clicks_open_photos_start_sfm_and_cancel_it(box, window_manager, tmp_path):
    photos = write_dtu_photos(tmp_path / "photos", size=(1600, 1200))  # long enough to cancel
    runs = tmp_path / "runs"
    ready, browsing, asked, recovering = (tmp_path / f"{name}.json" for name in
                                          ("ready", "browsing", "asked", "recovering"))
    actions = [{"wait": 1}, {"save_rects": str(ready)},
               {"expect": {"dialog": str(photos.resolve())}, "timeout": 60}, {"wait": 1},
               {"save_rects": str(browsing)},
               {"expect": {"confirm": ["!=", None]}, "timeout": 60}, {"save_rects": str(asked)},
               {"expect": {"sfm": "running", "sfm_stage": ["!=", "starting"]}, "timeout": 60}, {"wait": 1},
               {"save_rects": str(recovering)},
               {"expect": {"sfm": "cancelled"}, "timeout": 60}, {"mark": "cancelled"},
               {"request": "close"}]

    def drive(window: str, env: dict, studio: subprocess.Popen) -> None:
        def run(*args: str) -> None:
            subprocess.run(["xdotool", *args], env=env, timeout=30, check=True)

        def click(rects: Path, label: str) -> None:
            x0, y0, x1, y1 = json.loads(rects.read_text())[label]
            run("mousemove", "--window", window, str(round((x0 + x1) / 2)), str(round((y0 + y1) / 2)))
            time.sleep(0.5)  # the move first: a slow frame may read a press at the pointer's old place
            run("click", "1")

        wait_for_file(ready, studio)
        run("key", "--clearmodifiers", "ctrl+o")
        time.sleep(2.0)
        run("type", "--delay", "50", str(photos.resolve()))
        run("key", "Return")
        wait_for_file(browsing, studio)
        click(browsing, "Open")
        wait_for_file(asked, studio)
        time.sleep(1.0)
        run("key", "Return")  # yes to "Recover cameras (SfM)"
        wait_for_file(recovering, studio)
        click(recovering, "Cancel##sfm")

    result, outcome = window_tests.run_driven(actions, [box, "--runs", runs, *FAST], window_manager, tmp_path,
                                              drive)
    probe = assert_ok(result, outcome)
    assert outcome["marks"]["cancelled"]["status"] == "camera recovery cancelled: nothing was written"
    assert probe["scene"] == str(box) and probe["phase"] is None  # the scene open before stays
    assert leftovers(runs) == []  # no scene, no partial folder


@pytest.mark.slow
def test_photos_that_cannot_register_say_how_many_did_in_the_window(box, xvfb_display, tmp_path):
    photos = write_noise_photos(tmp_path / "noise")
    runs, shot = tmp_path / "runs", tmp_path / "sfm-failed.png"
    actions = [{"request": "open", "path": str(photos)},
               {"expect": {"confirm": ["!=", None]}, "timeout": 30},
               {"key": "enter"},
               {"expect": {"sfm": "failed"}, "timeout": 60}, {"wait": 0.5},
               {"request": "screenshot", "path": str(shot)}, {"mark": "failed"},
               {"request": "close"}]
    result, outcome = run_script(actions, [box, "--runs", runs, *FAST], xvfb_display, tmp_path)
    probe = assert_ok(result, outcome)
    error = outcome["marks"]["failed"]["sfm_error"]
    assert error.startswith(f"{photos}: structure from motion registered 0 of 3 photos") and "try" in error
    assert probe["status"] == f"structure from motion failed: {error}"
    assert probe["scene"] == str(box) and leftovers(runs) == []
    assert shot.is_file()


@pytest.mark.shared_data
@pytest.mark.slow
def test_quitting_during_sfm_asks_then_ends_it_at_once_and_leaves_nothing(box, xvfb_display, tmp_path):
    photos = write_dtu_photos(tmp_path / "photos", size=(1600, 1200))
    runs = tmp_path / "runs"
    actions = [{"request": "sfm", "photos": str(photos)},
               {"expect": {"sfm": "running", "sfm_stage": "features"}, "timeout": 60},
               {"key": "q"},
               {"expect": {"confirm": "Cancel the camera recovery and quit?"}, "timeout": 20}, {"wait": 1},
               {"key": "enter"}]
    result, outcome = run_script(actions, [box, "--runs", runs, *FAST], xvfb_display, tmp_path)
    probe = assert_ok(result, outcome)
    assert probe["sfm"] == "cancelled" and outcome["stop_seconds"] < 2.0
    assert leftovers(runs) == []


def test_photos_on_the_command_line_are_offered_sfm_as_open_offers_them(xvfb_display, tmp_path):
    # `edgedog studio PHOTOS` failed with "not a scene": it now shows the built-in scene (here a
    # small box in its place in the cache) and asks, as Open... on the photos does; Enter starts.
    cache, runs = tmp_path / "cache", tmp_path / "runs"
    builtin = write_box_scene(cache / "scenes" / f"{DEFAULT_SHAPE}-{DEFAULT_DETECTOR}", views=8, size=96)
    photos = write_noise_photos(tmp_path / "noise")
    actions = [{"expect": {"confirm": ["!=", None]}, "timeout": 30}, {"mark": "offered"},
               {"key": "enter"}, {"expect": {"sfm": "running"}, "timeout": 30},
               {"request": "cancel_sfm"}, {"expect": {"sfm": "cancelled"}, "timeout": 30},
               {"request": "close"}]
    result, outcome = run_script(actions, [photos, "--cache", cache, "--runs", runs, *FAST], xvfb_display,
                                 tmp_path)
    probe = assert_ok(result, outcome)
    offered = outcome["marks"]["offered"]
    assert offered["confirm"].startswith(f"{photos} holds 3 photos and no cameras")
    assert offered["scene"] == probe["scene"] == str(builtin) and probe["phase"] is None
    assert leftovers(runs) == []
