"""The occluding-contour test of extraction: a point that the views drawing it all see at grazing
incidence on the object's visual hull is on the contour of a curved face, not on an edge.

Edge maps draw the occluding contours of curved faces (a cylinder's sides, a fillet's rim) as
well as edges. A contour moves over the surface with the view, but each view draws it where the
surface turns away from that view, so training triangulates it onto the surface, where the views
that draw it look along the surface: the direction to their camera is nearly perpendicular to
the surface normal. An edge is drawn by views from all sides, most of them far from grazing
either of its two faces. The object's surface normal comes from its visual hull (carved from the
scene's masks), whose surface is the object's wherever a silhouette touches it: on the curved
faces whose contours are in question. Inside the hull (a pocket, a cavity) the normal is the
nearest hull face's, which the views looking into the pocket do not graze.
"""

from __future__ import annotations

from functools import cached_property

import cv2
import numpy as np
import torch
from scipy.ndimage import distance_transform_edt, gaussian_filter, map_coordinates

from edgedog.hull import HullGrid, carve, readable_mask
from edgedog.scenes import Scene

DRAWN_VALUE = 0.3
"""A view draws a point where its edge map (`window_max`) is at least this; the per-curve
diagnosis counts the views that draw a curve by the same value."""
COARSE_CELLS = 64
"""Cells per side of the first hull, over the scene's bounds, which finds the object's box."""
CLEAR_SKIP = 2.5
"""Cells from a point on which `HullSurface.unblocked` looks for the hull: the hull's surface lies
within a cell or so of the object's, so the cells around a point on the object are the hull's."""
CLEAR_BLOCK = 64
"""Steps marched at once by `HullSurface.unblocked`."""


def scene_hull(scene: Scene, masks: list[np.ndarray | None], cells: int) -> HullGrid | None:
    """The visual hull of the scene's `masks` (each view's `readable_mask`) on a `cells`^3 grid
    over the cube around the object: a first hull over the cube around the scene's bounds finds
    the object's box, one coarse cell wider on each side. None when no view has a readable mask.
    It depends on the scene only, so the diagnosis can re-apply the filter point by point."""
    if all(mask is None for mask in masks):
        return None
    low, high = np.asarray(scene.bounds, dtype=np.float64)
    coarse = carve(scene.cameras, masks, (low + high) / 2, float(np.max(high - low)), COARSE_CELLS)
    occupied = np.argwhere(coarse.occupied.numpy())
    if not len(occupied):
        return coarse  # the masks share no cell: no normal anywhere, nothing is judged
    low = coarse.origin + (occupied.min(axis=0) - 1) * coarse.cell
    high = coarse.origin + (occupied.max(axis=0) + 2) * coarse.cell
    return carve(scene.cameras, masks, (low + high) / 2, float(np.max(high - low)), cells)


def window_max(image: np.ndarray) -> np.ndarray:
    """(H, W) largest value of each pixel's 3x3 neighbourhood: a point projected a pixel off its
    line still lands on it."""
    return cv2.dilate(image, np.ones((3, 3), np.uint8))


def signed_distance(grid: HullGrid) -> np.ndarray:
    """(R, R, R) float32 signed distance to the hull's surface in cells (> 0 outside), smoothed
    over a cell against the grid's staircase."""
    occupied = grid.occupied.numpy()
    signed = distance_transform_edt(~occupied) - distance_transform_edt(occupied)
    return gaussian_filter(signed.astype(np.float32), 1.0)


class HullSurface:
    """A scene's masks, its visual hull (`scene_hull` at `cells` per side) and its signed
    distance, each read or carved on first use and then kept: one extraction's contour tests (the
    filter's and the line completion's) and the completion's views share them instead of reading
    and carving them each (seconds on a 50-view scene)."""

    def __init__(self, scene: Scene, cells: int):
        self.scene, self.cells = scene, cells

    @cached_property
    def masks(self) -> list[np.ndarray | None]:
        """Each view's (H, W) bool mask (`readable_mask`), None where it has none."""
        return [readable_mask(self.scene, i) for i in range(len(self.scene))]

    @property
    def every_view_masked(self) -> bool:
        """Whether every view has a readable mask (what the shading test and the line completion
        need: a view without one cannot tell the object from the background)."""
        return all(mask is not None for mask in self.masks)

    @cached_property
    def grid(self) -> HullGrid | None:
        """The hull's grid; None when no view has a readable mask."""
        return scene_hull(self.scene, self.masks, self.cells)

    @cached_property
    def box(self) -> np.ndarray:
        """(2, 3) the lowest and highest corners of the hull's occupied cells (the grid's cube
        where none is occupied). The grid must exist."""
        grid = self.grid
        occupied = np.argwhere(grid.occupied.numpy())
        if not len(occupied):
            return np.stack([grid.origin, grid.origin + grid.resolution * grid.cell])
        return np.stack([grid.origin + occupied.min(axis=0) * grid.cell,
                         grid.origin + (occupied.max(axis=0) + 1) * grid.cell])

    @cached_property
    def signed(self) -> np.ndarray:
        """(R, R, R) `signed_distance` of the grid (which must exist)."""
        return signed_distance(self.grid)

    def unblocked(self, points: np.ndarray, centres: np.ndarray, skip: float = CLEAR_SKIP) -> np.ndarray:
        """(N, V) bool: whether the segment from each point (N, 3) to each camera centre (V, 3)
        meets no cell of the hull from `skip` cells on (a view that surely sees the point, if
        the point is on the object: the hull holds the object). Marched half a cell at a time to
        the grid's far side; memory O(N V R). The hull's grid must exist."""
        grid = self.grid
        towards = centres[None] - points[:, None]
        towards /= np.maximum(np.linalg.norm(towards, axis=2, keepdims=True), 1e-12)
        steps = np.arange(skip, grid.resolution * np.sqrt(3.0), 0.5) * grid.cell
        blocked = np.zeros(towards.shape[:2], bool)
        for start in range(0, len(steps), CLEAR_BLOCK):
            block = steps[start:start + CLEAR_BLOCK]
            along = points[:, None, None] + towards[:, :, None] * block[None, None, :, None]
            blocked |= grid.lookup(torch.from_numpy(along)).numpy().any(axis=2)
        return ~blocked

    def normals(self, points: np.ndarray, probe: float = 0.0) -> np.ndarray:
        """(N, K, 3) unit outward normals of the hull's surface around each point (N, 3): at the
        point and, with `probe` > 0 cells, at the six points that far along the grid's axes
        (K = 7), so that a crease of the hull shows as normals that disagree. A normal is the
        gradient of the signed distance by central differences of a cell; zero where the gradient
        vanishes (far from any hull, or on its medial axis)."""
        grid = self.grid
        offsets = np.zeros((1, 3)) if probe <= 0 else np.concatenate([np.zeros((1, 3)), probe * np.eye(3),
                                                                       -probe * np.eye(3)])
        index = (points - grid.origin) / grid.cell - 0.5  # continuous cell coordinates
        probes = (index[:, None, :] + offsets[None]).reshape(-1, 3)
        gradient = np.empty_like(probes)
        for axis in range(3):
            step = np.zeros(3)
            step[axis] = 1.0
            ahead = map_coordinates(self.signed, (probes + step).T, order=1, mode="nearest")
            behind = map_coordinates(self.signed, (probes - step).T, order=1, mode="nearest")
            gradient[:, axis] = (ahead - behind) / 2
        length = np.linalg.norm(gradient, axis=1, keepdims=True)
        normals = np.where(length > 1e-6, gradient / np.maximum(length, 1e-6), 0.0)
        return normals.reshape(len(points), len(offsets), 3)


def grazing_shares(points: np.ndarray, normals: np.ndarray, scene: Scene, detector: str,
                   max_cosine: float) -> np.ndarray:
    """(N,) share of the views drawing each point (N, 3) that see it at grazing incidence: |cos|
    between the direction to the view's camera and every normal (N, K, 3) around the point
    below `max_cosine` (at a crease no view but one along it grazes both faces). 0 for a point
    that no view draws, or without a normal. Views are streamed: memory is O(N K) whatever the
    number of views."""
    drawing = np.zeros(len(points))
    grazing = np.zeros(len(points))
    for i in range(len(scene)):
        camera = scene.camera(i)
        pixels, inside = camera.pixels(points)
        edge_map = window_max(scene.load_edge_map(i, detector).astype(np.float32))
        drawn = np.zeros(len(points), bool)
        drawn[inside] = edge_map[pixels[inside, 1], pixels[inside, 0]] >= DRAWN_VALUE
        towards = camera.center - points[drawn]
        towards /= np.maximum(np.linalg.norm(towards, axis=1, keepdims=True), 1e-12)
        cosine = np.abs(np.einsum("ni,nki->nk", towards, normals[drawn])).max(axis=1)
        drawing[drawn] += 1
        grazing[drawn] += cosine < max_cosine
    has_normal = (np.linalg.norm(normals, axis=2) > 0).all(axis=1)
    return np.where(has_normal & (drawing > 0), grazing / np.maximum(drawing, 1), 0.0)


def contour_mask(points: np.ndarray, surface: HullSurface, detector: str, max_cosine: float,
                 max_share: float, probe: float = 0.0) -> np.ndarray | None:
    """Keep the points (N, 3) of which at most `max_share` of the drawing views see them at
    grazing incidence on the visual hull `surface` (`grazing_shares`); None when the scene has no
    masks."""
    if surface.grid is None:
        return None
    if len(points) == 0:
        return np.ones(0, bool)
    normals = surface.normals(points, probe)
    return grazing_shares(points, normals, surface.scene, detector, max_cosine) <= max_share
