"""Occlusion by the object's visual hull (`model.occlusion = 'hull'`).

Our splats have no occluders: a primitive on an edge that the object hides from most views (a
concave corner, the far side's edges) is drawn in every view, and the views that cannot see it
penalise it as a false edge. With the scene's masks (mask files or RGBA images) the object's
visual hull is known: the cells of a grid over the scene's cube whose centres every view's mask
holds. Each view's depth of the hull (the camera z of the first hull cell along each pixel's
ray) then says where the object stands in front of a primitive, and the primitive is not drawn
in that view when it lies more than `model.occlusion_margin` cells behind that depth.

A cell is kept when its centre projects inside every mask, so the hull's surface lies within
half a cell of the object's where the masks are tight: a point of the surface that a view sees
is not hidden by the hull unless the view grazes the surface; the margin absorbs the cells'
size. Where the masks leave the hull larger than the object (a pocket that no silhouette
shows), its edges lie inside the hull and would be hidden from every view: a primitive hidden
from all but fewer than `model.occlusion_min_views` of the views it projects into is drawn in
every view, as without occlusion.

The hull also bounds where an edge can be: a primitive farther outside it than the margin is
off the object, and the projection cull removes it (`Occlusion.outside`).

With `model.occlusion_shading` the depth is that of the hull carved further by the images'
grey values (edgedog.shaded_hull: the inside of a corner or a pocket), while the masks' hull
still bounds the primitives.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import torch
from scipy.ndimage import distance_transform_edt

from edgedog.errors import ConfigError
from edgedog.hull import HullGrid, carve, readable_mask
from edgedog.init import scene_cube
from edgedog.renderer.primitives import Primitives
from edgedog.scenes.camera import Camera
from edgedog.scenes.scene import Scene
from edgedog.shaded_hull import ShadedViews, shade_carve, view_projection
from edgedog.train.config import ModelSettings
from edgedog.train.resolution import any_in_block

HIDDEN_LOGIT = -40.0
"""The opacity logit of a primitive in a view that does not see it: sigmoid is about 4e-18."""
RAY_BLOCK = 32
"""Samples marched at once along every ray still looking for the hull."""
RAY_CHUNK = 65536
"""Rays marched at once: a block of them is (RAY_CHUNK, RAY_BLOCK, 3) float64, 50 MB."""
PROJECTED_AT_ONCE = 4_000_000
"""Primitive-view pairs projected at once by `Occlusion.hidden` ((pairs, 3) float64, 96 MB)."""


def box_span(origins: np.ndarray, directions: np.ndarray, low: np.ndarray, high: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """(M,) entry and exit ray parameters of rays `origins` + t `directions` (M, 3) in the box
    [low, high] (slab method; exit < entry where a ray misses it); entry >= 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = 1.0 / directions
        a, b = (low - origins) * inverse, (high - origins) * inverse
    a, b = np.nan_to_num(a, nan=-np.inf), np.nan_to_num(b, nan=np.inf)
    entry = np.maximum(np.minimum(a, b).max(axis=1), 0.0)
    return entry, np.maximum(a, b).min(axis=1)


def hull_depth(grid: HullGrid, camera: Camera, mask: np.ndarray | None) -> np.ndarray:
    """(H, W) float32 camera z of the first occupied cell along each pixel's ray of `camera`
    (inf where the ray misses the hull). Only the pixels of the (H, W) bool `mask` (None: all)
    are marched: the hull projects inside every mask.

    The rays step half a cell at a time, so no cell's interior is stepped over by more than
    half its side."""
    height, width = camera.height, camera.width
    depth = np.full((height, width), np.inf, np.float32)
    rows, cols = np.nonzero(np.ones((height, width), bool) if mask is None else mask)
    if not len(rows):
        return depth
    # A ray's parameter t is its point's camera z.
    directions = camera.ray_directions(np.stack([cols, rows], axis=1).astype(np.float64))
    low = grid.origin
    entry, leave = box_span(np.broadcast_to(camera.center, directions.shape), directions, low,
                            low + grid.resolution * grid.cell)
    step = 0.5 * grid.cell / np.linalg.norm(directions, axis=1)
    alive = np.flatnonzero(entry < leave)
    origin = torch.from_numpy(camera.center.astype(np.float64))
    for start in range(0, len(alive), RAY_CHUNK):
        rays = alive[start:start + RAY_CHUNK]
        found = first_hits(grid, origin, torch.from_numpy(directions[rays]), torch.from_numpy(entry[rays]),
                           torch.from_numpy(leave[rays]), torch.from_numpy(step[rays]))
        depth[rows[rays], cols[rays]] = found.numpy().astype(np.float32)
    return depth


def first_hits(grid: HullGrid, origin: torch.Tensor, directions: torch.Tensor, entry: torch.Tensor,
               leave: torch.Tensor, step: torch.Tensor) -> torch.Tensor:
    """(M,) float64 parameter t of the first occupied sample along each ray `origin` (3,) + t
    `directions` (M, 3), sampled every `step` (M,) from `entry` to `leave` (M,); inf where
    none is."""
    t = entry.clone()
    ahead = torch.arange(RAY_BLOCK, dtype=torch.float64)
    found = torch.full((len(t),), torch.inf, dtype=torch.float64)
    live = torch.arange(len(t))
    while len(live):
        ts = t[live, None] + step[live, None] * ahead  # (M, B)
        hit = grid.lookup(origin + directions[live, None, :] * ts[..., None]) & (ts <= leave[live, None])
        any_hit = hit.any(dim=1)
        first = torch.argmax(hit.to(torch.uint8), dim=1)
        found[live[any_hit]] = ts[any_hit, first[any_hit]]
        t[live] = ts[:, -1] + step[live]
        live = live[~any_hit & (t[live] <= leave[live])]
    return found


class Occlusion:
    """Which views see which primitives, by the visual hull's depth in each view.

    Attributes:
        depths: (V, h, w) float32 hull depth of each view at the depth maps' resolution.
        K: (V, 3, 3), w2c: (V, 4, 4) float64 the views' cameras at that resolution.
        margin: world units a primitive must lie behind the hull's depth to be hidden.
        min_views: a primitive seen by fewer of the views it projects into is drawn in all.
        hull: the visual hull's grid.
        clearance: (R, R, R) float32 world distance from each cell of `hull` to its nearest
            occupied cell, centre to centre (0 inside).
        report: what log.json records of the hull (views with a mask, cells, the share occupied).
    """

    def __init__(self, depths: torch.Tensor, K: torch.Tensor, w2c: torch.Tensor, margin: float,
                 min_views: int, hull: HullGrid, clearance: torch.Tensor, report: dict):
        self.depths, self.K, self.w2c = depths, K, w2c
        self.margin, self.min_views = float(margin), int(min_views)
        self.hull, self.clearance = hull, clearance
        self.report = report

    @classmethod
    def from_masks(cls, cameras: list[Camera], masks: list[np.ndarray | None], center: np.ndarray,
                   side: float, resolution: int, margin_cells: float, min_views: int,
                   downscale: int, device: torch.device, shaded: ShadedViews | None = None,
                   shading_tolerance: float = 0.0) -> Occlusion:
        """Carve the hull of the views' (H, W) bool `masks` (None: a view without one) over the
        cube (`center` (3,), `side`) at `resolution` cells a side, and take each view's depth
        of it at 1/`downscale` of the view's size. With `shaded` views, the depth is that of
        the hull carved further by their grey values (`shade_carve`, `shading_tolerance`)."""
        grid = carve(cameras, masks, center, side, resolution)
        report = {"views_with_mask": sum(mask is not None for mask in masks), "cells": resolution,
                  "cell": round(grid.cell, 6), "hull_share": round(float(grid.occupied.float().mean()), 4)}
        seen_grid = grid
        if shaded is not None:
            started = time.perf_counter()
            seen_grid, carved = shade_carve(grid, shaded, shading_tolerance, min_views)
            report.update(shading_carved=int(sum(carved)), shading_rounds=len(carved),
                          shading_seconds=round(time.perf_counter() - started, 2))
        depths, Ks, w2cs = [], [], []
        for camera, mask in zip(cameras, masks):
            small = camera.reduced(downscale)
            small_mask = None if mask is None else any_in_block(mask, small.width, small.height)
            depths.append(torch.from_numpy(hull_depth(seen_grid, small, small_mask)) if mask is not None
                          else torch.full((small.height, small.width), torch.inf))
            Ks.append(torch.from_numpy(small.K))
            w2cs.append(torch.from_numpy(small.w2c))
        shapes = {tuple(d.shape) for d in depths}
        if len(shapes) > 1:  # views of different sizes: pad to the largest (inf: nothing hides)
            h, w = max(s[0] for s in shapes), max(s[1] for s in shapes)
            depths = [torch.nn.functional.pad(d, (0, w - d.shape[1], 0, h - d.shape[0]), value=torch.inf)
                      for d in depths]
        clearance = torch.from_numpy((distance_transform_edt(~grid.occupied.numpy()) * grid.cell)
                                     .astype(np.float32)).to(device)
        return cls(torch.stack(depths).to(device), torch.stack(Ks).to(device), torch.stack(w2cs).to(device),
                   margin_cells * grid.cell, min_views, grid, clearance, report)

    def __len__(self) -> int:
        return int(self.depths.shape[0])

    def hidden(self, means: torch.Tensor) -> torch.Tensor:
        """(V, N) bool: primitive n (centre `means` (N, 3)) is hidden from view v: it lies more
        than the margin behind the hull's depth at all four depth pixels around its projection
        (the largest of them: a pixel's depth on a slanted face varies across it). A primitive
        seen by fewer than `min_views` of the views it projects into is hidden from none."""
        with torch.no_grad():
            points = means.detach().to(self.w2c.dtype)
            views = max(1, PROJECTED_AT_ONCE // max(1, len(points)))
            parts = [self._behind(points, first, min(first + views, len(self)))
                     for first in range(0, len(self), views)]
            inside = (torch.cat([p[0] for p in parts]) if parts
                      else torch.zeros(0, len(points), dtype=torch.bool, device=points.device))
            hidden = torch.cat([p[1] for p in parts]) if parts else inside
            seen = (inside & ~hidden).sum(dim=0)
            return hidden & (seen >= self.min_views)[None, :]

    def _behind(self, points: torch.Tensor, first: int, last: int) -> tuple[torch.Tensor, torch.Tensor]:
        """For views first..last-1 and the (N, 3) `points`: (V', N) bool whether each projects
        into the view's depth map, and whether it lies more than the margin behind the largest
        of the four depths around its projection."""
        depths = self.depths[first:last]
        uv, z = view_projection(points, self.K[first:last], self.w2c[first:last])
        height, width = depths.shape[1:]
        left, top = torch.floor(uv[..., 0]).long(), torch.floor(uv[..., 1]).long()
        inside = (z > 0) & (left >= 0) & (left + 1 < width) & (top >= 0) & (top + 1 < height)
        flat_depths = depths.reshape(last - first, -1)
        front = torch.full_like(z, -torch.inf)
        for dy in (0, 1):
            for dx in (0, 1):
                flat = (top + dy).clamp(0, height - 1) * width + (left + dx).clamp(0, width - 1)
                front = torch.maximum(front, torch.gather(flat_depths, 1, flat).to(z.dtype))
        return inside, inside & (z > front + self.margin)

    def outside(self, means: torch.Tensor) -> torch.Tensor:
        """(N,) bool: the centre `means` (N, 3) lies farther outside the hull than the margin
        (beyond the grid's cube, its distance to the cube is added to that of the cube's
        nearest cell)."""
        with torch.no_grad():
            grid = self.hull
            points = means.detach().double()
            low = torch.as_tensor(grid.origin, dtype=torch.float64, device=points.device)
            high = low + grid.resolution * grid.cell
            nearest = torch.minimum(torch.maximum(points, low), high)
            beyond = (points - nearest).norm(dim=1)
            index = grid.index(nearest).clamp(0, grid.resolution - 1)
            inside_distance = self.clearance.to(points.device)[index[:, 0], index[:, 1], index[:, 2]].double()
            return torch.nan_to_num(inside_distance + beyond, nan=torch.inf) > self.margin


def hide(logits: torch.Tensor, hidden: torch.Tensor) -> torch.Tensor:
    """(N,) opacity `logits` with those of the `hidden` (N,) bool primitives at `HIDDEN_LOGIT`
    (differentiable in the others)."""
    return torch.where(hidden, torch.full_like(logits, HIDDEN_LOGIT), logits)


def drawn_in_view(primitives: Primitives, hidden: torch.Tensor) -> Primitives:
    """`primitives` as one view draws them, for the rasterizer: those that `hidden` (N,) bool
    marks hidden from it at `HIDDEN_LOGIT`."""
    return dataclasses.replace(primitives, opacity_logits=hide(primitives.opacity_logits, hidden))


def scene_occlusion(scene: Scene, model: ModelSettings, side: float | None,
                    device: torch.device) -> Occlusion | None:
    """The `Occlusion` of `scene`'s masks over its cube (`edgedog.init.scene_cube` of `side`), as
    the `model.occlusion_*` settings say; None when `model.occlusion` is 'off', or 'auto' and the
    scene has no masks. A view whose mask cannot be read carves nothing and hides nothing.

    Raises:
        ConfigError when `model.occlusion` is 'hull' and no view's mask can be read.
    """
    if model.occlusion == "off" or (model.occlusion == "auto" and not scene.masked_views):
        return None
    masks = [readable_mask(scene, i) for i in range(len(scene))]
    if all(mask is None for mask in masks):
        raise ConfigError(f"model.occlusion='hull' needs object masks (mask files or RGBA images), "
                          f"and the scene {scene.root} has none that can be read")
    center, side = scene_cube(scene, side)
    shaded = None
    if model.occlusion_shading:
        masked = [i for i, mask in enumerate(masks) if mask is not None]
        shaded = ShadedViews.of([scene.camera(i) for i in masked], (scene.load_image(i) for i in masked),
                                [masks[i] for i in masked], model.occlusion_downscale)
    return Occlusion.from_masks(scene.cameras, masks, center, side, model.occlusion_cells,
                                model.occlusion_margin, model.occlusion_min_views,
                                model.occlusion_downscale, device, shaded, model.occlusion_shading_tolerance)
