"""The rasterizer's stages as differentiable functions over per-device ops (gsplat's layering).

The ops `torch.ops.edgedog.*` are declared once, in csrc/bindings.cpp, with the argument order
these wrappers and `_torch_ref` share: per-primitive tensors as the projection returns them
(means2d, conics, depths, extents), the activated parameters (opacity, a, t, support), the
colours, then the tiles and the frame. Each device registers kernels for the ops (the C++ CPU
kernels, and the CUDA kernels in a CUDA build) and torch's dispatcher runs those of the tensors'
device, so nothing here names a device but `resolve_device`, which picks one for a setting.
The autograd Functions save what their backward passes need with `ctx.save_for_backward` and
return None for inputs that need no gradient.
"""

from __future__ import annotations

import functools

import torch
from edgedog.renderer.extension import load_extension
from edgedog.renderer.primitives import RasterCamera

from edgedog.errors import ConfigError

OPS = ("project_forward", "project_backward", "tile_lists", "rasterize_forward", "rasterize_backward",
       "rasterize_fisher")
"""Every op a device needs kernels for."""


@functools.cache
def kernel_devices() -> tuple[str, ...]:
    """Device types present on this machine with a kernel for every op, e.g. ("cpu",).

    Computed once, after loading the extension that registers the ops and their kernels.
    """
    load_extension()
    present = ["cpu"]
    if torch.accelerator.is_available():
        present.append(torch.accelerator.current_accelerator().type)
    return tuple(device for device in present if all(
        getattr(torch.ops.edgedog, name).default.has_kernel_for_dispatch_key(
            getattr(torch.DispatchKey, device.upper())) for name in OPS))


def resolve_device(wanted: str) -> torch.device:
    """The device to compute on for a setting `wanted`: "cpu", "cuda", or "auto" (CUDA when this
    machine has a GPU and the extension was built with its kernels, else the CPU).

    Raises:
        ConfigError: "cuda" where it has no kernels (saying why).
    """
    if wanted == "auto":
        wanted = "cuda" if "cuda" in kernel_devices() else "cpu"
    elif wanted == "cuda" and "cuda" not in kernel_devices():
        why = ("torch sees no GPU" if not torch.cuda.is_available() else
               "the extension was built without CUDA (rebuild with a CUDA torch and toolkit: make build)")
        raise ConfigError(f"device 'cuda' asked for, but {why}")
    # With its index, as tensors report theirs (torch.device("cuda") != torch.device("cuda:0")).
    return torch.device("cuda", torch.cuda.current_device()) if wanted == "cuda" else torch.device(wanted)


def device_name(device: torch.device) -> str:
    """`device` for a report: 'cpu', or 'cuda' with the GPU's name."""
    return f"cuda ({torch.cuda.get_device_name(device)})" if device.type == "cuda" else device.type


def _ops(device: torch.device):
    """`torch.ops.edgedog`, for tensors on `device`.

    Raises:
        ValueError: `device` has no kernels (naming those that have).
    """
    devices = kernel_devices()
    if device.type not in devices:
        raise ValueError(f"the rasterizer has no kernels for device {device.type!r} (only for "
                         f"{', '.join(devices)}); move the primitives there or use "
                         "RasterConfig(backend='torch')")
    return torch.ops.edgedog


def _f32(x: torch.Tensor) -> torch.Tensor:
    return x.detach().to(torch.float32).contiguous()


class _Project(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means, scales, quats, support_q, K, w2c, width: int, height: int, near: float,
                eps2d: float):
        inputs = (_f32(means), _f32(scales), _f32(quats), _f32(support_q))
        means2d, conics, depths, extents, valid = _ops(means.device).project_forward(*inputs, K, w2c, width,
                                                                                     height, near, eps2d)
        ctx.save_for_backward(*inputs, K, w2c)
        ctx.scalars = (width, height, near, eps2d)
        ctx.mark_non_differentiable(extents, valid)
        return means2d, conics, depths, extents, valid

    @staticmethod
    def backward(ctx, g_means2d, g_conics, g_depths, _g_extents, _g_valid):
        need = ctx.needs_input_grad
        if not any(need[:3]):
            return (None,) * 10
        grads = _ops(g_means2d.device).project_backward(*ctx.saved_tensors, *ctx.scalars, _f32(g_means2d),
                                                        _f32(g_conics), _f32(g_depths))
        return tuple(g if need[k] else None for k, g in enumerate(grads)) + (None,) * 7


def project(means, scales, quats, support_q, camera: RasterCamera, eps2d: float):
    """EWA projection into one camera; differentiable w.r.t. means, scales and quats.

    Args:
        means: (N, 3) world positions; scales: (N, 3) positive axis lengths; quats: (N, 4)
            (w, x, y, z), any norm; support_q: (N,) the footprint's support as a squared
            Mahalanobis radius (no gradient); camera: read on the host;
            eps2d: dilation of the 2D covariance in pixels^2.
    Returns (float32): means2d (N, 2) pixels, conics (N, 3), depths (N,) (0 when culled),
        extents (N, 2) half-widths of the support ellipse (0 when culled), valid (N,) bool;
        extents and valid carry no gradient.
    """
    # The kernels read the camera on the host: it stays there, whatever the means' device.
    cam = camera.to("cpu")
    return _Project.apply(means, scales, quats, support_q, cam.K, cam.w2c, cam.width, cam.height, cam.near,
                          eps2d)


def tile_lists(means2d, depths, extents, valid, width: int, height: int):
    """Which primitives reach each 16x16 tile, front to back (no gradients).

    Args: means2d (N, 2), depths (N,), extents (N, 2), valid (N,) bool, as `project` returns them.
    Returns: offsets (tiles + 1,) int32, ids (M,) int32: tile k (row-major) composites
        ids[offsets[k]:offsets[k + 1]], sorted by depth (index order on ties).
    """
    return _ops(means2d.device).tile_lists(_f32(means2d), _f32(depths), _f32(extents), valid.contiguous(),
                                           width, height)


def _splat_args(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids, width, height,
                background):
    """The 14 leading arguments of every compositing op, as its kernels take them: 11 tensors
    (float32 splats, offsets, ids), width, height, the background or None."""
    splats = [_f32(x) for x in (means2d, conics, depths, extents, opacity, a, t, support, colors)]
    return *splats, offsets, ids, width, height, None if background is None else _f32(background)


class _Rasterize(torch.autograd.Function):
    @staticmethod
    def forward(ctx, means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids,
                width: int, height: int, background, absgrad):
        args = _splat_args(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids,
                           width, height, background)
        image, alpha, depth, final_T, last = _ops(means2d.device).rasterize_forward(*args)
        *tensors, _, _, background = args  # the 11 tensors, width, height, the background or None
        ctx.save_for_backward(*tensors, background, final_T, last)
        ctx.size, ctx.absgrad = (width, height), absgrad
        return image, alpha, depth

    @staticmethod
    def backward(ctx, g_image, g_alpha, g_depth):
        *tensors, background, final_T, last = ctx.saved_tensors
        *grads, absgrad = _ops(g_image.device).rasterize_backward(
            *tensors, *ctx.size, background, final_T, last, _f32(g_image), _f32(g_alpha), _f32(g_depth))
        if ctx.absgrad is not None:
            ctx.absgrad.add(absgrad)
        g_means2d, g_conics, g_depths, g_opacity, g_a, g_t, g_colors = grads
        by_input = (g_means2d, g_conics, g_depths, None, g_opacity, g_a, g_t, None, g_colors)
        return tuple(g if need else None for g, need in zip(by_input, ctx.needs_input_grad)) + (None,) * 6


def rasterize(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids, width: int,
              height: int, background=None, absgrad=None):
    """Front-to-back compositing of one view's splats.

    Args:
        means2d (N, 2), conics (N, 3), depths (N,), extents (N, 2): from `project`;
        opacity (N,), a (N,), t (N,), support (N,): the activated parameters (see
            primitives.Activated); colors (N, C);
        offsets, ids: from `tile_lists`; width, height: the image size;
        background: (C,) or None (black);
        absgrad: an object whose add((N, 2) tensor) each backward pass calls with the sum over
            pixels of |per-pixel dL/dmean2d|, or None.
    Returns (float32): image (H, W, C), alpha (H, W), depth (H, W); differentiable w.r.t.
        means2d, conics, depths, opacity, a, t and colors.
    """
    return _Rasterize.apply(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids,
                            width, height, background, absgrad)


def fisher(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids, width: int,
           height: int, background=None) -> torch.Tensor:
    """(N,) float32 sum over pixels and channels of (dI/dD_i)^2 for one view, without autograd.

    Arguments as for `rasterize`.
    """
    args = _splat_args(means2d, conics, depths, extents, opacity, a, t, support, colors, offsets, ids, width,
                       height, background)
    ops = _ops(means2d.device)
    _, _, _, final_T, last = ops.rasterize_forward(*args)
    return ops.rasterize_fisher(*args, final_T, last)
