"""The public rasterizer: primitives + camera(s) -> image, alpha, depth, screen-space means.

Stages: activation, EWA projection, tile intersection with depth sort, compositing. A backend
runs them: "kernels", the ops registered for the primitives' device (ops.py), or "torch", the
reference (_torch_ref.py); each is a render and a Fisher function in BACKENDS, picked by
RasterConfig.backend. docs/METHOD.md has the maths.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import torch
from edgedog.renderer import _torch_ref as ref
from edgedog.renderer import ops
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import Activated, Primitives, RasterCamera, activate


class AbsGradSink:
    """Receives, from each backward pass through a render, the (N, 2) sum over pixels of
    |per-pixel dL/dmean2d| (gsplat's "absgrad", which densification uses: unlike |dL/dmean2d|,
    pulls from both sides of an edge add up instead of cancelling). Every backend fills it."""

    def __init__(self):
        self.value: torch.Tensor | None = None

    def add(self, absgrad: torch.Tensor) -> None:
        self.value = absgrad if self.value is None else self.value + absgrad


@dataclass
class RenderOutput:
    """What one view's render gives.

    Attributes:
        image: (H, W, C) composited intensities.
        alpha: (H, W) accumulated opacity, 1 - final transmittance.
        depth: (H, W) expected depth sum_i z_i alpha_i T_i (not normalised by alpha).
        means2d: (N, 2) projected centres in pixels; its .grad holds dL/dmean2d after
            backward (for densification), when the primitives require gradients.
        extents: (N, 2) half-widths of each support box in pixels; valid: (N,) bool, not
            culled by the projection (both as the projection returns them).
        absgrad: after backward, `.value` is the (N, 2) sum over pixels of |per-pixel
            dL/dmean2d| (None before backward; with the torch backend, also when the means
            need no gradient).
    """

    image: torch.Tensor
    alpha: torch.Tensor
    depth: torch.Tensor
    means2d: torch.Tensor
    extents: torch.Tensor
    valid: torch.Tensor
    absgrad: AbsGradSink

    @functools.cached_property
    def visible(self) -> torch.Tensor:
        """(N,) bool, the primitive reaches at least one pixel of this view (computed when first
        asked for: training never asks, and on a GPU each of its dozen operators is a launch)."""
        height, width = self.alpha.shape
        return ref.support_boxes(self.means2d.detach(), self.extents, self.valid, width, height)[2]


def _background(config: RasterConfig, channels: int, dtype: torch.dtype, device: torch.device):
    """(C,) the configured background, or None."""
    if config.background is None:
        return None
    bg = torch.tensor(config.background, dtype=dtype, device=device)
    if bg.numel() != channels:
        raise ValueError(f"background has {bg.numel()} values for {channels} channels")
    return bg


def _project_reference(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig):
    """The reference projection in the primitives' dtype and device."""
    K, w2c = camera.K.to(prims.means), camera.w2c.to(prims.means)
    return ref.project(prims.means, act.scales, prims.quats, act.support_q, K, w2c, camera.width,
                       camera.height, camera.near, config.eps2d)


def _project_and_tile(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig):
    """The ops' projection and tile lists: means2d, conics, depths, extents, valid, offsets, ids."""
    means2d, conics, depths, extents, valid = ops.project(
        prims.means, act.scales, prims.quats, act.support_q, camera, config.eps2d)
    offsets, ids = ops.tile_lists(means2d, depths, extents, valid, camera.width, camera.height)
    return means2d, conics, depths, extents, valid, offsets, ids


def _render_kernels(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig,
                    absgrad: AbsGradSink):
    """means2d, extents, valid and (image, alpha, depth) by the ops (float32)."""
    means2d, conics, depths, extents, valid, offsets, ids = _project_and_tile(prims, act, camera, config)
    background = _background(config, prims.colors.shape[1], prims.colors.dtype, prims.colors.device)
    rendered = ops.rasterize(means2d, conics, depths, extents, act.opacity, act.a, act.t, act.support,
                             prims.colors, offsets, ids, camera.width, camera.height, background, absgrad)
    return means2d, extents, valid, rendered


def _render_reference(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig,
                      absgrad: AbsGradSink):
    """means2d, extents, valid and (image, alpha, depth) by the reference, in the primitives' dtype."""
    means2d, conics, depths, extents, valid = _project_reference(prims, act, camera, config)
    background = _background(config, prims.colors.shape[1], prims.colors.dtype, prims.colors.device)
    rendered = ref.rasterize(means2d, conics, depths, extents, act.opacity, act.a, act.t, act.support,
                             prims.colors, valid, camera.width, camera.height, background, absgrad)
    return means2d, extents, valid, rendered


def _fisher_kernels(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig):
    """(N,) float32 Fisher information of one view by the ops."""
    means2d, conics, depths, extents, _, offsets, ids = _project_and_tile(prims, act, camera, config)
    background = _background(config, prims.colors.shape[1], torch.float32, prims.colors.device)
    return ops.fisher(means2d, conics, depths, extents, act.opacity, act.a, act.t, act.support, prims.colors,
                      offsets, ids, camera.width, camera.height, background)


def _fisher_torch(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig):
    """(N,) float32 Fisher information of one view by the reference."""
    return fisher_reference(prims, camera, config).to(torch.float32)


class Implementation(NamedTuple):
    """How a backend runs the stages: a render and a Fisher function of (primitives, activated,
    camera, config[, absgrad sink]), as `_render_kernels` and `_fisher_kernels`."""

    render: Callable
    fisher: Callable


BACKENDS = {"kernels": Implementation(_render_kernels, _fisher_kernels),
            "torch": Implementation(_render_reference, _fisher_torch)}
"""RasterConfig.backend -> its implementation."""


def _render_one(
    prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig
) -> RenderOutput:
    absgrad = AbsGradSink()
    render = BACKENDS[config.backend].render
    means2d, extents, valid, (image, alpha, depth) = render(prims, act, camera, config, absgrad)
    if means2d.requires_grad:
        means2d.retain_grad()
    return RenderOutput(image, alpha, depth, means2d, extents, valid, absgrad)


def rasterize(
    primitives: Primitives,
    cameras: RasterCamera | Sequence[RasterCamera],
    config: RasterConfig = RasterConfig(),
) -> RenderOutput | list[RenderOutput]:
    """Render the primitives into one camera (-> RenderOutput) or several (-> a list).

    Everything runs on the primitives' device (the cameras are moved there).
    """
    act = activate(primitives, config)
    if isinstance(cameras, RasterCamera):
        return _render_one(primitives, act, cameras, config)
    return [_render_one(primitives, act, camera, config) for camera in cameras]


def fisher_information(
    primitives: Primitives, cameras: Sequence[RasterCamera], config: RasterConfig = RasterConfig()
) -> torch.Tensor:
    """(N,) float32 U_i = sum over views, pixels and channels of (dI/dD_i)^2, without autograd.

    D_i is primitive i's footprint response at a pixel (the DoG profile, before opacity): the
    Gauss-Newton approximation of the Fisher information of the render w.r.t. the footprint.
    The primitive-level pruning ranks primitives by it.
    """
    fisher = BACKENDS[config.backend].fisher
    with torch.no_grad():
        act = activate(primitives, config)
        total = torch.zeros(len(primitives), dtype=torch.float32, device=primitives.means.device)
        for camera in cameras:
            total += fisher(primitives, act, camera, config)
    return total


def fisher_reference(primitives: Primitives, camera: RasterCamera, config: RasterConfig) -> torch.Tensor:
    """Fisher information of one view by autograd through the torch reference (slow; for tests).

    Each pixel's footprint responses D(p, i) are made leaves; since D(p, i) only affects pixel p,
    d(sum_p I_c(p)) / dD(p, i) = dI_c(p) / dD(p, i).
    """
    with torch.enable_grad():
        act = activate(primitives, config)
        dtype = primitives.means.dtype
        means2d, conics, depths, extents, valid = _project_reference(primitives, act, camera, config)
        background = _background(config, primitives.colors.shape[1], dtype, primitives.colors.device)
        return ref.fisher_per_view(means2d.detach(), conics.detach(), depths.detach(), extents,
                                   act.opacity.detach(), act.a.detach(), act.t.detach(), act.support,
                                   primitives.colors.detach(), valid, camera.width, camera.height, background)
