"""A batch run one run after another in this process (no Ray): planned, executed, tabulated, and
rerun without training anything again."""

from __future__ import annotations

import json
import shutil
import socket
from pathlib import Path

import pytest

from edgedog.batch.executors import SequentialExecutor, check_reachable
from edgedog.batch.outcome import SKIPPED
from edgedog.batch.runner import run_batch
from edgedog.batch.suite import expand, load_suite
from edgedog.batch.table import BATCH_FILES
from edgedog.errors import ConfigError, InputError
from edgedog.train.run_folder import RunLock

SUITE = """\
scenes: [{scene}]
presets: [preview]
seeds: [0, 1]
set: [epochs=30, init_count=300]  # enough epochs for curves to score
"""


@pytest.fixture
def suite(tmp_path, small_box_scene) -> Path:
    path = tmp_path / "suite.yaml"
    path.write_text(SUITE.format(scene=small_box_scene))
    return path


def batch(suite: Path, out: Path):
    return run_batch(expand(load_suite(suite)), out, SequentialExecutor(), suite)


def test_a_batch_writes_its_tables_and_a_rerun_trains_nothing(suite, tmp_path):
    out = tmp_path / "out"
    first = batch(suite, out)
    assert [outcome.state for outcome in first.outcomes] == ["new", "new"]
    assert not first.failed
    assert [path.name for path in first.files] == list(BATCH_FILES)
    tables = json.loads((out / "batch.json").read_text())
    names = [outcome.spec.name for outcome in first.outcomes]
    assert [row["run"] for row in tables["runs"]] == names
    assert all(row["f10"] is not None and row["primitives"] > 0 for row in tables["runs"])
    (configuration,) = tables["configurations"]
    assert configuration["runs"] == 2 and configuration["seeds"] == "0 1"
    assert (out / "batch.png").read_bytes().startswith(b"\x89PNG")
    logs = {name: (out / name / "log.json").stat().st_mtime_ns for name in names}

    again = batch(suite, out)
    assert [outcome.state for outcome in again.outcomes] == [SKIPPED, SKIPPED]
    assert {name: (out / name / "log.json").stat().st_mtime_ns for name in names} == logs
    assert json.loads((out / "batch.json").read_text()) == tables


def test_a_folder_holding_another_run_stops_the_batch_before_any_training(suite, tmp_path):
    out, other = tmp_path / "out", tmp_path / "other"
    first = batch(suite, out).outcomes[0].spec.name
    shutil.copytree(out / first, other / first)
    record = json.loads((other / first / "config.json").read_text())
    (other / first / "config.json").write_text(json.dumps({**record, "scene": str(tmp_path / "elsewhere")}))
    with pytest.raises(InputError, match=f"{other / first}: holds a run of another scene or configuration"):
        batch(suite, other)
    assert sorted(path.name for path in other.iterdir() if path.is_dir()) == [first]


def test_one_batch_at_a_time_in_a_folder(suite, tmp_path):
    out = tmp_path / "out"
    with RunLock.acquire(out), pytest.raises(InputError, match="in use by another edgedog process"):
        batch(suite, out)


def test_an_unreachable_or_malformed_address_is_one_error():
    with socket.socket() as probe:  # a port nothing listens on once closed
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with pytest.raises(ConfigError, match=f"^--address ray://127.0.0.1:{port}: cannot reach 127.0.0.1:"):
        check_reachable(f"ray://127.0.0.1:{port}")
    with pytest.raises(ConfigError, match="^--address head: expected auto, HOST:PORT or ray://HOST:PORT"):
        check_reachable("head")
