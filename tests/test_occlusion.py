"""Occlusion by the visual hull (model.occlusion='hull'): the hull of a box's silhouettes, its
depth in a view, which views a point on a face is hidden from, the fallback for points inside,
and a run with it (finite, resumable, refused without masks)."""

from __future__ import annotations

import dataclasses
import json

import cv2
import numpy as np
import pytest
import torch

from edgedog.errors import ConfigError
from edgedog.hull import carve
from edgedog.synthetic.cameras import TARGET, orbit_cameras
from edgedog.train.config import ModelSettings
from edgedog.train.occlusion import HIDDEN_LOGIT, Occlusion, hide, hull_depth, scene_occlusion
from edgedog.train.trainer import Trainer
from tests.helpers.tiny_runs import every_fifth_view, tiny_config

SIZE = 200
CAMERAS = orbit_cameras(40, SIZE)
LOW, HIGH = np.array([0.1, 0.1, 0.2]), np.array([0.9, 0.9, 0.8])
"""The box's lowest and highest corners."""
CELLS = 48
SIDE = 1.1
CELL = SIDE / CELLS


def silhouette(camera) -> np.ndarray:
    """(H, W) bool mask of the box's silhouette."""
    corners = np.array([[x, y, z] for x in (LOW[0], HIGH[0]) for y in (LOW[1], HIGH[1])
                        for z in (LOW[2], HIGH[2])])
    uv, _ = camera.project(corners)
    mask = np.zeros((camera.height, camera.width), np.uint8)
    cv2.fillConvexPoly(mask, cv2.convexHull(np.rint(uv).astype(np.int32)), 1)
    return mask > 0


MASKS = [silhouette(c) for c in CAMERAS]


@pytest.fixture(scope="module")
def occlusion() -> Occlusion:
    return Occlusion.from_masks(CAMERAS, MASKS, TARGET, SIDE, CELLS, margin_cells=3.0, min_views=4,
                                downscale=2, device=torch.device("cpu"))


def cell_centres() -> np.ndarray:
    steps = (np.arange(CELLS) + 0.5) * CELL
    origin = TARGET - SIDE / 2
    return np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1) + origin


def test_the_hull_holds_the_box_and_little_else():
    grid = carve(CAMERAS, MASKS, TARGET, SIDE, CELLS)
    occupied = grid.occupied.numpy()
    centres = cell_centres()
    inside = np.all((centres >= LOW) & (centres <= HIGH), axis=-1)
    assert occupied[inside].all()
    far = np.any((centres < LOW - 2 * CELL) | (centres > HIGH + 2 * CELL), axis=-1)
    assert occupied[far].mean() < 0.01


def test_a_view_without_a_mask_carves_nothing():
    grid = carve(CAMERAS[:1], [None], TARGET, SIDE, 8)
    assert grid.occupied.all()


def test_the_hull_depth_is_the_box_face_in_front():
    grid = carve(CAMERAS, MASKS, TARGET, SIDE, CELLS)
    top = max(CAMERAS, key=lambda c: c.center[2])  # the view nearest +Z sees the top face
    depth = hull_depth(grid, top, None)
    uv, z = top.project(np.array([[0.5, 0.5, HIGH[2]]]))
    u, v = np.rint(uv[0]).astype(int)
    assert abs(depth[v, u] - z[0]) < 2 * CELL
    corner_uv, _ = top.project(np.array([[-0.3, -0.3, 0.5]]))  # beside the box: the ray misses it
    assert np.isinf(depth[int(round(corner_uv[0, 1])), int(round(corner_uv[0, 0]))])


def test_a_point_on_the_top_face_is_hidden_from_below_and_seen_from_above(occlusion):
    hidden = occlusion.hidden(torch.tensor([[0.5, 0.5, HIGH[2]], [0.5, 0.5, LOW[2]]]))
    heights = np.array([c.center[2] for c in CAMERAS]) - TARGET[2]
    below, above = heights < -1.0, heights > 1.0
    assert below.any() and above.any()
    top, bottom = hidden[:, 0].numpy(), hidden[:, 1].numpy()
    assert top[below].all() and not top[above].any()
    assert bottom[above].all() and not bottom[below].any()


def test_a_point_inside_the_hull_is_drawn_in_every_view(occlusion):
    assert not occlusion.hidden(torch.tensor([[0.5, 0.5, 0.5]])).any()


def test_points_behind_the_cameras_far_off_or_not_finite_are_never_hidden(occlusion):
    odd = torch.tensor([[50.0, 50.0, 50.0], [-80.0, 3.0, 0.5], [float("nan"), 0.5, 0.5],
                        [float("inf"), 0.5, 0.5]])
    assert not occlusion.hidden(odd).any()


def test_hide_sets_only_the_hidden_logits_and_keeps_the_others_gradients():
    logits = torch.tensor([0.5, -1.0, 2.0], requires_grad=True)
    shown = hide(logits, torch.tensor([False, True, False]))
    assert shown[1].item() == HIDDEN_LOGIT
    shown.sum().backward()
    assert logits.grad.tolist() == [1.0, 0.0, 1.0]


def test_a_run_with_occlusion_trains_finite_and_resumes(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    config = tiny_config(occlusion="hull", occlusion_cells=32, epochs=2, checkpoint_every=1,
                         fisher_every=1, cull_projection_epochs=(0,))
    trainer = Trainer(scene, config, tmp_path / "run", progress=False)
    assert trainer.occlusion is not None and len(trainer.occlusion) == len(scene)
    while trainer.epoch < 1:
        trainer.step()
    for tensor in trainer.model.tensors().values():
        assert torch.isfinite(tensor).all()
    assert trainer._hidden is not None and trainer._hidden.shape[0] == len(scene)
    events = {e["event"] for e in trainer.events}
    assert {"cull_projection", "fisher_prune"} <= events
    resumed = Trainer(scene, config, tmp_path / "run", progress=False)
    assert resumed.epoch == 1 and len(resumed.model) == len(trainer.model)
    while not resumed.done:
        resumed.step()
    resumed.write_outputs()
    logged = json.loads((tmp_path / "run" / "log.json").read_text())["occlusion"]
    assert logged["views_with_mask"] == len(scene) and 0 < logged["hull_share"] < 1


def test_a_scene_without_masks_is_refused(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    scene.views = [dataclasses.replace(v, alpha=False, mask_path=None) for v in scene.views]
    with pytest.raises(ConfigError, match="needs object masks"):
        Trainer(scene, tiny_config(occlusion="hull"), tmp_path / "run", progress=False)


def test_auto_occludes_where_the_scene_has_masks_and_trains_without_where_not(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    with_masks = Trainer(scene, tiny_config(occlusion="auto", occlusion_cells=16), tmp_path / "a",
                         progress=False)
    assert with_masks.occlusion is not None
    assert with_masks.occlusion.report["views_with_mask"] == len(scene)
    scene.views = [dataclasses.replace(v, alpha=False, mask_path=None) for v in scene.views]
    without = Trainer(scene, tiny_config(occlusion="auto"), tmp_path / "b", progress=False)
    assert without.occlusion is None


def test_views_projected_in_chunks_give_the_same_answer(occlusion, monkeypatch):
    points = torch.rand(50, 3) * 1.2 - 0.1
    whole = occlusion.hidden(points)
    monkeypatch.setattr("edgedog.train.occlusion.PROJECTED_AT_ONCE", 120)  # two views at a time
    assert torch.equal(occlusion.hidden(points), whole)
    assert whole.any() and not whole.all()


def test_rays_marched_in_chunks_give_the_same_depths(monkeypatch):
    grid = carve(CAMERAS, MASKS, TARGET, SIDE, 24)
    whole = hull_depth(grid, CAMERAS[3], MASKS[3])
    monkeypatch.setattr("edgedog.train.occlusion.RAY_CHUNK", 1000)
    assert np.array_equal(hull_depth(grid, CAMERAS[3], MASKS[3]), whole)
    assert np.isfinite(whole).any()


def test_a_point_off_the_hull_is_outside_and_points_on_or_in_it_are_not(occlusion):
    points = torch.tensor([[0.5, 0.5, 0.5], [0.5, 0.5, HIGH[2]], [HIGH[0], HIGH[1], HIGH[2]],
                           [0.5, 0.5, HIGH[2] + 0.2], [0.5, 0.5, 40.0], [float("nan"), 0.0, 0.0]])
    assert occlusion.outside(points).tolist() == [False, False, False, True, True, True]


def test_the_projection_cull_also_removes_what_lies_outside_the_hull(occlusion):
    from edgedog.renderer.config import RasterConfig

    from edgedog.init.points import InitialPoints
    from edgedog.train.model import EdgeModel
    from edgedog.train.optim import Optimizers
    from edgedog.train.strategy import DensityStrategy

    config = tiny_config(cull_projection_epochs=(0,), cull_projection_below=0.0, view_opacity=False)
    points = InitialPoints(np.array([[0.5, 0.5, HIGH[2]], [0.5, 0.5, HIGH[2] + 0.3]]), np.full(2, 0.01),
                           "uniform", {})
    model = EdgeModel.from_points(points, 0.1, 0.0, torch.Generator().manual_seed(0))
    strategy = DensityStrategy(config, RasterConfig(), occlusion)
    optimizers = Optimizers(model, config)
    state = strategy.initial_state(len(model), model.device)

    class Views:  # with one opacity for all views, the cull reads the pinholes and edge masks only
        pinholes = CAMERAS[:2]
        cameras = []
        edge_masks = [torch.ones(SIZE, SIZE, dtype=torch.bool)] * 2

    events = strategy.at_epoch_end(0, model, optimizers, state, Views(), torch.Generator(), 1.0)
    assert [e["event"] for e in events] == ["cull_projection", "cull_hull"]
    assert events[1]["before"] == 2 and events[1]["after"] == 1
    assert torch.allclose(model.means[0], torch.tensor([0.5, 0.5, HIGH[2]], dtype=model.means.dtype))


def test_the_shading_carve_only_deepens_the_hull_and_keeps_its_bounds(builtin_scene_dir):
    scene = every_fifth_view(builtin_scene_dir)
    cpu = torch.device("cpu")
    hull = ModelSettings(occlusion="hull", occlusion_cells=48)
    plain = scene_occlusion(scene, hull, None, cpu)
    shaded = scene_occlusion(scene, dataclasses.replace(hull, occlusion_shading=True), None, cpu)
    report = shaded.report
    assert report["shading_rounds"] >= 1 and report["shading_carved"] >= 0 and report["shading_seconds"] >= 0
    assert (shaded.depths >= plain.depths).all()  # carving only removes cells: no depth comes nearer
    assert torch.equal(shaded.clearance, plain.clearance)
