"""What a training step needs from the device without waiting for it.

On a GPU every value read back to the host (`.item()`, `bool(tensor)`) waits until the queued
kernels have run, so the host cannot queue the next step meanwhile. A step therefore keeps its
loss and its count of zeroed gradient entries on the device; they are read once an epoch (or when
a caller asks). On the CPU reading is free and the arithmetic is the same as reading every step.
"""

from __future__ import annotations

import numpy as np
import torch


class EpochLosses:
    """The projection losses of the steps of one epoch, kept as (0-d) tensors on their device."""

    def __init__(self):
        self._losses: list[torch.Tensor] = []

    def append(self, loss: torch.Tensor) -> None:
        self._losses.append(loss.detach())

    def __len__(self) -> int:
        return len(self._losses)

    def values(self) -> np.ndarray:
        """(S,) float64, the losses so far (one copy from the device)."""
        if not self._losses:
            return np.zeros(0)
        # float32 to float64 exactly, as `.item()` gives each: the sums below are those of the floats.
        return torch.stack(self._losses).cpu().double().numpy()

    def last(self) -> float:
        """The latest step's loss (NaN before the first)."""
        return float(self._losses[-1]) if self._losses else float("nan")

    def sum(self) -> float:
        return float(np.sum(self.values()))

    def mean(self) -> float:
        return float(np.mean(self.values())) if self._losses else float("nan")


def zero_non_finite(grads: list[torch.Tensor]) -> int | torch.Tensor:
    """Zero the non-finite entries of `grads` in place (no NaN ever reaches the parameters).

    Returns how many there were: an int on the CPU; on another device a 0-d tensor there (read it
    when needed: counting on the host would wait for the device at every step).
    """
    if not grads:
        return 0
    if grads[0].device.type != "cpu":
        flat = torch.cat([grad.reshape(-1) for grad in grads])
        for grad in grads:
            grad.nan_to_num_(nan=0.0, posinf=0.0, neginf=0.0)
        return (~torch.isfinite(flat)).sum()
    # Finite sums mean every entry is finite: one pass and no mask at almost every step.
    if bool(torch.isfinite(torch.stack([grad.sum() for grad in grads])).all()):
        return 0
    bad = 0
    for grad in grads:
        mask = ~torch.isfinite(grad)
        if mask.any():
            bad += int(mask.sum())
            grad[mask] = 0
    return bad
