"""The visual hull carved further by the images' shading (space carving by photo-consistency).

The masks' visual hull is larger than the object wherever no silhouette shows a concavity: the
inside of an L or a U section, a pocket, the corner between walls. Its depth then hides the
concave edges there from nearly every view (`edgedog.train.occlusion`). Under a fixed light a
matte object shades each point of its surface by the point's normal alone, so every view that
sees a cell of the true surface reads about the same grey value there; a cell of the hull that
lies outside the object is seen through to different faces by different views (the walls of a
corner, a pocket's floor and its sides) and so reads different grey values. Such cells are
carved, layer by layer from the hull's surface, and the views see deeper into the concavity.

A view sees a surface cell when the cell's centre lies within `VISIBLE_CELLS` of the nearest
surface centre drawn on its pixel (a depth buffer); a cell is judged only when at least
`min_views` views see it wholly on the object's image, and carved when the spread of their grey
values (between the `SPREAD_QUANTILE` quantiles) exceeds the tolerance. A few views reading an
edge's pixels do not carve a cell. A cell of the true surface astride an edge reads both faces
and may be carved; few views see into the hole it leaves, so carving stops within a cell or
two there. Faces whose grey values are equal (a soft light saturating on several faces) cannot
be told apart: carving stops where the views see only them. The hull only hides primitives:
what the shading carves never culls a primitive as outside the object.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from edgedog.hull import HullGrid
from edgedog.scenes.camera import Camera

SPREAD_QUANTILE = 0.2
"""A cell's grey values are compared between this quantile and its complement over the views
that see it (the nearest reading inwards): a fifth of the views reading another face carve it."""
VISIBLE_CELLS = 2.0
"""A view sees a cell whose centre lies within this many cells behind its depth buffer: the
buffer holds the nearest centre over each pixel, and the hull's surface is a staircase of cells."""
MAX_ROUNDS = 64
"""Layers of cells the shading carves at most (each round peels the hull's current surface)."""
NEIGHBOURS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])


def view_projection(points: torch.Tensor, K: torch.Tensor,
                    w2c: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Points (N, 3) in the views (K (V, 3, 3), w2c (V, 4, 4), of the points' dtype): (V, N, 2)
    pixel positions, those not finite at -2 and all within [-2, 1e6] so that a cast to int stays
    in range (meaningless for a point at or behind a camera); and (V, N) camera z."""
    cam = torch.einsum("vij,nj->vni", w2c[:, :3, :3], points) + w2c[:, None, :3, 3]
    depth = cam[..., 2]
    safe = torch.where(depth > 0, depth, torch.ones_like(depth))
    uv = torch.einsum("vij,vnj->vni", K[:, :2, :2], cam[..., :2] / safe[..., None]) + K[:, None, :2, 2]
    return torch.nan_to_num(uv, nan=-2.0, posinf=-2.0, neginf=-2.0).clamp(-2.0, 1e6), depth


@dataclass(frozen=True)
class ShadedViews:
    """The masked views as the shading carve reads them, at 1/downscale of their size (padded to
    the largest).

    Attributes:
        K: (V, 3, 3), w2c: (V, 4, 4) float32 the cameras at that size.
        grey: (V, h, w) float32 each image's grey value, area-averaged to that size.
        whole: (V, h, w) bool pixels wholly on the object (every full-size pixel under the mask);
            False in the padding.
    """

    K: torch.Tensor
    w2c: torch.Tensor
    grey: torch.Tensor
    whole: torch.Tensor

    @classmethod
    def of(cls, cameras: list[Camera], images: Iterable[np.ndarray], masks: list[np.ndarray],
           downscale: int) -> ShadedViews:
        """From the views' full-size `cameras`, (H, W, 3) float RGB `images` (read one at a time:
        a generator holds one full-size image, not all) and (H, W) bool `masks`."""
        smalls, greys, wholes = [], [], []
        for camera, image, mask in zip(cameras, images, masks):
            small = camera.reduced(downscale)
            size = (small.width, small.height)
            grey = image.mean(axis=2).astype(np.float32)
            greys.append(cv2.resize(grey, size, interpolation=cv2.INTER_AREA))
            wholes.append(cv2.resize(mask.astype(np.float32), size, interpolation=cv2.INTER_AREA) > 0.999)
            smalls.append(small)
        height, width = max(g.shape[0] for g in greys), max(g.shape[1] for g in greys)

        def padded(images: list[np.ndarray]) -> torch.Tensor:
            return torch.from_numpy(np.stack([np.pad(i, ((0, height - i.shape[0]), (0, width - i.shape[1])))
                                              for i in images]))

        K = torch.from_numpy(np.array([c.K for c in smalls], np.float32))
        w2c = torch.from_numpy(np.array([c.w2c for c in smalls], np.float32))
        return cls(K, w2c, padded(greys), padded(wholes))

    def readings(self, centres: np.ndarray, cell: float) -> tuple[torch.Tensor, torch.Tensor]:
        """For the centres (M, 3) of the hull's surface cells (`cell` world units a side): (V, M)
        bool whether each view sees each wholly on the object, and (V, M) float32 its grey
        value there (meaningful where seen).

        The depth buffer keeps, per pixel, the nearest centre drawn on it; each centre is drawn
        on the four pixels around its projection, so that a surface whose cells project about a
        pixel apart leaves no holes to see through."""
        views, height, width = self.grey.shape
        uv, depth = view_projection(torch.from_numpy(centres.astype(np.float32)), self.K, self.w2c)
        left, top = uv[..., 0].floor().long(), uv[..., 1].floor().long()
        on_image = (depth > 0) & (left >= 0) & (left + 1 < width) & (top >= 0) & (top + 1 < height)
        base = torch.arange(views)[:, None] * (height * width)
        buffer = torch.full((views * height * width,), torch.inf)
        drawn = torch.where(on_image, depth, torch.inf).reshape(-1)  # inf draws nothing
        top, left = top.clamp(0, height - 2), left.clamp(0, width - 2)
        for dy in (0, 1):
            for dx in (0, 1):
                buffer.scatter_reduce_(0, (base + (top + dy) * width + left + dx).reshape(-1), drawn, "amin")
        x = uv[..., 0].round().long().clamp(0, width - 1)
        y = uv[..., 1].round().long().clamp(0, height - 1)
        pixel = base + y * width + x
        seen = on_image & self.whole.reshape(-1)[pixel] & (depth <= buffer[pixel] + VISIBLE_CELLS * cell)
        return seen, self.grey.reshape(-1)[pixel]


def surface_cells(occupied: np.ndarray) -> np.ndarray:
    """(M, 3) int64 [x, y, z] of the occupied cells of (R, R, R) bool `occupied` with an empty
    face neighbour (or on the grid's boundary)."""
    padded = np.pad(occupied, 1, constant_values=False)
    r = occupied.shape[0]
    exposed = np.zeros_like(occupied)
    for dx, dy, dz in NEIGHBOURS:
        exposed |= ~padded[1 + dx:r + 1 + dx, 1 + dy:r + 1 + dy, 1 + dz:r + 1 + dz]
    return np.argwhere(occupied & exposed)


def seen_quantiles(values: torch.Tensor, counts: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(M,) the lower and upper `SPREAD_QUANTILE` quantiles (the nearest reading inwards) of each
    column of (V, M) `values`, whose `counts` (M,) readings are finite and the rest inf."""
    ordered = values.sort(dim=0).values
    lower = torch.floor(SPREAD_QUANTILE * (counts - 1) + 0.5).long()
    upper = counts - 1 - lower
    return ordered.gather(0, lower[None]).squeeze(0), ordered.gather(0, upper[None]).squeeze(0)


def shade_carve(grid: HullGrid, views: ShadedViews, tolerance: float, min_views: int,
                max_rounds: int = MAX_ROUNDS) -> tuple[HullGrid, list[int]]:
    """`grid` with the surface cells whose views' grey values disagree carved, a layer per
    round until a round carves nothing or `max_rounds` have run; and the cells carved per round.

    A surface cell is judged where at least `min_views` of `views` see it wholly on the object
    and carved where its grey values' spread between the `SPREAD_QUANTILE` quantiles exceeds
    `tolerance` (grey units, 0 to 1)."""
    occupied = grid.occupied.numpy().copy()
    carved_per_round = []
    for _ in range(max_rounds):
        cells = surface_cells(occupied)
        seen, greys = views.readings(grid.origin + (cells + 0.5) * grid.cell, grid.cell)
        counts = seen.sum(dim=0)
        judged = torch.nonzero(counts >= min_views).squeeze(1)
        low, high = seen_quantiles(torch.where(seen[:, judged], greys[:, judged], torch.inf), counts[judged])
        carve = judged[high - low > tolerance].numpy()
        carved_per_round.append(len(carve))
        if not len(carve):
            break
        occupied[tuple(cells[carve].T)] = False
    return HullGrid(torch.from_numpy(occupied), grid.origin, grid.cell), carved_per_round
