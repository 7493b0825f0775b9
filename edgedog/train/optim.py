"""Adam over the parameter groups, EdgeGaussians' learning-rate schedules, and the bookkeeping
that keeps Adam's moments aligned when primitives are pruned or duplicated."""

from __future__ import annotations

import torch

from edgedog.primitives import VIEW_OPACITY
from edgedog.train.config import TrainConfig
from edgedog.train.model import EdgeModel


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
    """One Adam over the groups of an EdgeModel (a parameter group each, named as the model's
    tensors); rebinds to the model's tensors after each change.

    The view-dependent opacity's b has AdamW's decoupled decay (`loss.view_opacity_decay`): each
    step shrinks it by lr x decay, so only a push that the views agree on keeps it from 0.
    One optimizer, not one per group: a step is one call (torch's Python around each call costs
    more than a small group's arithmetic), and on a GPU torch's fused Adam, one kernel per group
    where the default launches about ten. The CPU keeps torch's default arithmetic, the same as
    one Adam per group to the bit. Checkpoints hold one Adam state_dict per group (`state_dict`).
    """

    def __init__(self, model: EdgeModel, config: TrainConfig):
        self.config = config
        fused = True if model.device.type == "cuda" else None
        groups = [{"params": [tensor], "name": name,
                   "weight_decay": config.loss.view_opacity_decay if name == VIEW_OPACITY.raw else 0.0}
                  for name, tensor in model.tensors().items()]
        self.adam = torch.optim.Adam(groups, lr=0.0, eps=1e-15, fused=fused, decoupled_weight_decay=True)

    @property
    def groups(self) -> dict[str, dict]:
        """Adam's parameter groups by name (loading a state makes new group dicts: never kept)."""
        return {group["name"]: group for group in self.adam.param_groups}

    def set_epoch(self, epoch: int) -> None:
        groups = self.groups
        for name, lr in learning_rates(self.config, epoch).items():
            groups[name]["lr"] = lr

    def step(self) -> None:
        """Adam on every group with a gradient (a group without one is left as it is, moments
        and step count included)."""
        self.adam.step()

    def zero_grad(self) -> None:
        self.adam.zero_grad(set_to_none=True)

    def moments(self, name: str) -> dict[str, torch.Tensor]:
        """Adam's state of group `name` (exp_avg, exp_avg_sq, step; empty before its first step)."""
        return self.adam.state[self.groups[name]["params"][0]]

    def remap(self, model: EdgeModel, source: torch.Tensor) -> None:
        """After `model.replace`, row i of every new tensor came from old row source[i] (or is a
        fresh copy when source[i] < 0: zero moments). Rebinds Adam to the new tensors."""
        fresh = source < 0
        rows = source.clamp_min(0)
        groups = self.groups
        for name, tensor in model.tensors().items():
            group = groups[name]
            state = self.adam.state.pop(group["params"][0], None)
            group["params"] = [tensor]
            if state:
                for key in ("exp_avg", "exp_avg_sq"):
                    moved = state[key][rows].clone()
                    moved[fresh] = 0
                    state[key] = moved
                self.adam.state[tensor] = state

    def state_dict(self) -> dict:
        """{group name: that group's Adam state as a one-group Adam's state_dict}."""
        whole = self.adam.state_dict()
        return {group["name"]: {"state": {0: whole["state"][k]} if k in whole["state"] else {},
                                "param_groups": [{**group, "params": [0]}]}
                for k, group in enumerate(whole["param_groups"])}

    def load_state_dict(self, state: dict) -> None:
        """Restore `state_dict`'s output; a state saved before the view-dependent opacity existed
        has no entry for its group, whose moments start afresh."""
        whole = {"state": {}, "param_groups": []}
        for k, group in enumerate(self.adam.param_groups):
            name = group["name"]
            if name == VIEW_OPACITY.raw and name not in state:
                saved_group, saved_state = {}, {}
            else:
                saved_group, saved_state = state[name]["param_groups"][0], state[name]["state"]
            # The settings are this run's (its config); the learning rate and the moments, saved.
            whole["param_groups"].append({**{key: value for key, value in group.items() if key != "params"},
                                          "lr": saved_group.get("lr", group["lr"]), "params": [k]})
            if 0 in saved_state:
                whole["state"][k] = saved_state[0]
        self.adam.load_state_dict(whole)
