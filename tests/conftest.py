"""Shared fixtures: the real datasets in ../shared/data (skipped cleanly when absent) and the
built-in exact box scene generated once per session."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.helpers.paths import shared_path

if "PYTEST_XDIST_WORKER" in os.environ:
    # Under pytest-xdist (`make test`: a worker per core) each worker's torch, and the commands it
    # runs as subprocesses, take one thread: torch's default of one per core would put two workers'
    # threads on each core. Set before any test module imports torch.
    os.environ.setdefault("OMP_NUM_THREADS", "1")


@pytest.fixture(scope="session", autouse=True)
def user_cache(tmp_path_factory) -> Path:
    """The user cache (computed edge maps, built-in scenes) of this test session, commands run as
    subprocesses included: tests never write into the home folder."""
    folder = tmp_path_factory.mktemp("edgedog-cache")
    os.environ["EDGEDOG_CACHE"] = str(folder)
    return folder


@pytest.fixture(scope="session")
def small_box_scene(tmp_path_factory) -> Path:
    """A box made by `edgedog make-scene` (12 views at 96 px, Canny maps), shared by the session:
    tests read it, never change it (a test that must, copies it)."""
    from tests.helpers.tiny_runs import make_small_scene

    return make_small_scene(tmp_path_factory.mktemp("small") / "box")


@pytest.fixture(scope="module")
def bracket_scene(tmp_path_factory) -> Path:
    """The L-bracket (seed 0) as a scene: 12 views at 160 px with exact edge maps (the per-curve
    diagnosis' tests)."""
    from edgedog.builtin.writer import write_scene
    from edgedog.synthetic.shapes import make_part

    return write_scene(tmp_path_factory.mktemp("per-curve") / "bracket", make_part("l-bracket"), views=12,
                       size=160, detector="exact")


@pytest.fixture(scope="session")
def abc_nef_scene_dir() -> Path:
    return shared_path("abc_nef/00000006")


@pytest.fixture(scope="session")
def abc_emap_scene_dir() -> Path:
    return shared_path("abc_emap/data/00004926")


@pytest.fixture(scope="session")
def dtu_scene_dir() -> Path:
    return shared_path("dtu_scan37")


@pytest.fixture(scope="session")
def builtin_scene_dir(tmp_path_factory) -> Path:
    """The exact box scene (50 views at 400 px, "exact" edge maps): known answers for tests."""
    from edgedog.builtin.scene import write_box_scene

    return write_box_scene(tmp_path_factory.mktemp("cache") / "box")


@pytest.fixture
def xvfb_display() -> str:
    """A virtual X server's display name, e.g. ':7', for windowed tests (skipped without Xvfb)."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("Xvfb is not installed")
    read_end, write_end = os.pipe()
    server = subprocess.Popen([xvfb, "-displayfd", str(write_end), "-nolisten", "tcp", "-screen", "0",
                               "1600x1000x24"], pass_fds=(write_end,), stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    os.close(write_end)
    try:
        with os.fdopen(read_end) as pipe:
            number = pipe.readline().strip()  # written once the server is ready, newline last
        assert number, "Xvfb did not start"
        yield f":{number}"
    finally:
        server.terminate()
        server.wait()
