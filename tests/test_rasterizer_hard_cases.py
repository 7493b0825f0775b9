"""Numerical stability of the rasterizer: no NaN or Inf in any output or gradient.

Every case renders with the kernels of each device that has them (`@each_device`, see
tests/helpers/backends.py; and, where cheap, with the float64 torch reference on the CPU), runs a
backward pass of a random-cotangent loss, and checks that the image, alpha, depth,
means2d.grad and every parameter's .grad are finite, plus a property of the case.
"""

from __future__ import annotations

import math

import pytest
import torch
from edgedog.renderer.config import ALPHA_MAX, ALPHA_MIN, EARLY_STOP_T, FRUSTUM_SLACK, RasterConfig
from edgedog.renderer.primitives import Primitives, RasterCamera, activate
from edgedog.renderer.rasterize import fisher_information, fisher_reference, rasterize

from edgedog.synthetic.cameras import orbit_cameras
from tests.helpers.backends import each_device, on_device
from tests.helpers.raster_builders import random_primitives

F64 = torch.float64
F32 = torch.float32
PARAMS = ("means", "log_scales", "quats", "opacity_logits", "k_raw", "colors")


# ---------------------------------------------------------------------------------------------
# Helpers.
# ---------------------------------------------------------------------------------------------


def orbit_camera(width=64, height=48, view=0, focal=160.0) -> RasterCamera:
    """A camera of orbit_cameras (radius 4 around (0.5, 0.5, 0.5)) with its own intrinsics."""
    cam = orbit_cameras(8, 64)[view]
    K = torch.tensor([[focal, 0, (width - 1) / 2], [0, focal, (height - 1) / 2], [0, 0, 1]], dtype=F64)
    return RasterCamera(K, torch.as_tensor(cam.w2c, dtype=F64), width, height)


def axis_camera(width=64, height=48, focal=80.0, near=0.25, cx=None, cy=None) -> RasterCamera:
    """A camera at the origin looking down +z (w2c = identity): camera z is the world z."""
    cx = (width - 1) / 2 if cx is None else cx
    cy = (height - 1) / 2 if cy is None else cy
    K = torch.tensor([[focal, 0, cx], [0, focal, cy], [0, 0, 1]], dtype=F64)
    return RasterCamera(K, torch.eye(4, dtype=F64), width, height, near)


def placed_primitives(means, scales=(0.05, 0.02, 0.02), channels=1, logit=1.0) -> Primitives:
    """Primitives at given world positions (for axis_camera), one shape and colour for all."""
    means = torch.as_tensor(means, dtype=F64).reshape(-1, 3)
    n = means.shape[0]
    return Primitives(means, torch.log(torch.tensor(scales, dtype=F64)).expand(n, 3).clone(),
                      torch.tensor([[0.9, 0.3, -0.2, 0.1]], dtype=F64).expand(n, 4).clone(),
                      torch.full((n,), logit, dtype=F64), torch.zeros(n, 2, dtype=F64),
                      torch.linspace(0.3, 0.9, n * channels, dtype=F64).reshape(n, channels))


def with_field(prims: Primitives, **fields) -> Primitives:
    values = {k: getattr(prims, k) for k in PARAMS}
    values.update(fields)
    return Primitives(**values)


def without(prims: Primitives, index: int) -> Primitives:
    keep = torch.arange(len(prims)) != index
    return Primitives(*(getattr(prims, k)[keep] for k in PARAMS))


def leaf32(prims: Primitives, device="cpu") -> Primitives:
    return on_device(prims, device, F32)


def render_backward(prims, camera, config=RasterConfig(), dtype=F32, seed=0, device="cpu"):
    """Render leaf copies in `dtype` on `device`, backward a random-cotangent loss; (output,
    grads dict), on `device`."""
    leaves = on_device(prims, device, dtype, leaves=True)
    out = rasterize(leaves, camera, config)
    g = torch.Generator().manual_seed(seed)
    h, w, c = camera.height, camera.width, prims.colors.shape[1]
    loss = (out.image * torch.randn(h, w, c, generator=g, dtype=F64).to(device, dtype)).sum() \
        + (out.alpha * torch.randn(h, w, generator=g, dtype=F64).to(device, dtype)).sum() \
        + (out.depth * torch.randn(h, w, generator=g, dtype=F64).to(device, dtype)).sum()
    loss.backward()
    grads = {k: getattr(leaves, k).grad for k in PARAMS}
    grads["means2d"] = out.means2d.grad
    return out, grads


def assert_finite(out, grads, skip=()):
    for name in ("image", "alpha", "depth"):
        assert torch.isfinite(getattr(out, name)).all(), name
    for name, grad in grads.items():
        if name in skip:
            continue
        assert grad is not None, name
        assert torch.isfinite(grad).all(), f"grad {name}"


def close_to_reference(out, grads, out_ref, grads_ref, rel=1e-4, floor=1e-6, skip=()):
    """Kernels vs float64 reference, on the CPU: atol = rel x the tensor's largest magnitude (as in
    tests/test_rasterizer.py, where the measured worst is ~1e-5 of it) + an absolute floor.
    The floor (1e-6, for O(1) cotangents) covers gradients that the case makes vanish, e.g.
    every quats gradient of primitives centred exactly on a pixel (~1e-16 of float32 noise)."""
    pairs = [(getattr(out, n), getattr(out_ref, n), n) for n in ("image", "alpha", "depth")]
    pairs += [(grads[k], grads_ref[k], k) for k in grads if grads_ref[k] is not None and k not in skip]
    for actual, expected, name in pairs:
        scale = expected.abs().max().item() if expected.numel() else 0.0
        torch.testing.assert_close(actual.to("cpu", F64), expected.to("cpu", F64), rtol=0,
                                   atol=rel * scale + floor, msg=lambda m, name=name: f"{name}: {m}")


def torch_config(config=RasterConfig()) -> RasterConfig:
    return RasterConfig(kernel=config.kernel, k_activation=config.k_activation, eps2d=config.eps2d,
                        background=config.background, backend="torch")


# ---------------------------------------------------------------------------------------------
# Extreme DoG shapes.
# ---------------------------------------------------------------------------------------------


@each_device
@pytest.mark.parametrize("activation", ["sigmoid", "exp"])
@pytest.mark.parametrize("column,value", [(1, 30.0), (1, -30.0), (0, 30.0), (0, 6.0)])
def test_extreme_k_raw(activation, column, value, device):
    """t -> 1 and t -> 0 (k1 = +-30, either activation), huge inner scale a (k0 = 30 / 6)."""
    cam = orbit_camera()
    prims = random_primitives(100, 3, seed=1)
    k_raw = prims.k_raw.clone()
    k_raw[:, column] = value
    prims = with_field(prims, k_raw=k_raw)
    config = RasterConfig(k_activation=activation, background=(0.1, 0.2, 0.3))
    act = activate(leaf32(prims), config)
    assert torch.isfinite(act.t).all() and torch.isfinite(act.a).all() and torch.isfinite(act.support).all()
    out, grads = render_backward(prims, cam, config, device=device)
    assert_finite(out, grads)
    assert out.visible.sum() > 80
    out_ref, grads_ref = render_backward(prims, cam, torch_config(config), F64)
    assert_finite(out_ref, grads_ref)
    # a = exp(30): u = q / (2a) ~ 1e-13, D = 1 to float32 precision everywhere, and the k0
    # gradient (~1e-9) is float32 noise: compared by finiteness only.
    close_to_reference(out, grads, out_ref, grads_ref,
                       skip=("k_raw",) if (column, value, activation) == (0, 30.0, "exp") else ())
    fisher = fisher_information(on_device(prims, device), [cam], config)
    assert torch.isfinite(fisher).all() and (fisher >= 0).all()


@each_device
@pytest.mark.parametrize("activation,k1", [("sigmoid", 30.0), ("exp", -30.0)])
def test_t_equal_one_in_float32_is_the_limit_profile(activation, k1, device):
    """k1 = 30 (sigmoid) or -30 (exp) gives t == 1 exactly in float32: D = exp(-u) (1 - u)."""
    prims = placed_primitives([[0.0, 0.0, 2.0]], scales=(0.1, 0.1, 0.1), logit=0.0)
    prims = with_field(prims, k_raw=torch.tensor([[0.0, k1]], dtype=F64))
    config = RasterConfig(k_activation=activation)
    act = activate(leaf32(prims), config)
    assert act.t.item() == 1.0 and act.support.item() == pytest.approx(1.0)  # zero crossing at u = 1
    cam = axis_camera(17, 17, focal=80.0)  # the primitive sits on pixel (8, 8)
    out, grads = render_backward(prims, cam, config, device=device)
    assert_finite(out, grads)
    # Centre pixel: alpha = opacity D(0) = 0.5.
    assert out.image[8, 8, 0].item() == pytest.approx(0.5 * prims.colors[0, 0].item(), rel=1e-6)
    # Inside the zero crossing only: the ring of negative D is beyond the support.
    assert (out.image >= 0).all() and out.visible.all()
    assert grads["k_raw"][0, 1].abs().item() < 1e-3  # t saturated: (almost) no gradient to k1


@each_device
@pytest.mark.parametrize("activation", ["sigmoid", "exp"])
def test_t_to_zero_is_the_gaussian(activation, device):
    """k1 = -30 (sigmoid: t = 9e-14) or +3.5 (exp: t = 4e-15): the Gaussian kernel's render."""
    cam = orbit_camera()
    prims = random_primitives(100, 1, seed=2)
    k1 = -30.0 if activation == "sigmoid" else 3.5
    k0 = 0.0
    prims = with_field(prims, k_raw=torch.tensor([[k0, k1]], dtype=F64).expand(100, 2).clone())
    dog = RasterConfig(k_activation=activation)
    out, grads = render_backward(prims, cam, dog, device=device)
    assert_finite(out, grads)
    out_g, grads_g = render_backward(prims, cam, RasterConfig(kernel="gaussian"), device=device)
    torch.testing.assert_close(out.image, out_g.image, rtol=1e-6, atol=1e-6)
    for name in ("means", "log_scales", "quats", "opacity_logits", "colors"):
        scale = grads_g[name].abs().max().item()
        torch.testing.assert_close(grads[name], grads_g[name], rtol=0, atol=1e-5 * scale)


@each_device
@pytest.mark.parametrize("activation", ["sigmoid", "exp"])
def test_vanishing_inner_scale_renders_nothing(activation, device):
    """k0 = -30: a ~ 1e-13, the footprint shrinks below a pixel: nothing visible, zero gradients."""
    cam = orbit_camera()
    prims = random_primitives(50, 1, seed=3)
    k_raw = prims.k_raw.clone()
    k_raw[:, 0] = -30.0
    prims = with_field(prims, k_raw=k_raw)
    out, grads = render_backward(prims, cam, RasterConfig(k_activation=activation), device=device)
    assert_finite(out, grads)
    assert not out.visible.any() and (out.alpha == 0).all()
    assert all((g == 0).all() for g in grads.values())


# ---------------------------------------------------------------------------------------------
# Extreme sizes and rotations.
# ---------------------------------------------------------------------------------------------


@each_device
def test_tiny_scales(device):
    """Scales 1e-6: the footprint is the eps2d dilation alone; the render does not depend on them."""
    cam = orbit_camera()
    prims = with_field(random_primitives(100, 1, seed=4), log_scales=torch.full((100, 3), math.log(1e-6),
                                                                                   dtype=F64))
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    assert out.visible.sum() > 80 and out.alpha.max() > 0.5
    smaller_scales = with_field(prims, log_scales=prims.log_scales - math.log(10))
    smaller = render_backward(smaller_scales, cam, device=device)[0]
    torch.testing.assert_close(out.image, smaller.image, rtol=0, atol=1e-6)
    assert grads["log_scales"].abs().max() < 1e-6  # (J s)^2 ~ 1e-8 px^2 next to eps2d = 0.3
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    close_to_reference(out, grads, out_ref, grads_ref)


@each_device
@pytest.mark.parametrize("scales", [(1e3, 1e3, 1e3), (1e3, 1e-3, 1e-3), (1e3, 1e3, 1e-6)])
def test_huge_scales(scales, device):
    """Scales 1e3 (spheres, needles, discs): extents far beyond the image, all finite."""
    cam = orbit_camera()
    prims = random_primitives(30, 1, seed=5)
    prims = with_field(prims, log_scales=torch.log(torch.tensor(scales, dtype=F64)).expand(30, 3).clone())
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    assert out.visible.all() and out.alpha.max() > 0.5 and (out.alpha > 0).float().mean() > 0.5
    # The float64 reference agrees. (The reference in float32 does not: its 2x2 covariance of a
    # 1e3 x 1e-3 needle loses the determinant to cancellation and its gradients are NaN; the
    # C++ projection works in double for this reason.)
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    if scales[1] > 1e-3:
        close_to_reference(out, grads, out_ref, grads_ref, rel=1e-3)
    else:
        # The 1e6:1 needle: its conic, ~(1 / eps2d) n n^T + 1e-10 v v^T, is stored in float32,
        # which cannot hold the 1e-10 along-axis curvature next to entries ~3: the gradient of
        # the long axis' log-scale is float32 noise (measured 1.4e-3 vs 3e-5 in float64). Every
        # other gradient, the short axes' included, matches (measured worst 1.2e-4 of scale).
        close_to_reference(out, grads, out_ref, grads_ref, rel=1e-3, skip=("log_scales",))
        short, short_ref = grads["log_scales"][:, 1:], grads_ref["log_scales"][:, 1:]
        torch.testing.assert_close(short.to("cpu", F64), short_ref, rtol=0,
                                   atol=1e-3 * short_ref.abs().max().item())


@each_device
def test_slanted_needles_across_tiles_match_reference(device):
    """Needles 400:1 at every angle in the image plane, each crossing several tiles, whose
    bounding boxes are mostly empty: every pixel of each streak is composited as the reference
    does (a missed pixel costs at least 1/255 of alpha, 40x the tolerance)."""
    cam = axis_camera(width=160, height=112, focal=300.0)
    n = 24
    angles = torch.linspace(0, math.pi, n + 1, dtype=F64)[:-1]  # rotations about the view axis
    quats = torch.stack([torch.cos(angles / 2), 0 * angles, 0 * angles, torch.sin(angles / 2)], 1)
    means = torch.stack([0.15 * torch.cos(3 * angles), 0.1 * torch.sin(5 * angles), 2.0 + 0.05 * angles], 1)
    needle = torch.log(torch.tensor([0.2, 0.0005, 0.0005], dtype=F64))
    prims = with_field(placed_primitives(means), quats=quats, log_scales=needle.expand(n, 3).clone())
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    assert (out.alpha > ALPHA_MIN).sum() > 24 * 60  # long thin streaks (~100 px each), not dots
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    close_to_reference(out, grads, out_ref, grads_ref)


@each_device
def test_zero_quaternion_is_identity_rotation(device):
    cam = orbit_camera()
    prims = random_primitives(100, 1, seed=6)
    zero = with_field(prims, quats=torch.zeros(100, 4, dtype=F64))
    out, grads = render_backward(zero, cam, device=device)
    assert_finite(out, grads)
    identity = with_field(prims, quats=torch.tensor([[2.0, 0, 0, 0]], dtype=F64).expand(100, 4).clone())
    out_id, grads_id = render_backward(identity, cam, device=device)
    assert torch.equal(out.image, out_id.image)
    # Rotation entries are quadratic in the normalised quaternion: zero gradient at q = 0.
    assert (grads["quats"] == 0).all()
    out_ref, grads_ref = render_backward(zero, cam, torch_config(), F64)
    close_to_reference(out, grads, out_ref, grads_ref)


# ---------------------------------------------------------------------------------------------
# Positions relative to the camera.
# ---------------------------------------------------------------------------------------------

# An ordinary primitive in view next to the tested one, so that the image is never empty.
ANCHOR = [0.1, 0.0, 2.0]


@each_device
@pytest.mark.parametrize("z", [-1.0, -1e-3, 0.0, 0.25])
def test_behind_camera_or_on_near_plane_is_culled(z, device):
    """Behind the camera, at the camera centre's depth and exactly on the near plane (z = near
    = 0.25, exact in float32): culled, invisible, zero gradient, no effect on the image."""
    cam = axis_camera()
    for scales in ((0.05, 0.02, 0.02), (1.0, 0.5, 0.5)):
        prims = placed_primitives([[0.0, 0.0, z], ANCHOR], scales)
        for config, dtype in ((RasterConfig(), F32), (torch_config(), F64)):
            out, grads = render_backward(prims, cam, config, dtype, device=device)
            assert_finite(out, grads)
            assert out.visible.tolist() == [False, True]
            assert all((g[0] == 0).all() for g in grads.values())
            alone = render_backward(without(prims, 0), cam, config, dtype, device=device)[0]
            assert torch.equal(out.image, alone.image)


@each_device
@pytest.mark.parametrize("offset", [1e-6, 1e-3])
def test_just_in_front_of_near_plane(offset, device):
    """z = near + 1e-6: a huge footprint (J = f / z), finite, visible, with gradients."""
    cam = axis_camera()
    prims = placed_primitives([[0.01, 0.003, 0.25 + offset], ANCHOR])
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    assert out.visible.all()
    assert grads["colors"][0].abs().sum() > 0 and grads["means"][0].abs().sum() > 0
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    close_to_reference(out, grads, out_ref, grads_ref, rel=1e-3)


@each_device
@pytest.mark.parametrize("where", ["left edge", "top-left corner", "bottom edge"])
def test_straddling_the_border(where, device):
    cam = axis_camera()
    x_edge, y_edge = -31.5 / 80 * 2.0, -23.5 / 80 * 2.0  # pixel centre 0 at depth 2
    mean = {"left edge": [x_edge, 0.1, 2.0], "top-left corner": [x_edge, y_edge, 2.0],
            "bottom edge": [0.0, -y_edge + 0.004, 2.0]}[where]
    prims = placed_primitives([mean, ANCHOR])
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    assert out.visible[0]
    for name, grad in grads.items():
        assert grad[0].abs().sum() > 0, name
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    close_to_reference(out, grads, out_ref, grads_ref)


@each_device
def test_grazing_angle_beyond_frustum_clamp(device):
    """Far off-axis (x / z = 3, beyond the 1.3 half fields of view = 0.52 where the EWA Jacobian
    is clamped): a long primitive still reaches into the image; finite, matches the reference."""
    cam = axis_camera()
    lim = FRUSTUM_SLACK * 0.5 * cam.width / cam.K[0, 0].item()
    prims = placed_primitives([[3.0, 0.0, 1.0], [5.0, 0.5, 1.0], ANCHOR], scales=(3.0, 0.05, 0.05))
    prims = with_field(prims, quats=torch.tensor([[1.0, 0, 0, 0]], dtype=F64).expand(3, 4).clone())
    assert 3.0 / 1.0 > lim and 5.0 > lim
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    assert out.visible[0] and out.means2d[0, 0] > cam.width * 3
    assert grads["means"][0].abs().sum() > 0
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    assert torch.equal(out.visible.cpu(), out_ref.visible)
    close_to_reference(out, grads, out_ref, grads_ref)


# ---------------------------------------------------------------------------------------------
# Image sizes and primitive counts.
# ---------------------------------------------------------------------------------------------


@each_device
@pytest.mark.parametrize("width,height", [(1, 1), (37, 23), (1, 40), (17, 1)])
def test_small_and_odd_image_sizes(width, height, device):
    focal = 5.0 + 30.0 * max(width, height) / 8
    cam = orbit_camera(width, height, focal=focal)
    prims = random_primitives(100, 2, seed=7)
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    assert out.image.shape == (height, width, 2)
    assert out.alpha.shape == out.depth.shape == (height, width)
    assert out.means2d.shape == (100, 2) and out.visible.shape == (100,)
    assert out.visible.any() and out.alpha.max() > 0
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    assert torch.equal(out.visible.cpu(), out_ref.visible)
    close_to_reference(out, grads, out_ref, grads_ref)


@each_device
def test_zero_primitives(device):
    cam = orbit_camera(37, 23)
    for background in (None, (0.25, 0.5, 0.75)):
        config = RasterConfig(background=background)
        prims = random_primitives(0, 3)
        out, grads = render_backward(prims, cam, config, device=device)
        assert_finite(out, grads)
        expected = torch.zeros(3) if background is None else torch.tensor(background)
        assert out.image.shape == (23, 37, 3) and (out.image.cpu() == expected).all()
        assert (out.alpha == 0).all() and (out.depth == 0).all()
        assert out.means2d.shape == (0, 2) and out.visible.shape == (0,)
        shapes = {"means": (0, 3), "log_scales": (0, 3), "quats": (0, 4), "opacity_logits": (0,),
                  "k_raw": (0, 2), "colors": (0, 3), "means2d": (0, 2)}
        assert {k: tuple(g.shape) for k, g in grads.items()} == shapes
        assert fisher_information(on_device(prims, device), [cam], config).shape == (0,)
        # The reference's forward agrees.
        out_ref = rasterize(prims, cam, torch_config(config))
        torch.testing.assert_close(out_ref.image, expected.double().expand(23, 37, 3))


@each_device
@pytest.mark.parametrize("logit,clamped", [(0.0, False), (3.0, False), (8.0, True)])
def test_many_primitives_on_one_pixel(logit, clamped, device):
    """500 identical primitives: alpha saturates, compositing stops early, gradients finite."""
    cam = axis_camera(17, 17, focal=80.0, cx=8.0, cy=8.0)
    prims = placed_primitives([[0.0, 0.0, 2.0]] * 500, scales=(0.02, 0.02, 0.02), logit=logit)
    colors = torch.rand(500, 3, dtype=F64, generator=torch.Generator().manual_seed(0))
    prims = with_field(prims, colors=colors)
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    # Saturated, but the early stop keeps the transmittance >= EARLY_STOP_T. Clamped layers
    # (alpha = ALPHA_MAX): two composite ((1 - 0.99)^2 = 1e-4 >= EARLY_STOP_T), a third would not.
    if clamped:
        assert out.alpha[8, 8].item() == pytest.approx(1 - (1 - ALPHA_MAX) ** 2, abs=1e-6)
    else:
        assert 0.999 < out.alpha[8, 8] <= 1 - EARLY_STOP_T * (1 - 1e-3)
    # Early stop: at the centre only the first few primitives (ties keep index order) count.
    used = grads["colors"].abs().sum(1) > 0
    assert used[0] and not used[-1]
    fisher = fisher_information(on_device(prims, device), [cam], RasterConfig())
    assert torch.isfinite(fisher).all() and (fisher >= 0).all()
    if not clamped:  # (two clamped layers hit a rounding tie: see test_two_saturated_layers_*)
        out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
        close_to_reference(out, grads, out_ref, grads_ref)
        expected = fisher_reference(prims, cam, RasterConfig())
        torch.testing.assert_close(fisher.to("cpu", F64), expected, rtol=0, atol=1e-4 * expected.max().item())


@each_device
def test_one_million_primitives(device):
    """Forward and backward of 1M primitives into 64x64 (~15% of them visible): completes in
    about a second, ~0.5 GB, everything finite."""
    n = 1_000_000
    g = torch.Generator().manual_seed(0)
    cam = orbit_camera(64, 64, focal=100.0)
    prims = Primitives(0.5 + 3.0 * torch.randn(n, 3, generator=g),
                       math.log(0.01) + 0.5 * torch.randn(n, 3, generator=g),
                       torch.randn(n, 4, generator=g), torch.randn(n, generator=g) - 1.0,
                       0.5 * torch.randn(n, 2, generator=g), torch.rand(n, 1, generator=g))
    out, grads = render_backward(prims, cam, device=device)
    assert_finite(out, grads)
    visible = out.visible.sum().item()
    assert 10_000 < visible < n // 2
    assert (grads["colors"][~out.visible] == 0).all()
    assert (grads["colors"][out.visible].abs().sum(1) > 0).float().mean() > 0.5


# ---------------------------------------------------------------------------------------------
# NaN and Inf in the inputs.
# ---------------------------------------------------------------------------------------------

NAN, INF = math.nan, math.inf
# A non-finite value in one parameter of primitive 0 culls it: the others render exactly as
# without it, their gradients are unchanged, and only primitive 0's own gradients may be NaN.
CULLING_BAD_VALUES = [
    ("means", (0, 0), NAN), ("means", (0, 2), NAN), ("means", (0, 0), INF), ("means", (0, 2), INF),
    ("means", (0, 2), -INF), ("means", (0, 1), 1e30),
    ("log_scales", (0, 0), NAN), ("log_scales", (0, 1), INF),
    ("quats", (0, 0), NAN), ("quats", (0, 2), INF),
    ("opacity_logits", (0,), NAN), ("opacity_logits", (0,), -INF),
    ("k_raw", (0, 0), NAN), ("k_raw", (0, 1), NAN),
]


@each_device
@pytest.mark.parametrize("activation", ["sigmoid", "exp"])
@pytest.mark.parametrize("field,index,value", CULLING_BAD_VALUES)
def test_non_finite_input_does_not_poison_the_others(field, index, value, activation, device):
    cam = orbit_camera()
    prims = random_primitives(60, 3, seed=4)
    config = RasterConfig(k_activation=activation, background=(0.1, 0.1, 0.1))
    assert rasterize(on_device(prims, device), cam, config).visible[0]  # primitive 0 is normally in view
    bad = getattr(prims, field).clone()
    bad[index] = value
    prims_bad = with_field(prims, **{field: bad})
    out, grads = render_backward(prims_bad, cam, config, device=device)
    clean, grads_clean = render_backward(without(prims, 0), cam, config, device=device)
    for name in ("image", "alpha", "depth"):
        assert torch.equal(getattr(out, name), getattr(clean, name)), name
    # log_scales = +inf: a box of infinite extent, "visible", but every pixel skips it (q = NaN).
    assert not out.visible[0] or (field, value) == ("log_scales", INF)
    assert torch.equal(out.visible[1:], clean.visible)
    for name, grad in grads.items():
        scale = grads_clean[name].abs().max().item()
        # Same up to the summation order of the threads' gradient buffers.
        torch.testing.assert_close(grad[1:], grads_clean[name], rtol=0, atol=1e-5 * scale, msg=name)
    assert (grads["colors"][0] == 0).all()


@pytest.mark.parametrize("field,index,value", [("means", (0, 0), NAN), ("means", (0, 2), -INF),
                                               ("opacity_logits", (0,), NAN), ("k_raw", (0, 1), NAN)])
def test_non_finite_input_reference(field, index, value):
    """The float64 reference culls such primitives too (forward only: cheap check)."""
    cam = orbit_camera()
    prims = random_primitives(60, 1, seed=4)
    bad = getattr(prims, field).clone()
    bad[index] = value
    out = rasterize(with_field(prims, **{field: bad}), cam, torch_config())
    clean = rasterize(without(prims, 0), cam, torch_config())
    assert torch.equal(out.image, clean.image) and not out.visible[0]


@each_device
@pytest.mark.parametrize("value", [NAN, INF])
def test_non_finite_colour_stays_in_its_footprint(value, device):
    """A NaN or Inf colour is composited: the pixels it covers are non-finite (nothing can be
    done about that), every other pixel renders as without it."""
    cam = orbit_camera()
    prims = random_primitives(60, 1, seed=4)
    colors = prims.colors.clone()
    colors[0, 0] = value
    out = rasterize(leaf32(with_field(prims, colors=colors), device), cam)
    clean = rasterize(leaf32(without(prims, 0), device), cam)
    alone = rasterize(leaf32(Primitives(*(getattr(prims, k)[:1] for k in PARAMS)), device), cam)
    footprint = alone.alpha > 0
    assert footprint.any() and (~footprint).any()
    assert not torch.isfinite(out.image[footprint]).all()
    assert torch.equal(out.image[~footprint], clean.image[~footprint])
    assert torch.isfinite(out.alpha).all() and torch.isfinite(out.depth).all()


@each_device
def test_opacity_plus_infinity_is_opaque(device):
    """opacity_logit = +inf: opacity 1 (sigmoid saturates, no gradient to the logit); finite."""
    cam = orbit_camera()
    prims = random_primitives(60, 1, seed=4)
    logits = prims.opacity_logits.clone()
    logits[0] = INF
    out, grads = render_backward(with_field(prims, opacity_logits=logits), cam, device=device)
    assert_finite(out, grads)
    assert out.visible[0] and grads["colors"][0].abs().sum() > 0
    assert grads["opacity_logits"][0] == 0


@each_device
def test_reference_with_nothing_visible_is_differentiable(device):
    cam = axis_camera()
    prims = placed_primitives([[0.0, 0.0, -1.0], [0.3, 0.0, -2.0]])  # both behind the camera
    out, grads = render_backward(prims, cam, RasterConfig(), F32, device=device)  # kernels: all zero
    assert all((g == 0).all() for g in grads.values())
    out_ref, grads_ref = render_backward(prims, cam, torch_config(), F64)
    assert all(g is None or (g == 0).all() for g in grads_ref.values())
