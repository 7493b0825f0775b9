"""One Adam per parameter group, EdgeGaussians' learning-rate schedules, and the bookkeeping
that keeps Adam's moments aligned when primitives are pruned or duplicated."""

from __future__ import annotations

import torch

from edgedog.primitives import VIEW_OPACITY
from edgedog.train.config import TrainConfig
from edgedog.train.model import GROUPS, EdgeModel


def learning_rates(config: TrainConfig, epoch: int) -> dict[str, float]:
    """Each group's learning rate during `epoch` (0-based)."""
    s = config.schedule
    decays = sum(epoch >= e for e in s.lr_means_decay_epochs)
    return {
        "means": s.lr_means * s.lr_means_decay**decays,
        "log_scales": s.lr_scales if epoch >= s.scales_from_epoch else 0.0,
        "quats": s.lr_quats if epoch >= s.quats_from_epoch else 0.0,
        "opacity_logits": s.lr_opacity if epoch >= s.opacity_from_epoch else 0.0,
        "k_raw": s.lr_k if config.model.kernel == "dog" else 0.0,
        VIEW_OPACITY.raw: (s.lr_view_opacity
                           if config.model.view_opacity and epoch >= s.view_opacity_from_epoch else 0.0),
    }


class Optimizers:
    """Adam per group of an EdgeModel; rebinds to the model's tensors after each change.

    The view-dependent opacity's b has AdamW's decoupled decay (`loss.view_opacity_decay`): each
    step shrinks it by lr x decay, so only a push that the views agree on keeps it from 0.
    """

    def __init__(self, model: EdgeModel, config: TrainConfig):
        self.config = config
        self.adams = {name: (torch.optim.AdamW([tensor], lr=0.0, eps=1e-15,
                                               weight_decay=config.loss.view_opacity_decay)
                             if name == VIEW_OPACITY.raw else torch.optim.Adam([tensor], lr=0.0, eps=1e-15))
                      for name, tensor in model.tensors().items()}

    def set_epoch(self, epoch: int) -> None:
        for name, lr in learning_rates(self.config, epoch).items():
            self.adams[name].param_groups[0]["lr"] = lr

    def step(self, groups=GROUPS) -> None:
        for name in groups:
            self.adams[name].step()

    def zero_grad(self) -> None:
        for adam in self.adams.values():
            adam.zero_grad(set_to_none=True)

    def remap(self, model: EdgeModel, source: torch.Tensor) -> None:
        """After `model.replace`, row i of every new tensor came from old row source[i] (or is a
        fresh copy when source[i] < 0: zero moments). Rebinds Adam to the new tensors."""
        fresh = source < 0
        rows = source.clamp_min(0)
        for name, tensor in model.tensors().items():
            adam = self.adams[name]
            old = adam.param_groups[0]["params"][0]
            state = adam.state.pop(old, None)
            adam.param_groups[0]["params"] = [tensor]
            if state:
                for key in ("exp_avg", "exp_avg_sq"):
                    moved = state[key][rows].clone()
                    moved[fresh] = 0
                    state[key] = moved
                adam.state[tensor] = state

    def state_dict(self) -> dict:
        return {name: adam.state_dict() for name, adam in self.adams.items()}

    def load_state_dict(self, state: dict) -> None:
        """Restore `state_dict`'s output; a state saved before the view-dependent opacity existed
        has no entry for its group, whose Adam starts afresh."""
        for name, adam in self.adams.items():
            if name == VIEW_OPACITY.raw and name not in state:
                continue
            adam.load_state_dict(state[name])
