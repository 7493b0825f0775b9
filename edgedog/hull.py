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
"""The visual hull's grid: 192^3 cells are 7 million centres projected into every view (170 MB
of coordinates while carving)."""


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


def carve(cameras: list[Camera], masks: list[np.ndarray | None], center: np.ndarray, side: float,
          resolution: int) -> HullGrid:
    """The visual hull of the (H, W) bool `masks` on a `resolution`^3 grid over the cube of edge
    `side` centred on `center` (3,). A view without a mask (None) carves nothing; a cell that
    projects outside a view's image or behind its camera is not carved by that view (the view
    cannot tell). Each mask is grown by a pixel (`widened`)."""
    origin = np.asarray(center, np.float64) - side / 2
    cell = side / resolution
    steps = (np.arange(resolution) + 0.5) * cell
    grid = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3) + origin
    keep = np.ones(len(grid), bool)
    for camera, mask in zip(cameras, masks):
        if mask is None:
            continue
        grown = widened(mask)
        pixels, inside = camera.pixels(grid[keep])
        held = np.ones(len(pixels), bool)
        held[inside] = grown[pixels[inside, 1], pixels[inside, 0]]
        keep[np.flatnonzero(keep)[~held]] = False
    import torch  # here, not at the top: see TYPE_CHECKING above

    occupied = torch.from_numpy(keep.reshape(resolution, resolution, resolution))
    return HullGrid(occupied, origin, cell)


def readable_mask(scene: Scene, index: int) -> np.ndarray | None:
    """(H, W) bool mask of view `index`, None when it has none or it cannot be read."""
    try:
        return scene.load_mask(index)
    except InputError:
        return None
