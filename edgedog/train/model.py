"""The trainable primitives: one tensor per parameter group, grown and pruned by the strategy."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from edgedog.init.points import InitialPoints
from edgedog.primitives import RAW, VIEW_OPACITY
from edgedog.renderer.footprint import quat_to_rotmat
from edgedog.renderer.primitives import Primitives

GROUPS = (*RAW, VIEW_OPACITY.raw)
"""The parameter groups, one tensor (and optimizer) each: edgedog.primitives.SCHEMA's, which
the rasterizer takes, then the view-dependent opacity's b (edgedog.train.view_opacity)."""


@dataclass
class EdgeModel:
    """N primitives' raw parameters (leaf tensors that require gradients); `to_numpy` gives them
    to `edgedog.primitives.PrimitiveArrays.from_raw`, which activates them.

    Attributes:
        means: (N, 3); log_scales: (N, 3); quats: (N, 4); opacity_logits: (N,); k_raw: (N, 2).
        opacity_dirs: (N, 3) b of the view-dependent opacity (zeros when not given; trained only
            with `model.view_opacity`).
    Colours are fixed to one (edge maps are single-channel intensities).
    """

    means: torch.Tensor
    log_scales: torch.Tensor
    quats: torch.Tensor
    opacity_logits: torch.Tensor
    k_raw: torch.Tensor
    opacity_dirs: torch.Tensor | None = None

    def __post_init__(self):
        if self.opacity_dirs is None:
            self.opacity_dirs = self.means.new_zeros(len(self.means), 3)

    @classmethod
    def from_points(cls, points: InitialPoints, opacity: float, k_init: tuple[float, float],
                    generator: torch.Generator, sight_gain: float = 0.0) -> EdgeModel:
        """Primitives at the initial points: isotropic scales, uniformly random rotations; with
        `sight_gain` and points that carry a `sight`, the view-dependent opacity's b starts at
        sight_gain x sight (drawn toward the views that saw the point), else at 0."""
        n = len(points)
        quats = torch.randn(n, 4, generator=generator, dtype=torch.float32)  # uniform on SO(3)
        dirs = (torch.tensor(points.sight * sight_gain, dtype=torch.float32)
                if sight_gain and points.sight is not None else None)
        return cls(
            means=torch.tensor(points.positions, dtype=torch.float32),
            log_scales=torch.log(torch.tensor(points.scales, dtype=torch.float32))[:, None].repeat(1, 3),
            quats=quats / quats.norm(dim=1, keepdim=True),
            opacity_logits=torch.full((n,), math.log(opacity / (1 - opacity)), dtype=torch.float32),
            k_raw=torch.tensor(k_init, dtype=torch.float32).repeat(n, 1),
            opacity_dirs=dirs,
        ).requires_grad_()

    @classmethod
    def from_numpy(cls, arrays) -> EdgeModel:
        """Tensors sharing the memory of `arrays` (a mapping with one array per group, as
        `to_numpy` gives; without opacity_dirs, zeros); they do not require gradients."""
        return cls(**{name: torch.from_numpy(np.asarray(arrays[name])) for name in GROUPS
                      if name in RAW or name in arrays})

    def requires_grad_(self) -> EdgeModel:
        for name in GROUPS:
            getattr(self, name).requires_grad_(True)
        return self

    def __len__(self) -> int:
        return self.means.shape[0]

    def tensors(self) -> dict[str, torch.Tensor]:
        return {name: getattr(self, name) for name in GROUPS}

    @property
    def device(self) -> torch.device:
        return self.means.device

    def to(self, device: torch.device) -> EdgeModel:
        """This model with its tensors on `device` (the same tensors when already there); leaves
        that required gradients still do."""
        if device == self.device:
            return self
        return EdgeModel(**{name: tensor.detach().to(device).requires_grad_(tensor.requires_grad)
                            for name, tensor in self.tensors().items()})

    def primitives(self) -> Primitives:
        """The rasterizer's primitives, with the opacity logits a (the same in every view)."""
        return Primitives(**{name: getattr(self, name) for name in RAW},
                          colors=torch.ones(len(self), 1, device=self.device))

    def replace(self, tensors: dict[str, torch.Tensor]) -> None:
        """Swap in new leaf tensors (after pruning or duplication)."""
        for name in GROUPS:
            setattr(self, name, tensors[name].detach().requires_grad_(True))

    def major_axes(self) -> torch.Tensor:
        """(N, 3) unit axis of each primitive's largest scale (differentiable in quats, scales)."""
        R = quat_to_rotmat(self.quats)
        largest = self.log_scales.argmax(dim=1)
        return R[torch.arange(len(self), device=self.device), :, largest]

    def to_numpy(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name).detach().cpu().numpy().copy() for name in GROUPS}
