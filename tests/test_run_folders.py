"""Run folders others can trust: opening one runs no code, no folder that is not ours is written,
--resume checks the scene and the options, one writer at a time, Ctrl-C stops cleanly."""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from edgedog.errors import InputError, OutputError
from edgedog.files import atomic_write_json
from edgedog.train.checkpoint import read_checkpoint
from edgedog.train.lifecycle import is_finished
from edgedog.train.run_folder import LOCK_FILE, RUN_VERSION, RunLock, read_run
from tests.helpers.bad_inputs import edgedog, snapshot
from tests.helpers.old_runs import flat_config
from tests.helpers.tiny_runs import QUICK_TRAIN as TRAIN
from tests.helpers.tiny_runs import make_small_scene


@pytest.fixture(scope="module")
def tiny_scenes(small_box_scene, tmp_path_factory) -> tuple[Path, Path]:
    """Two small scenes: the session's box and a cylinder made alike."""
    return small_box_scene, make_small_scene(tmp_path_factory.mktemp("scenes") / "cylinder", "cylinder")


@pytest.fixture(scope="module")
def finished_run(tiny_scenes, tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("runs") / "box"
    result = edgedog("train", tiny_scenes[0], "--out", run, *TRAIN)
    assert result.returncode == 0, result.stderr
    return run


class CodeInPickle:
    """Unpickling this calls os.system: what a crafted checkpoint.pt would do."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def test_a_crafted_checkpoint_runs_no_code_on_resume(finished_run, tiny_scenes, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    marker = tmp_path / "marker"
    torch.save({"format": "edgedog-checkpoint", "version": 2, "model": CodeInPickle(marker)},
               run / "checkpoint.pt")
    result = edgedog("train", tiny_scenes[0], "--out", run, "--resume", "--quiet")
    assert result.returncode == 2, result.stderr
    assert "checkpoint.pt" in result.stderr and "not loaded" in result.stderr
    with pytest.raises(InputError, match="not loaded"):
        read_checkpoint(run / "checkpoint.pt")
    assert not marker.exists()


def test_checkpoints_hold_only_plain_data(finished_run):
    saved = torch.load(finished_run / "checkpoint.pt", weights_only=True)
    assert saved["format"] == "edgedog-checkpoint" and saved["version"] == 2
    assert isinstance(saved["model"]["means"], torch.Tensor)


def test_a_run_folder_of_format_2_reads_as_the_same_run_and_resumes(finished_run, tiny_scenes, tmp_path):
    """Before the sections: config.json of version 2, every config flat, 'paper' naming `full`."""
    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    now = read_run(run)
    data = json.loads((run / "config.json").read_text())
    assert data["version"] == RUN_VERSION == 3 and data["preset"] == "preview"
    data.update(version=2, config=flat_config(data["config"]))
    (run / "config.json").write_text(json.dumps(data))
    log = json.loads((run / "log.json").read_text())
    (run / "log.json").write_text(json.dumps({**log, "config": flat_config(log["config"])}))
    saved = torch.load(run / "checkpoint.pt", weights_only=True)
    torch.save({**saved, "config": flat_config(saved["config"])}, run / "checkpoint.pt")
    assert read_run(run) == now and is_finished(run)
    (run / "config.json").write_text(json.dumps({**data, "preset": "paper"}))
    assert read_run(run).preset == "full"  # what 'paper' named then
    resumed = edgedog("train", tiny_scenes[0], "--out", run, "--resume", "--quiet")
    assert resumed.returncode == 0, resumed.stderr


def test_a_folder_that_is_not_a_run_is_never_written(tiny_scenes, tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "config.json").write_text('{"mine": 1}')
    before = snapshot(mine)
    for scene in ("/nonexistent", tiny_scenes[0]):  # a bad scene, then a good one
        result = edgedog("train", scene, "--out", mine, *TRAIN)
        assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
        assert snapshot(mine) == before and sorted(os.listdir(mine)) == ["config.json"]
    assert "not an edgedog run folder" in result.stderr


@pytest.mark.slow
def test_resume_refuses_another_scene_and_new_settings(finished_run, tiny_scenes, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    before = snapshot(run)
    other = edgedog("train", tiny_scenes[1], "--out", run, "--resume", "--quiet")
    assert other.returncode == 2 and "other cameras or images" in other.stderr, other.stderr
    for options in (["--set", "epochs=200"], ["--preset", "full"], ["--set", "keep_ratio=5"]):
        changed = edgedog("train", tiny_scenes[0], "--out", run, "--resume", "--quiet", *options)
        assert changed.returncode == 2 and "cannot change them" in changed.stderr, changed.stderr
    assert snapshot(run) == before


def test_resume_accepts_the_same_scene_moved(finished_run, tiny_scenes, tmp_path):
    """The fingerprint is of the content: a copied scene folder is the same scene."""
    run, moved = tmp_path / "run", tmp_path / "moved-box"
    shutil.copytree(finished_run, run)
    shutil.copytree(tiny_scenes[0], moved)
    result = edgedog("train", moved, "--out", run, "--resume", "--quiet")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout.splitlines()[0])["resumed_at_step"] > 0


@pytest.mark.slow
def test_a_second_writer_is_refused(tiny_scenes, finished_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(finished_run, run)
    with RunLock.acquire(run):  # a writer in another process would hold the same flock
        for argv in (["train", tiny_scenes[0], "--out", run, "--resume", "--quiet"], ["extract", run],
                     ["export", run, "--format", "obj"]):
            result = edgedog(*argv)
            assert result.returncode == 2 and "in use by another edgedog process" in result.stderr, argv
            assert f"pid {os.getpid()}" in result.stderr
    assert edgedog("extract", run).returncode == 0  # released


def test_two_trainings_into_one_folder_one_is_refused(tiny_scenes, tmp_path):
    """Two `train` at once into one new folder: one trains, the other gets one line; the folder
    is one resumable run."""
    run = tmp_path / "run"
    argv = [sys.executable, "-m", "edgedog", "train", str(tiny_scenes[0]), "--out", str(run), *TRAIN]
    first, second = (subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                     for _ in range(2))
    results = [(p.wait(timeout=300), p.stderr.read()) for p in (first, second)]
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    refused = next(err for code, err in results if code == 2)
    assert "in use by another edgedog process" in refused or "already holds a run" in refused, refused
    assert read_run(run).config.schedule.epochs == 2 and (run / "log.json").is_file()


def test_the_lock_is_exclusive_and_released(tmp_path):
    lock = RunLock.acquire(tmp_path / "run")
    with pytest.raises(InputError, match="in use by another edgedog process"):
        RunLock.acquire(tmp_path / "run")
    lock.release()
    lock.release()  # twice is harmless
    with RunLock.acquire(tmp_path / "run"):
        assert (tmp_path / "run" / LOCK_FILE).read_text().strip() == str(os.getpid())


def test_the_lock_removes_what_a_killed_writer_left_mid_write(tmp_path):
    """kill -9 during atomic_write leaves '.NAME.XXXXXXXX.tmp'; the lock's next holder removes it
    (no writer of the folder is alive then) and nothing else."""
    run = tmp_path / "run"
    run.mkdir()
    left = run / ".checkpoint.pt.iv3z8nwk.tmp"
    kept = [run / name for name in ("notes.tmp", ".checkpoint.pt.short.tmp", "log.json")]
    for path in (left, *kept):
        path.write_text("x")
    with RunLock.acquire(run):
        assert not left.exists() and all(path.exists() for path in kept)


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_and_the_run_resumes(tiny_scenes, tmp_path):
    run = tmp_path / "run"
    argv = [sys.executable, "-m", "edgedog", "train", str(tiny_scenes[0]), "--out", str(run), "--preset",
            "preview", "--set", "epochs=40", "--set", "checkpoint_every=1", "--set", "init_count=300",
            "--quiet"]
    # As in a terminal: a test runner started in the background (e.g. `cmd &` in a script) passes
    # SIGINT on ignored, and Python then never turns it into KeyboardInterrupt.
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 120
    while not (run / "checkpoint.pt").is_file() and time.monotonic() < deadline:
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    assert "Traceback" not in err and err.strip().count("\n") == 0, err
    assert err.startswith("edgedog: error: interrupted") and "--resume" in err
    resumed = edgedog("train", tiny_scenes[0], "--out", run, "--resume", "--quiet")
    assert resumed.returncode == 0, resumed.stderr
    assert json.loads(resumed.stdout.splitlines()[0])["resumed_at_step"] > 0


def test_a_full_disk_keeps_the_old_file_and_names_the_path(tmp_path, monkeypatch):
    target = tmp_path / "log.json"
    atomic_write_json(target, {"kept": True})

    def no_space(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", no_space)
    with pytest.raises(OutputError, match="No space left on device") as caught:
        atomic_write_json(target, {"kept": False})
    assert str(caught.value).startswith(str(target))
    assert json.loads(target.read_text()) == {"kept": True}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.json"]  # no temporary file left


def test_a_new_folder_a_writer_holds_is_in_use_not_someone_elses(tmp_path):
    """Between a writer's lock and its config.json, its folder holds the lock and a temporary
    file: another process is told that the folder is in use, not that it is not a run."""
    from edgedog.train.run_folder import RunLock, check_new_run_folder, lock_holder

    run = tmp_path / "run"
    lock = RunLock.acquire(run)
    (run / ".config.json.0.tmp").write_text("{}")
    check = ("from pathlib import Path; from edgedog.train.run_folder import check_new_run_folder; "
             f"check_new_run_folder(Path({str(run)!r}))")
    refused = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True)
    assert f"is in use by another edgedog process (pid {os.getpid()})" in refused.stderr
    lock.release()
    assert lock_holder(run) is None
    with pytest.raises(InputError, match="is not empty and is not an edgedog run folder"):
        check_new_run_folder(run)
