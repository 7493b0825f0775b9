"""`edgedog batch` on a local Ray cluster of 2 CPUs (`ray start --head`, two worker processes): one
worker is killed mid-run, Ray runs its task again, the run resumes from its checkpoint, and the
tables and every run's primitives are those of the same suite run one run after another without
Ray; every run has a worker process of its own. A rerun trains nothing."""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from edgedog.batch.executors import SequentialExecutor
from edgedog.batch.runner import run_batch
from edgedog.batch.suite import expand, load_suite
from edgedog.batch.table import TIMINGS
from edgedog.train.run_folder import LOCK_FILE

pytestmark = pytest.mark.slow

SUITE = """\
scenes: [{scene}]
presets: [preview]
seeds: [0, 1, 2, 3]
set: [epochs=100, init_count=300, checkpoint_every=10]  # a few seconds a run: a kill lands mid-run
"""
STARTED = "Ray runtime started"


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture
def ray_cluster(tmp_path):
    """A Ray head of 2 CPUs on this machine, stopped (with its workers) after the test: its address
    and the environment that joins it (a token of its own, nothing written to the home folder)."""
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths must stay < 107 chars
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    port, log = free_port(), tmp_path / "ray-head.log"
    with log.open("w") as output:
        head = subprocess.Popen([Path(sys.executable).parent / "ray", "start", "--head", "--block",
                                 "--num-cpus", "2", "--port", str(port), "--temp-dir", temp,
                                 "--include-dashboard", "false", "--disable-usage-stats"],
                                env=env, stdout=output, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while STARTED not in log.read_text():
            assert head.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.2)
        yield f"127.0.0.1:{port}", env
    finally:
        head.terminate()  # `ray start --block` stops the processes it started
        head.wait(timeout=120)
        shutil.rmtree(temp, ignore_errors=True)


class WorkerKiller(threading.Thread):
    """Kills, once, the Ray worker executing a run of `out` that has a checkpoint and no log.json
    yet (the pid in its folder's lock), with SIGKILL; `killed` is then (run name, pid). Until
    stopped, records the Ray worker of every run it sees locked: `workers` {run name: pids}."""

    def __init__(self, out: Path):
        super().__init__(daemon=True)
        self.out, self.killed, self.stop = out, None, threading.Event()
        self.workers: dict[str, set[int]] = {}

    def run(self) -> None:
        while not self.stop.is_set():
            for lock in sorted(self.out.glob(f"*/{LOCK_FILE}")):
                run = lock.parent
                pid = _lock_pid(lock)
                if not pid or "ray::" not in _command_line(pid):
                    continue
                self.workers.setdefault(run.name, set()).add(pid)
                if (self.killed is None and (run / "checkpoint.pt").exists()
                        and not (run / "log.json").exists()):
                    os.kill(pid, signal.SIGKILL)
                    self.killed = (run.name, pid)
            time.sleep(0.02)


def _lock_pid(lock: Path) -> int:
    """The pid in a run folder's lock (0: gone or not written yet)."""
    try:
        return int(lock.read_text().strip() or 0)
    except (OSError, ValueError):
        return 0


def _command_line(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
    except OSError:
        return ""


def without_timings(tables: dict) -> dict:
    timed = {*TIMINGS, *(f"{key}_{part}" for key in TIMINGS for part in ("mean", "std"))}
    return {name: [{key: value for key, value in row.items() if key not in timed} for row in rows]
            for name, rows in tables.items()}


def batch_command(suite: Path, out: Path, address: str, env: dict) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "edgedog", "batch", suite, "--out", out, "--address", address,
               "--cpus-per-run", "1"]
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=400,
                          stdin=subprocess.DEVNULL)


def test_a_killed_worker_is_retried_and_the_batch_matches_a_sequential_one(tmp_path, small_box_scene,
                                                                           ray_cluster):
    address, env = ray_cluster
    suite = tmp_path / "suite.yaml"
    suite.write_text(SUITE.format(scene=small_box_scene))
    sequential = run_batch(expand(load_suite(suite)), tmp_path / "sequential", SequentialExecutor(1), suite)
    assert not sequential.failed

    out = tmp_path / "ray"
    killer = WorkerKiller(out)
    killer.start()
    try:
        result = batch_command(suite, out, address, env)
    finally:
        killer.stop.set()
        killer.join()
    assert result.returncode == 0, result.stdout + result.stderr
    assert killer.killed is not None, "no run was caught between its first checkpoint and its end"
    killed_run = killer.killed[0]
    assert f"{killed_run}: resume;" in result.stdout  # the retried task found the checkpoint
    assert "4 runs in" in result.stdout and "(3 new, 1 resume, 0 finished, 0 skipped)" in result.stdout
    # Every run in a worker process of its own (Ray's max_calls=1): a worker that trained one run
    # does not carry its memory into the next.
    seen = list(killer.workers.values())
    assert len(seen) >= 3, killer.workers
    assert all(a.isdisjoint(b) for i, a in enumerate(seen) for b in seen[i + 1:]), killer.workers

    tables = json.loads((out / "batch.json").read_text())
    reference = json.loads((tmp_path / "sequential" / "batch.json").read_text())
    assert without_timings(tables) == without_timings(reference)
    for outcome in sequential.outcomes:
        name = outcome.spec.name
        assert (out / name / "primitives.ply").read_bytes() == \
               (tmp_path / "sequential" / name / "primitives.ply").read_bytes(), name

    logs = {path: path.stat().st_mtime_ns for path in out.glob("*/log.json")}
    again = batch_command(suite, out, address, env)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "(0 new, 0 resume, 0 finished, 4 skipped)" in again.stdout
    assert {path: path.stat().st_mtime_ns for path in out.glob("*/log.json")} == logs


def test_the_ray_started_for_a_batch_writes_nothing_into_the_home_folder(tmp_path, small_box_scene):
    """Without --address the batch starts Ray here with a token of its own: Ray would otherwise
    write one into ~/.ray (token authentication is on for local instances since Ray 2.59)."""
    suite = tmp_path / "suite.yaml"
    suite.write_text(SUITE.format(scene=small_box_scene).replace("[0, 1, 2, 3]", "[0]")
                     .replace("epochs=100", "epochs=2"))
    home = tmp_path / "home"
    home.mkdir()
    env = {key: value for key, value in os.environ.items() if not key.startswith("RAY_AUTH")}
    env.update(HOME=str(home), RAY_TMPDIR=tempfile.mkdtemp(prefix="ray", dir="/tmp"))
    command = [sys.executable, "-m", "edgedog", "batch", suite, "--out", tmp_path / "out"]
    result = subprocess.run(command, env=env, capture_output=True, text=True, timeout=400,
                            stdin=subprocess.DEVNULL)
    shutil.rmtree(env["RAY_TMPDIR"], ignore_errors=True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert (tmp_path / "out" / "batch.csv").is_file()
    assert not (home / ".ray").exists(), sorted(home.rglob("*"))
