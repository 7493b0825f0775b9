"""`edgedog bench raster`: speed of the rasterizer's kernels (C++ on the CPU, or CUDA) against
the torch reference (on the CPU), and of a training step's loss on each view's render (the
fused op on the CPU, `losses.edge_loss`) against its torch functions.

The scene is ABC-like: thin primitives laid along the straight edges and circles of a CAD part
in [0, 1]^3 (a box with a circular hole and a boss), viewed from the ABC-NEF camera sphere.
"""

from __future__ import annotations

import platform
import resource
import time
from dataclasses import dataclass

import numpy as np
import torch

from edgedog.builtin.scene import CORNERS, EDGES
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.extension import load_extension
from edgedog.renderer.ops import device_name, resolve_device
from edgedog.renderer.primitives import Primitives, RasterCamera
from edgedog.renderer.rasterize import RenderOutput, fisher_information, rasterize
from edgedog.synthetic.cameras import orbit_cameras
from edgedog.train import losses

MAJOR_SCALE = 0.004  # 4 mm along the curve
MINOR_SCALE = 0.0008  # 0.8 mm across: thin edge primitives


@dataclass(frozen=True)
class RasterBenchConfig:
    """Attributes:
    primitives: number of primitives.
    size: image width and height in pixels.
    views: views timed with the kernels (each: forward, backward, Fisher).
    reference_views: views timed with the torch reference (it is slow), on the CPU.
    kernel: "dog" or "gaussian".
    seed: random seed of the scene.
    device: where the kernels run: "cpu", "cuda" or "auto" (CUDA when there are kernels for it).
    """

    primitives: int = 20000
    size: int = 800
    views: int = 50
    reference_views: int = 1
    kernel: str = "dog"
    seed: int = 0
    device: str = "auto"


def _curves() -> list[np.ndarray]:
    """Polylines (M, 3) of the part's feature curves: box edges, two circles and a boss."""
    curves = [CORNERS[[a, b]] for a, b in EDGES]
    angles = np.linspace(0, 2 * np.pi, 65)
    top, bottom = CORNERS[:, 2].max(), CORNERS[:, 2].min()
    for z in (top, bottom):  # a through hole of radius 0.1
        curves.append(
            np.stack([0.35 + 0.1 * np.cos(angles), 0.5 + 0.1 * np.sin(angles), np.full_like(angles, z)], 1)
        )
    for z in (top, top + 0.1):  # a cylindrical boss of radius 0.06
        curves.append(
            np.stack([0.65 + 0.06 * np.cos(angles), 0.5 + 0.06 * np.sin(angles), np.full_like(angles, z)], 1)
        )
    return curves


def abc_like_primitives(n: int, seed: int = 0) -> Primitives:
    """`n` thin primitives along the part's curves, major axis along the tangent."""
    rng = np.random.default_rng(seed)
    segments = np.concatenate([np.stack([c[:-1], c[1:]], 1) for c in _curves()])  # (S, 2, 3)
    lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    pick = rng.choice(len(segments), size=n, p=lengths / lengths.sum())
    s = rng.random((n, 1))
    means = segments[pick, 0] * (1 - s) + segments[pick, 1] * s
    tangent = segments[pick, 1] - segments[pick, 0]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    # The rotation taking +x to the tangent: quaternion (1 + x.d, x cross d), normalised.
    x = np.array([1.0, 0.0, 0.0])
    quats = np.concatenate([1 + tangent @ x[:, None], np.cross(x, tangent)], axis=1)
    flipped = quats[:, 0] < 1e-6  # tangent along -x: rotate half a turn about z
    quats[flipped] = [0.0, 0.0, 0.0, 1.0]
    log_scales = np.log(np.array([MAJOR_SCALE, MINOR_SCALE, MINOR_SCALE]))[None] + 0.1 * rng.standard_normal(
        (n, 3)
    )
    f32 = dict(dtype=torch.float32)
    return Primitives(
        means=torch.tensor(means, **f32).requires_grad_(),
        log_scales=torch.tensor(log_scales, **f32).requires_grad_(),
        quats=torch.tensor(quats, **f32).requires_grad_(),
        opacity_logits=torch.full((n,), 2.0, **f32).requires_grad_(),
        k_raw=torch.zeros(n, 2, **f32).requires_grad_(),
        colors=torch.ones(n, 1, **f32),
    )


def _moved(prims: Primitives, device: torch.device) -> Primitives:
    return Primitives(
        *(
            getattr(prims, f).detach().to(device).requires_grad_(getattr(prims, f).requires_grad)
            for f in ("means", "log_scales", "quats", "opacity_logits", "k_raw", "colors")
        )
    )


def _clock(device: torch.device) -> float:
    """The host's clock once the device's queued work is done (kernels run asynchronously)."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)
    return time.perf_counter()


def _evaluations(out: RenderOutput, prims: Primitives, camera: RasterCamera, config: RasterConfig) -> int:
    """Primitive-pixel evaluations of a forward pass: pixels inside each support box."""
    from edgedog.renderer import ops
    from edgedog.renderer._torch_ref import support_boxes
    from edgedog.renderer.primitives import activate

    with torch.no_grad():
        act = activate(prims, config)
        means2d, _, _, extents, valid = ops.project(
            prims.means, act.scales, prims.quats, act.support_q, camera, config.eps2d
        )
        lo, hi, _ = support_boxes(means2d, extents, valid, camera.width, camera.height)
        count = torch.clamp(hi - lo + 1, min=0).prod(1)
    return int(count[out.visible].sum())


def _time_view(
    prims: Primitives, camera: RasterCamera, config: RasterConfig, generator
) -> tuple[float, float, RenderOutput]:
    for tensor in (prims.means, prims.log_scales, prims.quats, prims.opacity_logits, prims.k_raw):
        tensor.grad = None
    device = prims.means.device
    cotangent = torch.randn((camera.height, camera.width, 1), generator=generator).to(device)
    start = _clock(device)
    out = rasterize(prims, camera, config)
    forward = _clock(device) - start
    start = _clock(device)
    out.image.backward(cotangent)
    return forward, _clock(device) - start, out


def _time_loss(out: RenderOutput, reference: bool, generator: torch.Generator) -> tuple[float, float]:
    """Seconds of a training step's loss on a render, forward and backward: over every pixel and
    over a sampled step's pixels (`edge_and_background_sample`), 'exp_neg' weighting. The target
    is the render's own edge pixels shifted by one pixel; `reference`: the torch functions on
    the host instead of `losses.edge_loss` on the render's device."""
    device = torch.device("cpu") if reference else out.image.device
    render = out.image.detach().squeeze(-1).to(device)
    depth = out.depth.detach().to(device)
    target = torch.roll((render > 0.1).float(), 1, dims=1)
    edges = losses.edge_pixels(target > 0)
    seconds = []
    for sampled in (False, True):
        sample = (losses.edge_and_background_sample(edges, target.numel(), generator).to(device)
                  if sampled else None)
        leaf = render.clone().requires_grad_()
        start = _clock(device)
        loss_of = losses.edge_loss_reference if reference else losses.edge_loss
        loss_of(leaf, target, depth, "exp_neg", sample).backward()
        seconds.append(_clock(device) - start)
    return seconds[0], seconds[1]


def run(cfg: RasterBenchConfig) -> dict:
    """Time the kernels on `views` views and the reference on `reference_views`; JSON-ready."""
    device = resolve_device(cfg.device)
    host_prims = abc_like_primitives(cfg.primitives, cfg.seed)
    prims = _moved(host_prims, device)
    cameras = [RasterCamera.from_camera(c) for c in orbit_cameras(cfg.views, cfg.size)]
    config = RasterConfig(kernel=cfg.kernel)
    generator = torch.Generator().manual_seed(cfg.seed)
    _time_view(prims, cameras[0], config, generator)  # warm-up: first-touch allocations
    forward, backward, evaluations, visible = [], [], 0, []
    loss, ref_loss = [], []  # (full, sampled) seconds per view
    for camera in cameras:
        f, b, out = _time_view(prims, camera, config, generator)
        forward.append(f)
        backward.append(b)
        evaluations += _evaluations(out, prims, camera, config)
        visible.append(int(out.visible.sum()))
        loss.append(_time_loss(out, False, generator))
        ref_loss.append(_time_loss(out, True, generator))
    start = _clock(device)
    fisher_information(prims, cameras, config)
    fisher = (_clock(device) - start) / len(cameras)

    ref_config = RasterConfig(kernel=cfg.kernel, backend="torch")
    ref_prims = _moved(host_prims, torch.device("cpu"))
    ref_forward, ref_backward = [], []
    for camera in cameras[: cfg.reference_views]:
        f, b, _ = _time_view(ref_prims, camera, ref_config, generator)
        ref_forward.append(f)
        ref_backward.append(b)
    start = time.perf_counter()
    fisher_information(ref_prims, cameras[:1], ref_config)
    ref_fisher = time.perf_counter() - start

    ms = lambda seconds: round(1000 * float(np.mean(seconds)), 3)  # noqa: E731
    kernels = {
        "forward_ms": ms(forward),
        "backward_ms": ms(backward),
        "forward_backward_ms": ms(np.add(forward, backward)),
        "fisher_ms": ms(fisher),
        "forward_backward_ms_p90": round(1000 * float(np.percentile(np.add(forward, backward), 90)), 3),
        "loss_ms": ms([full for full, _ in loss]),
        "sampled_loss_ms": ms([sampled for _, sampled in loss]),
    }
    reference = {
        "forward_ms": ms(ref_forward),
        "backward_ms": ms(ref_backward),
        "forward_backward_ms": ms(np.add(ref_forward, ref_backward)),
        "fisher_ms": ms(ref_fisher),
        "loss_ms": ms([full for full, _ in ref_loss]),
        "sampled_loss_ms": ms([sampled for _, sampled in ref_loss]),
    }
    return {
        "benchmark": "raster",
        "config": cfg.__dict__,
        "machine": {
            "cpu": platform.processor() or platform.machine(),
            "threads": torch.get_num_threads(),
            "torch": torch.__version__,
            "extension": load_extension().build_info(),
            "device": device_name(device),
        },
        "visible_primitives_per_view": round(float(np.mean(visible)), 1),
        "kernels": kernels,
        "torch_reference": reference,
        "speedup": {
            key: round(reference[key] / kernels[key], 1)
            for key in ("forward_ms", "backward_ms", "forward_backward_ms", "fisher_ms", "loss_ms",
                        "sampled_loss_ms")
        },
        "primitive_pixel_evaluations_per_s": round(evaluations / max(sum(forward), 1e-9)),
        "peak_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }


def summary(result: dict) -> str:
    ours, ref, speed = result["kernels"], result["torch_reference"], result["speedup"]
    return (
        f"kernels on {result['machine']['device']}: forward {ours['forward_ms']} ms, backward "
        f"{ours['backward_ms']} ms, Fisher {ours['fisher_ms']} ms per view; torch reference on the cpu: "
        f"forward {ref['forward_ms']} ms, "
        f"backward {ref['backward_ms']} ms "
        f"(speed-up x{speed['forward_backward_ms']} forward+backward, x{speed['fisher_ms']} Fisher); "
        f"a step's loss with its backward {ours['loss_ms']} ms, sampled {ours['sampled_loss_ms']} ms "
        f"(torch functions on the cpu: {ref['loss_ms']}, {ref['sampled_loss_ms']} ms)"
    )


__all__ = ["RasterBenchConfig", "abc_like_primitives", "run", "summary"]
