"""The rasterizer's kernels against the float64 torch reference, stage by stage and end to end.

The reference (`backend="torch"`, float64 primitives on the CPU) is the ground truth: it is
itself checked with `torch.autograd.gradcheck`. Every test of the kernels runs once per device
that has kernels (`@each_device`, see tests/helpers/backends.py; the C++ CPU kernels today). The C++
kernels compute in float32 (projection maths in double), so their outputs and gradients are
compared with tolerances relative to each tensor's scale (its largest magnitude): measured
worst errors are about 1e-5 of the scale, the tolerances are 1e-4 of it, and a deliberate 1%
perturbation (of a cotangent, or the other kernel's output) is shown to exceed them.
"""

from __future__ import annotations

import dataclasses
import inspect
import math

import pytest
import torch
from edgedog.renderer import _torch_ref as ref
from edgedog.renderer import footprint as fp
from edgedog.renderer import load_extension, ops
from edgedog.renderer.config import (
    ALPHA_MAX,
    ALPHA_MIN,
    EARLY_STOP_T,
    FRUSTUM_SLACK,
    TILE_SIZE,
    RasterConfig,
)
from edgedog.renderer.primitives import Primitives, RasterCamera, activate
from edgedog.renderer.rasterize import fisher_information, fisher_reference, rasterize

from edgedog.errors import ConfigError
from edgedog.synthetic.cameras import orbit_cameras
from tests.helpers.backends import each_device, on_device
from tests.helpers.raster_builders import random_primitives

F64 = torch.float64
PARAMS = ("means", "log_scales", "quats", "opacity_logits", "k_raw", "colors")

# Tolerances, as a fraction of the reference tensor's largest magnitude (rtol 0: the atol
# already scales with the tensor). Measured worst |cpp - ref| / max|ref| over 4 other seeds and
# the 8 configurations below (150 primitives, 64x48; the seeds used here give at most 4.6e-6):
# image 7.8e-6, alpha 6.6e-6, depth 6.9e-6,
# means 1.2e-5, log_scales 3.9e-6, quats 1.2e-5, opacity_logits 5.4e-6, k_raw 5.7e-6,
# colors 3.6e-6, means2d 1.1e-5 (float32 kernels vs float64: a few float32 ulps per pixel,
# summed over hundreds of pixels). 1e-4 leaves an 8x margin and is 100x below the effect of a
# 1% change of one cotangent (checked in test_tolerances_detect_perturbations).
REL_TOL = 1e-4


def assert_close_scaled(actual, expected, rel=REL_TOL, name=""):
    """|actual - expected| <= rel x max|expected| elementwise, compared in float64 on the CPU."""
    expected = expected.detach().to("cpu", F64)
    actual = actual.detach().to("cpu", F64)
    scale = max(expected.abs().max().item(), 1e-12) if expected.numel() else 1.0
    torch.testing.assert_close(actual, expected, rtol=0.0, atol=rel * scale,
                               msg=lambda m: f"{name}: {m} (scale {scale:.3g})")


def make_camera(width=64, height=48, view=0, focal=160.0, views=8, near=0.01) -> RasterCamera:
    """A camera of orbit_cameras (radius 4 around (0.5, 0.5, 0.5)) with its own intrinsics."""
    cam = orbit_cameras(views, 64)[view]
    K = torch.tensor([[focal, 0, (width - 1) / 2], [0, focal, (height - 1) / 2], [0, 0, 1]], dtype=F64)
    return RasterCamera(K, torch.as_tensor(cam.w2c, dtype=F64), width, height, near)


def leaf_copy(prims: Primitives, dtype, device="cpu") -> Primitives:
    return on_device(prims, device, dtype, leaves=True)


def cotangents(height, width, channels, seed):
    g = torch.Generator().manual_seed(seed)
    return (torch.randn(height, width, channels, generator=g, dtype=F64),
            torch.randn(height, width, generator=g, dtype=F64),
            torch.randn(height, width, generator=g, dtype=F64))


def render_with_grads(prims, camera, config, cot, dtype, device="cpu"):
    """Render leaf copies in `dtype` on `device`, backward <out, cot>; (output, {param: grad,
    'means2d': grad}), on `device`."""
    leaves = leaf_copy(prims, dtype, device)
    out = rasterize(leaves, camera, config)
    g_image, g_alpha, g_depth = (c.to(device, dtype) for c in cot)
    loss = (out.image * g_image).sum() + (out.alpha * g_alpha).sum() + (out.depth * g_depth).sum()
    loss.backward()
    grads = {k: getattr(leaves, k).grad for k in PARAMS}
    grads["means2d"] = out.means2d.grad
    return out, grads


def torch_config(config: RasterConfig) -> RasterConfig:
    return dataclasses.replace(config, backend="torch")


# (kernel, k_activation, background, channels): every kernel/activation pair with and without
# a background, C = 1 and C = 3 alternating so that each pair meets both.
CONFIGS = [
    ("dog", "sigmoid", False, 1), ("dog", "sigmoid", True, 3),
    ("dog", "exp", False, 3), ("dog", "exp", True, 1),
    ("gaussian", "sigmoid", False, 1), ("gaussian", "sigmoid", True, 3),
    ("gaussian", "exp", False, 3), ("gaussian", "exp", True, 1),
]


def config_of(kernel, activation, background, channels) -> RasterConfig:
    bg = tuple(0.2 + 0.1 * c for c in range(channels)) if background else None
    return RasterConfig(kernel=kernel, k_activation=activation, background=bg)


@pytest.fixture(scope="module")
def camera():
    return make_camera()


# ---------------------------------------------------------------------------------------------
# End to end: forward and gradients against the float64 reference.
# ---------------------------------------------------------------------------------------------


@each_device
@pytest.mark.parametrize("kernel,activation,background,channels", CONFIGS)
def test_render_and_gradients_match_reference(camera, kernel, activation, background, channels, device):
    config = config_of(kernel, activation, background, channels)
    prims = random_primitives(150, channels, seed=len(kernel) + channels)
    cot = cotangents(camera.height, camera.width, channels, seed=7)
    out_ref, g_ref = render_with_grads(prims, camera, torch_config(config), cot, F64)
    out, g = render_with_grads(prims, camera, config, cot, torch.float32, device)

    assert out.image.shape == (camera.height, camera.width, channels) and out.image.dtype == torch.float32
    assert out.image.device.type == device
    assert out.alpha.shape == out.depth.shape == (camera.height, camera.width)
    # A real scene, not an empty image: most primitives visible, many pixels covered.
    assert out.visible.sum() > 100 and (out_ref.alpha > 0.1).sum() > 200
    assert torch.equal(out.visible.cpu(), out_ref.visible)
    for name in ("image", "alpha", "depth"):
        assert_close_scaled(getattr(out, name), getattr(out_ref, name), name=name)
    assert_close_scaled(out.means2d, out_ref.means2d, rel=1e-6, name="means2d")
    for name, expected in g_ref.items():
        if name == "k_raw" and kernel == "gaussian":
            assert expected is None and g[name] is None  # k_raw is unused by the Gaussian kernel
            continue
        assert expected is not None and g[name] is not None, name
        assert expected.abs().max() > 0, name
        assert_close_scaled(g[name], expected, name=f"grad {name}")


@each_device
@pytest.mark.parametrize("kernel", ["dog", "gaussian"])
def test_absgrad_is_the_sum_of_per_pixel_absolute_mean_gradients(kernel, device):
    """absgrad_i = sum over pixels p of |d<out_p, cot_p>/dmean2d_i|, from the reference by one
    autograd pass per pixel; it bounds |dL/dmean2d| and exceeds it where pulls cancel. The
    kernels and the torch backend both give it."""
    camera = make_camera(width=16, height=12, focal=48.0)
    config = RasterConfig(kernel=kernel)
    prims = random_primitives(60, 1, seed=5)
    g_image, g_alpha, g_depth = cotangents(camera.height, camera.width, 1, seed=8)
    out_ref = rasterize(leaf_copy(prims, F64), camera, torch_config(config))
    per_pixel = (out_ref.image * g_image).sum(-1) + out_ref.alpha * g_alpha + out_ref.depth * g_depth
    per_pixel = per_pixel.reshape(-1)
    expected = torch.zeros(len(prims), 2, dtype=F64)
    for value in per_pixel:
        (grad,) = torch.autograd.grad(value, out_ref.means2d, retain_graph=True)
        expected += grad.abs()
    out, grads = render_with_grads(prims, camera, config, (g_image, g_alpha, g_depth), torch.float32, device)
    assert expected.abs().max() > 0 and out_ref.alpha.max() > 0.5
    assert_close_scaled(out.absgrad.value, expected, name="absgrad")
    absgrad, means2d_grad = out.absgrad.value.cpu(), grads["means2d"].cpu()
    assert torch.all(absgrad >= means2d_grad.abs() - 1e-6)
    assert (absgrad > 2 * means2d_grad.abs() + 1e-3).any()
    # The torch backend's, from per-pixel copies of the means: the same sums in float64.
    out_torch, _ = render_with_grads(prims, camera, torch_config(config), (g_image, g_alpha, g_depth), F64)
    assert out_torch.absgrad.value.dtype == F64
    assert_close_scaled(out_torch.absgrad.value, expected, rel=1e-12, name="torch absgrad")


@each_device
def test_tolerances_detect_perturbations(camera, device):
    """The tolerances above are tight enough to see a 1% error or the other kernel's output."""
    config = config_of("dog", "sigmoid", True, 3)
    prims = random_primitives(150, 3, seed=3)
    cot = cotangents(camera.height, camera.width, 3, seed=7)
    out, g = render_with_grads(prims, camera, config, cot, torch.float32, device)
    # 1% more image cotangent: every gradient fed by the image moves by ~1% of its scale.
    bumped = (cot[0] * 1.01, cot[1], cot[2])
    _, g_bumped = render_with_grads(prims, camera, torch_config(config), bumped, F64)
    for name in ("means", "log_scales", "quats", "opacity_logits", "k_raw", "colors", "means2d"):
        with pytest.raises(AssertionError):
            assert_close_scaled(g[name], g_bumped[name], name=name)
    # 1% more cotangent at a single pixel shows in the colour gradients of the primitives there.
    one_pixel = cot[0].clone()
    one_pixel[24, 32] *= 1.01
    _, g_pixel = render_with_grads(prims, camera, torch_config(config), (one_pixel, cot[1], cot[2]), F64)
    with pytest.raises(AssertionError):
        assert_close_scaled(g["colors"], g_pixel["colors"], name="colors")
    # The Gaussian kernel's render is not the DoG's.
    out_gauss, g_gauss = render_with_grads(prims, camera, dataclasses.replace(config, kernel="gaussian"),
                                           cot, torch.float32, device)
    for name in ("image", "alpha", "depth"):
        with pytest.raises(AssertionError):
            assert_close_scaled(getattr(out_gauss, name), getattr(out, name), name=name)
    with pytest.raises(AssertionError):
        assert_close_scaled(g_gauss["means"], g["means"], name="means")


@each_device
def test_multiple_cameras_match_single_renders(camera, device):
    prims = on_device(random_primitives(100, 1, seed=5, dtype=torch.float32), device)
    other = make_camera(40, 40, view=3, focal=120.0)
    outs = rasterize(prims, [camera, other])
    assert isinstance(outs, list) and len(outs) == 2
    for cam, out in zip([camera, other], outs):
        single = rasterize(prims, cam)
        assert torch.equal(out.image, single.image) and torch.equal(out.alpha, single.alpha)
        assert out.image.shape == (cam.height, cam.width, 1) and out.image.device.type == device


# ---------------------------------------------------------------------------------------------
# Stage by stage.
# ---------------------------------------------------------------------------------------------


@each_device
def test_project_forward_and_backward_match_reference(device):
    cam = make_camera(64, 48, view=2)
    prims = random_primitives(300, 1, seed=11)
    # Some primitives outside the frustum slack (their Jacobian is clamped), some behind the
    # camera (culled): place a few far off-axis and a few behind.
    centre = -cam.w2c[:3, :3].T @ cam.w2c[:3, 3]
    forward = cam.w2c[2, :3]
    right = cam.w2c[0, :3]
    means = prims.means.clone()
    means[:10] = centre + 2.0 * forward + (torch.arange(10, dtype=F64)[:, None] - 5) * 0.6 * right
    means[10:15] = centre - 1.0 * forward + 0.1 * torch.randn(5, 3, dtype=F64)
    scales = torch.exp(prims.log_scales)
    support_q = 2 * torch.rand(300, dtype=F64, generator=torch.Generator().manual_seed(1)) * 10
    args64 = [means.clone().requires_grad_(True), scales.clone().requires_grad_(True),
              prims.quats.clone().requires_grad_(True)]
    args32 = [x.detach().to(device, torch.float32).requires_grad_(True) for x in args64]
    support_q32 = support_q.to(device, torch.float32)
    eps2d = 0.3
    out_ref = ref.project(*args64, support_q, cam.K, cam.w2c, cam.width, cam.height, cam.near, eps2d)
    out = ops.project(*args32, support_q32, cam, eps2d)
    assert all(x.device.type == device for x in out)
    out = [x.cpu() for x in out]  # (differentiable copies)
    names = ("means2d", "conics", "depths", "extents", "valid")
    assert torch.equal(out[4], out_ref[4])
    valid = out_ref[4]
    assert 250 < valid.sum() < 300  # the five behind the camera are culled
    assert not valid[10:15].any()
    # Far off-axis: the clamp is active for these (x/z beyond 1.3 half fields of view).
    p = means[:10].detach() @ cam.w2c[:3, :3].T + cam.w2c[:3, 3]
    lim = FRUSTUM_SLACK * 0.5 * cam.width / cam.K[0, 0]
    assert (p[:, 0] / p[:, 2]).abs().gt(lim).sum() >= 4
    for name, a, b in zip(names[:4], out[:4], out_ref[:4]):
        # Float32 outputs of double maths: measured worst |err| / scale 1.1e-7 (one float32 ulp).
        assert_close_scaled(a, b, rel=1e-6, name=name)
    assert (out[3][~valid] == 0).all() and (out[2][~valid] == 0).all()

    g = torch.Generator().manual_seed(3)
    cots = [torch.randn(out_ref[k].shape, generator=g, dtype=F64) for k in range(3)]
    grads = torch.autograd.grad(sum((o * c.float()).sum() for o, c in zip(out[:3], cots)), args32)
    # Culled primitives get no gradient from the C++ backward, whatever the cotangents. (The
    # reference differs here: its placeholder means2d/conics of culled entries, computed with
    # z = 1, still depend on the means. Harmless end to end, since the compositing never sends
    # a cotangent to a culled primitive; compared below with their cotangents zeroed.)
    for a in grads:
        assert (a.cpu()[~valid] == 0).all()
    cots = [c * valid.reshape(-1, *([1] * (c.dim() - 1))) for c in cots]
    grads_ref = torch.autograd.grad(sum((o * c).sum() for o, c in zip(out_ref[:3], cots)), args64)
    out = [x.cpu() for x in ops.project(*args32, support_q32, cam, eps2d)]
    grads = torch.autograd.grad(sum((o * c.float()).sum() for o, c in zip(out[:3], cots)), args32)
    for name, a, b in zip(("means", "scales", "quats"), grads, grads_ref):
        # Measured worst |err| / scale 1.0e-7 (double maths, float32 in and out).
        assert_close_scaled(a, b, rel=1e-6, name=f"grad {name}")


@each_device
@pytest.mark.parametrize("width,height", [(64, 48), (37, 23), (16, 16), (1, 1)])
def test_tile_lists_match_reference(width, height, device):
    g = torch.Generator().manual_seed(width)
    n = 400
    means2d = torch.rand(n, 2, generator=g) * torch.tensor([width + 40.0, height + 40.0]) - 20
    extents = torch.rand(n, 2, generator=g) * 12
    extents[:20] = 0  # zero support: culled
    depths = torch.rand(n, generator=g) * 5
    depths[50:60] = depths[40]  # ties keep index order
    valid = torch.rand(n, generator=g) > 0.1
    on = (x.to(device) for x in (means2d, depths, extents, valid))
    offsets, ids = (x.cpu() for x in ops.tile_lists(*on, width, height))
    expected = ref.tile_lists(means2d.double(), depths.double(), extents.double(), valid, width, height)
    tiles = -(-width // TILE_SIZE) * -(-height // TILE_SIZE)
    assert offsets.dtype == ids.dtype == torch.int32
    assert offsets.shape == (tiles + 1,) and len(expected) == tiles
    assert offsets[0] == 0 and offsets[-1] == ids.numel()
    for k in range(tiles):
        got = ids[offsets[k]:offsets[k + 1]].long()
        assert torch.equal(got, expected[k]), f"tile {k}"
    assert sum(len(x) for x in expected) > 0


# ---------------------------------------------------------------------------------------------
# The reference itself: gradcheck in float64.
# ---------------------------------------------------------------------------------------------


def test_gradcheck_dog_profile():
    # u in [0, 6] and t across both branches (s = 1 - t >= 0.5 direct, below: stable form),
    # including t = 0 and t = 0.9999; no (s u) lands on the series limit 0.1 (a 2e-8 step).
    u = torch.tensor([0.0, 0.05, 0.3, 0.9, 1.7, 2.5, 4.0, 6.0], dtype=F64)
    for t_value in (0.0, 0.2, 0.49, 0.51, 0.8, 0.97, 0.9999):
        t = torch.full_like(u, t_value).requires_grad_(True)
        uu = u.clone().requires_grad_(True)
        assert torch.autograd.gradcheck(fp.dog_profile, (uu, t), eps=1e-7, atol=1e-7, rtol=1e-5), t_value


def _tiny_scene():
    """5 primitives in a 16x16 view, away from the kinks of the reference: opacity <= 0.8 so
    alpha never reaches the ALPHA_MAX clamp, 5 layers of at most 0.8 keep the transmittance
    above 0.2^5 > EARLY_STOP_T, all inside the field of view (no frustum clamp). What remains
    is the support/ALPHA_MIN cut-off, a jump of ~1/255 where a pixel crosses it: with this seed
    no pixel lies within the finite-difference step (1e-6) of it, so gradcheck passes."""
    cam = make_camera(16, 16, view=1, focal=100.0)
    g = torch.Generator().manual_seed(2)
    means = 0.5 + 0.08 * torch.randn(5, 3, generator=g, dtype=F64)
    log_scales = torch.log(torch.tensor([0.12, 0.05, 0.04], dtype=F64)) + 0.2 * torch.randn(5, 3, generator=g,
                                                                                              dtype=F64)
    quats = torch.randn(5, 4, generator=g, dtype=F64)
    opacity_logits = torch.linspace(-0.5, 1.2, 5, dtype=F64)  # opacity 0.38 .. 0.77
    k_raw = 0.5 * torch.randn(5, 2, generator=g, dtype=F64)
    colors = torch.rand(5, 2, generator=g, dtype=F64)
    return cam, (means, log_scales, quats, opacity_logits, k_raw, colors)


@pytest.mark.parametrize("kernel,activation", [("dog", "sigmoid"), ("dog", "exp"), ("gaussian", "sigmoid")])
def test_gradcheck_reference_render(kernel, activation):
    cam, params = _tiny_scene()
    config = RasterConfig(kernel=kernel, k_activation=activation, background=(0.1, 0.3), backend="torch")
    g = torch.Generator().manual_seed(4)
    w_image = torch.randn(16, 16, 2, generator=g, dtype=F64)
    w_alpha = torch.randn(16, 16, generator=g, dtype=F64)
    w_depth = torch.randn(16, 16, generator=g, dtype=F64)

    def loss(*p):
        out = rasterize(Primitives(*p), cam, config)
        return (out.image * w_image).sum() + (out.alpha * w_alpha).sum() + (out.depth * w_depth).sum()

    inputs = tuple(x.clone().requires_grad_(True) for x in params)
    out = rasterize(Primitives(*inputs), cam, config)
    assert out.visible.all() and (out.alpha > 0.05).sum() > 60
    assert out.alpha.max().item() < 1 - EARLY_STOP_T
    if kernel == "gaussian":  # k_raw has no gradient at all (unused): leave it out
        inputs = inputs[:4] + (params[4],) + inputs[5:]
    assert torch.autograd.gradcheck(loss, inputs, eps=1e-6, atol=1e-6, rtol=1e-4)


# ---------------------------------------------------------------------------------------------
# The DoG profile.
# ---------------------------------------------------------------------------------------------


def test_dog_profile_special_values():
    u = torch.linspace(0, 8, 81, dtype=F64)
    ts = torch.tensor([0.0, 1e-9, 0.1, 0.5, 0.7, 0.99, 1 - 1e-7], dtype=F64)
    for t in ts:
        D = fp.dog_profile(u, t.expand_as(u))
        assert D[0] == pytest.approx(1.0, abs=1e-12)  # D(0) = 1
        assert D.max() <= 1 + 1e-12
        # The direct formula where it is well conditioned; for t > 0.5 the stable form uses the
        # series of phi (truncation error < 2e-8 in phi, times u exp(-u) <= 1/e in D).
        if t < 0.99:
            direct = (torch.exp(-u) - t * torch.exp(-t * u)) / (1 - t)
            torch.testing.assert_close(D, direct, rtol=0, atol=1e-12 if t <= 0.5 else 1e-8)
    # t = 0: the Gaussian.
    torch.testing.assert_close(fp.dog_profile(u, torch.zeros_like(u)), torch.exp(-u), rtol=0, atol=0)
    # t -> 1: exp(-u) (1 - u) (the difference is O(1 - t) = 1e-7).
    limit = torch.exp(-u) * (1 - u)
    torch.testing.assert_close(fp.dog_profile(u, torch.full_like(u, 1 - 1e-7)), limit, rtol=0, atol=1e-6)
    torch.testing.assert_close(fp.dog_profile(u, torch.ones_like(u)), limit, rtol=0, atol=1e-15)
    # float32 at t = 1 - 1e-7 (rounds to 1 - 2^-24 or 1) and at 1: finite, close to the limit.
    for t32 in (1 - 1e-7, 1.0, 0.9999):
        D32 = fp.dog_profile(u.float(), torch.full_like(u.float(), t32))
        assert torch.isfinite(D32).all()
        torch.testing.assert_close(D32.double(), limit, rtol=0, atol=2e-4)


def test_dog_profile_gradients_finite_near_one():
    for dtype in (torch.float32, F64):
        u = torch.linspace(0, 6, 25, dtype=dtype, requires_grad=True)
        t = torch.full((25,), 1.0, dtype=dtype) - torch.tensor(1e-7, dtype=dtype)
        t.requires_grad_(True)
        gu, gt = torch.autograd.grad(fp.dog_profile(u, t).sum(), (u, t))
        assert torch.isfinite(gu).all() and torch.isfinite(gt).all()


def test_dog_profile_continuity_across_branches():
    u = torch.linspace(0, 8, 161, dtype=F64)
    # The branch boundary s = 1 - t = 0.5.
    below = fp.dog_profile(u, torch.full_like(u, 0.5 - 1e-12))
    above = fp.dog_profile(u, torch.full_like(u, 0.5 + 1e-12))
    torch.testing.assert_close(below, above, rtol=0, atol=1e-8)  # the series error, see above
    # The series limit |s u| = 0.1 of phi: s = 0.1, u around 1.
    x = torch.tensor([fp.SERIES_LIMIT - 1e-12, fp.SERIES_LIMIT + 1e-12, -fp.SERIES_LIMIT - 1e-12,
                      -fp.SERIES_LIMIT + 1e-12], dtype=F64)
    exact = torch.expm1(x) / x
    torch.testing.assert_close(fp.phi(x), exact, rtol=0, atol=2e-8)  # the documented series error
    xs = torch.linspace(-0.3, 0.3, 601, dtype=F64)
    xs = xs[xs != 0]
    torch.testing.assert_close(fp.phi(xs), torch.expm1(xs) / xs, rtol=0, atol=2e-8)
    assert fp.phi(torch.zeros(1, dtype=F64)).item() == 1.0
    t = torch.full((2,), 0.9, dtype=F64)
    uu = torch.tensor([1.0 - 1e-9, 1.0 + 1e-9], dtype=F64)  # s u = 0.1 -/+ 1e-10
    D = fp.dog_profile(uu, t)
    assert abs(D[0] - D[1]) < 1e-8
    direct = (torch.exp(-uu) - t * torch.exp(-t * uu)) / (1 - t)
    torch.testing.assert_close(D, direct, rtol=0, atol=1e-8)


def test_dog_zero_crossing():
    t = torch.tensor([1e-6, 0.01, 0.1, 1 / math.e, 0.5, 0.7, 0.9, 0.999], dtype=F64)
    u0 = fp.dog_zero_crossing(t)
    torch.testing.assert_close(u0, -torch.log(t) / (1 - t), rtol=1e-12, atol=0)
    torch.testing.assert_close(fp.dog_profile(u0, t), torch.zeros_like(t), rtol=0, atol=1e-12)
    assert (fp.dog_profile(u0 * 0.99, t) > 0).all() and (fp.dog_profile(u0 * 1.01, t) < 0).all()
    assert fp.dog_zero_crossing(torch.zeros(1, dtype=F64)).item() == math.inf
    assert fp.dog_zero_crossing(torch.ones(1, dtype=F64)).item() == 1.0
    near_one = fp.dog_zero_crossing(torch.tensor([1 - 1e-6], dtype=F64))
    assert near_one.item() == pytest.approx(1.0, abs=1e-6)


def test_support_u_reaches_alpha_min():
    opacity = torch.tensor([0.9, 0.5, 0.02, 0.9, 0.9, 1 / 300], dtype=F64)
    t = torch.tensor([0.0, 0.3, 0.5, 0.9, 1 - 1e-9, 0.5], dtype=F64)
    support = fp.support_u(opacity, t)
    assert support[-1] == 0  # opacity below ALPHA_MIN: never visible
    D_at = fp.dog_profile(support[:-1], t[:-1])
    u0 = fp.dog_zero_crossing(t[:-1])
    # Either cut by alpha (alpha = ALPHA_MIN there, for the Gaussian exactly) or by the zero crossing.
    by_alpha = support[:-1] < u0 - 1e-9
    assert ((opacity[:-1] * D_at <= ALPHA_MIN * (1 + 1e-9)) | ~by_alpha).all()
    assert opacity[0] * D_at[0] == pytest.approx(ALPHA_MIN, rel=1e-9)


@each_device
def test_gaussian_kernel_is_dog_with_t_to_zero(camera, device):
    """Kernels' kernel="gaussian" == their kernel="dog" with t = exp(-exp(3)) ~ 2e-9 and a = 1."""
    prims = random_primitives(150, 3, seed=9, dtype=torch.float32)
    prims.k_raw = torch.tensor([[0.0, 3.0]]).expand(150, 2).contiguous()
    cot = cotangents(camera.height, camera.width, 3, seed=1)
    dog = RasterConfig(kernel="dog", k_activation="exp", background=(0.1, 0.2, 0.3))
    a, t = activate(prims, dog).a, activate(prims, dog).t
    assert (a == 1).all() and (t < 3e-9).all() and (t > 0).all()
    out_dog, g_dog = render_with_grads(prims, camera, dog, cot, torch.float32, device)
    out_gauss, g_gauss = render_with_grads(prims, camera, dataclasses.replace(dog, kernel="gaussian"), cot,
                                           torch.float32, device)
    assert torch.equal(out_dog.visible, out_gauss.visible) and out_dog.visible.sum() > 100
    for name in ("image", "alpha", "depth"):
        # D differs by t (1 - exp(-u)) < 2e-9: float32 rounding only.
        torch.testing.assert_close(getattr(out_dog, name), getattr(out_gauss, name), rtol=1e-6, atol=1e-6)
    for name in ("means", "log_scales", "quats", "opacity_logits", "colors", "means2d"):
        # Measured worst |err| / scale 1.1e-7.
        assert_close_scaled(g_dog[name], g_gauss[name], rel=2e-6, name=name)
    assert g_gauss["k_raw"] is None
    # The DoG kernel still differentiates through t: dt/dk1 = -t exp(k1) ~ -4e-8 is tiny but
    # the gradient is there and finite.
    assert torch.isfinite(g_dog["k_raw"]).all()


# ---------------------------------------------------------------------------------------------
# Fisher information.
# ---------------------------------------------------------------------------------------------


@each_device
@pytest.mark.parametrize("kernel,channels,background", [("dog", 1, False), ("dog", 3, True),
                                                        ("gaussian", 1, True), ("gaussian", 3, False)])
def test_fisher_matches_reference(kernel, channels, background, device):
    cam = make_camera(40, 40, view=4, focal=130.0)
    prims = random_primitives(100, channels, seed=21 + channels)
    config = config_of(kernel, "sigmoid", background, channels)
    expected = fisher_reference(prims, cam, config)
    got = fisher_information(leaf_copy(prims, torch.float32, device), [cam], config)
    assert got.shape == (100,) and got.dtype == torch.float32 and got.device.type == device
    assert (expected > 0).sum() > 50
    # Measured worst |err| / max 2.1e-7 (sums of squares of float32 products).
    assert_close_scaled(got, expected, rel=1e-5, name="fisher")
    # The torch backend of fisher_information is the reference.
    torch.testing.assert_close(fisher_information(prims, [cam], torch_config(config)),
                               expected.float(), rtol=1e-6, atol=0)


@each_device
def test_fisher_properties(device):
    cams = [make_camera(40, 40, view=v, focal=130.0) for v in (0, 5)]
    prims = random_primitives(120, 3, seed=8, dtype=torch.float32)
    far = prims.means.clone()
    far[:10] = torch.tensor([50.0, -40.0, 60.0])  # far outside every view
    prims.means = far
    prims = on_device(prims, device)
    config = RasterConfig(background=(0.2, 0.2, 0.2))
    per_view = [fisher_information(prims, [c], config) for c in cams]
    both = fisher_information(prims, cams, config)
    assert all((f >= 0).all() for f in per_view)
    assert (both[:10] == 0).all()
    torch.testing.assert_close(both, per_view[0] + per_view[1], rtol=1e-6, atol=0)
    for c, f in zip(cams, per_view):
        visible = rasterize(prims, c, config).visible
        assert not visible[:10].any()
        assert (f[~visible] == 0).all() and (f[visible] > 0).sum() > 0.8 * visible.sum()


@each_device
@pytest.mark.parametrize("kernel,channels", [("dog", 1), ("dog", 3), ("gaussian", 2)])
def test_fisher_is_squared_gradient_at_one_pixel(kernel, channels, device):
    """On a 1x1 image, U_i = sum_c (dI_c/dD_i)^2, with I composited by hand in the test."""
    K = torch.tensor([[100.0, 0, 0], [0, 100.0, 0], [0, 0, 1]], dtype=F64)
    cam = RasterCamera(K, torch.eye(4, dtype=F64), 1, 1)  # camera at the origin looking down +z
    n = 6
    g = torch.Generator().manual_seed(channels)
    depth = torch.linspace(2.0, 4.0, n, dtype=F64)[torch.randperm(n, generator=g)]
    means = torch.cat([0.004 * torch.randn(n, 2, generator=g, dtype=F64), depth[:, None]], 1)
    prims = Primitives(means, torch.log(torch.full((n, 3), 0.03, dtype=F64)),
                       torch.randn(n, 4, generator=g, dtype=F64), torch.linspace(-1.0, 0.5, n, dtype=F64),
                       0.3 * torch.randn(n, 2, generator=g, dtype=F64),
                       torch.rand(n, channels, generator=g, dtype=F64))
    # 0.375: exactly representable in float32 (see test_float64_reference_background_is_exact).
    config = RasterConfig(kernel=kernel, background=(0.375,) * channels)
    act = activate(prims, config)
    means2d, conics, depths, _, _ = ref.project(prims.means, act.scales, prims.quats, act.support_q, K,
                                                cam.w2c, 1, 1, cam.near, config.eps2d)
    D, inside = ref.footprint_response(torch.zeros(1, 2, dtype=F64), means2d, conics, act.a, act.t,
                                       act.support)
    D = D[0].detach().requires_grad_(True)
    alpha = act.opacity * D
    assert inside.all() and (alpha.detach() > 2 * ALPHA_MIN).all() and (alpha.detach() < ALPHA_MAX).all()
    order = torch.argsort(depths)
    T = torch.ones((), dtype=F64)
    image = torch.zeros(channels, dtype=F64)
    for i in order:
        image = image + prims.colors[i] * alpha[i] * T
        T = T * (1 - alpha[i])
    assert T > EARLY_STOP_T
    image = image + T * torch.tensor(config.background, dtype=F64)
    expected = torch.zeros(n, dtype=F64)
    for c in range(channels):
        (grad,) = torch.autograd.grad(image[c], D, retain_graph=True)
        expected += grad**2
    got = fisher_information(on_device(prims, device), [cam], config)
    torch.testing.assert_close(got.to("cpu", F64), expected, rtol=1e-4, atol=1e-7)
    torch.testing.assert_close(fisher_reference(prims, cam, config), expected, rtol=1e-10, atol=1e-14)
    # The rendered pixel is the hand composite.
    out = rasterize(on_device(prims, device), cam, config)
    torch.testing.assert_close(out.image[0, 0].to("cpu", F64), image.detach(), rtol=0, atol=1e-5)


# ---------------------------------------------------------------------------------------------
# Constants and visibility.
# ---------------------------------------------------------------------------------------------


def test_cpp_constants_match_config():
    c = load_extension().constants()
    assert c["tile_size"] == TILE_SIZE
    # The float constants are float32 in C++: equal to the Python values rounded to float32.
    for key, value in (("alpha_min", ALPHA_MIN), ("alpha_max", ALPHA_MAX), ("early_stop_t", EARLY_STOP_T)):
        assert c[key] == torch.tensor(value, dtype=torch.float32).item(), key
    assert c["frustum_slack"] == FRUSTUM_SLACK


@each_device
def test_far_primitives_invisible_with_zero_gradients(camera, device):
    """Either backend, on the device: primitives outside the view get no gradient at all."""
    prims = random_primitives(80, 1, seed=13)
    means = prims.means.clone()
    means[:5] += torch.tensor([30.0, 0.0, 0.0])  # far outside the view, in front or behind
    means[5:10] = torch.tensor([0.5, 0.5, 0.5]) + 50 * torch.randn(5, 3, dtype=F64,
                                                                   generator=torch.Generator().manual_seed(0))
    prims.means = means
    cot = cotangents(camera.height, camera.width, 1, seed=2)
    for config in (RasterConfig(), RasterConfig(backend="torch")):
        dtype = torch.float32 if config.backend == "kernels" else F64
        out, g = render_with_grads(prims, camera, config, cot, dtype, device)
        assert not out.visible[:10].any() and out.visible[10:].sum() > 50
        for name, grad in g.items():
            assert (grad[:10] == 0).all(), name
        # Visible primitives get gradients; invisible ones none at all.
        assert (g["means"][out.visible].abs().sum(1) > 0).all()
        assert (g["means"][~out.visible] == 0).all() and (g["colors"][~out.visible] == 0).all()


def test_float64_reference_background_is_exact():
    cam = make_camera(16, 16)
    prims = random_primitives(0, 1)
    out = rasterize(prims, cam, RasterConfig(background=(0.1,), backend="torch"))
    assert out.image.dtype == F64
    assert (out.image == 0.1).all()


def _two_saturated_layers():
    """Three opaque primitives (opacity 0.9997) centred on pixel (8, 8) of a 17x17 view: their
    alphas there clamp to ALPHA_MAX = 0.99."""
    K = torch.tensor([[80.0, 0, 8.0], [0, 80.0, 8.0], [0, 0, 1]], dtype=F64)
    cam = RasterCamera(K, torch.eye(4, dtype=F64), 17, 17)
    prims = Primitives(torch.tensor([[0, 0, 2.0], [0, 0, 2.1], [0, 0, 2.2]], dtype=F64),
                       torch.log(torch.full((3, 3), 0.05, dtype=F64)),
                       torch.tensor([[1.0, 0, 0, 0]], dtype=F64).expand(3, 4).clone(),
                       torch.full((3,), 8.0, dtype=F64), torch.zeros(3, 2, dtype=F64),
                       torch.tensor([[1.0], [0.5], [0.25]], dtype=F64))
    return cam, prims


@each_device
def test_two_saturated_layers_float32_reference(device):
    """In float32 the kernels and the reference agree: after one clamped layer T = 0.01, the
    second leaves (1 - 0.99f)^2 ~ 1e-4, above EARLY_STOP_T (moved off that tie), so both composite."""
    cam, prims = _two_saturated_layers()
    out = rasterize(on_device(prims, device), cam)
    out32 = rasterize(Primitives(*(getattr(prims, k).float() for k in PARAMS)), cam,
                      RasterConfig(backend="torch"))
    assert out.alpha[8, 8].item() == pytest.approx(1 - (1 - ALPHA_MAX) ** 2, abs=1e-6)
    torch.testing.assert_close(out.image.cpu(), out32.image, rtol=0, atol=1e-6)


@each_device
def test_two_saturated_layers_match_float64_reference(device):
    cam, prims = _two_saturated_layers()
    out = rasterize(on_device(prims, device), cam)
    out_ref = rasterize(prims, cam, RasterConfig(backend="torch"))
    assert_close_scaled(out.image, out_ref.image, name="image")
    assert_close_scaled(out.alpha, out_ref.alpha, name="alpha")


# ---------------------------------------------------------------------------------------------
# The device seam: ops with one argument order, kernels per device.
# ---------------------------------------------------------------------------------------------


def _op_names(op: str, part: str = "arguments") -> list[str]:
    """The names of an edgedog op's arguments or returns, from its registered schema."""
    load_extension()
    return [x.name for x in getattr(getattr(torch.ops.edgedog, op).default._schema, part)]


def _parameters(function) -> list[str]:
    return list(inspect.signature(function).parameters)


def test_ops_wrappers_and_reference_share_one_argument_order():
    project, projected = _op_names("project_forward"), _op_names("project_forward", "returns")
    assert projected == ["means2d", "conics", "depths", "extents", "valid"]
    assert _parameters(ref.project) == project
    wrapper = _parameters(ops.project)  # the camera stands for its fields, in their order
    at = wrapper.index("camera")
    assert wrapper[:at] + [f.name for f in dataclasses.fields(RasterCamera)] + wrapper[at + 1:] == project
    assert _op_names("project_backward") == project + [f"g_{x}" for x in projected[:3]]
    assert _op_names("project_backward", "returns") == ["g_means", "g_scales", "g_quats"]

    tiles = _op_names("tile_lists")
    assert tiles == _parameters(ops.tile_lists) == _parameters(ref.tile_lists)
    assert tiles[:4] == [x for x in projected if x in tiles]  # in the projection's order

    splats = _op_names("rasterize_forward")
    assert splats[:4] == projected[:4]
    assert splats == _parameters(ops.fisher) == _parameters(ops.rasterize)[:-1]  # last: absgrad
    for function in (ref.rasterize, ref.fisher_per_view):  # `valid` in place of the tile lists
        params = [x for x in _parameters(function) if x != "absgrad"]
        at = params.index("valid")
        assert params[:at] + ["offsets", "ids"] + params[at + 1:] == splats, function.__name__
    rendered = _op_names("rasterize_forward", "returns")
    assert rendered == ["image", "alpha", "depth", "final_T", "last"]
    assert _op_names("rasterize_fisher") == splats + rendered[3:]
    assert _op_names("rasterize_backward") == splats + rendered[3:] + [f"g_{x}" for x in rendered[:3]]
    differentiable = ["means2d", "conics", "depths", "opacity", "a", "t", "colors"]
    assert _op_names("rasterize_backward", "returns") == [f"g_{x}" for x in differentiable] + ["absgrad"]


def test_kernels_refuse_a_device_without_kernels():
    assert "cpu" in ops.kernel_devices()
    camera = make_camera()
    moved = camera.to("meta")
    assert moved.K.device.type == moved.w2c.device.type == "meta" and camera.K.device.type == "cpu"
    assert (moved.width, moved.height, moved.near) == (camera.width, camera.height, camera.near)
    prims = on_device(random_primitives(10, 1, dtype=torch.float32), "meta")
    with pytest.raises(ValueError, match=r"no kernels for device 'meta' \(only for cpu.*backend='torch'"):
        rasterize(prims, camera)
    with pytest.raises(ConfigError, match="backend must be one of kernels, torch, got 'cpp'"):
        RasterConfig(backend="cpp")
