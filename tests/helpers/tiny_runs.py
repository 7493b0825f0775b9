"""Tiny training runs for tests: a few epochs at 1/4 resolution on the built-in box (uniform
initialisation, no density-control events unless a test asks for them), and small scenes made
with the command line."""

from __future__ import annotations

from pathlib import Path

from edgedog.scenes import load_scene
from edgedog.train.config import TrainConfig, preset, with_settings
from tests.helpers.bad_inputs import edgedog

QUICK_TRAIN = ["--preset", "preview", "--set", "epochs=2", "--set", "init.count=300", "--quiet"]
"""`edgedog train` options of a run finished in seconds on a small scene."""


def make_small_scene(folder: Path, shape: str = "box") -> Path:
    """`edgedog make-scene` of `shape` into `folder`, as a user makes one: 12 views at 96 px
    with Canny maps."""
    made = edgedog("make-scene", "--shape", shape, "--out", folder, "--views", "12", "--size", "96",
                   "--detector", "canny")
    assert made.returncode == 0, made.stderr
    return folder


def finished_run(scene: Path, out: Path) -> Path:
    """`edgedog train SCENE --out OUT` with QUICK_TRAIN, checked to finish: a run for tests to copy."""
    trained = edgedog("train", scene, "--out", out, *QUICK_TRAIN)
    assert trained.returncode == 0, trained.stderr
    return out


def tiny_config(**changes) -> TrainConfig:
    """Two epochs at 100 px from 300 uniform points, with `changes` (settings by bare or old flat
    name) applied."""
    base = with_settings(preset("preview"), {
        "downscale": 4, "epochs": 2, "init.count": 300, "init.side": 0.8, "init.method": "uniform",
        "duplicate_epochs": (), "cull_projection_epochs": (), "cull_opacity_epochs": (), "fisher_every": 100,
        "opacity_from_epoch": 0, "checkpoint_every": 2})
    return with_settings(base, changes)


def every_fifth_view(scene_dir):
    """The box scene at 1/4 resolution with every fifth view (10 views)."""
    scene = load_scene(scene_dir, downscale=4)
    scene.views = scene.views[::5]
    return scene
