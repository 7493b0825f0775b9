"""The visual hull of a scene's masks: the cells of a grid whose centres every view's mask holds.

Training hides primitives behind it (`model.occlusion`, edgedog.train.occlusion) and extraction
takes the object's surface normals from it (`extract.filter_contours`, edgedog.curves.contours).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from edgedog.errors import InputError
from edgedog.scenes.camera import Camera
from edgedog.scenes.scene import Scene

if TYPE_CHECKING:  # torch is imported where a hull is carved, so that `import edgedog` stays light
    import torch

MAX_HULL_CELLS = 192
"""The visual hull's grid: 192^3 cells are 7 million, and the contour test's signed distance of
them is carved in float64 distance transforms (about 110 MB while it is made)."""


@dataclass(frozen=True)
class HullGrid:
    """The visual hull on a grid over an axis-aligned cube.

    Attributes:
        occupied: (R, R, R) bool, indexed [x, y, z]: the cell's centre is inside every mask.
        origin: (3,) float64 the cube's lowest corner, world units.
        cell: a cell's side, world units.
    """

    occupied: torch.Tensor
    origin: np.ndarray
    cell: float

    @property
    def resolution(self) -> int:
        return int(self.occupied.shape[0])

    def index(self, points: torch.Tensor) -> torch.Tensor:
        """(..., 3) int64 [x, y, z] of the cell each point (..., 3) (float64) lies in, outside
        [0, R) for a point outside the cube."""
        return ((points - points.new_tensor(self.origin)) / self.cell).floor().long()

    def lookup(self, points: torch.Tensor) -> torch.Tensor:
        """(...) bool: whether each point (..., 3) (float64) lies in an occupied cell (False
        outside the cube)."""
        index = self.index(points)
        r = self.resolution
        inside = ((index >= 0) & (index < r)).all(dim=-1)
        flat = (index.clamp(0, r - 1) * index.new_tensor([r * r, r, 1])).sum(-1)
        return inside & self.occupied.reshape(-1)[flat]


def widened(mask: np.ndarray) -> np.ndarray:
    """(H, W) bool `mask` grown by one pixel (3 x 3): a mask's anti-aliased border may fall on
    either side of the 0.5 coverage it is cut at."""
    return cv2.dilate(mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0


FIRST_BLOCKS = 8
"""Blocks per side of the coarsest level of `carve` (each a power of two cells)."""
NO_BLOCKS = np.zeros((0, 3), np.int64)
"""An empty (0, 3) list of blocks' first cells."""
CHILD_OFFSETS = np.array(list(np.ndindex(2, 2, 2)), np.int64)
"""(8, 3) a block's children's first cells, in halves of its side."""
ROUNDING_PX = 1.5
"""What rounding to pixels can add to a block's footprint: a cell's pixel is its projected
centre rounded (up to 0.71 px off), and so is the block's (sqrt(2) in all, with room to spare)."""


@dataclass(frozen=True)
class _ViewClearance:
    """One masked view as `carve` reads it: its grown mask (`held`, (H, W) bool) and, over the
    image with a ring of one pixel around it that holds (a cell projected off the image is not
    carved by it), each pixel's distance to the nearest pixel that carves (`to_carving`) and to
    the nearest that holds (`to_holding`), (H + 2, W + 2) float32. The distances are chessboard
    distances, never more than the Euclidean: a block is judged whole only when it surely is."""

    camera: Camera
    held: np.ndarray
    to_carving: np.ndarray
    to_holding: np.ndarray

    @classmethod
    def of(cls, camera: Camera, mask: np.ndarray) -> _ViewClearance:
        held = widened(mask)
        ring = np.pad(held, 1, constant_values=True).astype(np.uint8)
        if ring.all():  # no pixel carves: every distance is unbounded
            to_carving = np.full(ring.shape, np.inf, np.float32)
        else:
            to_carving = cv2.distanceTransform(ring, cv2.DIST_C, 3)
        to_holding = cv2.distanceTransform(1 - ring, cv2.DIST_C, 3)
        return cls(camera, held, to_carving, to_holding)

    def held_centres(self, centres: np.ndarray) -> np.ndarray:
        """(N,) bool: whether the view leaves each cell centre (N, 3): its pixel is in the grown
        mask, or it projects off the image or behind the camera (the view cannot tell)."""
        pixels, inside = self.camera.pixels(centres)
        held = np.ones(len(centres), bool)
        held[inside] = self.held[pixels[inside, 1], pixels[inside, 0]]
        return held

    def judge_blocks(self, centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For blocks whose cell centres lie within `radii` (N,) of their `centres` (N, 3): (N,)
        bool `carved` (every cell's pixel is on the image and off the grown mask) and `held`
        (`held_centres` holds every cell). A block neither carved nor held straddles the mask's
        border, or the camera's plane."""
        camera = self.camera
        uv, depth = camera.project(centres)
        in_front = depth - radii > 0
        # A point within r of a centre at depth Z and normalised image position n lands within
        # |K| r (1 + |n|) / (Z - r) pixels of the centre's image, and each pixel is a rounded
        # projection.
        normalised = (uv - camera.K[:2, 2]) @ np.linalg.inv(camera.K[:2, :2]).T
        footprint = np.linalg.norm(camera.K[:2, :2], 2) * radii * (1 + np.linalg.norm(normalised, axis=1)) / (
            np.maximum(depth - radii, 1e-12)) + ROUNDING_PX
        uv = np.where(in_front[:, None], uv, 0.0)
        height, width = self.to_carving.shape
        far = 2.0 * max(width, height)  # off the image either way; keeps the cast to int in range
        ringed = np.rint(uv.clip(-far, far)).astype(np.int64) + 1
        on_ringed = ((ringed >= 0) & (ringed < [width, height])).all(axis=1)
        x, y = ringed[:, 0].clip(0, width - 1), ringed[:, 1].clip(0, height - 1)
        carved = in_front & on_ringed & (self.to_holding[y, x] > footprint)
        reach = footprint[:, None]
        off_image = ((uv + reach < -0.5) | (uv - reach > [width - 2.5, height - 2.5])).any(axis=1)
        behind = depth + radii < 0
        held = behind | (in_front & ((on_ringed & (self.to_carving[y, x] > footprint)) | off_image))
        return carved, held

    def refine(self, blocks: dict[int, np.ndarray], origin: np.ndarray, cell: float,
               resolution: int) -> dict[int, np.ndarray]:
        """The blocks (size in cells -> (M, 3) int64 first cells) of a `resolution`^3 grid
        (`origin`, `cell`) that this view also holds, largest first: a block it straddles is
        split into its eight children (those on the grid), single cells are tested by centre."""
        blocks, kept, size = dict(blocks), {}, max(blocks)
        while size >= 1:
            starts = blocks.pop(size, NO_BLOCKS)
            extent = np.minimum(size, resolution - starts)  # cells of each block, clipped to the grid
            centres = origin + (starts + extent / 2) * cell
            if size == 1:
                kept[1] = starts[self.held_centres(centres)]
            else:
                carved, held = self.judge_blocks(centres, np.linalg.norm(extent - 1, axis=1) * cell / 2)
                kept[size] = starts[held]
                children = (starts[~carved & ~held, None, :] + size // 2 * CHILD_OFFSETS[None]).reshape(-1, 3)
                blocks[size // 2] = np.concatenate([blocks.get(size // 2, NO_BLOCKS),
                                                    children[(children < resolution).all(axis=1)]])
            size //= 2
        return kept


def carve(cameras: list[Camera], masks: list[np.ndarray | None], center: np.ndarray, side: float,
          resolution: int) -> HullGrid:
    """The visual hull of the (H, W) bool `masks` on a `resolution`^3 grid over the cube of edge
    `side` centred on `center` (3,): the cells whose centre's pixel every view's mask holds. A
    view without a mask (None) carves nothing; a cell that projects outside a view's image or
    behind its camera is not carved by that view (the view cannot tell). Each mask is grown by a
    pixel (`widened`).

    The cells are kept as blocks (cubes of 2^k cells a side) that every view so far holds; each
    view in turn drops the blocks that lie wholly off its mask, keeps those wholly within it, and
    splits those that straddle its border, down to single cells tested by their centres. The
    cells are the same as testing every centre in every view (tests/test_hull.py); the work
    follows the hull's surface, not its volume, and one view's distances are held at a time."""
    origin = np.asarray(center, np.float64) - side / 2
    cell = side / resolution
    size = 1 << max(0, int(np.ceil(np.log2(resolution / FIRST_BLOCKS))))
    steps = np.arange(0, resolution, size)
    blocks = {size: np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3)}
    for camera, mask in zip(cameras, masks):
        if mask is not None:
            blocks = _ViewClearance.of(camera, mask).refine(blocks, origin, cell, resolution)
    occupied = np.zeros((resolution,) * 3, bool)
    occupied[tuple(blocks.pop(1, NO_BLOCKS).T)] = True
    for size, starts in blocks.items():
        for x, y, z in starts:
            occupied[x:x + size, y:y + size, z:z + size] = True
    import torch  # here, not at the top: see TYPE_CHECKING above

    return HullGrid(torch.from_numpy(occupied), origin, cell)


def readable_mask(scene: Scene, index: int) -> np.ndarray | None:
    """(H, W) bool mask of view `index`, None when it has none or it cannot be read."""
    try:
        return scene.load_mask(index)
    except InputError:
        return None
