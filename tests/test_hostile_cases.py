"""The hostile cases of issue 42 (../shared/reports/hostile-cases.md; each case named by its ID
there) that used to end in a traceback, a hang or a lost file: each now fails as a trusted tool
does (tests/helpers/bad_inputs.py: exit 2, one `edgedog: error:` line naming the file or option,
no traceback, every file that was there unchanged byte for byte), within a time limit.
"""

from __future__ import annotations

import json
import os
import pickle
import resource
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgedog.scenes import load_scene
from edgedog.train.run_folder import RunLock
from tests.helpers.bad_inputs import Case, assert_fails_cleanly, cases_as_params, edgedog_in_process
from tests.helpers.hostile_files import (
    CodeInPickle,
    checkpoint,
    colmap_as_binary,
    edited_json,
    obj_of_lines,
    place,
    ply_header,
    png_declaring,
    zero_png,
)
from tests.helpers.paths import shared_path
from tests.helpers.scene_builders import make_colmap, make_nerf
from tests.helpers.tiny_runs import QUICK_TRAIN as TRAIN
from tests.helpers.tiny_runs import finished_run

CASE_SECONDS = 60
"""Each case's limit (a case takes about a second; a hang used to take forever)."""
CASE_MEMORY = 512 * 2**20
"""How much a case may raise the peak resident memory of the process that runs it (bytes)."""
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


def suite_text(name: str, text: str, *words: str, folders: tuple[str, ...] = ()) -> Case:
    """A batch case: suite.yaml of `text` (SCENE: the built-in scene) beside the empty `folders`."""
    def build(folder: Path):
        for relative in folders:
            (folder / relative).mkdir(parents=True)
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


ENV_BEFORE: dict[str, str | None] = {}
"""Environment variables a case set, with their values before it (restored after the case)."""


def row(name: str, *args, prep=None, rc: int = 2, words=(), env=None, rewrites=()) -> Case:
    """A case of the table as the report wrote it: `edgedog ARGS` where {} is the case's folder,
    {SCENE} and {RUN} the module's scene and run (read, never changed), {scene} and {run} copies of
    them in the folder (made when named); `prep(folder)` then crafts the files, `env` sets
    variables for the case. The error line (or, with rc 0, the output) holds every word; a
    succeeding case may rewrite its own outputs `rewrites` (paths in the folder)."""
    def build(folder: Path):
        text = " ".join(map(str, [*args, *words]))
        if "{run}" in text:
            copied_run(folder)
        if "{scene}" in text:
            copied_scene(folder)
        if prep is not None:
            prep(folder)
        for key, value in (env or {}).items():
            ENV_BEFORE.setdefault(key, os.environ.get(key))
            os.environ[key] = value.replace("{}", str(folder))
        named = {"{SCENE}": SCENE, "{RUN}": RUN, "{scene}": folder / "scene", "{run}": folder / "run",
                 "{}": folder}
        if "{SHARED}" in text:  # the real datasets: the case skips where they are absent
            named["{SHARED}"] = shared_path(".")

        def expand(arg) -> str:
            arg = str(arg)
            for key, value in named.items():
                arg = arg.replace(key, str(value))
            return arg
        return [expand(arg) for arg in args], [expand(word) for word in words]
    return Case(name, build, rc, tuple(rewrites))


def with_paths(case: Case) -> Case:
    """`case` with {SCENE} and {RUN} in its command line and words replaced by the module's."""
    def build(folder: Path):
        args, words = case.build(folder)
        named = {"{SCENE}": str(SCENE), "{RUN}": str(RUN)}
        for key, value in named.items():
            args = [arg.replace(key, value) for arg in map(str, args)]
        return args, words
    return Case(case.name, build, case.returncode)


# --- The rest of the report's cases (by ID), as it ran them; where a case changed since the
# report (e.g. a file that is now refused), the row asserts today's behaviour.

def in_run(name: str, content):
    """prep: the copied run's file `name` holding `content` (see hostile_files.place)."""
    return lambda folder: place(folder / "run" / name, content)


def in_scene(name: str, content):
    return lambda folder: place(folder / "scene" / name, content)


def crafted_checkpoint(kind: str):
    return lambda folder: checkpoint(folder / "run" / "checkpoint.pt", kind)


def config_edit(edit):
    return lambda folder: edited_json(folder / "run" / "config.json", edit)


def settings(section: str, key: str, value):
    return config_edit(lambda data: data["config"][section].__setitem__(key, value))


def transforms(edit):
    return lambda folder: edited_json(folder / "scene" / "transforms_train.json", edit)


def frame(index: int, key: str, value):
    return transforms(lambda meta: meta["frames"][index].__setitem__(key, value))


def matrix(index: int, change):
    def edit(meta):
        pose = np.array(meta["frames"][index]["transform_matrix"], dtype=float)
        meta["frames"][index]["transform_matrix"] = change(pose).tolist()
    return transforms(edit)


def focal(index: int, value: float):
    return transforms(lambda meta: meta["frames"][index]["camera_intrinsics"][0].__setitem__(0, value))


def image(name: str, change):
    """prep: the copied scene's image `name` (e.g. train_img/3.png) changed by `change(path)`."""
    return lambda folder: change(folder / "scene" / name)


def resized(path: Path):
    cv2.imwrite(str(path), cv2.resize(cv2.imread(str(path)), (50, 70)))


def truncated(path: Path):
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def one_pixel(path: Path):
    pixels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    pixels.flat[0] = 255 - pixels.flat[0]
    cv2.imwrite(str(path), pixels)


def linked(target: str):
    """change: the file replaced by a symlink to `target` ({SCENE}: the module's scene)."""
    def change(path: Path):
        path.unlink()
        path.symlink_to(target.replace("{SCENE}", str(SCENE)))
    return change


def image_folder_linked(folder: Path):
    """SC-symdir: the copied scene's train_img is a symlink to the module's (outside the copy)."""
    shutil.rmtree(folder / "scene" / "train_img")
    (folder / "scene" / "train_img").symlink_to(SCENE / "train_img")


def big_views(folder: Path):
    """SC-bigimg_all: the 12 training images of 11000 px square (121 MP each, 470 KB)."""
    first, *rest = sorted((folder / "scene" / "train_img").glob("*.png"))
    data = zero_png(first, 11000)
    for path in rest:
        path.write_bytes(data)
    scale = 11000 / cv2.imread(str(SCENE / "train_img" / first.name)).shape[1]

    def cameras(meta):
        for each in meta["frames"]:
            each["camera_intrinsics"] = (np.array(each["camera_intrinsics"]) * [[scale], [scale],
                [1]]).tolist()
    edited_json(folder / "scene" / "transforms_train.json", cameras)


def files(**named):
    """prep: files in the case's folder (name -> content, see hostile_files.place; '/' in a name
    makes its folders)."""
    def prep(folder: Path):
        for name, content in named.items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            place(folder / name, content)
    return prep


def links(**named):
    """prep: symlinks in the case's folder (name -> target, {} the folder)."""
    def prep(folder: Path):
        for name, target in named.items():
            (folder / name).symlink_to(target.replace("{}", str(folder)))
    return prep


def both(*preps):
    def prep(folder: Path):
        for each in preps:
            each(folder)
    return prep


def other_scene(folder: Path):
    make_nerf(folder / "other")


def exported_config(folder: Path):
    """EXP-clobber-after: config.json holding what `export --format json` writes (curves)."""
    shutil.copyfile(folder / "run" / "curves.json", folder / "run" / "config.json")


def prims_from_curves(folder: Path):
    shutil.copyfile(folder / "run" / "curves.ply", folder / "run" / "primitives.ply")


def prims_nan(folder: Path):
    path = folder / "run" / "primitives.ply"
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    path.write_bytes(data[:end] + b"\x00\x00\xc0\x7f" * ((len(data) - end) // 4))


def prims_header(count: str):
    def prep(folder: Path):
        path = folder / "run" / "primitives.ply"
        data = path.read_bytes()
        start = data.index(b"element vertex ") + len(b"element vertex ")
        path.write_bytes(data[:start] + count.encode() + data[data.index(b"\n", start):])
    return prep


def no_ground_truth(folder: Path):
    shutil.rmtree(folder / "scene" / "gt")


def colmap_counting(count: int):
    """prep: a COLMAP scene with a binary model whose images.bin declares `count` images (pycolmap
    looped for ever on 2**64 - 1)."""
    def prep(folder: Path):
        model = colmap_as_binary(make_colmap(folder / "colmap"))
        data = (model / "images.bin").read_bytes()
        (model / "images.bin").write_bytes(count.to_bytes(8, "little") + data[8:])
    return prep


def evil_torch_weights(folder: Path):
    """ED-weights-rce2: a torch zip whose pickle would run os.system, named as PiDiNet's weights."""
    import torch

    (folder / "w").mkdir()
    torch.save({"state_dict": CodeInPickle(folder / "PWNED")}, folder / "w" / "table5_pidinet.pth")


RESUME = ("train", "{SCENE}", "--out", "{run}", "--resume", "--quiet")
TRAIN_NEW = ("--out", "{}/new", *TRAIN)
CKPT = "{run}/checkpoint.pt"
CFG = "{run}/config.json"
TJSON = "{scene}/transforms_train.json"
EVAL = ("--scene", "{SCENE}")
CURVE = '{"curves_ctl_pts": [[[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]]}'
ROWS = "".join(f"  {name}: []\n" for name in ("a", "b", "c", "d", "e", "f", "g", "h", "i"))

REPORT_ROWS = [
    row("T0", "train", "{SCENE}", *TRAIN_NEW, rc=0, words=["outputs in {}/new"]),
    # crafted checkpoints: never loaded as code, one line each
    *(row(f"CK-{kind}", *RESUME, prep=crafted_checkpoint(kind), words=[CKPT, *expected])
      for kind, expected in [("rce_raw", []), ("rce_zip", []), ("zip_trav", []), ("trunc", []),
                             ("empty", []), ("random", []), ("hugetensor", ["model.means"]),
                             ("nanmeans", ["model.means"]), ("stepneg", ["step_index"]),
                             ("stepstr", ["step_index"]), ("shape", ["model.log_scales"]),
                             ("optbad", []), ("genbad", []), ("hugestorage", ["record size"])]),
    row("CK-stephuge", *RESUME, prep=crafted_checkpoint("stephuge"), rc=0, rewrites=["run/log.json"]),
    row("CK-histbad", *RESUME, prep=crafted_checkpoint("histbad"), rc=0, rewrites=["run/log.json"]),
    row("CK-ckdir", *RESUME, prep=in_run("checkpoint.pt", "DIR"), words=[CKPT, "folder"]),
    row("CK-ckdevzero", *RESUME, prep=in_run("checkpoint.pt", "/dev/zero"), words=[CKPT]),
    row("CK-ckurandom", *RESUME, prep=in_run("checkpoint.pt", "/dev/urandom"), words=[CKPT]),
    row("EX-ck-trunc", "extract", "{run}", prep=crafted_checkpoint("trunc"), rc=0, words=["wrote"]),
    row("EX-ck-rce_zip", "extract", "{run}", prep=crafted_checkpoint("rce_zip"), rc=0, words=["wrote"]),
    # crafted config.json
    row("CFG-cfg_epochs_str", *RESUME, prep=settings("schedule", "epochs", "abc"), words=[CFG, "epochs"]),
    row("CFG-cfg_epochs_huge", *RESUME, prep=settings("schedule", "epochs", 10**30), words=[CFG, "epochs"]),
    row("CFG-cfg_badjson", *RESUME, prep=in_run("config.json", '{"scene": "x", "config": {"a": 1, , }}'),
        words=[CFG, "invalid JSON"]),
    row("CFG-cfg_config_list", *RESUME, prep=config_edit(lambda data: data.__setitem__("config", [])),
        words=[CFG, "'config'"]),
    row("CFG-cfg_version99", *RESUME, prep=config_edit(lambda data: data.__setitem__("version", 99)),
        words=[CFG, "version 99"]),
    # The run resumes on the scene passed, whose fingerprint is the recorded one (as RES-moved): the
    # folder recorded, /etc, is never read.
    row("CFG-cfg_scene_etc", *RESUME, prep=config_edit(lambda data: data.__setitem__("scene", "/etc")), rc=0,
        rewrites=["run/log.json"]),
    row("CFG-cfg_init_huge", *RESUME, prep=settings("init", "count", 10**10), words=[CFG, "init.count"]),
    row("CFG-cfg_downscale0", *RESUME, prep=settings("maps", "downscale", 0), words=[CFG, "maps.downscale"]),
    row("CFG-cfg_unknown", *RESUME, prep=config_edit(lambda data: data["config"].__setitem__("unknown_x",
        {})),
        words=[CFG, "unknown_x"]),
    row("CFG-cfg_seedneg", *RESUME, prep=settings("run", "seed", -1), words=[CFG, "run.seed"]),
    row("CFG-cfg_detector_trav", *RESUME, prep=settings("maps", "detector", "../../../etc/passwd"),
        words=["../../../etc/passwd"]),
    # a run's log.json and primitives.ply for extract
    row("EX-log_badtypes", "extract", "{run}", prep=in_run("log.json", '{"scene": 5, "detector": []}'),
        words=["{run}/log.json"]),
    row("EX-log_detector_trav", "extract", "{run}",
        prep=lambda folder: place(folder / "run" / "log.json",
                                  json.dumps({"scene": str(SCENE), "detector": "../../../../etc"})),
        words=["../../../../etc"]),
    row("EX-log_garbage", "extract", "{run}", prep=in_run("log.json", b"\xff\xfe\x00garbage"),
        words=["{run}/log.json"]),
    row("EX-log_missing", "extract", "{run}", prep=in_run("log.json", "MISSING"),
        words=["{run}/log.json", "not found"]),
    row("EX-ply_hugecount", "extract", "{run}", prep=prims_header("100000000000"),
        words=["{run}/primitives.ply"]),
    row("EX-ply_negcount", "extract", "{run}", prep=prims_header("-5"), words=["{run}/primitives.ply"]),
    row("EX-ply_trunc", "extract", "{run}", prep=lambda folder: truncated(folder / "run" / "primitives.ply"),
        words=["{run}/primitives.ply"]),
    row("EX-ply_noheader", "extract", "{run}", prep=in_run("primitives.ply", "no header here\n"),
        words=["{run}/primitives.ply"]),
    row("EX-ply_nan", "extract", "{run}", prep=prims_nan, words=["{run}/primitives.ply", "NaN"]),
    row("EX-ply_symlink_passwd", "extract", "{run}", prep=in_run("primitives.ply", "/etc/passwd"),
        words=["{run}/primitives.ply"]),
    # export
    row("EXP-curves_garbage", "export", "{run}", "--format", "obj",
        prep=in_run("curves.json", '{"curves_ctl_pts": 5}'), words=["{run}/curves.json"]),
    row("EXP-curves_nan", "export", "{run}", "--format", "obj",
        prep=in_run("curves.json", CURVE.replace("1,", "NaN,")), words=["{run}/curves.json"]),
    row("EXP-curves_1e308", "export", "{run}", "--format", "obj",
        prep=in_run("curves.json", CURVE.replace("1,", "1e308,")), words=["{run}/curves.json", "beyond"]),
    row("EXP-gt-1e308", "export", "{run}", "--format", "ply", "--frame", "gt",
        prep=in_run("curves.json", CURVE.replace("1,", "1e308,")), words=["{run}/curves.json", "beyond"]),
    row("EXP-out-slash", "export", "{RUN}", "--format", "obj", "--out", "/", words=["/:"]),
    row("EXP-out-wrongext", "export", "{RUN}", "--format", "obj", "--out", "{}/x.txt", words=["{}/x.txt"]),
    row("EXP-out-noparent", "export", "{RUN}", "--format", "obj", "--out", TJSON + "/x.obj",
        words=[TJSON + "/x.obj"]),
    row("EXP-clobber-after", *RESUME, prep=exported_config, words=[CFG, "'scene' and 'config'"]),
    row("EXP-curves_nan2", "export", "{run}", "--format", "ply",
        prep=in_run("curves.json", CURVE.replace("1,", "NaN,")), words=["{run}/curves.json"]),
    row("EXP-clobber-prims-after", "extract", "{run}", prep=prims_from_curves,
        words=["{run}/primitives.ply", "not a primitives PLY"]),
    # train --out
    row("OUT-file", "train", "{SCENE}", "--out", "{}/afile", *TRAIN, prep=files(afile="x"),
        words=["{}/afile", "is a file"]),
    row("OUT-scene", "train", "{scene}", "--out", "{scene}", *TRAIN, words=["{scene}"]),
    row("OUT-nonrun", "train", "{SCENE}", "--out", "{}/nonrun", *TRAIN, prep=files(**{"nonrun/a.txt": "x"}),
        words=["{}/nonrun", "not empty"]),
    row("OUT-existingrun", "train", "{SCENE}", "--out", "{run}", *TRAIN, words=["{run}",
        "already holds a run"]),
    row("OUT-underfile", "train", "{SCENE}", "--out", "{}/afile/run", *TRAIN, prep=files(afile="x"),
        words=["{}/afile/run"]),
    row("OUT-proc", "train", "{SCENE}", "--out", "/proc/self/run", *TRAIN, words=["/proc/self/run"]),
    row("OUT-symlink-nonrun", "train", "{SCENE}", "--out", "{}/link", *TRAIN,
        prep=both(files(**{"nonrun/a.txt": "x"}), links(link="{}/nonrun")), words=["{}/link"]),
    row("OUT-symloop", "train", "{SCENE}", "--out", "{}/loopA", *TRAIN,
        prep=links(loopA="{}/loopB", loopB="{}/loopA"), words=["{}/loopA"]),
    row("OUT-broken", "train", "{SCENE}", "--out", "{}/broken", *TRAIN, prep=links(broken="{}/nowhere"),
        words=["{}/broken", "broken symbolic link"]),
    # --resume
    row("RES-nonrun", "train", "{SCENE}", "--out", "{}/nonrun", "--resume", "--quiet",
        prep=files(**{"nonrun/a.txt": "x"}), words=["{}/nonrun", "nothing to resume"]),
    row("RES-set", *RESUME, "--set", "epochs=5", words=["{run}", "--set"]),
    row("RES-preset", *RESUME, "--preset", "full", words=["{run}", "--preset"]),
    row("RES-otherscene", "train", "{}/other", "--out", "{run}", "--resume", "--quiet", prep=other_scene,
        words=["{run}", "other cameras or images"]),
    row("RES-editedimg", "train", "{scene}", "--out", "{run}", "--resume", "--quiet",
        prep=image("train_img/0.png", one_pixel), words=["{run}", "other cameras or images"]),
    row("RES-moved", "train", "{scene}", "--out", "{run}", "--resume", "--quiet", rc=0,
        rewrites=["run/log.json"]),
    row("RES-editedpose", "train", "{scene}", "--out", "{run}", "--resume", "--quiet",
        prep=matrix(0, lambda pose: pose + np.pad([[0.001]], ((0, 3), (3, 0)))),
        words=["{run}", "other cameras or images"]),
    row("RES-editedmaps-note", "train", "{scene}", "--out", "{run}", "--resume", "--quiet",
        prep=image("train/3.png", one_pixel), words=["{run}", "other edge maps or masks"]),
    # scenes: transforms
    row("SC-nanpose", "info", "{scene}", prep=matrix(3, lambda pose: pose * np.nan), words=[TJSON]),
    row("SC-zerofocal", "info", "{scene}", prep=focal(0, 0.0), words=[TJSON, "frame 0"]),
    row("SC-negfocal", "info", "{scene}", prep=focal(2, -133.0), words=[TJSON, "frame 2"]),
    row("SC-zeroframes", "info", "{scene}", prep=transforms(lambda meta: meta.__setitem__("frames", [])),
        words=[TJSON]),
    row("SC-frames100k", "info", "{scene}",
        prep=transforms(lambda meta: meta.__setitem__("frames", meta["frames"][:1] * 100_000)),
        words=[TJSON, "100000 views"]),
    row("SC-dupnames", "info", "{scene}", prep=frame(1, "file_path", "./train/0"), words=["{scene}", "'0'"]),
    row("SC-scaledrot", "info", "{scene}", prep=matrix(0, lambda pose: pose * [[2], [2], [2], [1]]),
        words=[TJSON, "rotation"]),
    row("SC-badshape", "info", "{scene}", prep=frame(0, "transform_matrix", [[1, 0], [0, 1]]),
        words=[TJSON, "(2, 2)"]),
    row("SC-matstr", "info", "{scene}", prep=frame(0, "transform_matrix", "abc"), words=[TJSON]),
    row("SC-noframes", "info", "{scene}", prep=transforms(lambda meta: meta.pop("frames")),
        words=[TJSON, "'frames'"]),
    row("SC-framesdict", "info", "{scene}", prep=transforms(lambda meta: meta.__setitem__("frames",
        [{"a": 1}])),
        words=[TJSON, "frame 0"]),
    row("SC-travpath", "info", "{scene}", prep=frame(0, "file_path", "../../../../../../../../etc/passwd"),
        words=["outside the scene folder"]),
    row("SC-abspath", "info", "{scene}", prep=frame(0, "file_path", "/etc/hostname"),
        words=["outside the scene folder"]),
    row("SC-pathint", "info", "{scene}", prep=frame(0, "file_path", 5), words=[TJSON]),
    row("SC-pathnul", "info", "{scene}", prep=frame(0, "file_path", "./train/\0x"), words=[TJSON]),
    row("SC-hugefloat", "info", "{scene}", prep=matrix(0, lambda pose: pose + 1e308), words=[TJSON]),
    row("SC-tjson_dir", "info", "{scene}", prep=in_scene("transforms_train.json", "DIR"),
        words=["{scene}", "not a scene folder"]),
    row("SC-tjson_devzero", "info", "{scene}", prep=in_scene("transforms_train.json", "/dev/zero"),
        words=["{scene}"]),
    row("SC-tjson_fifo", "info", "{scene}", prep=in_scene("transforms_train.json", "FIFO"),
        words=["{scene}"]),
    # scenes: images
    row("SC-wrongsize", "info", "{scene}", prep=image("train_img/3.png", resized),
        words=["{scene}/train_img/3.png", "50x70"]),
    row("SC-notpng", "info", "{scene}", prep=in_scene("train_img/4.png", "not a png"), rc=0),
    row("SC-notpng_edge", "info", "{scene}", prep=in_scene("train/4.png", "not a png"), rc=0),
    row("SC-truncpng", "info", "{scene}", prep=image("train_img/5.png", truncated), rc=0),
    row("SC-pngbomb", "info", "{scene}", prep=image("train_img/6.png", lambda p: png_declaring(p, 10**5,
        10**5)),
        rc=0),
    row("SC-pngbomb_edge", "info", "{scene}",
        prep=image("train/6.png", lambda p: png_declaring(p, 60000, 60000)), rc=0),
    row("SC-symout", "info", "{scene}", prep=image("train_img/1.png", linked("{SCENE}/train_img/1.png")),
        words=["outside the scene folder"]),
    row("SC-symetc", "info", "{scene}", prep=image("train_img/1.png", linked("/etc/passwd")),
        words=["/etc/passwd", "outside the scene folder"]),
    row("SC-symloop", "info", "{scene}", prep=image("train_img/1.png", linked("1.png")),
        words=["{scene}/train_img"]),
    row("SC-symdir", "info", "{scene}", prep=image_folder_linked, words=["outside the scene folder"]),
    row("SC-symdirloop", "info", "{scene}", prep=links(**{"scene/loop": "{}/scene"}), rc=0),
    row("SC-bigimg_all", "info", "{scene}", prep=big_views, rc=0),
    row("TR-bigimg_all", "train", "{scene}", *TRAIN_NEW, prep=big_views,
        words=["{scene}", "of memory", "maps.downscale"]),
    row("TR-notpng", "train", "{scene}", *TRAIN_NEW, prep=in_scene("train_img/4.png", "not a png"),
        words=["{scene}/train_img/4.png", "damaged_views=skip"]),
    row("TR-notpng_edge", "train", "{scene}", *TRAIN_NEW, prep=in_scene("train/4.png", "not a png"),
        words=["{scene}/train/4.png", "cannot be decoded"]),
    row("TR-truncpng", "train", "{scene}", *TRAIN_NEW, prep=image("train_img/5.png", truncated),
        words=["{scene}/train_img/5.png", "cannot be decoded"]),
    row("TR-pngbomb", "train", "{scene}", *TRAIN_NEW,
        prep=image("train_img/6.png", lambda p: png_declaring(p, 10**5, 10**5)),
        words=["{scene}/train_img/6.png", "100000x100000"]),
    row("TR-pngbomb_edge", "train", "{scene}", *TRAIN_NEW,
        prep=image("train/6.png", lambda p: png_declaring(p, 60000, 60000)),
        words=["{scene}/train/6.png", "60000x60000"]),
    row("TR-symdirloop", "train", "{scene}", *TRAIN_NEW, prep=links(**{"scene/loop": "{}/scene"}), rc=0),
    row("TS-damagedskip", "train", "{scene}", *TRAIN_NEW, "--set", "damaged_views=skip",
        prep=in_scene("train_img/4.png", "not a png"), rc=0),
    row("EX-cfg_devzero", "extract", "{run}", prep=in_run("config.json", "/dev/zero"), words=["{run}"]),
    row("EX-cfg_fifo", "extract", "{run}", prep=in_run("config.json", "FIFO"), words=["{run}"]),
    # eval of crafted predictions
    row("EV-devzero", "eval", "{}/pred.json", *EVAL, prep=links(**{"pred.json": "/dev/zero"}),
        words=["{}/pred.json"]),
    *(row(f"EV-{name}-obj", "eval", "{}/pred.obj", *EVAL, prep=files(**{"pred.obj": text}),
          words=["{}/pred.obj", *expected])
      for name, text, expected in [
          ("neg_idx", "v 0 0 0\nv 1 0 0\nl 1 2\nl -5 2\n", ["out of range"]),
          ("big_idx", "v 0 0 0\nv 1 0 0\nl 1 99\n", ["out of range"]),
          ("coord1e308", "v 0 0 0\nv 1e308 0 0\nl 1 2\n", ["beyond"]),
          ("nan", "v 0 0 0\nv nan 0 0\nl 1 2\n", ["NaN"]),
          ("long_line2", "v -900000 0 0\nv 900000 0 0\nl 1 2\n", ["sampled"]),
          ("garbage", b"\x00\xff\xfe\x89PNG" * 50, ["not a text OBJ"]),
          ("empty", "", ["no edge samples"]),
          ("text_in_v", "v a b c\n", ["line 1"])]),
    row("EV-long_line-obj", "eval", "{}/pred.obj", *EVAL, prep=files(**{"pred.obj": obj_of_lines(1, 100.0)}),
        rc=0, words=["metrics written"]),
    row("EV-many_lines-obj", "eval", "{}/pred.obj", *EVAL,
        prep=files(**{"pred.obj": obj_of_lines(5000, 0.5)}), rc=0, words=["metrics written"]),
    *(row(f"EV-{name}-ply", "eval", "{}/pred.ply", *EVAL, prep=files(**{"pred.ply": text}),
          words=["{}/pred.ply", *expected])
      for name, text, expected in [
          ("huge_ascii", ply_header(10**11) + "0 0 0\n1 0 0\n", []),
          ("huge_bin", ply_header(10**11, binary=True).encode() + bytes(24), []),
          ("huge_edges", ply_header(2, edges=10**11) + "0 0 0\n1 0 0\n", []),
          ("neg_edges", ply_header(2, edges=1) + "0 0 0\n1 0 0\n-5 1\n", ["out of range"]),
          ("ply1e308", ply_header(2, edges=1) + "0 0 0\n1e308 0 0\n0 1\n", []),
          ("ply_list_bomb", "ply\nformat ascii 1.0\nelement vertex 1\nproperty list uint float x\n"
                            "end_header\n4000000000 1 2 3\n", []),
          ("ply_noverts", ply_header(0), ["no edge samples"]),
          ("ply_many_props", ply_header(2, props=[f"p{i}" for i in range(10000)]) + "0 " * 20000 + "\n",
           ["'vertex'"])]),
    *(row(f"EV-{name}-json", "eval", "{}/pred.json", *EVAL, prep=files(**{"pred.json": text}),
          words=["{}/pred.json", *expected])
      for name, text, expected in [
          ("json_far", '{"curves_ctl_pts": [[[0,0,0],[100000,0,0],[200000,0,0],[300000,0,0]]]}', ["sampled"]),
          ("json_longline", '{"lines_end_pts": [[[-900000,0,0],[900000,0,0]]]}', ["sampled"]),
          ("json_manylines", json.dumps({"lines_end_pts": [[[0, i, 0], [9000, i, 0]] for i in range(1000)]}),
           ["sampled"]),
          ("json_list", "[]", ["expected an object"])]),
    row("EV-gt-huge", "eval", "{RUN}/curves.obj", "--gt", "{}/gt.ply", "--json", "{}/x.json",
        prep=files(**{"gt.ply": ply_header(10**11) + "0 0 0\n"}), words=["{}/gt.ply"]),
    row("EV-json-dir", "eval", "{RUN}/curves.obj", *EVAL, "--json", "/", words=["/:"]),
    row("EV-noscene-gt", "eval", "{RUN}/curves.obj", "--scene", "{scene}", "--json", "{}/y.json",
        prep=no_ground_truth, words=["{scene}", "no ground truth"]),
    # batch suites
    # two scene folders of one name in different parents (relative to the suite's folder)
    suite_text("BA-globall", "scenes: [one/bin, two/bin]\n", "one folder name",
               folders=("one/bin", "two/bin")),
    *(suite_text(name, text, *expected) for name, text, expected in [
        ("BA-laughs", 'a: &a ["x","x"]\nb: &b [*a,*a]\nc: [*b,*b]\n', ["suite.yaml"]),
        ("BA-billion", "scenes: [SCENE]\ngrid: {seed: [0, 1, 2]}\n", ["seeds"]),
        ("BA-just-over", "scenes: [SCENE]\nrows:\n" + ROWS + "seeds: [1, 2, 3, 4, 5, 6, 7, 8, 9]\n"
         "presets: [preview, quick]\ngrid: {epochs: [1, 2, 3], init.count: [" + ", ".join(map(str,
             range(1, 72)))
         + "]}\n", ["more than 10000"])]),
    row("BA-dotdot", "batch", "{}/suite.yaml", "--out", "{}/batch",
        prep=files(**{"suite.yaml": "scenes: ['../../../../../../../../../etc']\n"}),
        words=["/etc", "not a scene folder"]),
    row("BA-binary", "batch", "{}/suite.yaml", "--out", "{}/batch",
        prep=files(**{"suite.yaml": b"\x00\xff\xfe"}),
        words=["{}/suite.yaml"]),
    row("BA-nonempty-out2", "batch", "{}/suite.yaml", "--out", "{}/out",
        prep=lambda folder: files(**{"suite.yaml": f"scenes: [{SCENE}]\n", "out/batch.csv": "mine"})(folder),
        words=["{}/out"]),
    # train --set, --layers, scenes that are not
    *(row(f"TS-{name}", "train", "{SCENE}", "--out", "{}/ts", *options, words=expected)
      for name, options, expected in [
          ("epochs0", ["--set", "epochs=0"], ["schedule.epochs"]),
          ("initneg", ["--set", "init_count=-1"], ["init.count"]),
          ("lrnan", ["--set", "lr_means=nan"], ["schedule.lr_means"]),
          ("ambig", ["--set", "every=3"], ["'every'"]),
          ("level", ["--layers", "L0", "--level", "L0=nosuch@0.3"], ["nosuch"]),
          ("layers-empty", ["--layers", ","], ["--layers"]),
          ("layers-many", ["--layers", ",".join(f"L{i}" for i in range(1000))], ["--layers"])]),
    row("TS-scenefile", "train", "{}/afile", *TRAIN_NEW, prep=files(afile="x"), words=["{}/afile",
        "is a file"]),
    row("TS-detector-weights", "train", "{SCENE}", *TRAIN_NEW, "--set", "detector=pidinet",
        env={"EDGEDOG_PIDINET": "{}/no-weights.pth"}, words=["PiDiNet weights not found"]),
    # make-scene
    *(row(f"MS-{name}", "make-scene", "--shape", "box", "--out", out, "--views", "4", "--size", "32",
        *options,
          words=expected)
      for name, out, options, expected in [
          ("size-huge", "{}/ms", ["--size", "100000"], ["--size"]),
          ("views-huge", "{}/ms", ["--views", "1000000000"], ["--views"]),
          ("views0", "{}/ms", ["--views", "0"], ["--views"]),
          ("existing", "{SCENE}", [], ["{SCENE}", "already exists"]),
          ("slash", "/", [], ["/: already exists"]),
          ("noise-nan", "{}/ms", ["--image-noise", "nan"], ["--image-noise"]),
          ("keep-neg", "{}/ms", ["--keep-views", "-3"], ["--keep-views"]),
          ("keep-more", "{}/ms", ["--keep-views", "100"], ["--keep-views"]),
          ("drop", "{}/ms", ["--drop-edges", "5"], ["--drop-edges"]),
          ("posenoise-inf", "{}/ms", ["--pose-noise-deg", "inf"], ["--pose-noise-deg"]),
          ("detector-bad", "{}/ms", ["--detector", "canny:abc,1"], ["canny:abc,1"])]),
    row("MS-badshape", "make-scene", "--shape", "nosuch", "--out", "{}/ms", words=["nosuch"]),
    row("MS-outfile", "make-scene", "--shape", "box", "--out", "{}/afile", "--views", "2", "--size", "32",
        prep=files(afile="x"), words=["{}/afile", "already exists"]),
    row("MS-seed-huge", "make-scene", "--shape", "box", "--out", "{}/ms", "--views", "4", "--size", "32",
        "--seed", str(10**30), rc=0),
    # sfm
    row("SFM-empty", "sfm", "{}/photos", "--out", "{}/sfm", prep=files(**{"photos/.keep": ""}),
        words=["{}/photos", "no images"]),
    row("SFM-junk", "sfm", "{}/photos", "--out", "{}/sfm",
        prep=files(**{f"photos/p{i}.jpg": b"\x00junk" * 99 for i in (1, 2, 3)}),
        words=["{}/photos/p1.jpg"]),
    row("SFM-existing", "sfm", "{SCENE}/train_img", "--out", "{}/sfm", prep=files(**{"sfm/a": "x"}),
        words=["{}/sfm", "already exists"]),
    row("SFM-maxsize-huge", "sfm", "{SCENE}/train_img", "--out", "{}/sfm", "--max-image-size", "1000000000",
        words=["{SCENE}/train_img"]),
    # detectors' weights and the environment
    row("ED-weights-rce", "edges", "{SCENE}", "--detector", "pidinet", "--weights", "{}/evil.pth",
        "--recompute",
        prep=files(**{"evil.pth": pickle.dumps(CodeInPickle(Path("PWNED")))}), words=["{}/evil.pth"]),
    row("ED-weights-rce2", "edges", "{SCENE}", "--detector", "pidinet", "--weights",
        "{}/w/table5_pidinet.pth",
        "--recompute", prep=evil_torch_weights, words=["{}/w/table5_pidinet.pth"]),
    row("ED-weights-dir", "calibrate-detector", "--detector", "pidinet", "--weights", "{}/w", "--views", "1",
        "--sizes", "64", "--shapes", "box", prep=evil_torch_weights, words=["{}/w/table5_pidinet.pth"]),
    row("ED-weights-passwd", "edges", "{SCENE}", "--detector", "pidinet", "--weights", "/etc/passwd",
        "--recompute", words=["/etc/passwd"]),
    row("ED-bg-junk", "info", "{SCENE}", "--background", "purple", words=["--background"]),
    row("ENV-cache-file", "edges", "{SCENE}", "--detector", "sobel", "--recompute", prep=files(cache="x"),
        env={"EDGEDOG_CACHE": "{}/cache"}, words=["{}/cache"]),
    row("ENV-cache-proc", "edges", "{SCENE}", "--detector", "sobel", "--recompute",
        env={"EDGEDOG_CACHE": "/proc/edgedog"}, words=["/proc/edgedog"]),
    row("ENV-cache-proc-train", "train", "{SCENE}", *TRAIN_NEW, "--set", "detector=sobel",
        env={"EDGEDOG_CACHE": "/proc/edgedog"}, words=["/proc/edgedog"]),
    row("ENV-cache-demo", "demo", "--quiet", env={"EDGEDOG_CACHE": "/proc/edgedog"}, words=["/proc/edgedog"]),
    row("ENV-pidinet-devzero", "edges", "{SCENE}", "--detector", "pidinet", "--recompute",
        env={"EDGEDOG_PIDINET": "/dev/zero"}, words=["/dev/zero"]),
    # bench, the command line
    row("BE-raster-ref", "bench", "raster", "--views", "1", "--reference-views", "5", "--primitives", "10",
        "--size", "16", words=["--reference-views"]),
    row("BE-edges-size", "bench", "edges", "--size", "1000000", words=["--size"]),
    row("BE-se-evals2", "bench", "speed-error", "{SCENE}", "--out", "{}/se2", "--evals", "1000000000",
        "--budgets", "preview-d4", "--set", "init_count=300", "--quiet", words=["--evals"]),
    row("INFO-real", "info", "{SHARED}/abc_nef/00000006", rc=0, words=["ground truth"]),
    row("ST-help", "studio", "--help", rc=0, words=["studio"]),
    row("CLI-nocmd", words=["COMMAND"]),
    row("CLI-version", "--version", rc=0, words=["edgedog"]),
    # concurrency the table can hold in one process: a writer holds the run's lock
    row("CONC-3", *RESUME, prep=lambda folder: HELD.append(RunLock.acquire(folder / "run")),
        words=["{run}", "in use"]),
    row("CONC-4", "extract", "{run}", prep=lambda folder: HELD.append(RunLock.acquire(folder / "run")),
        words=["{run}", "in use"]),
]


# --- Hostile cases of our own beyond the report: the bounded reader's size cap, devices, FIFOs
# and folders in every file a command reads, literals JSON has no place for, and outputs that
# are links to a file that is not the command's to replace.
OWN_ROWS = [
    *(row(f"NEW-cfg-{name}", *RESUME, prep=in_run("config.json", content), words=[CFG])
      for name, content in [("sparse", "SPARSE"), ("empty", ""), ("null", "null")]),
    row("NEW-cfg-urandom", *RESUME, prep=in_run("config.json", "/dev/urandom"), words=["{run}",
        "not an edgedog run"]),
    row("NEW-cfg-infinity", *RESUME, prep=settings("schedule", "lr_means", float("inf")), words=[CFG]),
    row("NEW-cfg-noscene", *RESUME, prep=config_edit(lambda data: data.pop("scene")), words=[CFG]),
    *(row(f"NEW-log-{name}", "extract", "{run}", prep=in_run("log.json", content), words=["{run}/log.json"])
      for name, content in [("sparse", "SPARSE"), ("fifo", "FIFO"), ("dir", "DIR"), ("urandom",
          "/dev/urandom")]),
    *(row(f"NEW-curves-{name}", "export", "{run}", "--format", "obj", prep=in_run("curves.json", content),
          words=["{run}/curves.json"])
      for name, content in [("sparse", "SPARSE"), ("fifo", "FIFO"), ("urandom", "/dev/urandom"),
                            ("infinity", CURVE.replace("1,", "Infinity,"))]),
    *(row(f"NEW-ck-{name}", *RESUME, prep=in_run("checkpoint.pt", content), words=[CKPT])
      for name, content in [("fifo", "FIFO"), ("sparse", "SPARSE")]),
    *(row(f"NEW-prims-{name}", "extract", "{run}", prep=in_run("primitives.ply", content),
          words=["{run}/primitives.ply"])
      for name, content in [("fifo", "FIFO"), ("devzero", "/dev/zero"), ("dir", "DIR")]),
    *(row(f"NEW-tjson-{name}", "info", "{scene}", prep=in_scene("transforms_train.json", content),
        words=[TJSON])
      for name, content in [("sparse", "SPARSE"), ("empty", ""), ("null", "null"), ("list", "[]")]),
    row("NEW-tjson-infinity", "info", "{scene}", prep=matrix(1, lambda pose: pose * np.inf), words=[TJSON]),
    row("NEW-tjson-201digits", "info", "{scene}",
        prep=transforms(lambda meta: meta.__setitem__("camera_angle_x", 10**200)), words=[TJSON]),
    *(row(f"NEW-suite-{name}", "batch", "{}/suite.yaml", "--out", "{}/batch",
        prep=files(**{"suite.yaml": text}),
          words=["{}/suite.yaml"])
      for name, text in [("sparse", "SPARSE"), ("fifo", "FIFO"), ("devzero", "/dev/zero"), ("empty", ""),
                         ("binary-tag", "scenes: !!binary AAAA\n"), ("merge",
                             "a: &x {b: 1}\nscenes: {<<: *x}\n"),
                         ("inf", "scenes: [x]\nseeds: [.inf]\n"), ("dir", "DIR")]),
    *(row(f"NEW-pred-{name}", "eval", "{}/" + pred, *EVAL, prep=files(**{pred: content}),
        words=["{}/" + pred])
      for name, pred, content in [("obj-devzero", "pred.obj", "/dev/zero"), ("ply-fifo", "pred.ply", "FIFO"),
                                  ("json-dir", "pred.json", "DIR"), ("json-sparse", "pred.json", "SPARSE"),
                                  ("obj-sparse", "pred.obj", "SPARSE")]),
    row("NEW-gt-devzero", "eval", "{RUN}/curves.obj", "--gt", "{}/gt.ply", "--json", "{}/m.json",
        prep=links(**{"gt.ply": "/dev/zero"}), words=["{}/gt.ply"]),
    row("NEW-export-out-link-passwd", "export", "{RUN}", "--format", "obj", "--out", "{}/x.obj",
        prep=links(**{"x.obj": "/etc/passwd"}), words=["{}/x.obj"]),
    row("NEW-export-out-link-run", "export", "{run}", "--format", "json", "--out", "{}/x.json",
        prep=links(**{"x.json": "{}/run/config.json"}), words=["{}/x.json"]),
    row("NEW-init-out-fifo", "init", "{SCENE}", "--method", "uniform", "--uniform-count", "100", "--out",
        "{}/p.ply", prep=files(**{"p.ply": "FIFO"}), words=["{}/p.ply"]),
    row("NEW-eval-json-scene", "eval", "{RUN}/curves.obj", "--scene", "{scene}", "--json", "{scene}/m.json",
        words=["inside the scene folder"]),
    row("NEW-bench-json-scene", "bench", "raster", "--views", "1", "--primitives", "10", "--size", "16",
        "--json", "{scene}/b.json", words=["inside the scene folder"]),
    row("NEW-batch-out-scene", "batch", "{}/suite.yaml", "--out", "{scene}/b",
        prep=lambda folder: place(folder / "suite.yaml", f"scenes: [{SCENE}]\n"),
            words=["inside the scene folder"]),
    row("NEW-train-out-linked-scene", "train", "{SCENE}", "--out", "{}/link/run", *TRAIN,
        prep=both(copied_scene, links(link="{}/scene")), words=["{}/link/run", "inside the scene folder"]),
    row("NEW-colmap-bin-count", "info", "{}/colmap", prep=colmap_counting(2**64 - 1),
        words=["{}/colmap/sparse/0/images.bin", "declares 18446744073709551615 images"]),
    row("NEW-resume-fifo-scene", "train", "{}/fifo", "--out", "{run}", "--resume", "--quiet",
        prep=files(fifo="FIFO"), words=["{}/fifo"]),
]

@pytest.mark.parametrize("case", cases_as_params(CASES + [with_paths(case) for case in HELD_CASES]
                                                 + REPORT_ROWS + OWN_ROWS))
def test_hostile_case_fails_cleanly(case, tmp_path):
    """Each row: its exit code, one error line naming the file, no traceback, every file that was
    there unchanged, within CASE_SECONDS, and the process's peak memory raised by at most
    CASE_MEMORY (the report's blow-ups took 4.5 and 4.85 GB)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    try:
        with time_limit(CASE_SECONDS):
            assert_fails_cleanly(case, tmp_path)
        grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - peak
        assert grown <= CASE_MEMORY, f"peak memory grew by {grown / 2**20:.0f} MiB"
    finally:
        while HELD:
            HELD.pop().release()
        while ENV_BEFORE:
            key, value = ENV_BEFORE.popitem()
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


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


# --- Cases that need a second process: Ctrl-C, kill -9 and two writers at once. Each child runs
# under the report's `ulimit -v` (SUBPROCESS_ADDRESS_SPACE) and its peak RSS is asserted.
SUBPROCESS_ADDRESS_SPACE = 6 * 2**30
SUBPROCESS_MEMORY = 1536 * 2**20
"""Peak resident memory a child may reach (a tiny train peaks near 450 MB)."""
LONG_TRAIN = ["--preset", "preview", "--set", "epochs=100", "--set", "checkpoint_every=1", "--set",
              "init.count=300", "--quiet"]
"""A run with a checkpoint each epoch (an epoch of the small scene trains in about 25 ms on 2 cores),
long enough that three kills, each up to 0.45 s past a checkpoint, land while it trains."""
OUTPUTS = ("primitives.ply", "curves.json", "curves.obj", "curves.ply", "points.ply", "edge_points.ply",
           "extract.json")


def child_limits(file_size: int | None = None):
    resource.setrlimit(resource.RLIMIT_AS, (SUBPROCESS_ADDRESS_SPACE, SUBPROCESS_ADDRESS_SPACE))
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # as in a terminal, even under a backgrounded runner
    if file_size is not None:  # a write past it fails with EFBIG, as one on a full disk with ENOSPC
        resource.setrlimit(resource.RLIMIT_FSIZE, (file_size, file_size))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


class Child:
    """`python -m edgedog ARGV` in the background, its output in files of `folder`."""

    def __init__(self, argv: list, folder: Path, name: str, file_size: int | None = None):
        self.err = folder / f"{name}.stderr"
        with open(folder / f"{name}.stdout", "w") as out, open(self.err, "w") as err:
            self.process = subprocess.Popen([sys.executable, "-m", "edgedog", *map(str, argv)], stdout=out,
                                            stderr=err, stdin=subprocess.DEVNULL,
                                            preexec_fn=lambda: child_limits(file_size))

    def finish(self, seconds: float = CASE_SECONDS) -> tuple[int, str]:
        """Wait for the child (killed after `seconds`); its exit code (-N: killed by signal N) and
        stderr, after checking its peak memory."""
        deadline = time.monotonic() + seconds
        while True:
            pid, status, usage = os.wait4(self.process.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                self.process.kill()
                raise AssertionError(f"still running after {seconds} s")
            time.sleep(0.05)
        self.process.returncode = os.waitstatus_to_exitcode(status)
        assert usage.ru_maxrss * 1024 <= SUBPROCESS_MEMORY, f"peak RSS {usage.ru_maxrss} KB"
        return self.process.returncode, self.err.read_text()


def wait_for_checkpoint(run: Path, child: Child, after: float = 0.0, seconds: float = CASE_SECONDS):
    """Until the run's checkpoint.pt exists and was written after `after` (a time.time()); fails at
    once when the child has ended first (the run was too short to interrupt there)."""
    deadline = time.monotonic() + seconds
    checkpoint = run / "checkpoint.pt"
    while not (checkpoint.is_file() and checkpoint.stat().st_mtime > after):
        # WNOWAIT: leave the child to Child.finish, which reads its peak memory when reaping it
        ended = os.waitid(os.P_PID, child.process.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
        assert ended is None, f"the run ended before a new checkpoint: {child.err.read_text()[-500:]}"
        assert time.monotonic() < deadline, "no checkpoint written"
        time.sleep(0.02)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """LONG_TRAIN uninterrupted: what every interrupted and resumed run must end as, byte for byte."""
    out = tmp_path_factory.mktemp("reference") / "run"
    done = edgedog_in_process(["train", SCENE, "--out", out, *LONG_TRAIN], out.parent)
    assert done.returncode == 0, done.stderr
    return out


def assert_resumes_as(run: Path, reference: Path):
    """`train --resume` of an interrupted `run` finishes it with the reference's outputs."""
    resumed = edgedog_in_process(["train", SCENE, "--out", run, "--resume", "--quiet"], run.parent)
    assert resumed.returncode == 0 and "Traceback" not in resumed.stderr, resumed.stderr
    assert not list(run.glob("*.tmp")), "a temporary file left behind"
    for name in OUTPUTS:
        assert (run / name).read_bytes() == (reference / name).read_bytes(), f"{name} differs"


@pytest.mark.slow  # a second process: about 8 s each
@pytest.mark.parametrize("name, interruptions", [
    pytest.param(name, signals, id=name)
    for name, signals in [("SIGINT-1", [signal.SIGINT]), ("KILL9-1", [signal.SIGKILL]),
                          ("KILL9-2", [signal.SIGKILL] * 3)]])
def test_an_interrupted_run_resumes_byte_identical(name, interruptions, reference, tmp_path):
    """SIGINT-1, KILL9-1, KILL9-2: Ctrl-C (exit 130, one line with the resume command) or kill -9
    (some during a checkpoint's write: the Nth kill waits N x 0.15 s past a checkpoint), then
    --resume: the outputs are byte-identical to the uninterrupted run's."""
    run = tmp_path / "run"
    written = 0.0
    for index, interruption in enumerate(interruptions):
        argv = ["train", SCENE, "--out", run, *(LONG_TRAIN if index == 0 else ["--resume", "--quiet"])]
        child = Child(argv, tmp_path, f"{name}-{index}")
        wait_for_checkpoint(run, child, after=written)
        written = (run / "checkpoint.pt").stat().st_mtime
        time.sleep(0.15 * index)
        child.process.send_signal(interruption)
        code, err = child.finish()
        assert "Traceback" not in err, err
        if interruption == signal.SIGINT:
            assert code == 130 and err.strip().count("\n") == 0, err
            assert err.startswith("edgedog: error: interrupted") and "--resume" in err, err
        else:
            assert code == -signal.SIGKILL, err
    assert_resumes_as(run, reference)


@pytest.mark.slow  # a second process: about 8 s each
@pytest.mark.parametrize("name", ["CONC-1", "CONC-2"])
def test_two_trains_into_one_new_folder(name, tmp_path):
    """CONC-1, CONC-2: two `train` at once into one new folder: one trains to the same outputs as
    the module's run, the other says in one line that the folder is taken."""
    run = tmp_path / "run"
    children = [Child(["train", SCENE, "--out", run, *TRAIN], tmp_path, f"{name}-{i}") for i in range(2)]
    results = sorted(child.finish() for child in children)
    assert [code for code, _ in results] == [0, 2], results
    refused = results[1][1].strip()
    assert "Traceback" not in refused and refused.count("\n") == 0, refused
    assert "in use by another edgedog process" in refused or "already holds a run" in refused, refused
    for name in OUTPUTS:
        assert (run / name).read_bytes() == (RUN / name).read_bytes(), f"{name} differs"


@pytest.mark.slow  # a second process: about 8 s each
def test_a_write_that_fails_is_one_line_and_the_same_command_then_trains(reference, tmp_path):
    """DISK-fsize, standing in for DISK-full, DISK-full2 and DISK-resume (a small tmpfs needs a
    mount, which tests cannot make): `train` with every file limited to 40 KB (RLIMIT_FSIZE; the
    first write past it, SIFT's feature database of the initialisation, fails with EFBIG as one
    on a full disk fails with ENOSPC) stops with one line naming the file and leaves no run
    folder; the same command with room then trains to the uninterrupted run's outputs. It was a
    traceback (pycolmap's RuntimeError)."""
    run = tmp_path / "run"
    child = Child(["train", SCENE, "--out", run, *LONG_TRAIN], tmp_path, "disk", file_size=40_000)
    code, err = child.finish()
    assert code == 2 and "Traceback" not in err and err.strip().count("\n") == 0, err
    assert err.startswith("edgedog: error: ") and "cannot write" in err, err
    assert not run.exists()
    again = edgedog_in_process(["train", SCENE, "--out", run, *LONG_TRAIN], tmp_path)
    assert again.returncode == 0, again.stderr
    for name in OUTPUTS:
        assert (run / name).read_bytes() == (reference / name).read_bytes(), f"{name} differs"
