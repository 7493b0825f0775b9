"""The shading carve (edgedog.shaded_hull) on parts ray-cast from boxes under a fixed light: it
carves the notch of an L section that no silhouette shows and leaves the part itself; a convex
block loses nothing; the grey values' quantiles; and the training occlusion's depth sees into
the notch with it."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from edgedog.hull import carve
from edgedog.scenes.camera import Camera
from edgedog.shaded_hull import ShadedViews, seen_quantiles, shade_carve, surface_cells
from edgedog.synthetic.cameras import TARGET, orbit_cameras
from edgedog.train.occlusion import Occlusion, box_span

SIZE = 160
CELLS = 48
SIDE = 0.8
LIGHT = np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])
THICKNESS = 0.18
L_SECTION = [  # (low, high) corners: an L section in x-y, extruded along z
    (np.array([0.2, 0.2, 0.2]), np.array([0.8, 0.2 + THICKNESS, 0.8])),
    (np.array([0.2, 0.2, 0.2]), np.array([0.2 + THICKNESS, 0.8, 0.8])),
]
BLOCK = [(np.array([0.3, 0.3, 0.3]), np.array([0.7, 0.65, 0.6]))]


def side_cameras() -> list[Camera]:
    """Orbit cameras more than 35 degrees from the z axis: none looks along the L's extrusion,
    so no silhouette shows its notch."""
    return [c for c in orbit_cameras(60, SIZE) if abs(c.forward[2]) < np.cos(np.radians(35))]


def cast(camera: Camera, boxes: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) RGB of the union of `boxes` lit by LIGHT (ambient 0.15, diffuse 0.75) on a
    black background, and its (H, W) bool mask: each pixel centre's ray, nearest box face."""
    rows, cols = np.mgrid[0:camera.height, 0:camera.width]
    pixels = np.stack([cols.ravel(), rows.ravel()], axis=1).astype(np.float64)
    directions = camera.ray_directions(pixels)
    origins = np.broadcast_to(camera.center, directions.shape)
    nearest = np.full(len(pixels), np.inf)
    normals = np.zeros((len(pixels), 3))
    for low, high in boxes:
        entry, leave = box_span(origins, directions, low, high)
        hit = (entry < leave) & (entry < nearest)
        with np.errstate(divide="ignore", invalid="ignore"):
            a, b = (low - origins) / directions, (high - origins) / directions
        axis = np.argmax(np.minimum(a, b), axis=1)
        normal = np.zeros_like(normals)
        normal[np.arange(len(pixels)), axis] = -np.sign(directions[np.arange(len(pixels)), axis])
        nearest = np.where(hit, entry, nearest)
        normals[hit] = normal[hit]
    mask = np.isfinite(nearest)
    grey = np.where(mask, 0.15 + 0.75 * np.maximum(normals @ LIGHT, 0.0), 0.0)
    shape = (camera.height, camera.width)
    return np.repeat(grey.reshape(shape)[..., None], 3, axis=2).astype(np.float32), mask.reshape(shape)


def inside_depth(centres: np.ndarray, boxes: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """(N,) how deep each point (N, 3) lies inside the union of `boxes` (0 outside)."""
    depth = np.zeros(len(centres))
    for low, high in boxes:
        depth = np.maximum(depth, np.minimum(centres - low, high - centres).min(axis=1).clip(0))
    return depth


@pytest.fixture(scope="module")
def l_section():
    """The L section's cameras, images, masks, mask hull and shaded views (at full size)."""
    cameras = side_cameras()
    images, masks = zip(*(cast(camera, L_SECTION) for camera in cameras))
    hull = carve(cameras, list(masks), TARGET, SIDE, CELLS)
    return cameras, list(images), list(masks), hull, ShadedViews.of(cameras, list(images), list(masks), 1)


def cell_centres(grid, cells: np.ndarray) -> np.ndarray:
    return grid.origin + (cells + 0.5) * grid.cell


def notch_cells(grid, occupied: np.ndarray) -> np.ndarray:
    """(N, 3) occupied cells in the L's notch at least three cells from its walls."""
    cells = np.argwhere(occupied)
    centres = cell_centres(grid, cells)
    inner = 0.2 + THICKNESS + 3 * grid.cell
    along = (centres[:, 2] > 0.2) & (centres[:, 2] < 0.8)
    return cells[(centres[:, 0] > inner) & (centres[:, 1] > inner) & along]


def test_the_notch_is_carved_and_the_part_is_kept(l_section):
    _, _, _, hull, views = l_section
    before = notch_cells(hull, hull.occupied.numpy())
    assert len(before) > 1000  # no silhouette shows the notch: the masks' hull fills it
    carved, per_round = shade_carve(hull, views, tolerance=0.03, min_views=4)
    occupied = carved.occupied.numpy()
    assert per_round[-1] == 0 and len(per_round) > 3  # layer by layer until nothing changes
    left = notch_cells(hull, occupied)
    assert len(left) < 0.6 * len(before)  # about half: cells beside a wall read only that wall
    lost = np.argwhere(hull.occupied.numpy() & ~occupied)
    depth = inside_depth(cell_centres(hull, lost), L_SECTION)
    assert (depth > 1.5 * hull.cell).sum() == 0  # the part itself is kept but for its skin
    assert (depth > 0).mean() < 0.2


def test_a_convex_block_loses_at_most_its_skin():
    cameras = side_cameras()
    images, masks = zip(*(cast(camera, BLOCK) for camera in cameras))
    hull = carve(cameras, list(masks), TARGET, SIDE, CELLS)
    carved, _ = shade_carve(hull, ShadedViews.of(cameras, list(images), list(masks), 1), 0.03, 4)
    lost = np.argwhere(hull.occupied.numpy() & ~carved.occupied.numpy())
    assert (inside_depth(cell_centres(hull, lost), BLOCK) > 1.5 * hull.cell).sum() == 0
    assert len(lost) < 0.02 * hull.occupied.sum()


def test_no_view_wholly_on_the_object_carves_nothing(l_section):
    cameras, images, masks, hull, _ = l_section
    empty = [np.zeros_like(mask) for mask in masks]
    carved, per_round = shade_carve(hull, ShadedViews.of(cameras, images, empty, 1), 0.03, 4)
    assert per_round == [0]
    assert torch.equal(carved.occupied, hull.occupied)


def test_surface_cells_of_a_cube():
    occupied = np.zeros((6, 6, 6), bool)
    occupied[1:5, 1:5, 1:5] = True
    assert len(surface_cells(occupied)) == 4 ** 3 - 2 ** 3
    assert len(surface_cells(np.ones((3, 3, 3), bool))) == 26  # the grid's boundary is exposed


def test_seen_quantiles_take_the_nearest_reading_inwards():
    values = torch.tensor([[0.1, 0.5, 0.3], [0.9, 0.2, torch.inf], [0.4, torch.inf, torch.inf],
                           [0.2, torch.inf, torch.inf], [0.6, torch.inf, torch.inf],
                           [torch.inf] * 3])
    low, high = seen_quantiles(values, torch.tensor([5, 2, 1]))
    # five readings 0.1 0.2 0.4 0.6 0.9: the 20 % quantile is the second, 80 % the fourth
    assert low.tolist() == pytest.approx([0.2, 0.2, 0.3])
    assert high.tolist() == pytest.approx([0.6, 0.5, 0.3])


def test_the_occlusion_depth_sees_into_the_notch(l_section):
    cameras, _, masks, _, views = l_section
    args = (cameras, masks, TARGET, SIDE, CELLS, 3.0, 4, 1, torch.device("cpu"))
    plain = Occlusion.from_masks(*args)
    shaded = Occlusion.from_masks(*args, shaded=views, shading_tolerance=0.03)
    assert shaded.report["shading_carved"] > 0
    # the view looking most squarely into the notch (from +x +y) sees deeper with the shading
    into = int(np.argmax([c.forward @ -np.array([1.0, 1.0, 0.0]) for c in cameras]))
    finite = torch.isfinite(plain.depths[into])
    assert (shaded.depths[into][finite] >= plain.depths[into][finite]).all()
    deeper = shaded.depths[into][finite] > plain.depths[into][finite] + 2 * plain.hull.cell
    assert deeper.float().mean() > 0.05
    assert torch.equal(shaded.clearance, plain.clearance)  # the masks' hull still bounds the primitives
