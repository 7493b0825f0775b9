"""The 2D inspectors of one training view, computed from a snapshot (never from live tensors).

Side by side: the image, the pseudo-edge map, the current render of the training rasterizer,
its depth, the pixel uncertainty U (normalised Sobel magnitude of that depth) and the loss
weight w(U), exactly as `Trainer.step` computes them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from edgedog.app.colors import colormap, with_alpha
from edgedog.app.state import WEIGHTING_FORMULAS
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import Primitives, RasterCamera
from edgedog.renderer.rasterize import rasterize

from edgedog.edges.cache import attach_edge_maps
from edgedog.scenes import Scene
from edgedog.train import losses

NAMES = ("image", "edge map", "render", "depth", "U", "w")
"""The inspectors, in the order they are shown (w is labelled with its formula, e.g. w = exp(-U))."""


@dataclass(frozen=True)
class Inspector:
    """One panel: `rgba` (H, W, 4) uint8; `cmap`, `lo`, `hi`: its colour bar (cmap None: no bar)."""

    name: str
    rgba: np.ndarray
    cmap: str | None = None
    lo: float = 0.0
    hi: float = 1.0
    note: str = ""


def snapshot_primitives(snapshot) -> Primitives:
    """The rasterizer's raw parameters of a snapshot (which holds activated ones)."""
    raw = snapshot.primitives.raw()  # copies (torch.tensor) keep the snapshot untouched
    return Primitives(**{name: torch.tensor(np.asarray(values, np.float32)) for name, values in raw.items()},
                      colors=torch.ones(len(snapshot.means), 1))


def _scalar(name: str, values: np.ndarray, cmap: str, lo: float | None = None, hi: float | None = None,
            note: str = "") -> Inspector:
    lo = float(np.nanmin(values)) if lo is None else lo
    hi = float(np.nanmax(values)) if hi is None else hi
    return Inspector(name, with_alpha(colormap(values, lo, hi, cmap)), cmap, lo, hi, note)


def inspect_view(snapshot, scene: Scene, view: int, detector: str | None, raster: RasterConfig,
                 weighting: str, pixel_uncertainty: bool) -> list[Inspector]:
    """The six inspectors of training view `view` for the primitives of `snapshot`; without a
    snapshot only the image and (when `detector` names one) the edge map."""
    image = np.clip(scene.load_image(view) * 255, 0, 255).round().astype(np.uint8)
    inputs = [Inspector(NAMES[0], with_alpha(image))]
    if detector is not None:
        # A resumed layered run trains one layer: the maps of those below were never loaded here.
        attach_edge_maps(scene, detector)
        inputs.append(_scalar(NAMES[1], scene.load_edge_map(view, detector), "gray", 0.0, 1.0))
    if snapshot is None:
        return inputs
    camera = RasterCamera.from_camera(scene.camera(view))
    with torch.no_grad():
        out = rasterize(snapshot_primitives(snapshot), camera, raster)
        up = losses.depth_uncertainty(out.depth)
        weight = losses.uncertainty_weight(up, weighting) if pixel_uncertainty else torch.ones_like(up)
    note = "" if pixel_uncertainty else "pixel uncertainty off"
    return inputs + [
        _scalar(NAMES[2], out.image[..., 0].numpy(), "gray", 0.0, 1.0),
        _scalar(NAMES[3], out.depth.numpy(), "viridis"),
        _scalar(NAMES[4], up.numpy(), "magma", 0.0, 1.0, note),
        _scalar(f"{NAMES[5]} = {WEIGHTING_FORMULAS[weighting]}", weight.numpy(), "magma", note=note),
    ]
