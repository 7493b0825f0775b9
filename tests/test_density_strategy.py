"""Density control's duplication on a known absgrad: which primitives it copies, how many times,
where the copies go, and the primitive budget; the spacing control, which makes the count follow
the length of edge."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from edgedog.renderer.config import RasterConfig

from edgedog.spacing import edge_directions, redundant
from edgedog.train.config import TrainConfig, with_settings
from edgedog.train.model import EdgeModel
from edgedog.train.optim import Optimizers
from edgedog.train.strategy import DensityStrategy, primitive_limit
from edgedog.train.trainer import Trainer
from tests.helpers.tiny_runs import every_fifth_view, tiny_config

N = 10
# Normalised by its range (0 to 10), above the 0.5 threshold at 6, 8, 9 and 10: rows 2, 4, 6 and 9.
ABSGRAD = torch.tensor([0.0, 1.0, 10.0, 2.0, 9.0, 0.0, 6.0, 3.0, 4.0, 8.0])
CHOSEN = [2, 4, 6, 9]


def duplicate(max_primitives: int) -> tuple[EdgeModel, EdgeModel, Optimizers, list[dict]]:
    """The model before and after a duplication event at epoch 0 (copies 2, noise 0.05), its Adam
    (after one step of unit gradients at learning rate 0: every moment nonzero), and the log."""
    config = with_settings(TrainConfig(), dict(
        duplicate_epochs=(0,), cull_projection_epochs=(), cull_opacity_epochs=(), primitive_uncertainty=False,
        duplicate_copies=2, duplicate_threshold=0.5, duplicate_noise=0.05, max_primitives=max_primitives))
    g = torch.Generator().manual_seed(0)
    arrays = (torch.rand(N, 3, generator=g), torch.randn(N, 3, generator=g), torch.randn(N, 4, generator=g),
              torch.randn(N, generator=g), torch.randn(N, 2, generator=g))
    before = EdgeModel(*(a.clone() for a in arrays))
    model = EdgeModel(*arrays).requires_grad_()
    optimizers = Optimizers(model, config)
    for tensor in model.tensors().values():
        tensor.grad = torch.ones_like(tensor)
    optimizers.step()
    strategy = DensityStrategy(config, RasterConfig())
    state = strategy.initial_state(N, torch.device("cpu"))
    state.absgrad = ABSGRAD.clone()
    events = strategy.at_epoch_end(0, model, optimizers, state, views=None, generator=g, keep_ratio=1.0)
    assert torch.equal(state.absgrad, torch.zeros(len(model)))  # the signal restarts after a change
    return before, model, optimizers, events


def test_duplication_copies_the_primitives_above_the_threshold():
    before, model, optimizers, events = duplicate(max_primitives=1000)
    assert events == [{"event": "duplicate", "before": N, "after": N + 2 * len(CHOSEN), "epoch": 0}]
    sources = torch.tensor(CHOSEN * 2, dtype=torch.long)
    for name, tensor in model.tensors().items():
        old = getattr(before, name)
        assert torch.equal(tensor.detach()[:N], old)  # the originals stay as they were
        if name != "means":
            assert torch.equal(tensor.detach()[N:], old[sources])
        # Adam follows: the originals keep their moments, the copies start from zero.
        moments = optimizers.moments(name)["exp_avg"]
        assert moments[:N].abs().min() > 0 and not moments[N:].any()
    # The copies' centres move by N(0, 0.05^2) from their source's.
    moved = (model.means.detach()[N:] - before.means[sources]).abs()
    assert moved.max() > 0 and moved.max() < 0.05 * 5


@pytest.mark.parametrize(("max_primitives", "sources"), [(16, [2, 4, 9]), (14, [2, 4]), (13, [2]), (10, [])])
def test_duplication_stays_within_the_budget(max_primitives, sources):
    # With room for fewer than the chosen, the largest gradients are copied (10, 9, 8 at rows
    # 2, 4, 9: not row 6's 6, though it comes first), in row order.
    before, model, _, events = duplicate(max_primitives)
    assert events[0]["after"] == len(model) == N + 2 * len(sources)
    rows = torch.tensor(sources * 2, dtype=torch.long)
    assert torch.equal(model.k_raw.detach()[N:], before.k_raw[rows])


def test_the_limit_follows_a_thinned_edge_vote():
    settings = with_settings(TrainConfig(), {"edge_budget": 2.5, "max_primitives": 10_000}).strategy
    vote = {"method": "edge-vote", "points": 1808, "spacing": 0.0099}
    assert primitive_limit(settings, vote) == 4520
    assert primitive_limit(settings, {**vote, "points": 6000}) == 10_000  # never past max_primitives
    # Unthinned votes, other starts and a budget of 0 leave max_primitives alone.
    assert primitive_limit(settings, {**vote, "spacing": 0.0}) == 10_000
    assert primitive_limit(settings, {"method": "uniform", "points": 1808}) == 10_000
    off = with_settings(TrainConfig(), {"max_primitives": 10_000}).strategy
    assert primitive_limit(off, vote) == 10_000


def test_a_run_with_an_edge_budget_stays_within_it(builtin_scene_dir, tmp_path):
    # Duplicating every epoch from a thinned edge vote on the box: the count reaches the budget,
    # 1.5 times the start, and never passes it; the limit is kept by a resumed run.
    scene = every_fifth_view(builtin_scene_dir)
    config = tiny_config(**{"init.method": "edge-vote", "init.vote_spacing": 0.02, "init.count": 30_000,
                            "duplicate_epochs": (0, 1, 2), "duplicate_threshold": 0.1, "edge_budget": 1.5,
                            "epochs": 4})
    trainer = Trainer(scene, config, tmp_path / "run", progress=False)
    limit = round(1.5 * trainer.initial_count)
    assert trainer.primitive_limit == limit
    while trainer.epoch < 2:
        trainer.step()
    trainer.save_checkpoint()
    resumed = Trainer(scene, config, tmp_path / "run", progress=False)
    assert resumed.primitive_limit == limit
    while not resumed.done:
        resumed.step()
    counts = [e["after"] for e in resumed.events if e["event"] == "duplicate"]
    assert max(counts) <= limit and limit - max(counts) <= config.strategy.duplicate_copies


# --- spacing control (edgedog.spacing): a budget per length of edge

def along_edges(corners: list[tuple[tuple[float, float, float], tuple[float, float, float]]], count: int,
                seed: int) -> EdgeModel:
    """`count` small round primitives spread at random along the segments (start, end) in
    proportion to their lengths (the same count whatever the edge length, as a uniform start ends
    today): centres 1 mm off the segment at most, scales 1.2 : 1 : 0.9 along random axes (as
    trained primitives, whose major axis is no edge direction), random opacity."""
    g = torch.Generator().manual_seed(seed)
    ends = torch.tensor(corners, dtype=torch.float64)
    lengths = (ends[:, 1] - ends[:, 0]).norm(dim=1)
    segment = torch.multinomial(lengths, count, replacement=True, generator=g)
    t = torch.rand(count, 1, generator=g, dtype=torch.float64)
    means = ends[segment, 0] + t * (ends[segment, 1] - ends[segment, 0])
    means += (torch.rand(count, 3, generator=g, dtype=torch.float64) - 0.5) * 0.002
    quats = torch.randn(count, 4, generator=g)
    log_scales = torch.log(torch.tensor([0.0048, 0.004, 0.0036])).repeat(count, 1)
    return EdgeModel(means.float(), log_scales, quats / quats.norm(dim=1, keepdim=True),
                     torch.randn(count, generator=g), torch.zeros(count, 2)).requires_grad_()


def box_edges(side: float) -> list:
    """The 12 edges of a cube of `side` at the origin."""
    corners = [(x, y, z) for x in (0, side) for y in (0, side) for z in (0, side)]
    return [(a, b) for i, a in enumerate(corners) for b in corners[i + 1:]
            if sum(p != q for p, q in zip(a, b)) == 1]


def square_edges(side: float) -> list:
    """The 4 edges of a square of `side` in the plane z = 0."""
    c = [(0, 0, 0), (side, 0, 0), (side, side, 0), (0, side, 0)]
    return [(c[i], c[(i + 1) % 4]) for i in range(4)]


def spaced(model: EdgeModel, optimizers: Optimizers | None = None, **changes) -> tuple[EdgeModel, list[dict],
                                                                                     Optimizers]:
    """`model` after a spacing event at epoch 0 (no other event), the log, and its Adam
    (`optimizers`, or new ones); one opacity for every view, as `model` has."""
    config = with_settings(TrainConfig(), dict(
        duplicate_epochs=(), cull_projection_epochs=(), cull_opacity_epochs=(), primitive_uncertainty=False,
        spacing_epochs=(0,), view_opacity=False, **changes))
    optimizers = optimizers or Optimizers(model, config)
    strategy = DensityStrategy(config, RasterConfig())
    state = strategy.initial_state(len(model), torch.device("cpu"))
    events = strategy.at_epoch_end(0, model, optimizers, state, views=None, generator=torch.Generator(),
                                   keep_ratio=1.0)
    return model, events, optimizers


def test_spacing_makes_the_count_follow_the_edge_length():
    # A cube's 12 edges (length 6) and a square's 4 (length 2), each covered by the same 4000
    # primitives. At a 2 cm spacing, kept neighbours along an edge are 2 to 4 cm apart (a greedy
    # suppression in the order of opacity leaves gaps of 1.3 spacings on average): 25 to 50 per
    # unit of length whatever the count before.
    counts = {}
    for name, edges, length in (("cube", box_edges(0.5), 6.0), ("square", square_edges(0.5), 2.0)):
        model, events, _ = spaced(along_edges(edges, 4000, seed=1), spacing=0.02)
        assert events[0]["before"] == 4000 and events[0]["after"] == len(model) and events[0]["split"] == 0
        counts[name] = len(model) / length
        assert 0.5 / 0.02 < counts[name] < 1 / 0.02, (name, len(model))
    assert 0.7 < counts["cube"] / counts["square"] < 1.3, counts
    # No two kept primitives along one edge (away from its ends) are closer than the spacing.
    model, _, _ = spaced(along_edges(square_edges(0.5), 4000, seed=2), spacing=0.02)
    means = model.means.detach()
    inner = means[(means[:, 1] < 0.002) & (means[:, 0] > 0.02) & (means[:, 0] < 0.48)]
    assert len(inner) > 10 and torch.pdist(inner).min() >= 0.02


def test_spacing_keeps_the_most_opaque_and_both_edges_that_meet():
    # Two edges crossing at the origin, along x and y, 400 primitives on each.
    before = along_edges([((-0.2, 0, 0), (0.2, 0, 0)), ((0, -0.2, 0), (0, 0.2, 0))], 800, seed=4)
    means, logits = before.means.detach().clone(), before.opacity_logits.detach().clone()
    model, _, _ = spaced(before, spacing=0.02)
    kept = ((means[:, None] - model.means.detach()[None]).abs().sum(dim=2) == 0).any(dim=1)
    on_x = means[:, 1].abs() < 0.002
    for line in (on_x, ~on_x):  # each edge keeps one primitive per 2 to 4 cm, the crossing too
        assert 0.4 / 0.04 <= int((kept & line).sum()) <= 0.4 / 0.02 + 1
    # Each primitive removed has a kept one on its edge within the spacing, at least as opaque
    # (away from the crossing, where the edge's direction is the two edges').
    for row in torch.nonzero(~kept & (means.norm(dim=1) > 0.03)).squeeze(1).tolist():
        same_edge = kept & (on_x == on_x[row]) & ((means - means[row]).norm(dim=1) < 0.02)
        assert bool((logits[same_edge] >= logits[row]).any())


def test_redundant_compares_the_directions_of_the_edge():
    # Three primitives at one place: two where the edge runs along x (ranks 1 and 2), one where
    # it runs along y (rank 0): the less ranked along x goes; at 60 degrees apart, so does y's.
    means, axes = np.zeros((3, 3)), np.array([[1.0, 0, 0], [-1.0, 0, 0], [0.5, 0.866, 0]])
    rank = np.array([1.0, 2.0, 0.0])
    assert redundant(means, axes, rank, 0.01, 30.0).tolist() == [True, False, False]
    assert redundant(means, axes, rank, 0.01, 61.0).tolist() == [True, False, True]
    # Apart by the spacing or more, all stay.
    assert not redundant(np.array([[0.0, 0, 0], [0.01, 0, 0], [0.02, 0, 0]]), axes[[0, 0, 0]], rank, 0.01,
                         30.0).any()


def test_spacing_splits_a_primitive_longer_than_the_spacing():
    # A long one, a short one, and a large round one (its size is no length of edge).
    scales = torch.tensor([[0.05, 0.002, 0.002], [0.005, 0.002, 0.002], [0.05, 0.03, 0.03]])
    long = EdgeModel(torch.tensor([[0.5, 0.5, 0.5], [0.0, 0.0, 0.0], [-0.5, 0.0, 0.0]]), torch.log(scales),
                     torch.tensor([[1.0, 0, 0, 0]] * 3), torch.zeros(3), torch.zeros(3, 2)).requires_grad_()
    optimizers = Optimizers(long, with_settings(TrainConfig(), {}))
    for tensor in long.tensors().values():
        tensor.grad = torch.ones_like(tensor)
    optimizers.step()
    model, events, optimizers = spaced(long, optimizers, spacing=0.02)
    # ceil(0.05 / 0.02) = 3 pieces along x at -2/3, 0, 2/3 of the scale, each a third as long.
    assert events[0]["split"] == 1 and len(model) == 5
    torch.testing.assert_close(model.means.detach()[2:, 0], torch.tensor([0.5 - 0.1 / 3, 0.5, 0.5 + 0.1 / 3]))
    torch.testing.assert_close(model.log_scales.detach()[2:].exp(),
                               torch.tensor([[0.05 / 3, 0.002, 0.002]] * 3))
    # The short and the round ones stay as they were.
    assert torch.equal(model.means.detach()[:2], torch.tensor([[0.0, 0.0, 0.0], [-0.5, 0.0, 0.0]]))
    moments = optimizers.moments("means")["exp_avg"]
    assert moments[:2].abs().min() > 0 and not moments[2:].any()  # the pieces start afresh


def test_relative_spacing_follows_the_objects_size():
    small = len(spaced(along_edges(square_edges(0.5), 3000, seed=3), spacing=0.04, spacing_relative=True)[0])
    big = along_edges(square_edges(0.5), 3000, seed=3)
    with torch.no_grad():
        big.means.mul_(10)
        big.log_scales.add_(float(np.log(10)))
    assert len(spaced(big, spacing=0.04, spacing_relative=True)[0]) == small
    assert 0.5 * 2 / 0.02 < small < 2 / 0.02  # 4 % of a 0.5 side: 2 cm


@pytest.mark.parametrize("keep", ["opacity", "fisher"])
def test_spacing_in_a_run_keeps_the_best_ranked(builtin_scene_dir, tmp_path, keep):
    # A spacing event on the primitives of a tiny run on the box after one epoch: it keeps those
    # `redundant` keeps when ranked by the opacity or the Fisher scores the strategy computes.
    scene = every_fifth_view(builtin_scene_dir)
    config = tiny_config(spacing_epochs=(1,), spacing=0.05, spacing_keep=keep, spacing_split=False)
    trainer = Trainer(scene, config, tmp_path / "run", progress=False)
    while trainer.epoch < 1:
        trainer.step()
    model = trainer.model
    rank = (trainer.strategy.fisher_scores(model, trainer.views) if keep == "fisher"
            else model.opacity_logits.detach())
    means = model.means.detach().double().numpy()
    removed = redundant(means, edge_directions(means, 8, 0.05), rank.double().numpy(), 0.05, 30.0)
    expected = model.means.detach()[torch.from_numpy(~removed)]
    events = trainer.strategy.at_epoch_end(1, model, trainer.optimizers, trainer.state, trainer.views,
                                           trainer.generator, keep_ratio=1.0)
    assert events == [{"event": "spacing", "before": len(removed), "after": len(expected), "spacing": 0.05,
                       "removed": int(removed.sum()), "split": 0, "epoch": 1}]
    assert 0 < removed.sum() < len(removed) and torch.equal(model.means.detach(), expected)
