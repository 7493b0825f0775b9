"""Plain-torch reference of every rasterizer stage, and of the whole render.

Differentiable by autograd in any dtype and on any device (the tests run it in float64 as
ground truth and `gradcheck` it); slow. The ops of `ops.py` (the C++ kernels in csrc/)
implement exactly these functions, stage by stage, with hand-written backward passes, and take
their arguments in the same order. The maths is documented in docs/METHOD.md.
"""

from __future__ import annotations

import torch
from edgedog.renderer.config import (
    ALPHA_MAX,
    ALPHA_MIN,
    EARLY_STOP_T,
    FRUSTUM_SLACK,
    TILE_SIZE,
)
from edgedog.renderer.footprint import dog_profile, quat_to_rotmat


def project(means, scales, quats, support_q, K, w2c, width: int, height: int, near: float, eps2d: float):
    """EWA projection of 3D Gaussians.

    Args:
        means: (N, 3) world positions; scales: (N, 3) positive axis lengths;
        quats: (N, 4) rotations (w, x, y, z); support_q: (N,) Mahalanobis radius^2 of each
        footprint's support; K: (3, 3); w2c: (4, 4) OpenCV.
    Returns:
        means2d (N, 2) pixels, conics (N, 3) = inverse 2D covariance (a, b, c),
        depths (N,) camera z (0 when culled), extents (N, 2) half-widths in pixels of the
        support ellipse (0 when culled), valid (N,) bool (in front of the near plane).
    """
    R_cam, t_cam = w2c[:3, :3], w2c[:3, 3]
    p = means @ R_cam.T + t_cam
    x, y, z = p.unbind(-1)
    valid = z > near
    z = torch.where(valid, z, torch.ones_like(z))  # keeps culled entries finite
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    # Clamp the direction to 1.3x the field of view: beyond it the affine (EWA) approximation
    # of the projection explodes (3DGS does the same).
    lim_x = FRUSTUM_SLACK * 0.5 * width / fx
    lim_y = FRUSTUM_SLACK * 0.5 * height / fy
    tx = z * torch.clamp(x / z, -lim_x, lim_x)
    ty = z * torch.clamp(y / z, -lim_y, lim_y)
    zeros = torch.zeros_like(z)
    J = torch.stack([fx / z, zeros, -fx * tx / z**2, zeros, fy / z, -fy * ty / z**2], -1).reshape(-1, 2, 3)
    M = quat_to_rotmat(quats) * scales[:, None, :]  # R S
    T = J @ R_cam
    TM = T @ M
    cov = TM @ TM.transpose(1, 2)
    a = cov[:, 0, 0] + eps2d
    b = cov[:, 0, 1]
    c = cov[:, 1, 1] + eps2d
    det = a * c - b * b
    conics = torch.stack([c / det, -b / det, a / det], -1)
    means2d = torch.stack([fx * x / z + cx, fy * y / z + cy], -1)
    # The ellipse d^T cov^-1 d <= s spans sqrt(s cov_xx) in x and sqrt(s cov_yy) in y.
    support_q = torch.where(valid, support_q.clamp_min(0), torch.zeros_like(support_q))
    extents = torch.stack([torch.sqrt(support_q * a), torch.sqrt(support_q * c)], -1).detach()
    return means2d, conics, torch.where(valid, p[:, 2], torch.zeros_like(z)), extents, valid


def support_boxes(means2d, extents, valid, width: int, height: int):
    """Pixel-centre ranges each primitive's support box covers inside the image.

    A primitive covers the pixel centres x in [m - e, m + e] (likewise y).
    Returns:
        lo (N, 2), hi (N, 2): inclusive pixel ranges clipped to the image (as floats);
        usable (N,) bool: valid, with a non-empty box that reaches at least one pixel.
    """
    lo = torch.clamp(torch.ceil(means2d - extents), min=0)
    hi = torch.minimum(torch.floor(means2d + extents), means2d.new_tensor([width - 1, height - 1]))
    return lo, hi, valid & (extents > 0).all(1) & (lo <= hi).all(1)


def tile_lists(means2d, depths, extents, valid, width: int, height: int):
    """Primitives whose support box reaches each 16x16 tile, front to back (no gradients).

    Returns:
        list over tiles (row-major) of (n_i,) int64 primitive indices sorted by depth.
    """
    lo, hi, usable = support_boxes(means2d, extents, valid, width, height)
    lo_tile = torch.where(usable[:, None], lo, torch.zeros_like(lo)).long() // TILE_SIZE
    hi_tile = torch.where(usable[:, None], hi, -torch.ones_like(hi)).long() // TILE_SIZE
    tiles_x, tiles_y = -(-width // TILE_SIZE), -(-height // TILE_SIZE)
    order = torch.argsort(depths, stable=True)
    lists = []
    for ty in range(tiles_y):
        for tx in range(tiles_x):
            hit = usable & (lo_tile[:, 0] <= tx) & (hi_tile[:, 0] >= tx) & (lo_tile[:, 1] <= ty) \
                & (hi_tile[:, 1] >= ty)
            lists.append(order[hit[order]])
    return lists


def composite(alpha: torch.Tensor, colors: torch.Tensor, depths: torch.Tensor, background=None):
    """Front-to-back compositing of P pixels over N depth-sorted primitives.

    Args:
        alpha: (P, N) per-pixel opacities, 0 where a primitive is skipped.
        colors: (N, C); depths: (N,); background: (C,) or None (black).
    Returns:
        image (P, C), alpha (P,), depth (P,) = sum z_i alpha_i T_i.
    A primitive counts while the transmittance after it stays >= EARLY_STOP_T, as in 3DGS.
    """
    after = torch.cumprod(1 - alpha, dim=1)
    keep = (after >= EARLY_STOP_T).to(alpha.dtype)  # a prefix, since `after` decreases
    before = torch.cat([torch.ones_like(alpha[:, :1]), after[:, :-1]], dim=1)
    weight = alpha * before * keep
    image = weight @ colors
    final_T = 1 - weight.sum(1)
    if background is not None:
        image = image + final_T[:, None] * background
    return image, 1 - final_T, weight @ depths


def footprint_response(pixels, means2d, conics, a, t, support):
    """(P, N) DoG response D of N primitives at P pixel centres (P, 2), and where u <= support.

    means2d: (N, 2), or (P, N, 2) with one copy per pixel (its gradient is then per pixel).
    """
    d = pixels[:, None, :] - means2d
    A, B, C = conics.unbind(-1)
    q = A * d[..., 0] ** 2 + 2 * B * d[..., 0] * d[..., 1] + C * d[..., 1] ** 2
    u = q / (2 * a)
    inside = u <= support
    return dog_profile(torch.where(inside, u, torch.zeros_like(u)), t.expand_as(u)), inside


def alpha_from_response(D, inside, opacity):
    """(P, N) alpha = min(ALPHA_MAX, opacity D), zero where skipped (outside, or < ALPHA_MIN)."""
    alpha = torch.clamp(opacity * D, max=ALPHA_MAX)
    return torch.where(inside & (alpha >= ALPHA_MIN), alpha, torch.zeros_like(alpha))


def _tiles(lists, width: int, height: int, like: torch.Tensor):
    """(tile's primitive ids, pixel rows, pixel columns, pixel centres (P, 2) in `like`'s dtype
    and device) of the non-empty tiles."""
    tiles_x = -(-width // TILE_SIZE)
    for index, ids in enumerate(lists):
        if len(ids) == 0:
            continue
        y0, x0 = (index // tiles_x) * TILE_SIZE, (index % tiles_x) * TILE_SIZE
        ys, xs = torch.meshgrid(torch.arange(y0, min(y0 + TILE_SIZE, height), device=like.device),
                                torch.arange(x0, min(x0 + TILE_SIZE, width), device=like.device),
                                indexing="ij")
        ys, xs = ys.reshape(-1), xs.reshape(-1)
        yield ids, ys, xs, torch.stack([xs, ys], -1).to(like.dtype)


def rasterize(means2d, conics, depths, extents, opacity, a, t, support, colors, valid,
              width: int, height: int, background=None, absgrad=None):
    """Tile by tile, the splats' image (H, W, C), alpha (H, W) and depth (H, W).

    Arguments as for ops.rasterize, with `valid` (N,) bool (from `project`) in place of the tile
    lists, which are built here. `absgrad`, when given, gets from each backward pass through a
    tile add((N, 2) tensor): that tile's sum over pixels of |per-pixel dL/dmean2d|.
    """
    lists = tile_lists(means2d.detach(), depths.detach(), extents, valid, width, height)
    # Zero, but connected to every input: with nothing visible, backward still gives zeros.
    # (Sums of empty slices: exactly 0 even where an input holds NaN.)
    zero = sum(x[:0].sum() for x in (means2d, conics, depths, opacity, a, t, colors))
    image = means2d.new_zeros(height, width, colors.shape[1]) + zero
    alpha_out = means2d.new_zeros(height, width) + zero
    depth_out = means2d.new_zeros(height, width) + zero
    if background is not None:
        image = image + background
    for ids, ys, xs, pixels in _tiles(lists, width, height, means2d):
        means = means2d[ids].expand(len(pixels), -1, -1)  # (P, n, 2): one copy per pixel
        if absgrad is not None and means.requires_grad:
            means.register_hook(_absgrad_hook(absgrad, ids, len(means2d)))
        D, inside = footprint_response(pixels, means, conics[ids], a[ids], t[ids], support[ids])
        img, alp, dep = composite(alpha_from_response(D, inside, opacity[ids]), colors[ids], depths[ids],
                                  background)
        image = image.index_put((ys, xs), img)
        alpha_out = alpha_out.index_put((ys, xs), alp)
        depth_out = depth_out.index_put((ys, xs), dep)
    return image, alpha_out, depth_out


def _absgrad_hook(absgrad, ids: torch.Tensor, n: int):
    """A hook on one tile's per-pixel means (P, len(ids), 2) that adds their absolute gradients,
    summed over the pixels, to `absgrad` as an (n, 2) tensor (nothing when no gradient reached
    them: autograd then passes None)."""
    def hook(grad: torch.Tensor | None) -> None:
        if grad is not None:
            absgrad.add(grad.new_zeros(n, 2).index_add_(0, ids, grad.abs().sum(0)))
    return hook


def fisher_per_view(means2d, conics, depths, extents, opacity, a, t, support, colors, valid,
                    width: int, height: int, background=None):
    """(N,) sum over pixels and channels of (dI_c / dD_i)^2, by autograd with D as leaves.

    Arguments as for `rasterize`.
    """
    lists = tile_lists(means2d, depths, extents, valid, width, height)
    fisher = means2d.new_zeros(means2d.shape[0])
    for ids, _, _, pixels in _tiles(lists, width, height, means2d):
        D, inside = footprint_response(pixels, means2d[ids], conics[ids], a[ids], t[ids], support[ids])
        D = D.detach().requires_grad_(True)
        image, _, _ = composite(alpha_from_response(D, inside, opacity[ids]), colors[ids], depths[ids],
                                background)
        for channel in range(colors.shape[1]):
            (grad,) = torch.autograd.grad(image[:, channel].sum(), D, retain_graph=True)
            fisher.index_add_(0, ids, (grad**2).sum(0))
    return fisher
