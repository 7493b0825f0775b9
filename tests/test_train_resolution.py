"""Coarse-to-fine training (schedule.coarse_downscale, schedule.fine_from_epoch): the coarse
views are the fine ones at a lower resolution, and a run ends at the maps' own resolution."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from edgedog.train.resolution import ViewSet, any_in_block, coarser
from edgedog.train.trainer import Trainer
from tests.helpers.tiny_runs import every_fifth_view, tiny_config


def test_a_one_pixel_line_stays_an_edge_in_the_coarse_mask():
    mask = np.zeros((8, 10), bool)
    mask[5, :] = True  # a horizontal line on an odd row
    coarse = any_in_block(mask, 5, 4)
    assert coarse.shape == (4, 5) and coarse[2].all() and coarse.sum() == 5


def test_the_coarse_views_project_and_average_like_the_fine_ones(builtin_scene_dir):
    from edgedog.renderer.primitives import RasterCamera

    from edgedog.scenes import load_scene

    scene = load_scene(builtin_scene_dir, downscale=4)  # 100 px
    pinholes = scene.cameras[:3]
    maps = [torch.from_numpy(scene.load_edge_map(i, "exact")) for i in range(3)]
    cameras = [RasterCamera.from_camera(c) for c in pinholes]
    fine = ViewSet(1, pinholes, cameras, maps, [m >= 0.5 for m in maps])
    coarse = coarser(fine, 2)
    assert coarse.factor == 2 and coarser(fine, 1) is fine
    for pinhole, camera, target, fine_target in zip(pinholes, coarse.cameras, coarse.targets, maps):
        assert (camera.width, camera.height) == (50, 50) and target.shape == (50, 50)
        # The area average keeps the maps' mean; a world point lands on the matching coarse pixel.
        assert float(target.mean()) == pytest.approx(float(fine_target.mean()), rel=1e-5)
        point = np.array([[0.45, 0.52, 0.48]])
        fine_uv = pinhole.project(point)[0][0]
        coarse_uv = pinhole.scaled(50, 50).project(point)[0][0]
        np.testing.assert_allclose(coarse_uv, (fine_uv + 0.5) / 2 - 0.5, atol=1e-9)
        np.testing.assert_allclose(camera.K.numpy(), pinhole.scaled(50, 50).K)


def test_a_coarse_to_fine_run_renders_coarse_then_ends_at_full_resolution(builtin_scene_dir, tmp_path):
    box = every_fifth_view(builtin_scene_dir)  # 100 px
    config = tiny_config(epochs=4, coarse_downscale=2, fine_from_epoch=2)
    trainer = Trainer(box, config, tmp_path, progress=False)
    sizes = []
    while not trainer.done:
        views = trainer.views_at(trainer.epoch)
        sizes.append(views.targets[0].shape)
        trainer.step()
    per_epoch = len(box)
    assert sizes[:2 * per_epoch] == [(50, 50)] * (2 * per_epoch)
    assert sizes[2 * per_epoch:] == [(100, 100)] * (2 * per_epoch)
    assert trainer.views_at(config.schedule.epochs - 1) is trainer.views
    assert all(torch.isfinite(t).all() for t in trainer.model.tensors().values())


def test_without_a_coarse_downscale_every_step_is_at_full_resolution(builtin_scene_dir, tmp_path):
    box = every_fifth_view(builtin_scene_dir)
    trainer = Trainer(box, tiny_config(fine_from_epoch=2), tmp_path, progress=False)
    assert trainer.views_at(0) is trainer.views and trainer.coarse is trainer.views
