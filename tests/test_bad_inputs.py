"""Bad run folders, checkpoints and output paths: each fails with one line naming the file, exit 2,
no traceback, nothing that was there changed (the harness: tests/helpers/bad_inputs.py; the scene and
settings tables: test_bad_inputs_scenes.py, test_bad_inputs_settings.py)."""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.helpers.bad_inputs import Case, assert_fails_cleanly, cases_as_params
from tests.helpers.tiny_runs import QUICK_TRAIN as TRAIN
from tests.helpers.tiny_runs import finished_run

SCENE: Path
RUN: Path


@pytest.fixture(scope="module", autouse=True)
def scene_and_run(small_box_scene, tmp_path_factory):
    """The small box scene and a finished run of it, copied by the cases that change them."""
    global SCENE, RUN
    SCENE, RUN = small_box_scene, finished_run(small_box_scene, tmp_path_factory.mktemp("bad-inputs") / "run")


def copied_run(folder: Path) -> Path:
    shutil.copytree(RUN, folder / "run")
    return folder / "run"


def edited_json(file: Path, edit) -> None:
    data = json.loads(file.read_text())
    edit(data)
    file.write_text(json.dumps(data))


def resume(run: Path) -> list:
    return ["train", SCENE, "--out", run, "--resume", "--quiet"]


def with_checkpoint(write):
    """A case: the run's checkpoint.pt replaced by `write(path)`, then --resume."""
    def build(folder: Path):
        run = copied_run(folder)
        write(run / "checkpoint.pt")
        return resume(run), [run / "checkpoint.pt"]
    return build


def with_run_json(name: str, edit, command=resume):
    """A case: the run's `name` (config.json, log.json) edited, then `command(run)`."""
    def build(folder: Path):
        run = copied_run(folder)
        edited_json(run / name, edit)
        return command(run), [run / name]
    return build


def extract(run: Path) -> list:
    return ["extract", run]


def torch_checkpoint(payload):
    return lambda path: torch.save(payload, path)


def truncated(path: Path) -> None:
    path.write_bytes(RUN.joinpath("checkpoint.pt").read_bytes()[:5000])


def zip_without_data(path: Path) -> None:
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("archive/version", "3\n")


def non_finite_means(path: Path) -> None:
    saved = torch.load(RUN / "checkpoint.pt", weights_only=True)
    saved["model"]["means"][0, 0] = float("nan")
    torch.save(saved, path)


def other_shapes(path: Path) -> None:
    saved = torch.load(RUN / "checkpoint.pt", weights_only=True)
    saved["model"]["quats"] = saved["model"]["quats"][:, :3]
    torch.save(saved, path)


def missing_optimizers(path: Path) -> None:
    saved = torch.load(RUN / "checkpoint.pt", weights_only=True)
    saved["optimizers"] = {"means": 5}
    torch.save(saved, path)


def fresh_out(folder: Path, out, *extra) -> tuple[list, list]:
    return ["train", SCENE, "--out", out, *TRAIN, *extra], [out]


def into_folder_with(*names: str):
    def build(folder: Path):
        out = folder / "mine"
        out.mkdir()
        for name in names:
            (out / name).write_text('{"mine": 1}')
        return fresh_out(folder, out)
    return build


def a_file(folder: Path):
    (folder / "notes.txt").write_text("mine")
    return fresh_out(folder, folder / "notes.txt")


def under_a_file(folder: Path):
    (folder / "notes.txt").write_text("mine")
    return ["train", SCENE, "--out", folder / "notes.txt" / "run", *TRAIN], ["notes.txt"]


def a_symlink_loop(folder: Path):
    (folder / "loop").symlink_to(folder / "loop")
    return fresh_out(folder, folder / "loop")


def into_a_run(folder: Path):
    return fresh_out(folder, copied_run(folder))


def export_to(out_name: str, make_file: str | None = None):
    """A case: export the run's curves to `out_name` (a folder when it ends in /; absolute or in
    the case's folder), after writing a file `make_file` there."""
    def build(folder: Path):
        run = copied_run(folder)
        if make_file:
            (folder / make_file).write_text("mine")
        out = folder / out_name if not out_name.startswith("/") else Path(out_name)
        if out_name.endswith("/"):
            out.mkdir()
        return ["export", run, "--format", "obj", "--out", out], [str(out).rstrip("/")]
    return build


def eval_json_to(target: str):
    """A case: `eval` of one 20 cm line with its metrics written to `target` (a folder when it
    ends in /)."""
    def build(folder: Path):
        prediction = folder / "line.obj"
        prediction.write_text("v 0 0 0\nv 0.2 0 0\nl 1 2\n")
        out = folder / target if not target.startswith("/") else Path(target)
        if target.endswith("/"):
            out.mkdir()
        return ["eval", prediction, "--scene", SCENE, "--json", out], [str(out).rstrip("/")]
    return build


def init_out_to_folder(folder: Path):
    (folder / "points.ply").mkdir()
    return ["init", SCENE, "--method", "uniform", "--out", folder / "points.ply"], [folder / "points.ply"]


def resume_of(builder):
    """A case: --resume of whatever `builder(folder)` makes."""
    def build(folder: Path):
        out = builder(folder)
        return ["train", SCENE, "--out", out, "--resume", "--quiet"], [out]
    return build


def empty_folder(folder: Path) -> Path:
    (folder / "empty").mkdir()
    return folder / "empty"


def foreign_folder(folder: Path) -> Path:
    (folder / "mine").mkdir()
    (folder / "mine" / "config.json").write_text('{"mine": 1}')
    return folder / "mine"


def layers_spec(spec: str):
    return lambda folder: (["train", SCENE, "--out", folder / "layered", "--layers", spec, *TRAIN],
                           ["--layers"])


def config_json_text(content: str | bytes):
    """A case: the run's config.json replaced by `content`, then --resume."""
    def build(folder: Path):
        run = copied_run(folder)
        file = run / "config.json"
        file.write_bytes(content if isinstance(content, bytes) else content.encode())
        return resume(run), [file]
    return build


def set_config(path, value):
    """An edit of a run file's 'config' setting `path` ('schedule.epochs')."""
    section, key = path.split(".")

    def edit(data):
        data["config"][section][key] = value
    return edit


CASES = [
    # point 1: checkpoints are data; anything else is one line
    Case("checkpoint-truncated", with_checkpoint(truncated)),
    Case("checkpoint-empty", with_checkpoint(lambda p: p.write_bytes(b""))),
    Case("checkpoint-random", with_checkpoint(lambda p: p.write_bytes(np.random.default_rng(0).bytes(4096)))),
    Case("checkpoint-zip-without-data", with_checkpoint(zip_without_data)),
    Case("checkpoint-a-list", with_checkpoint(torch_checkpoint([1, 2, 3]))),
    Case("checkpoint-foreign-dict", with_checkpoint(torch_checkpoint({"state_dict": {}}))),
    Case("checkpoint-newer-version", with_checkpoint(torch_checkpoint({"format": "edgedog-checkpoint",
                                                                       "version": 99}))),
    Case("checkpoint-nan-means", with_checkpoint(non_finite_means)),
    Case("checkpoint-wrong-shapes", with_checkpoint(other_shapes)),
    Case("checkpoint-bad-optimizers", with_checkpoint(missing_optimizers)),
    Case("checkpoint-a-folder", with_checkpoint(lambda p: (p.unlink(), p.mkdir()))),
    # config.json and log.json of a run
    Case("config-json-config-is-5", with_run_json("config.json", lambda d: d.update(config=5))),
    Case("config-json-epochs-two", with_run_json("config.json", set_config("schedule.epochs", "two"))),
    Case("config-json-epochs-list", with_run_json("config.json", set_config("schedule.epochs", [1, 2]))),
    Case("config-json-newer-format", with_run_json("config.json", lambda d: d.update(version=99))),
    Case("config-json-scene-number", with_run_json("config.json", lambda d: d.update(scene=5))),
    Case("config-json-not-json", config_json_text("{")),
    Case("config-json-not-utf8", config_json_text(b"\xff\xfe{}")),
    Case("log-json-downscale-two", with_run_json("log.json", set_config("maps.downscale", "two"), extract)),
    Case("log-json-scene-missing", with_run_json("log.json", lambda d: d.pop("scene"), extract)),
    # point 2: never into a folder that is not ours
    Case("out-folder-with-config-json", into_folder_with("config.json")),
    Case("out-folder-with-other-files", into_folder_with("log.json", "curves.json")),
    Case("out-is-a-file", a_file),
    Case("out-under-a-file", under_a_file),
    Case("out-in-proc", lambda folder: fresh_out(folder, Path("/proc/edgedog-run"))),
    Case("out-symlink-loop", a_symlink_loop),
    Case("out-holds-a-run", into_a_run),
    Case("layers-comma", layers_spec(",")),
    Case("layers-empty", layers_spec("")),
    Case("layers-gap", layers_spec("L0,L2")),
    # point 3: resume checks what it continues
    Case("resume-empty-folder", resume_of(empty_folder)),
    Case("resume-missing-folder", resume_of(lambda folder: folder / "nothing")),
    Case("resume-foreign-folder", resume_of(foreign_folder)),
    Case("resume-with-set", lambda folder: ([*resume(copied_run(folder)), "--set", "epochs=9"], ["--set"])),
    Case("resume-with-preset",
         lambda folder: ([*resume(copied_run(folder)), "--preset", "fast"], ["--preset"])),
    # outputs that cannot be written
    Case("export-out-is-a-folder", export_to("out.obj/")),
    Case("export-out-in-proc", export_to("/proc/edgedog.obj")),
    Case("export-out-under-a-file", export_to("notes.txt/out.obj", make_file="notes.txt")),
    Case("eval-json-in-proc", eval_json_to("/proc/edgedog.json")),
    Case("eval-json-is-a-folder", eval_json_to("metrics/")),
    Case("init-out-is-a-folder", init_out_to_folder),
    # Canny: the detector does not matter here, and PiDiNet (auto) would load its weights first.
    Case("make-scene-out-in-proc", lambda folder: (["make-scene", "--shape", "box", "--out",
                                                    "/proc/edgedog-box", "--views", "4", "--size", "32",
                                                    "--detector", "canny"],
                                                   ["/proc/edgedog-box"])),
    Case("extract-not-a-run", lambda folder: (["extract", foreign_folder(folder)], ["mine"])),
    Case("extract-missing", lambda folder: (["extract", folder / "nothing"], ["nothing"])),
]


@pytest.mark.parametrize("case", cases_as_params(CASES))
def test_bad_run_or_output_fails_cleanly(case, tmp_path):
    assert_fails_cleanly(case, tmp_path)
