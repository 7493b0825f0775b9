"""The fused projection loss (csrc/edge_loss.cpp, `losses.edge_loss` on the CPU) against its
torch reference (`depth_uncertainty`, `uncertainty_weight`, `projection_loss`): forward and
backward, every weighting, sampled pixels, a moving target, and the hard cases."""

import pytest
import torch

from edgedog.train import losses
from edgedog.train.losses import WEIGHTINGS


def inputs(seed, height=37, width=53):
    g = torch.Generator().manual_seed(seed)
    render = torch.rand(height, width, generator=g)
    target = (torch.rand(height, width, generator=g) > 0.8).float()
    depth = torch.rand(height, width, generator=g) * 3
    depth[:, : width // 2] = 1.5  # a flat half and a step: the Sobel's flat and steep parts
    return render, target, depth


def both(render, target, depth, weighting, sample=None, target_grad=False):
    """(loss, d render, d target) of the fused loss and of the reference."""
    results = []
    for loss_of in (losses.edge_loss, losses.edge_loss_reference):
        r = render.clone().requires_grad_()
        t = target.clone().requires_grad_(target_grad)
        loss = loss_of(r, t, depth, weighting, sample)
        loss.backward()
        results.append((loss.detach(), r.grad, t.grad))
    return results


def test_the_weightings_are_the_settings():
    from typing import get_args

    from edgedog.train.config import Weighting

    assert set(WEIGHTINGS) == set(get_args(Weighting))


@pytest.mark.parametrize("weighting", WEIGHTINGS)
@pytest.mark.parametrize("with_depth", [True, False])
def test_the_fused_loss_matches_the_reference(weighting, with_depth):
    render, target, depth = inputs(0)
    fused, ref = both(render, target, depth if with_depth else None, weighting)
    assert torch.allclose(fused[0], ref[0], rtol=1e-5, atol=1e-7)
    assert torch.allclose(fused[1], ref[1], rtol=1e-5, atol=1e-9)


def test_on_sampled_pixels_and_a_moving_target():
    render, target, depth = inputs(1)
    sample = losses.edge_and_background_sample(losses.edge_pixels(target > 0), target.numel(),
                                               torch.Generator().manual_seed(2))
    fused, ref = both(render, target, depth, "exp_neg", sample, target_grad=True)
    assert torch.allclose(fused[0], ref[0], rtol=1e-5)
    assert torch.allclose(fused[1], ref[1], rtol=1e-5, atol=1e-9)
    assert torch.allclose(fused[2], ref[2], rtol=1e-5, atol=1e-9)
    outside = torch.ones(target.numel(), dtype=torch.bool)
    outside[sample] = False
    assert torch.all(fused[1].reshape(-1)[outside] == 0)  # only the sampled pixels move


def test_the_same_inputs_give_the_same_loss_whatever_the_threads():
    render, target, depth = (x.repeat(8, 8) for x in inputs(3))  # 296 x 424: many sum blocks
    threads = torch.get_num_threads()
    try:
        values = []
        for n in (1, 2, 3):
            torch.set_num_threads(n)
            values.append(losses.edge_loss(render, target, depth, "exp_neg").item())
    finally:
        torch.set_num_threads(threads)
    assert values[0] == values[1] == values[2]


def test_hard_cases():
    render, target, depth = inputs(4)
    # A flat depth: Up = 0 everywhere, so w = w(0).
    flat = both(render, target, torch.full_like(depth, 2.0), "exp")
    assert torch.allclose(flat[0][0], flat[1][0], rtol=1e-6)
    # An empty edge map and an exact render: zero loss and a zero gradient (|x| at 0).
    zero = both(torch.zeros_like(render), torch.zeros_like(target), depth, "exp_neg")
    assert zero[0][0] == 0 and torch.all(zero[0][1] == 0)
    # A NaN in the depth: the reference's min-max gives no uncertainty; so does the fused loss.
    nan_depth = depth.clone()
    nan_depth[3, 4] = float("nan")
    fused, ref = both(render, target, nan_depth, "exp_neg")
    assert torch.allclose(fused[0], ref[0], rtol=1e-5) and torch.allclose(fused[1], ref[1], rtol=1e-5)
    # A NaN in the render: a NaN loss, and no gradient there (torch's sgn of NaN is 0).
    nan_render = render.clone()
    nan_render[5, 6] = float("nan")
    fused, ref = both(nan_render, target, depth, "exp_neg")
    assert fused[0].isnan() and ref[0].isnan()
    assert torch.equal(fused[1].isnan(), ref[1].isnan()) and fused[1][5, 6] == 0
    # Infinite depth: the same as the reference, NaN where it has NaN.
    inf_depth = depth.clone()
    inf_depth[7, 8] = float("inf")
    fused, ref = both(render, target, inf_depth, "one_minus")
    assert torch.allclose(fused[1], ref[1], rtol=1e-5, equal_nan=True)


def test_bad_inputs_are_refused():
    render, target, depth = inputs(5)
    with pytest.raises(RuntimeError, match="target"):
        losses.edge_loss(render, target[:-1], depth, "one")
    with pytest.raises(RuntimeError, match="out of range"):
        losses.edge_loss(render, target, depth, "one", torch.tensor([render.numel()]))


def test_the_raster_bench_times_the_loss_both_ways():
    from edgedog.bench.raster import RasterBenchConfig, run

    result = run(RasterBenchConfig(primitives=300, size=64, views=2, reference_views=1, device="cpu"))
    for side in ("kernels", "torch_reference"):
        assert result[side]["loss_ms"] > 0 and result[side]["sampled_loss_ms"] > 0
    assert result["speedup"]["loss_ms"] > 0
