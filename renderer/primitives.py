"""The primitives' raw parameters, the cameras the rasterizer takes, and their activations."""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.footprint import support_u

from edgedog.primitives import SCHEMA


@dataclass
class Primitives:
    """N primitives' raw (unactivated) parameters, the tensors an optimizer trains (the `raw`
    names of edgedog.primitives.SCHEMA, which says how each is activated), and colours.

    Attributes:
        means: (N, 3) world positions.
        log_scales: (N, 3) log of the axis lengths.
        quats: (N, 4) rotations (w, x, y, z), any norm.
        opacity_logits: (N,) opacity = sigmoid(logit).
        k_raw: (N, 2) DoG shape before activation (see RasterConfig.k_activation).
        colors: (N, C) intensities; C >= 1 (edges use C = 1, fixed to 1).
    """

    means: torch.Tensor
    log_scales: torch.Tensor
    quats: torch.Tensor
    opacity_logits: torch.Tensor
    k_raw: torch.Tensor
    colors: torch.Tensor

    def __post_init__(self):
        n = self.means.shape[0]
        for p in SCHEMA:
            shape = tuple(getattr(self, p.raw).shape)
            if shape != p.shape(n):
                raise ValueError(f"{p.raw} has shape {shape}, expected {p.shape(n)}")
        if self.colors.dim() != 2 or self.colors.shape[0] != n or self.colors.shape[1] < 1:
            raise ValueError(f"colors has shape {tuple(self.colors.shape)}, expected ({n}, C >= 1)")

    def __len__(self) -> int:
        return self.means.shape[0]


@dataclass(frozen=True)
class RasterCamera:
    """A pinhole camera as the rasterizer takes it.

    Attributes:
        K: (3, 3) float64 intrinsics (pixel centres at integers).
        w2c: (4, 4) float64 world-to-camera, OpenCV convention.
        width, height: image size in pixels.
        near: primitives with camera z <= near are culled.
    """

    K: torch.Tensor
    w2c: torch.Tensor
    width: int
    height: int
    near: float = 0.01

    @classmethod
    def from_camera(cls, camera, near: float = 0.01) -> RasterCamera:
        """From an `edgedog.scenes.Camera`."""
        return cls(torch.as_tensor(camera.K, dtype=torch.float64),
                   torch.as_tensor(camera.w2c, dtype=torch.float64), camera.width, camera.height, near)

    def to(self, device: torch.device | str) -> RasterCamera:
        """This camera with K and w2c on `device` (tensors already there are not copied)."""
        return replace(self, K=self.K.to(device), w2c=self.w2c.to(device))


def dog_shape(k_raw: torch.Tensor, config: RasterConfig) -> tuple[torch.Tensor, torch.Tensor]:
    """Raw DoG parameters (N, 2) -> inner scale a (N,) and ratio t (N,) in [0, 1).

    sigmoid: a = 2 sigmoid(k0) in (0, 2), t = sigmoid(k1): raw 0 gives a = 1 (the inner
        Gaussian is the primitive's own footprint) and t = 1/2 (surround sqrt(2) wider).
    exp: a = exp(k0) > 0, t = exp(-exp(k1)): raw 0 gives a = 1 and t = 1/e, a surround 1.65x
        wider, Marr and Hildreth's DoG ratio of about 1.6.
    gaussian kernel: a = 1, t = 0, the plain 3DGS footprint, k_raw ignored.
    """
    if config.kernel == "gaussian":
        ones = torch.ones_like(k_raw[:, 0])
        return ones, torch.zeros_like(ones)
    # unbind: one backward node that stacks both columns' gradients, where two column selects
    # would each fill a zero (N, 2) tensor and add it.
    inner, outer = k_raw.unbind(1)
    if config.k_activation == "sigmoid":
        return 2 * torch.sigmoid(inner), torch.sigmoid(outer)
    return torch.exp(inner), torch.exp(-torch.exp(outer))


@dataclass
class Activated:
    """The primitives' parameters as the kernels take them, with the footprint's support."""

    scales: torch.Tensor   # (N, 3)
    opacity: torch.Tensor  # (N,)
    a: torch.Tensor        # (N,)
    t: torch.Tensor        # (N,)
    support: torch.Tensor  # (N,) largest u that can reach the minimum alpha (no gradient)

    @property
    def support_q(self) -> torch.Tensor:
        """(N,) the support as a squared Mahalanobis radius, q = 2 a u."""
        return (2 * self.a * self.support).detach()


def activate(primitives: Primitives, config: RasterConfig) -> Activated:
    opacity = torch.sigmoid(primitives.opacity_logits)
    a, t = dog_shape(primitives.k_raw, config)
    with torch.no_grad():
        support = support_u(opacity, t)
    return Activated(torch.exp(primitives.log_scales), opacity, a, t, support)
