"""Corrections of a detector's measured bias (`edgedog.edges.calibration`): pure functions.

Sign convention (the calibration's): a *shift* (dx, dy) moves the map's content by +dx px to
the right and +dy px down. Shifting by a calibration's `correction` (minus its offset) puts
the map's ridge on the ground truth. Pixel centres sit at integer coordinates, as everywhere.

To thin the bands to their ridge instead, use `edgedog.edges.thin.thin_edge_map`.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import torch
import torch.nn.functional as F


def shift_edge_map(edge_map: np.ndarray, dx: float, dy: float, nearest: bool = False) -> np.ndarray:
    """Translate a map by a sub-pixel shift (linear interpolation, or the nearest pixel), with
    zeros coming in.

    Args:
        edge_map: (H, W) float map, or a bool mask with `nearest`.
        dx, dy: the shift in px (content moves right and down for positive values).
        nearest: sample the nearest pixel instead: for masks of edge pixels, whose thin lines
            would fall below the edge threshold if interpolated (as in `OutlinePull.apply`).
    Returns:
        (H, W) float32 map with out(x, y) = edge_map(x - dx, y - dy) (bool with `nearest` on a
        bool mask).
    """
    height, width = edge_map.shape
    matrix = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    shifted = cv2.warpAffine(np.asarray(edge_map, np.float32), matrix, (width, height),
                             flags=cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return shifted > 0.5 if edge_map.dtype == bool else shifted


def warp_target(target: torch.Tensor, shift: torch.Tensor) -> torch.Tensor:
    """`shift_edge_map` in torch, differentiable in `shift`: for learning a dataset's shift
    jointly with the primitives.

    Args:
        target: (H, W) or (N, H, W) float maps.
        shift: (2,) float tensor (dx, dy) in px, same convention as `shift_edge_map`.
    Returns:
        The shifted maps, shaped like `target`: out(x, y) = target(x - dx, y - dy), bilinear,
        zeros outside.
    """
    height, width = target.shape[-2:]
    maps = target.reshape(-1, 1, height, width)
    shift = shift.to(target.dtype)
    # align_corners=False: -1 and +1 are the outer edges of the border pixels, so the centre of
    # pixel x is at (2x + 1) / W - 1, and a shift of d px is 2d / W in these units.
    like = {"dtype": target.dtype, "device": target.device}
    xs = (2 * torch.arange(width, **like) + 1) / width - 1 - 2 * shift[0] / width
    ys = (2 * torch.arange(height, **like) + 1) / height - 1 - 2 * shift[1] / height
    grid = torch.stack(torch.broadcast_tensors(xs[None, :], ys[:, None]), dim=-1)  # (H, W, 2) as (x, y)
    grid = grid.expand(maps.shape[0], height, width, 2)
    warped = F.grid_sample(maps, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    return warped.reshape(target.shape)


def gaussian_kernel(sigma_px: float) -> torch.Tensor:
    """(2r + 1,) float32 normalised 1D Gaussian of standard deviation `sigma_px`, r = ceil(3 sigma)."""
    radius = max(1, math.ceil(3 * sigma_px))
    offsets = torch.arange(-radius, radius + 1, dtype=torch.float32)
    kernel = torch.exp(-0.5 * (offsets / sigma_px) ** 2)
    return kernel / kernel.sum()


def blur_to_profile(render: torch.Tensor, sigma_px: float) -> torch.Tensor:
    """Widen a thin rendered edge map to a detector's measured band, differentiably.

    A line of profile width s_render blurred by sigma_px has width sqrt(s_render^2 + sigma_px^2):
    to match a map whose profile width (`EdgeProfile.width_px`) is s_map, blur by
    sqrt(s_map^2 - s_render^2). The blur keeps the line's integral, not its peak.

    Args:
        render: (H, W) float tensor.
        sigma_px: Gaussian standard deviation in px (> 0).
    Returns:
        (H, W) the separable Gaussian blur of `render` (zeros beyond the border).
    """
    weights = gaussian_kernel(sigma_px).tolist()
    return _blur_along(_blur_along(render, weights, 1), weights, 0)


def _blur_along(image: torch.Tensor, weights: list[float], dim: int) -> torch.Tensor:
    """(H, W) `image` filtered along `dim` by the symmetric kernel `weights` (2r + 1 taps),
    zeros beyond the border. A weighted sum of shifted views: F.conv2d with one channel takes
    the CPU's slow generic path (about 300 ms per 800x800 step, forward and backward, on
    one thread; this takes about 15 ms)."""
    radius = (len(weights) - 1) // 2
    padded = F.pad(image, (radius, radius, 0, 0) if dim == 1 else (0, 0, radius, radius))
    size = image.shape[dim]
    return sum(w * padded.narrow(dim, k, size) for k, w in enumerate(weights))
