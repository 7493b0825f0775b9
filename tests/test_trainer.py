"""The trainer on the built-in box: resume exactness, density control, losses, controls."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from edgedog.errors import ConfigError
from edgedog.primitives import read_ply
from edgedog.scenes import load_scene
from edgedog.train import losses
from edgedog.train.config import TrainConfig, for_detector, preset, with_epochs, with_overrides, with_settings
from edgedog.train.model import GROUPS, EdgeModel
from edgedog.train.optim import Optimizers, learning_rates
from edgedog.train.resolution import ViewSet
from edgedog.train.trainer import Trainer
from edgedog.train.view_opacity import camera_centres, largest_logits
from tests.helpers.backends import KERNEL_DEVICES, each_device
from tests.helpers.paths import shared_path


def small_config(**changes) -> TrainConfig:
    """A few epochs at 1/4 resolution with every event early, on 12 of the box's views."""
    base = with_settings(preset("preview"), {
        "downscale": 4, "epochs": 6, "init.count": 400, "duplicate_epochs": (1, 3),
        "cull_projection_epochs": (2,), "cull_opacity_epochs": (4,), "fisher_every": 2,
        "loss.sampled_from_epoch": 1, "ratio_from_epoch": 1, "direction_from_epoch": 2,
        "checkpoint_every": 3, "init.side": 0.8})
    return with_settings(base, changes)


@pytest.fixture
def box(builtin_scene_dir, tmp_path):
    scene = load_scene(builtin_scene_dir, downscale=4)
    scene.views = scene.views[::4]
    return scene


def test_a_killed_run_resumes_exactly(box, tmp_path):
    config = small_config()
    whole = Trainer(box, config, tmp_path / "whole", progress=False)
    whole.run()
    # The same run, stopped after its first checkpoint (epoch 3), then continued by a new process.
    part = Trainer(box, config, tmp_path / "part", progress=False)
    while part.epoch < 3:
        part.step()
    resumed = Trainer(box, config, tmp_path / "part", progress=False)
    assert resumed.step_index == 3 * len(box)
    resumed.run()
    for name in GROUPS:
        torch.testing.assert_close(getattr(resumed.model, name), getattr(whole.model, name), rtol=0, atol=0)
    assert [e["after"] for e in resumed.events] == [e["after"] for e in whole.events]


@pytest.mark.skipif("cuda" not in KERNEL_DEVICES, reason="no CUDA kernels here (a CUDA build and a GPU)")
@pytest.mark.shared_data
def test_a_run_on_cuda_checkpoints_and_resumes(tmp_path):
    """On a GPU (whose atomics make runs differ in the last bits, so not `resumes_exactly`): the
    checkpoint holds the device's draws and the fused Adam's moments, and the run goes on from
    them. On 00000006 (its own maps), not the built-in box: a GPU machine need not have the CAD
    kernel that makes the box."""
    scene = load_scene(shared_path("abc_nef/00000006"), downscale=4)
    scene.views = scene.views[::4]
    config = small_config(device="cuda")
    part = Trainer(scene, config, tmp_path / "part", progress=False)
    while part.epoch < 3:
        part.step()
    resumed = Trainer(scene, config, tmp_path / "part", progress=False)
    assert resumed.step_index == 3 * len(scene) and resumed.model.device.type == "cuda"
    assert resumed.pixel_generator.device.type == "cuda"
    assert torch.equal(resumed.pixel_generator.get_state(), part.pixel_generator.get_state())
    assert resumed.optimizers.adam.defaults["fused"]
    torch.testing.assert_close(resumed.optimizers.moments("means")["exp_avg"],
                               part.optimizers.moments("means")["exp_avg"], rtol=0, atol=0)
    resumed.run()
    assert resumed.done and all(bool(torch.isfinite(t).all()) for t in resumed.model.tensors().values())


def test_density_control_events_and_outputs(box, tmp_path):
    trainer = Trainer(box, small_config(), tmp_path / "run", progress=False)
    trainer.run()
    kinds = [e["event"] for e in trainer.events]
    assert kinds == ["duplicate", "fisher_prune", "cull_projection", "duplicate", "fisher_prune",
                     "cull_opacity"]
    for event in trainer.events:
        if event["event"] == "fisher_prune":
            assert event["after"] == round(0.9 * event["before"])
        elif event["event"] == "duplicate":  # which rows, how many times: test_density_strategy.py
            added = event["after"] - event["before"]
            assert added > 0 and added % trainer.config.strategy.duplicate_copies == 0
        else:
            assert event["after"] <= event["before"]
    # Adam's moments stay aligned with the parameters through every change, those of b, the
    # view-dependent opacity (on by default, trained from epoch 5 of 6 here), among them.
    assert trainer.model.opacity_dirs.any()
    assert trainer.model.opacity_dirs.norm(dim=1).max() <= trainer.config.model.view_opacity_cap + 1e-5
    for name, tensor in trainer.model.tensors().items():
        assert trainer.optimizers.groups[name]["params"] == [tensor]
        state = trainer.optimizers.moments(name)
        assert state["exp_avg"].shape == tensor.shape
        assert torch.isfinite(tensor).all()
    for output in ("primitives.ply", "points.ply", "log.json", "checkpoint.pt"):
        assert (tmp_path / "run" / output).is_file()
    logged = json.loads((tmp_path / "run" / "log.json").read_text())["config"]  # resolved for the maps
    assert (logged["loss"]["direction_factor"], logged["loss"]["ratio_factor"],
            logged["maps"]["edge_profile"]) == (0.1, 0.05, "raw")
    snap = trainer.snapshot()
    assert snap.means.shape == (len(trainer.model), 3) and snap.step == trainer.step_index
    # primitives.ply holds the final snapshot's activated arrays, which invert to the parameters
    # (the opacity to its logit's largest over the views).
    saved = read_ply(tmp_path / "run" / "primitives.ply")
    for name in ("means", "scales", "quats", "opacity", "k_raw"):
        assert np.array_equal(getattr(saved, name), getattr(trainer.snapshot().primitives, name)), name
    model = trainer.model
    largest = largest_logits(model.opacity_logits, model.opacity_dirs, model.means,
                             camera_centres(trainer.cameras, model.device))
    for name, values in saved.raw().items():
        expected = largest if name == "opacity_logits" else getattr(model, name)
        torch.testing.assert_close(torch.from_numpy(values), expected.detach(), rtol=1e-4, atol=1e-3)


def test_the_baseline_switches_off_edgedog(box, tmp_path):
    config = small_config(kernel="gaussian", pixel_uncertainty=False, primitive_uncertainty=False, epochs=3)
    trainer = Trainer(box, config, tmp_path / "base", progress=False)
    k_before = trainer.model.k_raw.detach().clone()
    trainer.run()
    assert "fisher_prune" not in [e["event"] for e in trainer.events]
    assert torch.equal(trainer.model.k_raw.detach()[: len(k_before)].unique(), k_before.unique())


def test_controls_apply_at_the_next_step(box, tmp_path):
    trainer = Trainer(box, small_config(epochs=3), tmp_path / "run", progress=False)
    trainer.controls.update(keep_ratio=0.5, weighting="one")
    snapshot = trainer.snapshot()
    while trainer.epoch < 2:
        trainer.step()
    prune = [e for e in trainer.events if e["event"] == "fisher_prune"][0]
    assert prune["keep_ratio"] == 0.5 and prune["after"] == round(0.5 * prune["before"])
    # Snapshots are copies: training moved the model, not the snapshot.
    assert not np.array_equal(snapshot.means[:10], trainer.model.means.detach().numpy()[:10])


def test_direction_loss_gradient_repeats_exactly_with_two_threads():
    """Primitives are each other's neighbours many times over; the gradient's sums over them
    must not depend on thread timing, or seeded runs on two cores diverge."""
    g = torch.Generator().manual_seed(0)
    n = 20000
    model = EdgeModel(torch.rand(n, 3, generator=g), torch.randn(n, 3, generator=g) - 5,
                      torch.randn(n, 4, generator=g), torch.zeros(n), torch.zeros(n, 2)).requires_grad_()
    neighbours = losses.nearest_neighbours(model, 5)
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        gradients = []
        for _ in range(12):
            model.means.grad = None
            losses.direction_loss(model, neighbours).backward()
            gradients.append(model.means.grad.clone())
    finally:
        torch.set_num_threads(threads)
    for gradient in gradients[1:]:
        assert torch.equal(gradient, gradients[0])


def test_depth_uncertainty_and_weighting():
    depth = torch.zeros(20, 20)
    depth[:, 10:] = 2.0
    up = losses.depth_uncertainty(depth)
    assert up.max() == 1 and up[:, :8].max() == 0 and up[:, 12:].max() == 0 and up[:, 9:11].min() == 1
    assert torch.equal(losses.uncertainty_weight(up, "one"), torch.ones_like(up))
    assert torch.allclose(losses.uncertainty_weight(up, "exp"), torch.exp(up))
    assert torch.allclose(losses.uncertainty_weight(up, "one_minus"), 1 - up)
    assert torch.allclose(losses.uncertainty_weight(up, "exp_neg"), torch.exp(-up))
    assert losses.depth_uncertainty(torch.ones(5, 5)).max() == 0  # flat depth: no uncertainty


def test_depth_uncertainty_matches_a_replicate_padded_sobel_convolution():
    depth = torch.rand(37, 53, generator=torch.Generator().manual_seed(0)) * 3
    sobel_x = torch.tensor([[-1.0, 0.0, 1.0], [-2.0, 0.0, 2.0], [-1.0, 0.0, 1.0]])
    padded = torch.nn.functional.pad(depth[None, None], (1, 1, 1, 1), mode="replicate")
    grad = torch.nn.functional.conv2d(padded, torch.stack([sobel_x, sobel_x.T])[:, None])[0]
    magnitude = grad.pow(2).sum(0).sqrt()
    expected = (magnitude - magnitude.min()) / (magnitude.max() - magnitude.min())
    assert torch.allclose(losses.depth_uncertainty(depth), expected, atol=1e-6)


def test_the_sampled_loss_takes_the_edges_and_as_many_distinct_background_pixels():
    mask = torch.rand(40, 30, generator=torch.Generator().manual_seed(1)) > 0.9
    edges = losses.edge_pixels(mask)
    sample = losses.edge_and_background_sample(edges, mask.numel(), torch.Generator().manual_seed(7))
    flat = mask.reshape(-1)
    count = int(flat.sum())
    assert torch.equal(sample[:count], torch.nonzero(flat).squeeze(1))
    background = sample[count:]
    assert len(background) == count and len(set(background.tolist())) == count
    assert not flat[background].any()
    # The same draw as picking from the list of background pixels (EdgeGaussians' way).
    listed = torch.nonzero(~flat).squeeze(1)
    pick = losses.distinct_draw(count, len(listed), torch.Generator().manual_seed(7))
    assert torch.equal(background, listed[pick])


@pytest.mark.parametrize("count, total",
                         [(0, 0), (0, 9), (3, 200), (40, 1000), (50, 200), (199, 200), (200, 200)])
def test_a_distinct_draw_is_a_uniform_subset(count, total):
    """Small shares are drawn with replacement and their repeats dropped, large ones permuted:
    either way `count` distinct values of [0, total), each as likely (within 5 sigma)."""
    generator, draws = torch.Generator().manual_seed(11), 3000
    counts = torch.zeros(total)
    for _ in range(draws):
        drawn = losses.distinct_draw(count, total, generator)
        assert drawn.dtype == torch.int64 and len(drawn) == count == len(set(drawn.tolist()))
        counts[drawn] += 1
    if total:
        p = count / total
        assert torch.all((counts / draws - p).abs() <= 5 * (p * (1 - p) / draws) ** 0.5)


def test_one_adam_over_the_groups_steps_each_as_its_own_adam_would():
    """Optimizers' one Adam (AdamW's decoupled decay on b) against an Adam per group, as the
    runs before it were trained: the same parameters to the bit after steps where some groups
    have no gradient (skipped, as the orientation losses' steps leave all but the geometry)."""
    g = torch.Generator().manual_seed(0)
    n = 50
    model = EdgeModel(*(torch.randn(n, *shape, generator=g) for shape in ((3,), (3,), (4,), (), (2,))),
                      opacity_dirs=torch.randn(n, 3, generator=g)).requires_grad_()
    twin = EdgeModel(**{name: t.detach().clone() for name, t in model.tensors().items()}).requires_grad_()
    config = with_settings(TrainConfig(), {"model.view_opacity": True})
    ours = Optimizers(model, config)
    ours.set_epoch(200)
    rates = learning_rates(config, 200)
    decay = config.loss.view_opacity_decay
    alone = {name: (torch.optim.AdamW([t], lr=rates[name], eps=1e-15, weight_decay=decay)
                    if name == "opacity_dirs" else torch.optim.Adam([t], lr=rates[name], eps=1e-15))
             for name, t in twin.tensors().items()}
    assert all(rate > 0 for rate in rates.values())
    for step in range(6):
        stepped = GROUPS if step % 2 == 0 else ("means", "log_scales", "quats")
        for m in (model, twin):
            sum((torch.sin(getattr(m, name) * (step + 1))).sum() for name in stepped).backward()
        ours.step()
        ours.zero_grad()
        for name in stepped:
            alone[name].step()
        for adam in alone.values():
            adam.zero_grad(set_to_none=True)
    for name in GROUPS:
        assert torch.equal(getattr(model, name), getattr(twin, name)), name


@each_device
def test_the_sampled_loss_draws_on_its_generators_device(device):
    """A generator of the run's device draws there (on a GPU: no host permutation, no copy):
    the edges, then as many distinct background pixels; the same seed, the same draw."""
    mask = (torch.rand(60, 50, generator=torch.Generator().manual_seed(2)) > 0.8).to(device)
    edges, flat = losses.edge_pixels(mask), mask.reshape(-1)
    draws = [losses.edge_and_background_sample(edges, mask.numel(),
                                               torch.Generator(device).manual_seed(5)) for _ in range(2)]
    count = int(flat.sum())
    assert draws[0].device.type == device and torch.equal(draws[0], draws[1])
    background = draws[0][count:]
    assert len(background) == count and len(set(background.tolist())) == count
    assert not flat[background].any()


def test_the_sampled_loss_is_the_mean_of_the_edge_and_background_losses_in_expectation():
    generator = torch.Generator().manual_seed(3)
    mask = torch.zeros(10, 12, dtype=torch.bool)
    mask[4, 2:10] = True  # 8 edge pixels, 112 background
    render, target = torch.rand(10, 12, generator=generator), mask.float()
    edges, draws = losses.edge_pixels(mask), 4000
    counts = torch.zeros(mask.numel())
    total = 0.0
    for _ in range(draws):
        sample = losses.edge_and_background_sample(edges, mask.numel(), generator)
        counts[sample[8:]] += 1
        total += float(losses.projection_loss(render, target, None, sample))
    error = (render - target).abs()
    expected = 0.5 * (error[mask].mean() + error[~mask].mean())
    assert abs(total / draws - float(expected)) < 0.01
    # Every background pixel is drawn as often (8 of 112 per draw): uniform, within 5 sigma.
    frequency = counts[~mask.reshape(-1)] / draws
    p = 8 / 112
    assert torch.all((frequency - p).abs() < 5 * (p * (1 - p) / draws) ** 0.5)
    assert counts[mask.reshape(-1)].sum() == 0


def test_the_sampled_loss_at_the_extremes():
    generator = torch.Generator().manual_seed(0)
    none, every = torch.zeros(6, 5, dtype=torch.bool), torch.ones(6, 5, dtype=torch.bool)
    assert len(losses.edge_and_background_sample(losses.edge_pixels(none), 30, generator)) == 0
    assert torch.equal(losses.edge_and_background_sample(losses.edge_pixels(every), 30, generator),
                       torch.arange(30))
    most = every.clone()
    most[0, :3] = False  # more edges than background: every background pixel, once
    sample = losses.edge_and_background_sample(losses.edge_pixels(most), 30, generator)
    assert sorted(sample.tolist()) == list(range(30))


def test_the_direction_losss_neighbours_are_reused_within_an_epoch(box, tmp_path, monkeypatch):
    """`loss.neighbours_every`: the k-d tree is searched every so many direction steps and anew
    after each epoch's density events (which renumber the primitives)."""
    searches = []
    search = losses.nearest_neighbours

    def counted(model, k):
        searches.append(len(model))
        return search(model, k)

    monkeypatch.setattr(losses, "nearest_neighbours", counted)
    views = len(box)
    for every in (1, 5):
        searches.clear()
        config = small_config(epochs=5, direction_from_epoch=2, orientation_every=1, neighbours_every=every)
        trainer = Trainer(box, config, tmp_path / f"every-{every}", progress=False)
        trainer.run()
        assert len(searches) == 3 * -(-views // every)  # 3 epochs with the loss on, a step a view
        assert any(event["epoch"] >= 2 for event in trainer.events)  # the count changed between epochs


def test_a_view_without_edges_keeps_the_full_loss(box, tmp_path):
    trainer = Trainer(box, small_config(epochs=3, sampled_every=1), tmp_path / "run", progress=False)
    views = trainer.views
    blank = [torch.zeros_like(views.targets[0])] + views.targets[1:]
    trainer.views = trainer.coarse = ViewSet(views.factor, views.pinholes, views.cameras, blank,
                                             [torch.zeros_like(views.edge_masks[0])] + views.edge_masks[1:])
    trainer.run()
    assert len(trainer.views.edge_pixels[0]) == 0
    assert all(np.isfinite(epoch["loss"]) for epoch in trainer.history)
    assert trainer.bad_gradients == 0


def test_config_overrides():
    given = ["model.kernel=gaussian", "keep_ratio=0.8", "pixel_uncertainty=off", "duplicate_epochs=5,10",
             "init_side=none"]  # dotted, bare and old flat names
    config = with_overrides(TrainConfig(), given)
    assert config.model.kernel == "gaussian" and config.strategy.keep_ratio == 0.8
    assert not config.loss.pixel_uncertainty
    assert config.strategy.duplicate_epochs == (5, 10) and config.init.side is None
    with pytest.raises(ConfigError, match="unknown setting 'nonsense'"):
        with_overrides(TrainConfig(), ["nonsense=1"])
    with pytest.raises(ConfigError, match="expected KEY=VALUE"):
        with_overrides(TrainConfig(), ["keep_ratio"])
    with pytest.raises(ConfigError, match="strategy.keep_ratio"):
        with_overrides(TrainConfig(), ["keep_ratio=1.5"])
    preview, fast = preset("preview"), preset("fast")
    assert preview.schedule.epochs == 100 and preview.maps.downscale == 2
    assert preview.strategy.duplicate_epochs[0] == 10
    assert fast.schedule.epochs == 200 and fast.maps.downscale == 1 and fast.strategy.fisher_every == 25
    with pytest.raises(ConfigError, match="choose one of: full: .*; fast: .*; preview: .*; paper: "):
        preset("turbo")


def test_settings_left_open_follow_the_detector():
    def open_settings(config):
        return config.loss.direction_factor, config.loss.ratio_factor, config.maps.edge_profile

    dexined = for_detector(TrainConfig(), "DexiNed")
    assert open_settings(dexined) == (0.01, 0.01, "profile")
    pidinet = for_detector(TrainConfig(), "pidinet")
    assert open_settings(pidinet) == (0.1, 0.05, "raw")
    chosen = with_overrides(TrainConfig(), ["direction_factor=0.2", "edge_profile=thin"])
    assert open_settings(for_detector(chosen, "dexined")) == (0.2, 0.01, "thin")
    assert for_detector(dexined, "pidinet") == dexined  # a resolved config stays as it is


def test_with_epochs_stretches_the_whole_schedule():
    full = preset("full")
    half = with_epochs(full, 200)
    assert half.schedule.epochs == 200 and half.strategy.fisher_every == 25
    assert half.loss.direction_from_epoch == 125 and half.maps.shift_from_epoch == 50
    assert half.run.checkpoint_every == 25 and half.schedule.lr_means_decay_epochs == (5, 10, 15, 20, 25)
    assert half.strategy.duplicate_epochs[0] == 20 and half.strategy.cull_opacity_epochs == (62, 155)
    assert (half.loss.sampled_every, half.loss.orientation_every) == (5, 5)  # periods in steps stay
    assert half.schedule.fine_from_epoch == 0  # from the start stays from the start
    early = with_epochs(with_overrides(full, ["loss.sampled_from_epoch=0", "loss.ratio_from_epoch=1"]), 100)
    assert (early.loss.sampled_from_epoch, early.loss.ratio_from_epoch) == (0, 1)
    assert with_epochs(full, 400) == full
    with pytest.raises(ConfigError):
        with_epochs(full, 0)
