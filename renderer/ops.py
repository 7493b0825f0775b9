"""Autograd wrappers over the C++ kernels, one per stage (gsplat's layering).

Each Function checks shapes in C++, saves what its backward pass needs, and returns None for
inputs that need no gradient. The same stages exist in plain torch in `_torch_ref`.
"""

from __future__ import annotations

import torch
from edgedog.renderer.extension import load_extension
from edgedog.renderer.primitives import RasterCamera


def _f32(x: torch.Tensor) -> torch.Tensor:
    return x.detach().to(torch.float32).contiguous()


class _Project(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means, scales, quats, support_q, camera: RasterCamera, eps2d: float):
        args = (_f32(means), _f32(scales), _f32(quats), _f32(support_q), camera.K, camera.w2c,
                camera.width, camera.height, camera.near, eps2d)
        means2d, conics, depths, extents, valid = load_extension().project_forward(*args)
        ctx.save_for_backward(*args[:4])
        ctx.camera, ctx.eps2d = camera, eps2d
        ctx.mark_non_differentiable(extents, valid)
        return means2d, conics, depths, extents, valid

    @staticmethod
    def backward(ctx, g_means2d, g_conics, g_depths, _g_extents, _g_valid):
        if not any(ctx.needs_input_grad[:3]):
            return None, None, None, None, None, None
        cam = ctx.camera
        g_means, g_scales, g_quats = load_extension().project_backward(
            *ctx.saved_tensors, cam.K, cam.w2c, cam.width, cam.height, cam.near, ctx.eps2d,
            _f32(g_means2d), _f32(g_conics), _f32(g_depths))
        need = ctx.needs_input_grad
        return (g_means if need[0] else None, g_scales if need[1] else None,
                g_quats if need[2] else None, None, None, None)


def project(means, scales, quats, support_q, camera: RasterCamera, eps2d: float):
    """C++ EWA projection: means2d (N, 2), conics (N, 3), depths (N,), extents (N, 2), valid (N,).

    Differentiable w.r.t. means, scales and quats; extents and valid carry no gradient.
    """
    return _Project.apply(means, scales, quats, support_q, camera, eps2d)


def tile_lists(means2d, extents, depths, valid, width: int, height: int):
    """C++ tile intersection and depth sort (no gradients): offsets (tiles + 1,), ids (M,) int32."""
    return load_extension().tile_lists(_f32(means2d), _f32(extents), _f32(depths), valid.contiguous(),
                                       width, height)


class _Rasterize(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, opacity, a, t, colors, depths, support, extents, offsets, ids,
                width: int, height: int, background, absgrad_sink):
        args = [_f32(x) for x in (means2d, conics, opacity, a, t, support, extents, colors, depths)]
        args += [offsets, ids, width, height, None if background is None else _f32(background)]
        image, alpha, depth, final_T, last = load_extension().rasterize_forward(*args)
        ctx.args = args
        ctx.absgrad_sink = absgrad_sink
        ctx.save_for_backward(final_T, last)
        return image, alpha, depth

    @staticmethod
    def backward(ctx, g_image, g_alpha, g_depth):
        final_T, last = ctx.saved_tensors
        gm, gc, go, ga, gt, gcol, gd, gm_abs = load_extension().rasterize_backward(
            *ctx.args, final_T, last, _f32(g_image), _f32(g_alpha), _f32(g_depth))
        if ctx.absgrad_sink is not None:
            ctx.absgrad_sink.add(gm_abs)
        need = ctx.needs_input_grad
        grads = (gm, gc, go, ga, gt, gcol, gd)
        return tuple(g if need[k] else None for k, g in enumerate(grads)) + (None,) * 8


class AbsGradSink:
    """Receives, from each backward pass, the (N, 2) sum over pixels of |per-pixel dL/dmean2d|
    (gsplat's "absgrad", which densification uses: unlike |dL/dmean2d|, pulls from both sides
    of an edge add up instead of cancelling)."""

    def __init__(self):
        self.value: torch.Tensor | None = None

    def add(self, absgrad: torch.Tensor) -> None:
        self.value = absgrad if self.value is None else self.value + absgrad


def rasterize(means2d, conics, opacity, a, t, colors, depths, support, extents, offsets, ids,
              width: int, height: int, background=None, absgrad_sink: AbsGradSink | None = None):
    """C++ compositing: image (H, W, C), alpha (H, W), depth (H, W).

    Differentiable w.r.t. means2d, conics, opacity, a, t, colors and depths; a backward pass
    also adds the means' absgrad to `absgrad_sink` when given.
    """
    return _Rasterize.apply(means2d, conics, opacity, a, t, colors, depths, support, extents, offsets,
                            ids, width, height, background, absgrad_sink)


def fisher(means2d, conics, opacity, a, t, colors, depths, support, extents, offsets, ids,
           width: int, height: int, background=None) -> torch.Tensor:
    """(N,) sum over pixels and channels of (dI/dD_i)^2 for one view, without autograd."""
    args = [_f32(x) for x in (means2d, conics, opacity, a, t, support, extents, colors, depths)]
    args += [offsets, ids, width, height, None if background is None else _f32(background)]
    ext = load_extension()
    _, _, _, final_T, last = ext.rasterize_forward(*args)
    out = torch.zeros(means2d.shape[0], dtype=torch.float32)
    ext.rasterize_fisher(*args, final_T, last, out)
    return out
