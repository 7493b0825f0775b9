"""The public rasterizer: primitives + camera(s) -> image, alpha, depth, screen-space means.

Stages (each swappable between the C++ kernels and the torch reference): activation, EWA
projection, tile intersection with depth sort, compositing. docs/METHOD.md has the maths.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from edgedog.renderer import _torch_ref as ref
from edgedog.renderer import ops
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import Activated, Primitives, RasterCamera, activate


@dataclass
class RenderOutput:
    """What one view's render gives.

    Attributes:
        image: (H, W, C) composited intensities.
        alpha: (H, W) accumulated opacity, 1 - final transmittance.
        depth: (H, W) expected depth sum_i z_i alpha_i T_i (not normalised by alpha).
        means2d: (N, 2) projected centres in pixels; its .grad holds dL/dmean2d after
            backward (for densification), when the primitives require gradients.
        visible: (N,) bool, the primitive reaches at least one pixel of this view.
        absgrad: after backward, `.value` is the (N, 2) sum over pixels of |per-pixel
            dL/dmean2d| (C++ backend only; None before backward or with the torch backend).
    """

    image: torch.Tensor
    alpha: torch.Tensor
    depth: torch.Tensor
    means2d: torch.Tensor
    visible: torch.Tensor
    absgrad: ops.AbsGradSink


def _background(config: RasterConfig, channels: int, dtype: torch.dtype) -> torch.Tensor | None:
    if config.background is None:
        return None
    bg = torch.tensor(config.background, dtype=dtype)
    if bg.numel() != channels:
        raise ValueError(f"background has {bg.numel()} values for {channels} channels")
    return bg


def _project_reference(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig):
    """The reference projection in the primitives' dtype."""
    dtype = prims.means.dtype
    return ref.project(prims.means, act.scales, prims.quats, act.support_q, camera.K.to(dtype),
                       camera.w2c.to(dtype), camera.width, camera.height, camera.near, config.eps2d)


def _project_and_tile(prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig):
    """The C++ projection and tile lists: means2d, conics, depths, extents, valid, offsets, ids."""
    means2d, conics, depths, extents, valid = ops.project(
        prims.means, act.scales, prims.quats, act.support_q, camera, config.eps2d)
    offsets, ids = ops.tile_lists(means2d, extents, depths, valid, camera.width, camera.height)
    return means2d, conics, depths, extents, valid, offsets, ids


def _render_one(
    prims: Primitives, act: Activated, camera: RasterCamera, config: RasterConfig
) -> RenderOutput:
    background = _background(config, prims.colors.shape[1], prims.colors.dtype)
    w, h = camera.width, camera.height
    absgrad = ops.AbsGradSink()
    if config.backend == "cpp":
        means2d, conics, depths, extents, valid, offsets, ids = _project_and_tile(prims, act, camera, config)
        if means2d.requires_grad:
            means2d.retain_grad()
        image, alpha, depth = ops.rasterize(
            means2d,
            conics,
            act.opacity,
            act.a,
            act.t,
            prims.colors,
            depths,
            act.support,
            extents,
            offsets,
            ids,
            w,
            h,
            background,
            absgrad,
        )
    else:
        means2d, conics, depths, extents, valid = _project_reference(prims, act, camera, config)
        if means2d.requires_grad:
            means2d.retain_grad()
        image, alpha, depth = ref.rasterize(
            means2d,
            conics,
            depths,
            act.opacity,
            act.a,
            act.t,
            prims.colors,
            act.support,
            extents,
            valid,
            w,
            h,
            background,
        )
    visible = ref.support_boxes(means2d.detach(), extents, valid, w, h)[2]
    return RenderOutput(image, alpha, depth, means2d, visible, absgrad)


def rasterize(
    primitives: Primitives,
    cameras: RasterCamera | Sequence[RasterCamera],
    config: RasterConfig = RasterConfig(),
) -> RenderOutput | list[RenderOutput]:
    """Render the primitives into one camera (-> RenderOutput) or several (-> a list)."""
    act = activate(primitives, config)
    if isinstance(cameras, RasterCamera):
        return _render_one(primitives, act, cameras, config)
    return [_render_one(primitives, act, camera, config) for camera in cameras]


def fisher_information(
    primitives: Primitives, cameras: Sequence[RasterCamera], config: RasterConfig = RasterConfig()
) -> torch.Tensor:
    """(N,) U_i = sum over views, pixels and channels of (dI/dD_i)^2, without autograd.

    D_i is primitive i's footprint response at a pixel (the DoG profile, before opacity): the
    Gauss-Newton approximation of the Fisher information of the render w.r.t. the footprint.
    The primitive-level pruning ranks primitives by it.
    """
    with torch.no_grad():
        act = activate(primitives, config)
        total = torch.zeros(len(primitives), dtype=torch.float32)
        for camera in cameras:
            w, h = camera.width, camera.height
            if config.backend == "cpp":
                means2d, conics, depths, extents, _, offsets, ids = _project_and_tile(
                    primitives, act, camera, config)
                total += ops.fisher(
                    means2d,
                    conics,
                    act.opacity,
                    act.a,
                    act.t,
                    primitives.colors,
                    depths,
                    act.support,
                    extents,
                    offsets,
                    ids,
                    w,
                    h,
                    _background(config, primitives.colors.shape[1], torch.float32),
                )
            else:
                total += fisher_reference(primitives, camera, config).to(torch.float32)
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
        return ref.fisher_per_view(
            means2d.detach(),
            conics.detach(),
            depths.detach(),
            act.opacity.detach(),
            act.a.detach(),
            act.t.detach(),
            primitives.colors.detach(),
            act.support,
            extents,
            valid,
            camera.width,
            camera.height,
            _background(config, primitives.colors.shape[1], dtype),
        )
