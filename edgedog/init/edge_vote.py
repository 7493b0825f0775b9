"""Initial points where the views' edge maps agree: a coarse-to-fine vote over the cube.

Every cell of a grid over the uniform cube is projected into every view. A cell is carved away
when a view with a mask sees it outside the (dilated) object; otherwise each view votes whether
an edge lies at the cell's projection (the thinned map, dilated by the cell's projected size).
A cell off every edge still gets votes by chance: each view's chance is the share of its object
pixels that are (dilated) edge. A cell is kept when its votes are unlikely under chance, in
either of two ways:

- over all views (an edge most views see: outlines and convex edges), or
- within a cone of neighbouring views (an edge that only a few views see, such as the floor of
  a pocket or a concave corner, whose walls hide it from the rest: there, the few views that see
  it all vote for it, and no count over every view could tell it from chance).

The surprise of a cell is -log10 of the smaller p-value (the cones' corrected for their number).
At the finest level only the crest of the surprise is kept (its local maxima across the edge),
and the survivors of each level are split in eight and voted again at half the cell size.

Unlike SIFT triangulation this needs no texture (CAD renders have almost none), and unlike the
uniform cube its count follows the edge length the scene holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.ndimage import maximum_filter
from scipy.spatial import cKDTree
from scipy.stats import binom

from edgedog.edges.thin import ridge_mask
from edgedog.init.points import InitialPoints, nearest_neighbour_scales
from edgedog.scenes.camera import Camera
from edgedog.spacing import redundant

OFFSETS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
"""(8, 3) directions from a cell's centre to its eight children's, in quarter cells."""
CHUNK = 65536
"""Cells voted at once: the votes of a chunk are a (CHUNK, V) table."""
MAX_CANDIDATES = 8_000_000
"""Cells voted at one level at most (a level keeps the most surprising when more survive)."""


@dataclass(frozen=True)
class VoteSettings:
    """How the vote runs.

    Attributes:
        finest: cells per side of the finest grid.
        levels: grids from coarse to fine, each halving the cell (the coarsest has
            finest / 2^(levels - 1) cells per side).
        cone: views in each cone of neighbouring views (by direction from the cube's centre).
        surprise: at the finest level, -log10 of the p-value a kept cell's votes must reach.
        coarse_surprise: the same at the levels between the coarsest and the finest (looser:
            their dilated maps cover much of the object). The coarsest level only carves: its
            cells are so large that an edge seen by few views is lost in chance there.
        crest: at the finest level, a kept cell's surprise is at least this share of the
            largest within `crest_cells` cells (non-maximum suppression across the edge).
        crest_cells: half the side, in cells, of the cube that `crest` compares with.
        edge_threshold: an edge pixel is a ridge pixel of the map (non-maximum suppressed
            across the edge) whose value is at least this.
    """

    finest: int = 256
    levels: int = 3
    cone: int = 6
    surprise: float = 1.5
    coarse_surprise: float = 1.0
    crest: float = 0.8
    crest_cells: int = 2
    edge_threshold: float = 0.3


@dataclass(frozen=True)
class VoteView:
    """One view as the vote reads it, at one level.

    Attributes:
        camera: the view's camera.
        edges: (H, W) bool edge pixels dilated by the level's radius.
        mask: (H, W) bool object mask dilated by the same radius, or None (no mask: no carving).
        chance: share of the object's pixels (without a mask: of the edges' convex hull) that
            `edges` covers: the probability that a cell off every edge still lands on one.
    """

    camera: Camera
    edges: np.ndarray
    mask: np.ndarray | None
    chance: float


def disk(radius: int) -> np.ndarray:
    """(2r+1, 2r+1) uint8 structuring element of a disk of `radius` pixels."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def projected_radius(camera: Camera, center: np.ndarray, half_diagonal: float) -> int:
    """Pixels that a cell's half diagonal spans in `camera` at the depth of `center` (at least 1)."""
    depth = float(camera.project(center[None])[1][0])
    focal = float(max(camera.K[0, 0], camera.K[1, 1]))
    return max(1, int(np.ceil(focal * half_diagonal / max(depth, 1e-6))))


def vote_view(camera: Camera, edges: np.ndarray, mask: np.ndarray | None, radius: int) -> VoteView:
    """A view's dilated maps and chance of a vote for cells of a given projected `radius`.

    Args:
        edges: (H, W) bool edge pixels.
        mask: (H, W) bool object mask or None.
    """
    kernel = disk(radius)
    dilated = cv2.dilate(edges.astype(np.uint8), kernel) > 0
    grown = None if mask is None else cv2.dilate(mask.astype(np.uint8), kernel) > 0
    region = edge_hull(dilated) if grown is None else grown
    chance = float(dilated[region].mean()) if region.any() else 0.0
    return VoteView(camera, dilated, grown, chance)


def edge_hull(edges: np.ndarray) -> np.ndarray:
    """(H, W) bool convex hull of the edge pixels: where the object lies in a view without a
    mask, as far as its edges tell (the whole image would make edges look rarer than they are)."""
    hull = np.zeros(edges.shape, np.uint8)
    points = cv2.findNonZero(edges.astype(np.uint8))
    if points is not None:
        cv2.fillConvexPoly(hull, cv2.convexHull(points), 1)
    return hull > 0


def view_cones(cameras: list[Camera], center: np.ndarray, size: int) -> np.ndarray:
    """(V, V) float 0/1: row v marks view v and its `size` - 1 nearest views by the direction
    from `center` to their cameras (all views when there are fewer)."""
    directions = np.stack([c.center - center for c in cameras])
    directions /= np.maximum(np.linalg.norm(directions, axis=1, keepdims=True), 1e-12)
    nearest = np.argsort(-directions @ directions.T, axis=1, kind="stable")[:, :min(size, len(cameras))]
    cones = np.zeros((len(cameras), len(cameras)))
    np.put_along_axis(cones, nearest, 1.0, axis=1)
    return cones


def cast_votes(points: np.ndarray, views: list[VoteView]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Carving and votes of each point in each view.

    Args:
        points: (N, 3) world positions (cell centres).
    Returns:
        inside: (N,) bool, outside no view's (dilated) mask;
        votes: (N, V) bool, the view draws an edge at the point's projection;
        seen: (N, V) bool, the point projects into the view's image, in front of it.
    """
    n, count = len(points), len(views)
    inside = np.ones(n, dtype=bool)
    votes = np.zeros((n, count), dtype=bool)
    seen = np.zeros((n, count), dtype=bool)
    for v, view in enumerate(views):
        pixels, seen[:, v] = view.camera.pixels(points)
        rows = np.flatnonzero(seen[:, v])
        x, y = pixels[rows, 0], pixels[rows, 1]
        if view.mask is not None:
            inside[rows[~view.mask[y, x]]] = False
        votes[rows, v] = view.edges[y, x]
    return inside, votes, seen


def surprise(votes: np.ndarray, seen: np.ndarray, chance: np.ndarray, cones: np.ndarray) -> np.ndarray:
    """(N,) -log10 of the p-value of each point's votes under chance: the smaller of the p-value
    over the views that see the point and the smallest over the cones (each a binomial tail at
    the views' mean chance; the cones' times their number).

    Args:
        votes, seen: (N, V) bool from `cast_votes`.
        chance: (V,) each view's chance of a vote.
        cones: (V, V) 0/1 from `view_cones`.
    """
    votes_f, seen_f = votes.astype(np.float64), seen.astype(np.float64)
    views_seeing = seen_f.sum(axis=1)
    mean_chance = (seen_f @ chance) / np.maximum(views_seeing, 1.0)
    log_global = binom.logsf(votes_f.sum(axis=1) - 1, views_seeing, mean_chance) / np.log(10.0)
    in_cone = np.rint(votes_f @ cones.T).astype(np.int64)  # (N, V): votes within each view's cone
    size = cones.sum(axis=1)
    # (V, K + 1) log10 P(at least k votes in cone v by chance), looked up rather than computed per point
    counts = np.arange(int(size.max()) + 1)
    table = binom.logsf(counts[None] - 1, size[:, None], (cones @ chance / size)[:, None]) / np.log(10.0)
    tails = table[np.arange(len(size))[None], in_cone]
    log_cone = tails.min(axis=1) + np.log10(len(chance))
    return -np.minimum(log_global, np.minimum(log_cone, 0.0))


def on_crest(points: np.ndarray, score: np.ndarray, center: np.ndarray, side: float, resolution: int,
             reach: int, share: float) -> np.ndarray:
    """(N,) bool: cells whose score is at least `share` of the largest within `reach` cells (a
    cube of 2 reach + 1 cells): the crest of the vote, not the tube of cells around an edge that
    a few views also see on it.

    Args:
        points: (N, 3) centres of cells of the `resolution`-per-side grid over the cube.
        score: (N,) their surprise.
    """
    index = np.floor((points - center) / side * resolution + resolution / 2)
    index = np.clip(index, 0, resolution - 1).astype(np.int64)
    grid = np.zeros((resolution,) * 3, dtype=np.float32)
    grid[index[:, 0], index[:, 1], index[:, 2]] = score
    peak = maximum_filter(grid, size=2 * reach + 1, mode="constant", cval=0.0)
    return score >= share * peak[index[:, 0], index[:, 1], index[:, 2]]


def grid_centres(center: np.ndarray, side: float, resolution: int) -> np.ndarray:
    """(resolution^3, 3) centres of the cells of a `resolution`-per-side grid over the cube."""
    ticks = (np.arange(resolution) + 0.5) / resolution - 0.5
    x, y, z = np.meshgrid(ticks, ticks, ticks, indexing="ij")
    return center + side * np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def level_scores(points: np.ndarray, views: list[VoteView],
                 cones: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) bool inside the masks and (N,) surprise of each point, voted CHUNK points at a time."""
    chance = np.array([v.chance for v in views])
    inside, score = np.zeros(len(points), dtype=bool), np.zeros(len(points))
    for start in range(0, len(points), CHUNK):
        part = slice(start, start + CHUNK)
        inside[part], votes, seen = cast_votes(points[part], views)
        score[part] = surprise(votes, seen, chance, cones)
    return inside, score


def sight(points: np.ndarray, views: list[VoteView]) -> np.ndarray:
    """(N, 3) mean of the unit directions from each point to the cameras of the views that vote
    for it: long (up to 1) toward the few views that see an edge hidden from the rest, short for
    one that views all around see."""
    _, votes, _ = cast_votes(points, views)
    total = np.zeros_like(points)
    for v, view in enumerate(views):
        offsets = view.camera.center - points
        length = np.maximum(np.linalg.norm(offsets, axis=1, keepdims=True), 1e-12)
        total += votes[:, v, None] * offsets / length
    return total / np.maximum(votes.sum(axis=1, keepdims=True), 1)


@dataclass(frozen=True)
class Vote:
    """The outcome of `vote_cells`.

    Attributes:
        centres: (M, 3) the kept cells' centres.
        views: the views as the finest level read them (for `sight`).
        report: the cells kept at each level, the finest cell's size ("cell") and the coarsest
            grid's resolution.
    """

    centres: np.ndarray
    views: list[VoteView]
    report: dict


def vote_cells(cameras: list[Camera], edge_maps: list[np.ndarray], masks: list[np.ndarray | None],
               center: np.ndarray, side: float, settings: VoteSettings) -> Vote:
    """Cells of the finest grid that the views' edge maps agree on.

    Args:
        cameras: V cameras at the maps' resolution.
        edge_maps: V (H, W) float maps in [0, 1].
        masks: V (H, W) bool object masks or None.
        center: (3,) the cube's centre; side: its edge.
    """
    edges = [ridge_mask(np.asarray(m), floor=settings.edge_threshold) for m in edge_maps]
    cones = view_cones(cameras, center, settings.cone)
    resolution = max(1, settings.finest >> (settings.levels - 1))
    points, cell = grid_centres(center, side, resolution), side / resolution
    kept = []
    for level in range(settings.levels):
        last = level == settings.levels - 1
        radius = [projected_radius(c, center, cell * np.sqrt(3) / 2) for c in cameras]
        views = [vote_view(c, e, m, r) for c, e, m, r in zip(cameras, edges, masks, radius)]
        inside, score = level_scores(points, views, cones)
        threshold = settings.surprise if last else settings.coarse_surprise if level else 0.0
        keep = inside & (score >= threshold)
        points, score = points[keep], score[keep]
        if last:
            crest = on_crest(points, score, center, side, resolution << level, settings.crest_cells,
                             settings.crest)
            points, score = points[crest], score[crest]
        elif 8 * len(points) > MAX_CANDIDATES:
            strongest = np.argsort(-score, kind="stable")[:MAX_CANDIDATES // 8]
            points, score = points[strongest], score[strongest]
        kept.append(int(len(points)))
        if not last:
            points = (points[:, None, :] + OFFSETS[None] * cell / 4).reshape(-1, 3)
            cell /= 2
    report = {"cells_kept": kept, "cell": cell, "coarsest": resolution}
    return Vote(points, views, report)


def thin_to_spacing(points: np.ndarray, spacing: float) -> np.ndarray:
    """(M,) sorted indices into `points` (N, 3) no two of which lie within `spacing` of each other,
    every other point within `spacing` of one of them: the spacing control's greedy suppression
    (`edgedog.spacing.redundant`) on distance alone, keeping first the points with the most
    neighbours within `spacing` (the middle of the vote's crest, not its rim).

    Along a thin tube of points (the crest around an edge) the kept ones lie one to two spacings
    apart whatever the edge's direction: the count follows the length of edge, not the tube's
    thickness.
    """
    if spacing <= 0:
        return np.arange(len(points))
    crowd = cKDTree(points).query_ball_point(points, spacing, return_length=True)
    one_direction = np.tile(np.array([1.0, 0.0, 0.0]), (len(points), 1))  # every close pair conflicts
    return np.flatnonzero(~redundant(points, one_direction, crowd, spacing, max_angle=90.0))


def edge_vote_points(cameras: list[Camera], edge_maps: list[np.ndarray], masks: list[np.ndarray | None],
                     center: np.ndarray, side: float, count: int, scale_range: tuple[float, float],
                     settings: VoteSettings = VoteSettings(), seed: int = 0,
                     spacing: float = 0.0) -> InitialPoints:
    """At most `count` initial points on the cells the views' edges agree on, one per cell,
    jittered within it, with nearest-neighbour scales clipped to `scale_range` and the cells'
    `sight`.

    With `spacing` > 0 the agreeing cells are first thinned to about one per `spacing` of edge
    (`thin_to_spacing`), so that the count follows the length of edge the maps draw. Where more
    cells are left than `count`, a random `count` of them are kept (uniformly along the edges:
    the most surprising would favour the edges that many views see over concave ones).
    """
    vote = vote_cells(cameras, edge_maps, masks, center, side, settings)
    rng = np.random.default_rng(seed)
    chosen = thin_to_spacing(vote.centres, spacing)
    if len(chosen) > count:
        chosen = np.sort(rng.choice(len(chosen), size=count, replace=False))
    cell = vote.report["cell"]
    positions = vote.centres[chosen] + (rng.random((len(chosen), 3)) - 0.5) * cell
    scales = nearest_neighbour_scales(positions, lo=scale_range[0], hi=scale_range[1])
    report = {**vote.report, "points": int(len(positions)), "cells_agreeing": int(len(vote.centres)),
              "spacing": float(spacing),
              "center": [float(c) for c in center], "side": float(side), "seed": int(seed)}
    directions = sight(vote.centres[chosen], vote.views)
    return InitialPoints(positions, scales, "edge-vote", report, sight=directions)
