"""The loss terms: weighted L1 to the edge map, direction and scale-ratio regularisers, and the
pixel-level uncertainty from the rendered depth."""

from __future__ import annotations

import torch
import torch.nn.functional as F

from edgedog.renderer.ops import kernel_devices
from edgedog.train import neighbours as neighbour_search
from edgedog.train.model import EdgeModel

WEIGHTINGS = ("one", "exp_neg", "one_minus", "up", "exp")
"""The weightings w(Up) (`LossSettings.weighting`), in the order of csrc/edge_loss.h's codes."""


def depth_uncertainty(depth: torch.Tensor) -> torch.Tensor:
    """Up: the Sobel gradient magnitude of the rendered depth (H, W), min-max normalised to [0, 1]
    per view (all zeros for a flat depth) and detached (the paper's pixel-level uncertainty:
    depth discontinuities)."""
    # The 3x3 Sobel as its two separable passes on slices: twice as fast as a conv2d, and this
    # runs at every step. (OpenCV's Sobel is faster still, but its results vary in the last bit
    # from call to call, which would break exact resumes.)
    with torch.no_grad():
        # Replicated borders: zero padding would make the image frame a depth discontinuity.
        padded = F.pad(depth[None, None], (1, 1, 1, 1), mode="replicate")[0, 0]
        vertical = (padded[:-2] + padded[2:]).add_(padded[1:-1], alpha=2)  # (H, W + 2)
        horizontal = (padded[:, :-2] + padded[:, 2:]).add_(padded[:, 1:-1], alpha=2)  # (H + 2, W)
        magnitude = torch.hypot(vertical[:, 2:] - vertical[:, :-2], horizontal[2:] - horizontal[:-2])
        lo, hi = torch.aminmax(magnitude)
        return magnitude.sub_(lo).div_(hi - lo) if hi > lo else torch.zeros_like(magnitude)


def uncertainty_weight(up: torch.Tensor, weighting: str) -> torch.Tensor:
    """w(Up) for the weighting functions of the paper's Table 4."""
    if weighting == "one":
        return torch.ones_like(up)
    if weighting == "exp_neg":
        return torch.exp(-up)
    if weighting == "one_minus":
        return 1 - up
    if weighting == "up":
        return up
    return torch.exp(up)


def projection_loss(render: torch.Tensor, target: torch.Tensor, weight: torch.Tensor | None,
                    sample: torch.Tensor | None = None) -> torch.Tensor:
    """Mean (weighted) L1 between the render and the edge map (both (H, W)), over all pixels, or
    over the flat pixel indices `sample` when given."""
    error = (render - target).abs()
    if weight is not None:
        error = error * weight
    # index_select, not error[sample]: its backward adds into the sampled pixels, where indexing's
    # accumulates through a sort of the indices on a GPU (the pixels are distinct: same sums).
    return error.mean() if sample is None else error.reshape(-1).index_select(0, sample).mean()


def edge_loss(render: torch.Tensor, target: torch.Tensor, depth: torch.Tensor | None, weighting: str,
              sample: torch.Tensor | None = None) -> torch.Tensor:
    """A step's projection loss: `projection_loss` weighted by `uncertainty_weight` of the
    `depth_uncertainty` of `depth` (None: unweighted).

    On the CPU one op computes it (csrc/edge_loss.cpp: two passes over the pixels for the weight,
    one for the L1 and its gradient, where these torch functions take about ten; half their time,
    docs/RESULTS.md); on other devices, these functions.

    Args:
        render: (H, W) the rendered edges (with gradient); target: (H, W) the edge map (with a
            gradient when a learned shift moves it); depth: (H, W) the rendered depth, detached.
        sample: flat pixel indices (`edge_and_background_sample`) or None (every pixel).
    Returns:
        the scalar loss, on the render's device.
    """
    if render.device.type == "cpu" and "cpu" in kernel_devices():
        return _FusedEdgeLoss.apply(render, target, depth, WEIGHTINGS.index(weighting), sample)
    return edge_loss_reference(render, target, depth, weighting, sample)


def edge_loss_reference(render: torch.Tensor, target: torch.Tensor, depth: torch.Tensor | None,
                        weighting: str, sample: torch.Tensor | None = None) -> torch.Tensor:
    """`edge_loss` by the torch functions, on any device (what the fused op is checked against)."""
    weight = None if depth is None else uncertainty_weight(depth_uncertainty(depth), weighting)
    return projection_loss(render, target, weight, sample)


class _FusedEdgeLoss(torch.autograd.Function):
    """`edge_loss` by the op torch.ops.edgedog.edge_loss, whose forward pass also writes the
    gradient with respect to the render (the loss is a mean of |render - target| terms)."""

    @staticmethod
    def forward(ctx, render, target, depth, weighting: int, sample):
        loss, grad = torch.ops.edgedog.edge_loss(
            render.detach().contiguous(), target.detach().contiguous(),
            None if depth is None else depth.detach().to(torch.float32).contiguous(), weighting,
            None if sample is None else sample.to(torch.int64).contiguous())
        ctx.save_for_backward(grad)
        return loss

    @staticmethod
    def backward(ctx, grad_loss):
        (grad,) = ctx.saved_tensors
        grad_render = grad * grad_loss
        return (grad_render if ctx.needs_input_grad[0] else None,
                -grad_render if ctx.needs_input_grad[1] else None, None, None, None)


def edge_pixels(edge_mask: torch.Tensor) -> torch.Tensor:
    """(E,) int32 sorted flat indices of the edge pixels of an (H, W) bool mask (at most H x W
    entries: no more memory than the view's float32 map)."""
    return torch.nonzero(edge_mask.reshape(-1)).squeeze(1).to(torch.int32)


def edge_and_background_sample(edges: torch.Tensor, pixels: int, generator: torch.Generator) -> torch.Tensor:
    """Flat indices of every edge pixel plus as many distinct random background pixels
    (EdgeGaussians' sampled loss).

    Args:
        edges: (E,) sorted flat indices of the edge pixels (`edge_pixels`).
        pixels: H x W of the image.
        generator: draws the background pixels, on its own device.
    Returns:
        (2E,) int64 on the edges' device (fewer when the background has fewer than E pixels):
        the edges, then the background pixels of a uniform random draw without replacement.
    """
    edges = edges.long()
    background = pixels - len(edges)
    ranks = distinct_draw(min(len(edges), background), background, generator).to(edges.device)
    # The background pixel of rank k is k plus the edges before it; edge i has edges[i] - i
    # background pixels before it. (No background index list: 5 MB and two nonzero passes per view.)
    before = edges - torch.arange(len(edges), device=edges.device)
    return torch.cat([edges, ranks + torch.searchsorted(before, ranks, right=True)])


def distinct_draw(count: int, total: int, generator: torch.Generator) -> torch.Tensor:
    """(count,) int64 distinct integers of [0, total), a uniform random subset in random order,
    on the generator's device; count <= total.

    A small share is drawn with replacement, its repeats dropped and `count` of the distinct
    values kept at random (the distinct values of independent uniform draws are a uniform
    subset of their size): work in proportion to `count`, where a permutation of all `total`
    took 3 to 5 ms at 800x800, a fifth of a sampled step. A large share is a permutation.
    """
    device = generator.device
    if 4 * count >= total:
        return torch.randperm(total, generator=generator, device=device)[:count]
    while True:  # with 1.5x the draws, fewer than `count` distinct ones is rare even at a quarter
        distinct = torch.unique(torch.randint(total, (count + count // 2 + 32,), generator=generator,
                                              device=device))
        if len(distinct) >= count:
            return distinct[torch.randperm(len(distinct), generator=generator, device=device)[:count]]


def nearest_neighbours(model: EdgeModel, k: int) -> torch.Tensor:
    """(N, k) indices of each primitive's k nearest other primitives (by centre), on the model's
    device (`edgedog.train.neighbours`: a k-d tree on the host, blocked distances on a GPU up to
    its `DEVICE_SEARCH_LIMIT` primitives)."""
    return neighbour_search.nearest_neighbours(model.means.detach(), k).to(model.device)


def direction_loss(model: EdgeModel, neighbours: torch.Tensor) -> torch.Tensor:
    """1 - mean over primitives and neighbours of |major axis . unit direction to the neighbour|."""
    # index_select, not means[neighbours]: the backward of advanced indexing sums the repeated
    # rows in a thread-dependent order on the CPU (runs with 2 threads diverged); index_add does not.
    around = model.means.index_select(0, neighbours.reshape(-1)).reshape(*neighbours.shape, 3)
    offsets = around - model.means[:, None, :]
    directions = offsets / offsets.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    alignment = (model.major_axes()[:, None, :] * directions).sum(-1).abs()
    return 1 - alignment.mean()


def ratio_loss(model: EdgeModel) -> torch.Tensor:
    """Mean ratio of the second largest to the largest scale: pushes primitives to be thin."""
    scales = torch.sort(torch.exp(model.log_scales), dim=1, descending=True).values
    return (scales[:, 1] / scales[:, 0]).mean()
