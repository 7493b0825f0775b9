"""The view-dependent opacity (model.view_opacity): its gradients, a primitive seen from one side
learned as such, and its parameter group through density control, checkpoints, layers and
primitives.ply."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import Primitives, RasterCamera
from edgedog.renderer.rasterize import rasterize

from edgedog.errors import InputError
from edgedog.primitives import VIEW_OPACITY, PrimitiveArrays, read_ply, write_ply, write_point_columns
from edgedog.train.checkpoint import CHECKPOINT, read_checkpoint, write_checkpoint
from edgedog.train.config import TrainConfig, with_settings
from edgedog.train.layers import LowerLayers
from edgedog.train.model import GROUPS, EdgeModel
from edgedog.train.optim import Optimizers
from edgedog.train.strategy import DensityStrategy, edge_hit_share
from edgedog.train.trainer import Trainer, read_stack
from edgedog.train.view_opacity import (
    camera_centres,
    cap_,
    directions,
    largest_logits,
    relative_opacity,
    seen_from,
    view_logits,
)
from tests.helpers.tiny_runs import every_fifth_view, tiny_config

SIZE = 48


def ring_cameras(count: int = 8, radius: float = 3.0) -> list[RasterCamera]:
    """`count` cameras on a horizontal circle round the origin, looking at it (OpenCV, z up in
    the world), 48 px, f = 60 px."""
    cameras = []
    for k in range(count):
        angle = 2 * math.pi * k / count
        centre = np.array([radius * math.cos(angle), radius * math.sin(angle), 0.3])
        forward = -centre / np.linalg.norm(centre)
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        w2c = np.eye(4)
        w2c[:3, :3] = np.stack([right, down, forward])
        w2c[:3, 3] = -w2c[:3, :3] @ centre
        K = np.array([[60.0, 0, (SIZE - 1) / 2], [0, 60.0, (SIZE - 1) / 2], [0, 0, 1]])
        cameras.append(RasterCamera(torch.tensor(K), torch.tensor(w2c), SIZE, SIZE))
    return cameras


def vertical_edge(logit: float = 0.0) -> Primitives:
    """One primitive at the origin, long along z: an edge seen from every camera of the ring."""
    return Primitives(torch.zeros(1, 3), torch.tensor([[-3.5, -3.5, -1.2]]), torch.tensor([[1.0, 0, 0, 0]]),
                      torch.tensor([logit]), torch.zeros(1, 2), torch.ones(1, 1))


def test_the_view_logits_are_a_plus_b_dot_d_with_exact_gradients():
    g = torch.Generator().manual_seed(0)
    means = torch.randn(6, 3, generator=g, dtype=torch.float64)
    centre = torch.tensor([0.5, -2.0, 3.0], dtype=torch.float64)
    a = torch.randn(6, generator=g, dtype=torch.float64, requires_grad=True)
    b = torch.randn(6, 3, generator=g, dtype=torch.float64, requires_grad=True)
    d = (centre - means) / (centre - means).norm(dim=1, keepdim=True)
    torch.testing.assert_close(view_logits(a, b, means, centre), a + (b * d).sum(1))
    assert torch.autograd.gradcheck(lambda a, b: view_logits(a, b, means, centre), (a, b))


def test_gradients_through_the_rasterizer_follow_the_chain_rule():
    """dL/db = dL/dlogit * d and dL/da = dL/dlogit, with dL/dlogit from the kernels."""
    camera = ring_cameras()[1]
    centre = camera_centres([camera], torch.device("cpu"))[0]
    base = vertical_edge(0.3)
    dirs = torch.tensor([[0.4, -0.2, 0.1]], requires_grad=True)
    logits = base.opacity_logits.clone().requires_grad_()
    weights = torch.rand(SIZE, SIZE, generator=torch.Generator().manual_seed(1))
    primitives = seen_from(dataclasses.replace(base, opacity_logits=logits), dirs, centre)
    (rasterize(primitives, camera, RasterConfig()).image[..., 0] * weights).sum().backward()
    leaf = primitives.opacity_logits.detach().clone().requires_grad_()
    (rasterize(dataclasses.replace(base, opacity_logits=leaf), camera, RasterConfig()).image[..., 0]
     * weights).sum().backward()
    assert leaf.grad.abs().item() > 0
    torch.testing.assert_close(logits.grad, leaf.grad)
    torch.testing.assert_close(dirs.grad, leaf.grad[:, None] * directions(base.means, centre))


def test_a_primitive_seen_from_one_side_only_fades_on_the_other():
    """The maps draw the edge in the views from x > 0 and nothing in the others (a wall hides it):
    a + b . d learns to draw it where it is seen and not where it is hidden."""
    cameras = ring_cameras()
    centres = camera_centres(cameras, torch.device("cpu"))
    drawn = [rasterize(vertical_edge(3.0), camera, RasterConfig()).image[..., 0] for camera in cameras]
    targets = [image if centre[0] > 0.1 else torch.zeros_like(image) for image, centre in zip(drawn, centres)]
    a = torch.zeros(1, requires_grad=True)
    b = torch.zeros(1, 3, requires_grad=True)
    adam = torch.optim.Adam([a, b], lr=0.05)
    for step in range(300):
        view = step % len(cameras)
        primitives = seen_from(dataclasses.replace(vertical_edge(), opacity_logits=a), b, centres[view])
        render = rasterize(primitives, cameras[view], RasterConfig()).image[..., 0]
        loss = (render - targets[view]).abs().mean()
        adam.zero_grad()
        loss.backward()
        adam.step()
    logits = torch.stack([view_logits(a, b, torch.zeros(1, 3), c) for c in centres]).detach()[:, 0]
    opacity = torch.sigmoid(logits)
    seen, hidden = opacity[centres[:, 0] > 0.1], opacity[centres[:, 0] < -0.1]
    assert seen.min() > 0.7 and hidden.max() < 0.2, opacity
    assert b[0, 0] > 1 and abs(b[0, 1]) < 0.5  # towards the seeing side, symmetric across it


def test_a_primitive_at_a_camera_centre_gets_finite_values():
    camera = ring_cameras()[0]
    centre = camera_centres([camera], torch.device("cpu"))[0]
    means = torch.stack([centre, torch.zeros(3)]).requires_grad_()
    a = torch.zeros(2, requires_grad=True)
    b = torch.ones(2, 3, requires_grad=True)
    logits = view_logits(a, b, means, centre)
    assert logits[0] == 0 and torch.isfinite(logits).all()
    primitives = Primitives(means, torch.full((2, 3), -2.0), torch.tensor([[1.0, 0, 0, 0]] * 2), logits,
                            torch.zeros(2, 2), torch.ones(2, 1))
    rasterize(primitives, camera, RasterConfig()).image.sum().backward()
    for tensor in (means, a, b):
        assert tensor.grad is None or torch.isfinite(tensor.grad).all()
    assert torch.isfinite(largest_logits(a, b, means, centre[None])).all()


def test_the_cap_bounds_b_and_the_largest_logit_is_over_the_views():
    dirs = torch.tensor([[3.0, 4.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.0]])
    cap_(dirs, 2.0)
    torch.testing.assert_close(dirs, torch.tensor([[1.2, 1.6, 0.0], [0.1, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    # Rows within the cap are multiplied by exactly 1.
    assert torch.equal(dirs[1:], torch.tensor([[0.1, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    centres = torch.tensor([[10.0, 0, 0], [0, 10.0, 0]])
    largest = largest_logits(torch.zeros(3), dirs, torch.zeros(3, 3), centres)
    torch.testing.assert_close(largest, torch.tensor([1.6, 0.1, 0.0]))


def model_with_dirs(n: int = 12) -> EdgeModel:
    g = torch.Generator().manual_seed(0)
    return EdgeModel(torch.rand(n, 3, generator=g), torch.randn(n, 3, generator=g) - 3,
                     torch.randn(n, 4, generator=g), torch.randn(n, generator=g),
                     torch.randn(n, 2, generator=g), torch.randn(n, 3, generator=g)).requires_grad_()


def test_b_follows_duplication_with_its_own_adam_moments():
    config = with_settings(TrainConfig(), dict(
        view_opacity=True, view_opacity_from_epoch=0, duplicate_epochs=(0,), cull_projection_epochs=(),
        cull_opacity_epochs=(), primitive_uncertainty=False, duplicate_threshold=0.5))
    model = model_with_dirs()
    before = model.opacity_dirs.detach().clone()
    optimizers = Optimizers(model, config)
    optimizers.set_epoch(0)
    for tensor in model.tensors().values():
        tensor.grad = torch.ones_like(tensor)
    optimizers.step()
    assert not torch.equal(model.opacity_dirs.detach(), before)  # trained from epoch 0
    moved = model.opacity_dirs.detach().clone()
    strategy = DensityStrategy(config, RasterConfig())
    state = strategy.initial_state(len(model), torch.device("cpu"))
    state.absgrad = torch.arange(len(model), dtype=torch.float32)  # the top half is duplicated
    strategy.at_epoch_end(0, model, optimizers, state, None, torch.Generator().manual_seed(0), 1.0)
    sources = torch.nonzero(torch.arange(12) / 11 > 0.5).squeeze(1).repeat(2)
    assert len(model) == 12 + len(sources)
    torch.testing.assert_close(model.opacity_dirs.detach(), torch.cat([moved, moved[sources]]))
    moments = optimizers.moments(VIEW_OPACITY.raw)["exp_avg"]
    assert moments[:12].abs().min() > 0 and not moments[12:].any()


def test_the_opacity_cull_reads_each_primitives_largest_opacity_over_the_views():
    config = with_settings(TrainConfig(), dict(
        view_opacity=True, duplicate_epochs=(), cull_projection_epochs=(), cull_opacity_epochs=(0,),
        primitive_uncertainty=False, cull_opacity_below=0.05, opacity_logit_cap=0.08))
    cameras = ring_cameras(4)
    # Three faint primitives: one opaque from the +x camera, one from none, one opaque everywhere.
    model = EdgeModel(torch.zeros(3, 3), torch.zeros(3, 3), torch.tensor([[1.0, 0, 0, 0]] * 3),
                      torch.tensor([-5.0, -5.0, 2.0]), torch.zeros(3, 2),
                      torch.tensor([[6.0, 0, 0], [0, 0, 0], [0, 0, 0]])).requires_grad_()
    optimizers = Optimizers(model, config)
    strategy = DensityStrategy(config, RasterConfig())
    state = strategy.initial_state(3, torch.device("cpu"))
    views = SimpleNamespace(cameras=cameras)
    events = strategy.at_epoch_end(0, model, optimizers, state, views, torch.Generator(), 1.0)
    assert events[0]["after"] == 2
    largest = largest_logits(model.opacity_logits, model.opacity_dirs, model.means,
                             camera_centres(cameras, torch.device("cpu")))
    torch.testing.assert_close(largest, torch.tensor([0.08, 0.08]))  # the reset caps the largest
    torch.testing.assert_close(model.opacity_dirs.detach(), torch.tensor([[6.0, 0, 0], [0, 0, 0]]))


def test_b_is_carried_by_the_layers():
    model = model_with_dirs(6)
    lower = LowerLayers.empty().plus(model, 0).plus(model_with_dirs(4), 1)
    assert torch.equal(lower.model.opacity_dirs[:6], model.opacity_dirs.detach())
    assert torch.equal(lower.below(1).model.opacity_dirs, model.opacity_dirs.detach())
    assert LowerLayers.empty().model.opacity_dirs.shape == (0, 3)


@pytest.fixture
def box(builtin_scene_dir):
    return every_fifth_view(builtin_scene_dir)


def on_config(**changes) -> TrainConfig:
    """A tiny run with the view-dependent opacity trained from the start, every density event."""
    return tiny_config(view_opacity=True, view_opacity_from_epoch=0, epochs=3, checkpoint_every=1,
                       duplicate_epochs=(0,), cull_opacity_epochs=(1,), fisher_every=1, **changes)


def test_a_run_with_view_opacity_resumes_exactly_and_writes_b(box, tmp_path):
    config = on_config()
    whole = Trainer(box, config, tmp_path / "whole", progress=False)
    whole.run()
    assert [e["event"] for e in whole.events] == ["duplicate", "fisher_prune", "cull_opacity", "fisher_prune"]
    assert whole.model.opacity_dirs.abs().max() > 0
    assert whole.model.opacity_dirs.norm(dim=1).max() <= config.model.view_opacity_cap + 1e-5
    part = Trainer(box, config, tmp_path / "part", progress=False)
    while part.epoch < 2:
        part.step()
    resumed = Trainer(box, config, tmp_path / "part", progress=False)
    resumed.run()
    for name in GROUPS:
        torch.testing.assert_close(getattr(resumed.model, name), getattr(whole.model, name), rtol=0, atol=0)
    saved = read_ply(tmp_path / "whole" / "primitives.ply")
    assert np.array_equal(saved.opacity_dirs, whole.model.opacity_dirs.detach().numpy())
    largest = largest_logits(whole.model.opacity_logits, whole.model.opacity_dirs, whole.model.means,
                             camera_centres(whole.cameras, torch.device("cpu")))
    np.testing.assert_allclose(saved.opacity, torch.sigmoid(largest).numpy(), rtol=1e-6)
    assert torch.equal(read_stack(tmp_path / "whole").model.opacity_dirs, whole.model.opacity_dirs.detach())


def test_off_it_stays_zero_and_out_of_the_files_and_old_checkpoints_resume(box, tmp_path):
    config = tiny_config(epochs=2, checkpoint_every=1, view_opacity=False)
    part = Trainer(box, config, tmp_path / "run", progress=False)
    while part.epoch < 1:
        part.step()
    assert not part.model.opacity_dirs.any() and part.model.opacity_dirs.grad is None
    # A checkpoint written before the group existed: no b in the model, no Adam for it.
    path = tmp_path / "run" / CHECKPOINT
    saved = read_checkpoint(path)
    del saved["model"][VIEW_OPACITY.raw], saved["optimizers"][VIEW_OPACITY.raw]
    write_checkpoint(path, {key: value for key, value in saved.items() if key not in ("format", "version")})
    resumed = Trainer(box, config, tmp_path / "run", progress=False)
    resumed.run()
    assert read_ply(tmp_path / "run" / "primitives.ply").opacity_dirs is None
    assert not resumed.model.opacity_dirs.any()


def test_a_checkpoint_with_a_bad_b_is_refused(box, tmp_path):
    config = tiny_config(epochs=1)
    Trainer(box, config, tmp_path / "run", progress=False).run()
    path = tmp_path / "run" / CHECKPOINT
    saved = read_checkpoint(path)
    saved["model"][VIEW_OPACITY.raw] = torch.full((3, 3), float("nan"))
    write_checkpoint(path, {key: value for key, value in saved.items() if key not in ("format", "version")})
    with pytest.raises(InputError, match="opacity_dirs"):
        Trainer(box, config, tmp_path / "run", progress=False)


def test_primitives_ply_round_trips_b_and_refuses_part_of_it(tmp_path):
    rng = np.random.default_rng(0)
    primitives = PrimitiveArrays(rng.normal(size=(5, 3)).astype(np.float32), np.ones((5, 3), np.float32),
                                 np.tile(np.float32([1, 0, 0, 0]), (5, 1)), np.full(5, 0.5, np.float32),
                                 np.zeros((5, 2), np.float32),
                                 opacity_dirs=rng.normal(size=(5, 3)).astype(np.float32))
    back = read_ply(write_ply(tmp_path / "a.ply", primitives))
    assert np.array_equal(back.opacity_dirs, primitives.opacity_dirs)
    assert np.array_equal(back.subset(np.array([1, 3])).opacity_dirs, primitives.opacity_dirs[[1, 3]])
    columns = {"x": primitives.means[:, 0], "y": primitives.means[:, 1], "z": primitives.means[:, 2],
               **{f"scale_{i}": primitives.scales[:, i] for i in range(3)},
               **{f"rot_{i}": primitives.quats[:, i] for i in range(4)}, "opacity": primitives.opacity,
               "k_0": primitives.k_raw[:, 0], "k_1": primitives.k_raw[:, 1],
               "opacity_dir_0": primitives.means[:, 0]}
    with pytest.raises(InputError, match="opacity_dir_0 but not all"):
        read_ply(write_point_columns(tmp_path / "b.ply", columns))


def test_the_projection_cull_counts_only_the_views_where_a_primitive_is_drawn():
    cameras = ring_cameras(4)
    def pixels(points):  # every point at pixel (5, 5), inside the view
        return np.full((len(points), 2), 5), np.ones(len(points), bool)

    pinholes = [SimpleNamespace(pixels=pixels) for _ in cameras]
    # The point lands on an edge in the first view only.
    masks = [torch.ones(SIZE, SIZE, dtype=torch.bool)] + [torch.zeros(SIZE, SIZE, dtype=torch.bool)] * 3
    points = np.zeros((2, 3))
    assert edge_hit_share(points, pinholes, masks).tolist() == [0.25, 0.25]
    ones = torch.ones(4, 2)
    assert torch.equal(edge_hit_share(points, pinholes, masks, ones), edge_hit_share(points, pinholes, masks))
    # The first is drawn in the first view only (b towards it); the second everywhere.
    dirs = torch.tensor([[6.0, 0, 0], [0, 0, 0]])
    weights = relative_opacity(torch.tensor([-3.0, -3.0]), dirs, torch.zeros(2, 3),
                               camera_centres(cameras, torch.device("cpu")))
    assert weights.max() == 1 and torch.equal(weights[:, 1], torch.ones(4))
    share = edge_hit_share(points, pinholes, masks, weights)
    assert share[0] > 0.9 and share[1] == 0.25


def test_a_layer_above_renders_the_lower_layers_with_their_b(box, tmp_path):
    first = Trainer(box, tiny_config(view_opacity=True, view_opacity_from_epoch=0), tmp_path / "L0",
                    progress=False)
    first.run()
    lower = first.stack()
    before = lower.model.opacity_dirs.clone()
    assert before.abs().max() > 0
    config = tiny_config(view_opacity=True, view_opacity_from_epoch=0, layer=1, lower_lr_scale=0.5)
    second = Trainer(box, config, tmp_path / "L1", progress=False, lower=lower)
    second.run()
    assert second.lower_optimizers.groups[VIEW_OPACITY.raw]["lr"] == 0.5 * 0.03
    assert not torch.equal(second.lower.model.opacity_dirs, before)  # fine-tuned
    stack = read_stack(tmp_path / "L1")
    torch.testing.assert_close(stack.model.opacity_dirs, torch.cat([second.lower.model.opacity_dirs,
                                                                     second.model.opacity_dirs]).detach())
    snapshot = second.snapshot()
    assert snapshot.opacity_dirs.shape == (len(stack), 3) and np.isfinite(snapshot.opacity).all()
