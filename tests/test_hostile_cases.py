"""The hostile cases of issue 42 (../shared/reports/hostile-cases.md; each case named by its ID
there) that used to end in a traceback, a hang or a lost file: each now fails as a trusted tool
does (tests/helpers/bad_inputs.py: exit 2, one `edgedog: error:` line naming the file or option,
no traceback, every file that was there unchanged byte for byte), within a time limit.
"""

from __future__ import annotations

import os
import shutil
import signal
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgedog.scenes import load_scene
from edgedog.train.run_folder import RunLock
from tests.helpers.bad_inputs import Case, assert_fails_cleanly, cases_as_params, edgedog_in_process
from tests.helpers.tiny_runs import QUICK_TRAIN as TRAIN
from tests.helpers.tiny_runs import finished_run

CASE_SECONDS = 60
"""Each case's limit (a case takes about a second; a hang used to take forever)."""
DEEP = "[" * 200_000 + "]" * 200_000
"""Nested far beyond the reader's 64 levels and Python's recursion limit."""
HUGE_INT = "9" * 5000
"""More digits than Python converts (4300) and than the reader takes (100)."""

SCENE: Path
RUN: Path


@pytest.fixture(scope="module", autouse=True)
def scene_and_run(small_box_scene, tmp_path_factory):
    """The small box scene and a finished run of it, copied by the cases that change them."""
    global SCENE, RUN
    SCENE, RUN = small_box_scene, finished_run(small_box_scene, tmp_path_factory.mktemp("hostile") / "run")


@contextmanager
def time_limit(seconds: int):
    """A case still running after `seconds` is interrupted (and fails as an internal error)."""
    def interrupt(*_):
        raise TimeoutError(f"still running after {seconds} s")
    previous = signal.signal(signal.SIGALRM, interrupt)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def copied_run(folder: Path) -> Path:
    shutil.copytree(RUN, folder / "run")
    return folder / "run"


def copied_scene(folder: Path) -> Path:
    shutil.copytree(SCENE, folder / "scene")
    return folder / "scene"


def run_file(name: str, content: str | None, command):
    """A case: the copied run's `name` holding `content` (None: a symlink to /dev/zero), then
    `command(run)`; the error must name the file."""
    def build(folder: Path):
        run = copied_run(folder)
        (run / name).unlink()
        if content is None:
            (run / name).symlink_to("/dev/zero")
        else:
            (run / name).write_text(content)
        return command(run), [run / name]
    return build


def resume(run: Path) -> list:
    return ["train", SCENE, "--out", run, "--resume", "--quiet"]


def extract(run: Path) -> list:
    return ["extract", run]


def export_obj(run: Path) -> list:
    return ["export", run, "--format", "obj"]


def scene_file(name: str, content: str, command):
    """A case: a copy of the scene with `name` holding `content`, then `command(scene, folder)`."""
    def build(folder: Path):
        scene = copied_scene(folder)
        (scene / name).write_text(content)
        return command(scene, folder), [scene / name]
    return build


def info(scene: Path, folder: Path) -> list:
    return ["info", scene]


def train(scene: Path, folder: Path) -> list:
    return ["train", scene, "--out", folder / "new-run", *TRAIN]


def evaluated(name: str, content: str):
    """A case: `eval` of the prediction file `name` holding `content` against the scene."""
    def build(folder: Path):
        (folder / name).write_text(content)
        return ["eval", folder / name, "--scene", SCENE], [folder / name]
    return build


def suite(content: str):
    def build(folder: Path):
        (folder / "suite.yaml").write_text(content)
        return ["batch", folder / "suite.yaml", "--out", folder / "batch"], [folder / "suite.yaml"]
    return build


def into_run(argv_of, name: str):
    """A case: a command writing the copied run's own file `name` (`argv_of(run, target)`)."""
    def build(folder: Path):
        run = copied_run(folder)
        return argv_of(run, run / name), [run / name, "is a file of the run"]
    return build


def beside(argv_of, name: str, words=("already exists", "--force")):
    """A case: a command writing `name` where a file of the user's is (`argv_of(run, target)`)."""
    def build(folder: Path):
        (folder / name).write_text("mine")
        return argv_of(copied_run(folder), folder / name), [folder / name, *words]
    return build


def export_json_to(run: Path, target: Path) -> list:
    return ["export", run, "--format", "json", "--out", target]


def export_ply_to(run: Path, target: Path) -> list:
    return ["export", run, "--format", "ply", "--out", target]


def init_to(run: Path, target: Path) -> list:
    return ["init", SCENE, "--method", "uniform", "--uniform-count", "100", "--out", target]


def bench_raster_to(run: Path, target: Path) -> list:
    return ["bench", "raster", "--views", "1", "--primitives", "10", "--size", "16", "--json", target]


def eval_to(run: Path, target: Path) -> list:
    return ["eval", run / "curves.obj", "--scene", SCENE, "--json", target]


def inside_scene(argv_of):
    """A case: a command told to write into (a copy of) the scene folder."""
    def build(folder: Path):
        scene = copied_scene(folder)
        return argv_of(scene), [scene, "inside the scene folder"]
    return build


HELD: list[RunLock] = []


def into_held_run(folder: Path):
    """CONC-5: export into a run folder whose lock another writer holds."""
    run = copied_run(folder)
    HELD.append(RunLock.acquire(run))
    return ["export", RUN, "--format", "obj", "--out", run / "x.obj"], [run, "in use"]


def folder_with(names: tuple[str, ...], argv_of):
    """A case: a command filling a folder that holds the user's `names`."""
    def build(folder: Path):
        out = folder / "out"
        out.mkdir()
        for name in names:
            (out / name).write_text("mine")
        return argv_of(out), [out, "did not write"]
    return build


def edited_map(folder: Path):
    """RES-editedmaps: --resume with a copy of the scene whose first shipped edge map was blanked."""
    run, scene = copied_run(folder), copied_scene(folder)
    edge_map = sorted((scene / "train").glob("*.png"))[0]
    cv2.imwrite(str(edge_map), np.zeros_like(cv2.imread(str(edge_map), cv2.IMREAD_UNCHANGED)))
    return ["train", scene, "--out", run, "--resume", "--quiet"], [run, "other edge maps or masks"]


def batch_into(out: Path) -> list:
    (out.parent / "suite.yaml").write_text(f"scenes: [{SCENE}]\n")
    return ["batch", out.parent / "suite.yaml", "--out", out]


def far_ground_truth(folder: Path):
    """EV-gt-nan: ground-truth points so far out that the distances to them overflow to Infinity."""
    (folder / "far.ply").write_text("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                                    "property float y\nproperty float z\nend_header\n0 0 0\n1e38 0 0\n")
    return (["eval", RUN / "curves.obj", "--gt", folder / "far.ply", "--json", folder / "x.json"],
            [folder / "far.ply", "beyond"])


CASES = [
    # item 2: the reader -- depth, digits, size, devices
    Case("CFG-cfg_deep", run_file("config.json", DEEP, resume)),
    Case("CFG-cfg_bigint", run_file("config.json", '{"scene": "x", "config": {"schedule": {"epochs": '
                                    + HUGE_INT + "}}}", resume)),
    Case("CFG-cfg_nan", run_file("config.json", '{"scene": "x", "config": {"schedule": {"lr_means": NaN}}}',
                                 resume)),
    Case("EX-log_deep", run_file("log.json", DEEP, extract)),
    Case("EX-log_devzero", run_file("log.json", None, extract)),
    Case("EX-log_bigint", run_file("log.json", '{"scene": "x", "detector": ' + HUGE_INT + "}", extract)),
    Case("EXP-curves_deep", run_file("curves.json", DEEP, export_obj)),
    Case("EXP-curves_devzero", run_file("curves.json", None, export_obj)),
    Case("SC-deepjson", scene_file("transforms_train.json", DEEP, info)),
    Case("SC-bigint", scene_file("transforms_train.json", '{"frames": [' + HUGE_INT + "]}", info)),
    Case("SC-deepjson-train", scene_file("transforms_train.json", DEEP, train)),
    Case("EV-json_deep-json", evaluated("deep.json", DEEP)),
    Case("EV-json_bigint-json", evaluated("big.json", '{"curves_ctl_pts": [' + HUGE_INT + "]}")),
    Case("BA-deep", suite(DEEP)),
    Case("BA-deep-block", suite("".join("  " * i + "-\n" for i in range(5000)))),
    Case("BA-alias", suite("a: &a [1]\nscenes: *a\n")),
    Case("BA-bigint", suite("scenes: [x]\nseeds: [" + HUGE_INT + "]\n")),
    # item 1: the output policy -- a run's files, the user's files, scenes, held runs
    Case("EXP-clobber-config", into_run(export_json_to, "config.json")),
    Case("EXP-clobber-prims", into_run(export_ply_to, "primitives.ply")),
    Case("IN-out-runcfg", into_run(init_to, "primitives.ply")),
    Case("BE-json-clobber", into_run(bench_raster_to, "config.json")),
    Case("EV-json-clobber", into_run(eval_to, "log.json")),
    Case("EXP-out-existing", beside(export_json_to, "mine.json")),
    Case("IN-out-existing", beside(init_to, "points.ply")),
    Case("BE-json-existing", beside(bench_raster_to, "bench.json")),
    Case("EV-json-existing", beside(eval_to, "metrics.json")),
    Case("EXP-out-scene", inside_scene(lambda scene: ["export", RUN, "--format", "obj", "--out",
                                                      scene / "curves.obj"])),
    Case("IN-out-scene", inside_scene(lambda scene: init_to(RUN, scene / "points.ply"))),
    Case("OUT-insidescene", inside_scene(lambda scene: ["train", scene, "--out", scene / "myrun", *TRAIN])),
    Case("BA-out-scene", inside_scene(lambda scene: ["bench", "steps", scene, "--out", scene / "steps"])),
    Case("CONC-5", into_held_run),
    Case("BA-nonempty-out", folder_with(("batch.md", "batch.csv"), batch_into)),
    Case("BE-steps-out", folder_with(("notes.txt",), lambda out: ["bench", "steps", SCENE, "--out", out])),
    Case("BE-abl-out", folder_with(("ablation.md",), lambda out: ["bench", "ablation", SCENE, "--out", out])),
    Case("BE-se-out", folder_with(("batch.json",), lambda out: ["bench", "speed-error", SCENE, "--out",
                                                                out])),  # not a record of ours: "mine"
    Case("EV-gt-nan", far_ground_truth),
    # item 4: the resume fingerprint covers the shipped edge maps and masks
    Case("RES-editedmaps", edited_map),
    # item 3: numbers that size a loop
    Case("BE-se-evals", lambda folder: (["bench", "speed-error", SCENE, "--out", folder / "se", "--evals",
                                         "1000000000"], ["--evals"])),
    Case("CAL-views", lambda folder: (["calibrate-detector", "--detector", "sobel", "--views", "1000000000"],
                                      ["--views"])),
    Case("CAL-sizes", lambda folder: (["calibrate-detector", "--detector", "sobel", "--sizes", "100000"],
                                      ["--sizes"])),
]




def argv(name: str, *args, words=()):
    """A case of the report that needs no crafted file: `edgedog ARGS` (the case's folder as `{}`)."""
    def build(folder: Path):
        return [str(arg).replace("{}", str(folder)) for arg in args], list(words)
    return Case(name, build)


def suite_text(name: str, text: str, *words: str) -> Case:
    def build(folder: Path):
        argv_, files = suite(text.replace("SCENE", str(SCENE)))(folder)
        return argv_, [*files, *words]
    return Case(name, build)


# The report's one-line refusals that held already: kept as they are.
HELD_CASES = [
    argv("TS-unknown", "train", "{SCENE}", "--out", "{}/ts", "--set", "nosuch=1", words=["nosuch"]),
    argv("TS-noeq", "train", "{SCENE}", "--out", "{}/ts", "--set", "epochs", words=["expected KEY=VALUE"]),
    argv("TS-epochsbig", "train", "{SCENE}", "--out", "{}/ts", "--set", "epochs=1000000000000",
         words=["schedule.epochs"]),
    argv("TS-maxprim", "train", "{SCENE}", "--out", "{}/ts", "--set", "max_primitives=1000000000000000",
         words=["strategy.max_primitives"]),
    argv("TS-downscale", "train", "{SCENE}", "--out", "{}/ts", "--set", "downscale=1000",
         words=["maps.downscale"]),
    argv("TS-noscene", "train", "{}/nosuchscene", "--out", "{}/ts", words=["scene folder not found"]),
    argv("OUT-slash", "train", "{SCENE}", "--out", "/", words=["not empty"]),
    argv("RES-missing", "train", "{SCENE}", "--out", "{}/nothere", "--resume", words=["nothing to resume"]),
    argv("IN-count-huge", "init", "{SCENE}", "--method", "uniform", "--uniform-count", "1000000000000",
         words=["--uniform-count"]),
    argv("IN-side-nan", "init", "{SCENE}", "--method", "uniform", "--uniform-side", "nan",
         words=["--uniform-side"]),
    argv("IN-minpts-neg", "init", "{SCENE}", "--min-points", "-1", words=["--min-points"]),
    argv("IN-neigh-huge", "init", "{SCENE}", "--match-neighbours", "1000000000",
         words=["--match-neighbours"]),
    argv("IN-out-slash", "init", "{SCENE}", "--method", "uniform", "--out", "/", words=["is a folder"]),
    argv("IN-thresh", "init", "{SCENE}", "--edge-threshold", "5", words=["--edge-threshold"]),
    argv("ED-detector-bad", "edges", "{SCENE}", "--detector", "sobel:1,2", words=["sobel takes no options"]),
    argv("ED-canny-neg", "edges", "{SCENE}", "--detector", "canny:-5,99999999999", words=["canny:-5"]),
    argv("ED-downscale0", "edges", "{SCENE}", "--detector", "canny", "--downscale", "0",
         words=["--downscale"]),
    argv("ED-downscale-huge", "edges", "{SCENE}", "--detector", "canny", "--downscale", "1000000",
         words=["--downscale"]),
    argv("ED-bg-nan", "edges", "{SCENE}", "--background", "nan,0,0", words=["--background"]),
    argv("ED-bg-range", "info", "{SCENE}", "--background", "5,5,5", words=["--background"]),
    argv("BE-raster-huge", "bench", "raster", "--primitives", "1000000000000", words=["--primitives"]),
    argv("BE-raster-size", "bench", "raster", "--size", "1000000", words=["--size"]),
    argv("BE-raster-views0", "bench", "raster", "--views", "0", words=["--views"]),
    argv("BE-edges-rep", "bench", "edges", "--repeats", "-1", words=["--repeats"]),
    argv("BE-abl-rows", "bench", "ablation", "{SCENE}", "--out", "{}/abl", "--rows", "nosuch",
         words=["--rows"]),
    argv("BE-abl-seeds", "bench", "ablation", "{SCENE}", "--out", "{}/abl", "--seeds", "-1",
         words=["--seeds"]),
    argv("BE-se-budgets", "bench", "speed-error", "{SCENE}", "--out", "{}/se", "--budgets", "nosuch",
         words=["--budgets"]),
    argv("SFM-maxsize0", "sfm", "{SCENE}/train_img", "--out", "{}/sfm", "--max-image-size", "0",
         words=["--max-image-size"]),
    argv("SFM-missing", "sfm", "{}/nophotos", "--out", "{}/sfm", words=["photo folder not found"]),
    argv("CLI-badcmd", "nosuchcommand", words=["nosuchcommand"]),
    argv("EV-gt-missing", "eval", "{RUN}/curves.obj", "--gt", "{}/nothing.ply", words=["file not found"]),
    suite_text("BA-pyobj", "scenes: !!python/object/apply:os.system ['true']\n", "invalid YAML"),
    suite_text("BA-seeds1e9", "scenes: [SCENE]\nseeds: [1000000000000]\n", "seeds"),
    suite_text("BA-dotdot2", "scenes: [SCENE]\nrows: {'../../escape': {}}\n", "rows"),
    suite_text("BA-badtypes", "scenes: 5\n", "'scenes'"),
    suite_text("BA-syntax", "scenes: [\n- bad: yaml: here\n", "invalid YAML"),
    suite_text("BA-unknownkey", "scenes: [SCENE]\nsed: 1\n", "unknown key 'sed'"),
    suite_text("BA-badset", "scenes: [SCENE]\nset: ['epochs=1e309']\n", "schedule.epochs"),
    suite_text("BA-billion2", "scenes: [SCENE]\ngrid: {epochs: [" + ", ".join(map(str, range(1, 1001)))
               + "], init.count: [" + ", ".join(map(str, range(1, 1001))) + "]}\n", "more than 10000"),
]


def with_paths(case: Case) -> Case:
    """`case` with {SCENE} and {RUN} in its command line and words replaced by the module's."""
    def build(folder: Path):
        args, words = case.build(folder)
        named = {"{SCENE}": str(SCENE), "{RUN}": str(RUN)}
        for key, value in named.items():
            args = [arg.replace(key, value) for arg in map(str, args)]
        return args, words
    return Case(case.name, build, case.returncode)


@pytest.mark.parametrize("case", cases_as_params(CASES + [with_paths(case) for case in HELD_CASES]))
def test_hostile_case_fails_cleanly(case, tmp_path):
    try:
        with time_limit(CASE_SECONDS):
            assert_fails_cleanly(case, tmp_path)
    finally:
        while HELD:
            HELD.pop().release()


def test_a_refused_train_leaves_nothing_behind(tmp_path):
    """TR-notpng_edge: an edge map that cannot be decoded refuses the run before it trains, leaving
    no folder, config.json or lock: the same command then says the same (it used to say "already
    holds a run"), and an empty folder given as --out stays empty."""
    scene = copied_scene(tmp_path)
    edge_map = sorted((scene / "train").glob("*.png"))[0]
    edge_map.write_bytes(b"not a png")
    case = Case("TR-notpng_edge", lambda folder: (train(scene, folder), [edge_map, "cannot be decoded"]))
    for _ in range(2):
        assert_fails_cleanly(case, tmp_path)
        assert not (tmp_path / "new-run").exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    assert_fails_cleanly(Case("into-empty", lambda folder: (["train", scene, "--out", empty, *TRAIN],
                                                            [edge_map])), tmp_path)
    assert os.listdir(empty) == []


def test_force_replaces_a_users_file_and_the_default_output_is_replaced_as_before(tmp_path):
    run = copied_run(tmp_path)
    mine = tmp_path / "mine.obj"
    mine.write_text("mine")
    export = ["export", run, "--format", "obj"]
    for argv in ([*export, "--out", mine, "--force"], export, export):
        done = edgedog_in_process(argv, tmp_path)
        assert done.returncode == 0, done.stderr
    assert mine.read_bytes() == (run / "curves_world.obj").read_bytes() != b"mine"


def test_views_beyond_the_memory_budget_are_refused_with_the_downscale_that_fits(tmp_path, monkeypatch):
    """TR-bigimg_all (12 views of 11000 px square, 4.5 GB, then cv2 out of memory): here the small
    scene against a budget it exceeds at full size and fits at 1/4 (about 8.3 MB and 0.8 MB)."""
    from edgedog.train import memory

    monkeypatch.setattr(memory, "memory_limit", lambda: 1_000_000)
    case = Case("TR-bigimg_all", lambda folder: (train(SCENE, folder),
                                                 [SCENE, "GiB of memory", "--set maps.downscale=4 fits"]))
    assert_fails_cleanly(case, tmp_path)
    assert not (tmp_path / "new-run").exists()
    needed = [memory.views_memory(load_scene(SCENE), downscale) for downscale in (1, 3, 4)]
    assert needed[2] <= 1_000_000 < needed[1] < needed[0]


def test_ray_that_cannot_start_is_one_line(tmp_path, monkeypatch):
    """BA-nonempty-out under `ulimit -v`: Ray failing to start was a traceback (here its start
    raises the MemoryError that the address-space limit gave)."""
    from types import SimpleNamespace

    from edgedog.batch import executors

    def no_memory(**_):
        raise MemoryError("std::bad_alloc")

    monkeypatch.setattr(executors, "import_ray", lambda: SimpleNamespace(init=no_memory))
    case = Case("BA-ray-start", lambda folder: (batch_into(folder / "out"),
                                                ["cannot start Ray (MemoryError: std::bad_alloc)"]))
    assert_fails_cleanly(case, tmp_path)
