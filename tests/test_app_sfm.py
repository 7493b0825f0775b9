"""Photos to cameras in the studio, without a window: the progress read from `edgedog sfm`'s
lines, the job that runs it in a child process (its cancel stops at once and leaves nothing),
photo folders told apart from scenes and runs, and the sparse points drawn offscreen (EGL)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from edgedog.app.folder_dialog import PHOTOS, folder_kind
from edgedog.app.photos import offer, sfm_scene_folder
from edgedog.app.points_view import PointsView
from edgedog.app.sfm_job import CANCELLED, DONE, FAILED, SfmJob, error_line, unique_folder
from edgedog.app.sfm_progress import STAGES, SfmProgress, advance
from edgedog.renderer.gl.context import GLUnavailableError, offscreen_context

from edgedog.builtin.scene import write_box_scene
from edgedog.errors import EdgeDogError, InputError
from edgedog.scenes import load_scene
from edgedog.scenes.sfm import REGISTRATION_LINES, registration_reporter
from tests.helpers.paths import shared_path

DTU_VIEWS = range(10, 20)
"""Ten neighbouring views of DTU scan 37's second row: all register, in about 8 s at 800 px."""
LINES = ["sfm: extracting SIFT features from 49 photos in /p (one shared camera)",
         "sfm: matching (exhaustive)",
         "sfm: 600 image pairs with geometrically verified matches; incremental mapping",
         "sfm:   10 images registered", "sfm:   20 images registered",
         "sfm: largest of 1 model(s): 49 of 49 photos, 9000 points, mean reprojection error 0.4 px; "
         "undistorting",
         "sfm: wrote /out in 300 s"]
"""What `edgedog sfm` prints on 49 photos (edgedog.scenes.sfm.run_sfm's lines)."""


def write_dtu_photos(folder: Path, views=DTU_VIEWS, size=(800, 600)) -> Path:
    """Copies of DTU scan 37's photos (no cameras) at `size`, or skip without ../shared."""
    dtu = shared_path("dtu_scan37")
    folder.mkdir(parents=True)
    for index in views:
        image = cv2.imread(str(dtu / "image" / f"{index:06d}.jpg"))
        cv2.imwrite(str(folder / f"{index:06d}.jpg"), cv2.resize(image, size, interpolation=cv2.INTER_AREA))
    return folder


def write_noise_photos(folder: Path, count: int = 3) -> Path:
    """Independent noise images: features, but no geometrically consistent matches."""
    folder.mkdir(parents=True)
    rng = np.random.default_rng(0)
    for i in range(count):
        noise = rng.integers(0, 256, size=(48, 64, 3), dtype=np.uint8)
        cv2.imwrite(str(folder / f"{i}.png"), cv2.resize(noise, (320, 240), interpolation=cv2.INTER_NEAREST))
    return folder


def wait_until(condition, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.01)


def finished(job: SfmJob, timeout: float = 120.0):
    """The job's outcome once it has ended."""
    wait_until(lambda: not job.busy, timeout)
    return job.poll()


# --- progress --------------------------------------------------------------------------------

def test_progress_follows_every_stage_of_the_command():
    progress = SfmProgress()
    assert (progress.stage_name, progress.fraction, progress.label) == ("starting", 0.0, "starting")
    seen = []
    for line in LINES:
        progress = advance(progress, line + "\n")
        seen.append((progress.stage_name, progress.fraction, progress.label))
    assert seen == [("features", 0.0, "1/4 features"), ("matching", 0.25, "2/4 matching"),
                    ("mapping", 0.5, "3/4 mapping: 0 of 49 registered"),
                    ("mapping", 0.5 + 10 / 49 / 4, "3/4 mapping: 10 of 49 registered"),
                    ("mapping", 0.5 + 20 / 49 / 4, "3/4 mapping: 20 of 49 registered"),
                    ("undistortion", 0.75, "4/4 undistortion"), ("done", 1.0, "done")]
    assert (progress.photos, progress.registered, progress.points) == (49, 49, 9000)
    assert progress.message == "wrote /out in 300 s"
    # Other output (pycolmap's, a traceback) changes nothing.
    assert advance(progress, "W1127 some pycolmap warning\n") == progress


@pytest.mark.parametrize("photos, every", [(3, 1), (9, 1), (39, 1), (40, 2), (49, 2), (400, 20)])
def test_the_mapping_says_each_registration_on_few_photos_and_about_20_lines_on_many(photos, every, capsys):
    report = registration_reporter(photos)
    for _ in range(photos):
        report()
    lines = capsys.readouterr().out.splitlines()
    assert lines == [f"sfm:   {count} images registered" for count in range(every, photos + 1, every)]
    assert len(lines) < 2 * REGISTRATION_LINES
    # Under 10 photos the bar moves with each one (it stayed at "0 of N" when every 10th was said).
    if photos < 10:
        progress = advance(SfmProgress(), LINES[0].replace("49", str(photos)) + "\n")
        for line in [LINES[2], *lines]:
            progress = advance(progress, line + "\n")
            assert progress.label == f"3/4 mapping: {progress.registered} of {photos} registered"
        assert progress.registered == photos and progress.fraction == 0.75


def test_the_error_line_is_the_commands_one_line():
    lines = ["sfm: matching (exhaustive)",
             "edgedog: error: /p: structure from motion registered 0 of 3 photos"]
    assert error_line(lines, 2) == "/p: structure from motion registered 0 of 3 photos"
    assert error_line(["Traceback ...", "RuntimeError: boom", ""], 1) == "RuntimeError: boom"
    assert error_line([], -9) == "edgedog sfm exited with status -9"


# --- photo folders ---------------------------------------------------------------------------

def test_a_photo_folder_is_told_from_scenes_runs_and_plain_folders(tmp_path):
    photos = write_noise_photos(tmp_path / "photos")
    scene = write_box_scene(tmp_path / "box", views=2, size=32)
    (tmp_path / "plain").mkdir()
    (tmp_path / "plain" / "notes.txt").write_text("")
    assert folder_kind(photos) == PHOTOS and folder_kind(tmp_path / "plain") == ""
    assert folder_kind(scene) == "nerf scene"  # a scene's images are no photos to recover


def test_the_scene_of_photos_goes_beside_the_runs_never_inside_the_photos(tmp_path):
    photos = write_noise_photos(tmp_path / "photos")
    runs = tmp_path / "runs"
    assert sfm_scene_folder(runs, photos) == runs / "photos-sfm"
    (runs / "photos-sfm").mkdir(parents=True)
    assert sfm_scene_folder(runs, photos) == runs / "photos-sfm-2" == unique_folder(runs, "photos-sfm")
    for inside in (photos, photos / "runs"):
        with pytest.raises(InputError, match="inside the photo folder") as info:
            sfm_scene_folder(inside, photos)
        assert "\n" not in str(info.value)
    question = offer(photos, 3, runs / "photos-sfm", "the run under way (it keeps its last checkpoint)")
    assert "holds 3 photos and no cameras" in question and question.endswith("keeps its last checkpoint).")


# --- the job, with stand-in children ---------------------------------------------------------

STUCK_CHILD = """
import sys, time, pathlib
out = pathlib.Path(sys.argv[1])
print("sfm: extracting SIFT features from 5 photos in /p (one shared camera)", flush=True)
(out.parent / f".{out.name}.partial-x1y2z3").mkdir()
if sys.argv[2] == "renamed":
    out.mkdir()
print("sfm: matching (exhaustive)", flush=True)
time.sleep(120)  # as a long pycolmap call: nothing in Python runs until it returns
"""


@pytest.mark.parametrize("where", ["partial", "renamed"])
def test_cancel_ends_the_child_at_once_and_leaves_nothing(tmp_path, where):
    out = tmp_path / "scene"
    job = SfmJob(tmp_path / "photos", out)
    job.command = [sys.executable, "-c", STUCK_CHILD, str(out), where]
    job.start()
    wait_until(lambda: job.progress.stage_name == "matching")
    assert job.busy and job.poll() is None
    started = time.monotonic()
    assert job.cancel(timeout=10)
    seconds = time.monotonic() - started
    outcome = job.poll()
    assert outcome.status == CANCELLED and outcome.error is None and seconds < 2.0, seconds
    assert outcome.progress.stage_name == "matching"
    assert list(tmp_path.iterdir()) == []  # neither the temporary folder nor a renamed scene
    assert job.poll() is None  # an outcome is taken once


def test_a_failing_child_gives_its_one_line_error(tmp_path):
    job = SfmJob(tmp_path / "photos", tmp_path / "scene")
    job.command = [sys.executable, "-c", "import sys; print('sfm: matching (exhaustive)'); "
                   "print('edgedog: error: /p: too few photos', file=sys.stderr); sys.exit(2)"]
    job.start()
    outcome = finished(job)
    assert (outcome.status, outcome.error) == (FAILED, "/p: too few photos")
    assert outcome.progress.stage_name == "matching" and not (tmp_path / "scene").exists()


def test_a_child_that_cannot_start_is_one_error(tmp_path):
    job = SfmJob(tmp_path / "photos", tmp_path / "scene")
    job.command = [str(tmp_path / "no-such-python")]
    with pytest.raises(EdgeDogError, match="cannot start edgedog sfm") as info:
        job.start()
    assert "\n" not in str(info.value) and not job.busy and job.poll() is None


# --- the job, running `edgedog sfm` ----------------------------------------------------------

def test_photos_that_cannot_register_say_how_many_did_and_what_to_try(tmp_path):
    photos = write_noise_photos(tmp_path / "photos")
    job = SfmJob(photos, tmp_path / "runs" / "photos-sfm")
    job.start()
    outcome = finished(job)
    assert outcome.status == FAILED and "\n" not in outcome.error
    assert outcome.error.startswith(f"{photos}: structure from motion registered 0 of 3 photos")
    assert "try more photos with more overlap" in outcome.error
    assert outcome.progress.stage_name == "mapping"  # it got as far as mapping
    assert list((tmp_path / "runs").iterdir()) == []  # no partial scene


@pytest.mark.shared_data
@pytest.mark.slow
def test_dtu_photos_go_through_every_stage_into_a_scene_that_loads(tmp_path):
    photos = write_dtu_photos(tmp_path / "photos")
    out = tmp_path / "runs" / "photos-sfm"
    job = SfmJob(photos, out, max_image_size=800)
    job.start()
    fractions = []
    while job.busy:
        fractions.append(job.progress.fraction)
        time.sleep(0.01)
    outcome = job.poll()
    assert outcome.status == DONE, outcome.tail
    assert fractions == sorted(fractions) and 0.0 < max(fractions)  # the bar only moves on
    stages, progress = [], SfmProgress()
    for line in outcome.tail:  # every stage of the real command is recognised
        progress = advance(progress, line)
        if progress.stage_name not in stages:
            stages.append(progress.stage_name)
    assert stages == [*STAGES, "done"]
    assert (progress.registered, progress.photos) == (len(DTU_VIEWS), len(DTU_VIEWS))
    scene = load_scene(out)
    assert len(scene) == len(DTU_VIEWS) and len(scene.sfm_points) == progress.points > 500
    assert sorted(p.name for p in out.parent.iterdir()) == ["photos-sfm"]  # nothing partial beside it
    assert sorted(p.name for p in photos.iterdir()) == [f"{i:06d}.jpg" for i in DTU_VIEWS]  # untouched


@pytest.mark.shared_data
@pytest.mark.slow
def test_cancelling_real_sfm_in_the_middle_stops_it_within_a_second(tmp_path):
    photos = write_dtu_photos(tmp_path / "photos")
    out = tmp_path / "runs" / "photos-sfm"
    job = SfmJob(photos, out, max_image_size=800)
    job.start()
    wait_until(lambda: job.progress.stage_name == "matching" or not job.busy)
    started = time.monotonic()
    assert job.cancel(timeout=10)
    seconds = time.monotonic() - started
    outcome = job.poll()
    assert outcome.status == CANCELLED and seconds < 1.0, seconds
    assert list(out.parent.iterdir()) == []


# --- the sparse points in the 3D view (offscreen) --------------------------------------------

@pytest.mark.gl
def test_the_sparse_points_are_drawn_in_their_colours_and_hidden_on_demand(tmp_path):
    try:
        ctx = offscreen_context()
    except GLUnavailableError as error:
        pytest.skip(f"no headless OpenGL: {error}")
    scene = load_scene(write_box_scene(tmp_path / "box", views=4, size=32))
    view = PointsView(ctx, 160, 120)
    try:
        view.set_scene(scene.cameras, scene.bounds, None)
        rng = np.random.default_rng(0)
        points = scene.bounds[0] + rng.random((400, 3)) * (scene.bounds[1] - scene.bounds[0])
        view.set_points(points, np.tile(np.array([[255, 0, 0]], np.uint8), (400, 1)))
        view.sync_points(False)
        assert view.render() and view.points_shown == 0
        empty = view.target.read()[..., :3].copy()
        view.sync_points(True)
        assert view.points_shown == 400 and view.render()
        drawn = view.target.read()[..., :3]  # floats in [0, 1]
        changed = np.abs(drawn - empty).sum(axis=2) > 0
        assert changed.sum() > 100
        assert (drawn[changed][:, 0] > drawn[changed][:, 1] + 0.4).all()  # red, as coloured
        view.sync_points(True)
        assert not view.render()  # nothing changed: nothing re-drawn
        view.set_points(None, None)  # another scene without points
        view.sync_points(True)
        assert view.points_shown == 0 and view.render()
        assert np.array_equal(view.target.read()[..., :3], empty)
    finally:
        view.release()
        ctx.release()

