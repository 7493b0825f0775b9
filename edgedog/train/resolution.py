"""The training views at one resolution (what a step renders and compares, what density control
projects onto), and their coarser copy for a coarse-to-fine schedule.

Early epochs only have to bring the primitives near their edges; at 1/2 resolution a step costs
about a quarter of the pixels. `schedule.coarse_downscale` and `schedule.fine_from_epoch` say how
coarse and until when; from `fine_from_epoch` on every step renders the maps' own resolution.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from edgedog.renderer.primitives import RasterCamera
from edgedog.scenes.camera import Camera
from edgedog.scenes.images import resize_to
from edgedog.train.losses import edge_pixels


@dataclass(frozen=True)
class ViewSet:
    """The training views at one resolution.

    Attributes:
        factor: the resolution's downscale from the training maps (1: the maps' own).
        pinholes: the cameras as `edgedog.scenes.Camera` (for projecting centres).
        cameras: the same cameras as the rasterizer takes them (renders, Fisher information).
        targets: (H, W) float32 maps to fit.
        edge_masks: (H, W) bool edge pixels (the sampled loss's edges, the projection cull).
        edge_pixels: (E,) int32 sorted flat indices of each mask's edge pixels (the sampled loss
            draws around them at its sampled steps; found once here).
    """

    factor: int
    pinholes: list[Camera]
    cameras: list[RasterCamera]
    targets: list[torch.Tensor]
    edge_masks: list[torch.Tensor]
    edge_pixels: list[torch.Tensor] = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "edge_pixels", [edge_pixels(mask) for mask in self.edge_masks])

    def to(self, device: torch.device) -> ViewSet:
        """These views with their maps and masks on `device` (the cameras stay on the host); these
        very views when they are there."""
        if all(t.device == device for t in (*self.targets, *self.edge_masks)):
            return self
        return ViewSet(self.factor, self.pinholes, self.cameras, [t.to(device) for t in self.targets],
                       [m.to(device) for m in self.edge_masks])


def coarse_size(width: int, height: int, factor: int) -> tuple[int, int]:
    """(width, height) of a `width` x `height` view at 1/factor (at least 1 px each way)."""
    return max(1, width // factor), max(1, height // factor)


def any_in_block(mask: np.ndarray, width: int, height: int) -> np.ndarray:
    """(height, width) bool: a coarse pixel is an edge where any fine pixel of its block is (an
    area average would dim a 1 px line below the edge threshold). The fine (H, W) mask is cropped
    to a multiple of the coarse size."""
    fy, fx = mask.shape[0] // height, mask.shape[1] // width
    blocks = mask[:height * fy, :width * fx].reshape(height, fy, width, fx)
    return blocks.any(axis=(1, 3))


def coarser(fine: ViewSet, factor: int) -> ViewSet:
    """`fine` at 1/factor of its resolution: targets area-averaged (as `maps.downscale` loads
    maps), masks by `any_in_block`, cameras scaled about the image corner.

    Args:
        fine: the views at the training maps' resolution (factor 1).
        factor: the downscale, >= 1 (1 returns `fine`).
    """
    if factor == 1:
        return fine
    pinholes, cameras, targets, masks = [], [], [], []
    for pinhole, camera, target, mask in zip(fine.pinholes, fine.cameras, fine.targets, fine.edge_masks):
        width, height = coarse_size(pinhole.width, pinhole.height, factor)
        pinholes.append(pinhole.scaled(width, height))
        cameras.append(RasterCamera.from_camera(pinholes[-1], near=camera.near))
        targets.append(torch.from_numpy(np.ascontiguousarray(resize_to(target.numpy(), width, height))))
        masks.append(torch.from_numpy(any_in_block(mask.numpy(), width, height)))
    return ViewSet(factor, pinholes, cameras, targets, masks)
