"""A step's values kept on the device: the zeroed gradients and the epoch's losses read as the
host's floats would be, on every device with kernels."""

from __future__ import annotations

import numpy as np
import torch

from edgedog.train.readback import EpochLosses, zero_non_finite
from tests.helpers.backends import each_device


@each_device
def test_non_finite_gradients_are_zeroed_and_counted(device):
    means = torch.zeros(10, 3, device=device)
    means[3] = float("nan")
    quats = torch.full((10, 4), float("inf"), device=device)
    quats[0, 0] = -float("inf")
    fine = torch.ones(10, device=device)
    bad = zero_non_finite([means, quats, fine])
    assert int(bad) == 3 + quats.numel()
    assert torch.isfinite(means).all() and (means == 0).all() and (quats == 0).all()
    assert (fine == 1).all()


@each_device
def test_finite_gradients_are_left_alone(device):
    grads = [torch.randn(50, 3, device=device), torch.randn(50, device=device)]
    before = [grad.clone() for grad in grads]
    assert int(zero_non_finite(grads)) == 0
    assert all(torch.equal(a, b) for a, b in zip(grads, before))
    assert zero_non_finite([]) == 0


@each_device
def test_the_epochs_losses_read_as_the_hosts_floats(device):
    losses = EpochLosses()
    assert np.isnan(losses.last()) and np.isnan(losses.mean()) and losses.sum() == 0.0
    values = torch.rand(37, generator=torch.Generator().manual_seed(3)) * 0.1
    floats = [value.item() for value in values]
    for value in values:
        # A loss with a graph behind it, as a step's is: the log keeps it detached.
        losses.append((value.to(device).requires_grad_(True) * 1).squeeze())
    assert len(losses) == 37 and losses.last() == floats[-1]
    assert losses.sum() == float(np.sum(floats)) and losses.mean() == float(np.mean(floats))
    assert losses.values().dtype == np.float64
