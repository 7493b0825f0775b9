"""Tiny training runs on the built-in box for tests: a few epochs at 1/4 resolution, uniform
initialisation, no density-control events unless a test asks for them."""

from __future__ import annotations

import dataclasses

from edgedog.scenes import load_scene
from edgedog.train.config import TrainConfig, preset


def tiny_config(**changes) -> TrainConfig:
    """Two epochs at 100 px from 300 uniform points, with `changes` applied."""
    base = dataclasses.replace(preset("preview"), downscale=4, epochs=2, init_count=300, init_side=0.8,
                               init_method="uniform", duplicate_epochs=(), cull_projection_epochs=(),
                               cull_opacity_epochs=(), fisher_every=100, opacity_from_epoch=0,
                               checkpoint_every=2, snapshot_every=5)
    return dataclasses.replace(base, **changes)


def every_fifth_view(scene_dir):
    """The box scene at 1/4 resolution with every fifth view (10 views)."""
    scene = load_scene(scene_dir, downscale=4)
    scene.views = scene.views[::5]
    return scene
