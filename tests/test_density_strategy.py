"""Density control's duplication on a known absgrad: which primitives it copies, how many times,
where the copies go, and the primitive budget."""

from __future__ import annotations

import pytest
import torch
from edgedog.renderer.config import RasterConfig

from edgedog.train.config import TrainConfig, with_settings
from edgedog.train.model import EdgeModel
from edgedog.train.optim import Optimizers
from edgedog.train.strategy import DensityStrategy

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
        moments = optimizers.adams[name].state[tensor]["exp_avg"]
        assert moments[:N].abs().min() > 0 and not moments[N:].any()
    # The copies' centres move by N(0, 0.05^2) from their source's.
    moved = (model.means.detach()[N:] - before.means[sources]).abs()
    assert moved.max() > 0 and moved.max() < 0.05 * 5


@pytest.mark.parametrize(("max_primitives", "copied"), [(14, 2), (13, 1), (10, 0)])
def test_duplication_stays_within_the_budget(max_primitives, copied):
    before, model, _, events = duplicate(max_primitives)
    assert events[0]["after"] == len(model) == N + 2 * copied
    sources = torch.tensor(CHOSEN[:copied] * 2, dtype=torch.long)  # the first chosen rows, as room allows
    assert torch.equal(model.k_raw.detach()[N:], before.k_raw[sources])
