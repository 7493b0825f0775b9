"""The 2D inspectors of one training view, computed from a snapshot (never from live tensors).

Side by side: the image, the pseudo-edge map, the current render of the training rasterizer,
its depth, the pixel uncertainty U (normalised Sobel magnitude of that depth) and the loss
weight w(U), exactly as `Trainer.step` computes them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch
from edgedog.app.colors import colormap, with_alpha
from edgedog.app.state import WEIGHTING_FORMULAS
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import Primitives, RasterCamera
from edgedog.renderer.rasterize import fisher_information, rasterize

from edgedog.edges.cache import attach_edge_maps
from edgedog.scenes import Scene
from edgedog.scenes.camera import Camera
from edgedog.train import losses
from edgedog.train.view_opacity import camera_centres, largest_logits, seen_from

NAMES = ("image", "edge map", "render", "depth", "U", "w")
"""The inspectors, in the order they are shown (w is labelled with its formula, e.g. w = exp(-U))."""


@dataclass(frozen=True)
class Inspector:
    """One panel: `rgba` (H, W, 4) uint8; `cmap`, `lo`, `hi`: its colour bar (cmap None: no bar);
    `values`: (H, W) the scalar map it shows (None: a colour image, read from `rgba`)."""

    name: str
    rgba: np.ndarray
    cmap: str | None = None
    lo: float = 0.0
    hi: float = 1.0
    note: str = ""
    values: np.ndarray | None = None

    @property
    def slot(self) -> str:
        """Its entry of NAMES (the name without w's formula)."""
        return self.name.split(" = ")[0]

    def readout(self, x: int, y: int) -> str:
        """What pixel (x, y) holds: the map's value, or the image's R G B."""
        if self.values is None:
            return "RGB {} {} {}".format(*self.rgba[y, x, :3])
        return f"value {float(self.values[y, x]):.4g}"


def snapshot_primitives(snapshot) -> Primitives:
    """The rasterizer's raw parameters of a snapshot (which holds activated ones)."""
    raw = snapshot.primitives.raw()  # copies (torch.tensor) keep the snapshot untouched
    return Primitives(**{name: torch.tensor(np.asarray(values, np.float32)) for name, values in raw.items()},
                      colors=torch.ones(len(snapshot.means), 1))


@dataclass(frozen=True)
class FisherScores:
    """The Fisher scores of one snapshot: its publication `key` (run, version), its `step`, and
    (N,) `scores` (`fisher_scores`)."""

    key: tuple[int, int]
    step: int
    scores: np.ndarray

    def matching(self, run: int, count: int) -> np.ndarray | None:
        """The scores, for a snapshot of run `run` with `count` primitives: those of the same run
        and count (a snapshot taken since, with no density event in between), else None."""
        return self.scores if self.key[0] == run and len(self.scores) == count else None


def fisher_scores(snapshot, cameras: Sequence[Camera], raster: RasterConfig) -> np.ndarray:
    """(N,) each primitive's Fisher information over the training `cameras`, the score the
    primitive-level pruning ranks by (renderer.rasterize.fisher_information): low is uncertain.

    With a view-dependent opacity every view sees its own opacities, as in the pruning; the
    snapshot holds each primitive's largest, from which the base logit a is recovered.
    """
    if not len(snapshot.means):
        return np.zeros(0, np.float32)
    primitives = snapshot_primitives(snapshot)
    views = [RasterCamera.from_camera(camera) for camera in cameras]
    with torch.no_grad():
        if snapshot.opacity_dirs is None:
            return fisher_information(primitives, views, raster).numpy()
        dirs = torch.tensor(np.asarray(snapshot.opacity_dirs, np.float32))
        centres = camera_centres(views, torch.device("cpu"))
        largest = largest_logits(torch.zeros(len(dirs)), dirs, primitives.means, centres)
        base = dataclasses.replace(primitives, opacity_logits=primitives.opacity_logits - largest)
        return sum(fisher_information(seen_from(base, dirs, centre), [view], raster)
                   for view, centre in zip(views, centres)).numpy()


def _scalar(name: str, values: np.ndarray, cmap: str, lo: float | None = None, hi: float | None = None,
            note: str = "") -> Inspector:
    lo = float(np.nanmin(values)) if lo is None else lo
    hi = float(np.nanmax(values)) if hi is None else hi
    return Inspector(name, with_alpha(colormap(values, lo, hi, cmap)), cmap, lo, hi, note, values)


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
