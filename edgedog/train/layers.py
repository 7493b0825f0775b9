"""Multi-granularity layers (the paper's Sec. 4.5, after LapisGS): each layer adds primitives
fitted to finer pseudo edges while the layers below stay fixed (or are fine-tuned slowly).

The trainer of layer k is given `LowerLayers`: the primitives of layers 0 .. k-1, each with its
layer index, rendered in front of its own. Layer k starts from the residual: the points of the
usual initialisation that land on edges of its maps which the layers below do not render.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import torch

from edgedog.init.points import InitialPoints
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import Primitives, RasterCamera
from edgedog.renderer.rasterize import rasterize
from edgedog.scenes.camera import Camera
from edgedog.train.config import TrainConfig
from edgedog.train.model import GROUPS, EdgeModel
from edgedog.train.strategy import edge_hit_share

_SHAPES = {"means": (3,), "log_scales": (3,), "quats": (4,), "opacity_logits": (), "k_raw": (2,)}


def layer_name(index: int) -> str:
    """Display and folder name of layer `index`: 'L0', 'L1', ..."""
    return f"L{index}"


@dataclass
class LowerLayers:
    """The primitives of the layers below the one being trained.

    Attributes:
        model: their raw parameters, M primitives (they require gradients only when fine-tuned).
        layers: (M,) int64 layer index of each primitive, on the host.
    """

    model: EdgeModel
    layers: torch.Tensor

    @classmethod
    def empty(cls) -> LowerLayers:
        model = EdgeModel(**{name: torch.zeros((0, *shape)) for name, shape in _SHAPES.items()})
        return cls(model, torch.zeros(0, dtype=torch.long))

    def __len__(self) -> int:
        return len(self.layers)

    def stacked_with(self, top: EdgeModel) -> Primitives:
        """These layers' primitives followed by `top`'s: N = M + len(top), for one render."""
        if not len(self):
            return top.primitives()
        low, high = self.model.primitives(), top.primitives()
        return Primitives(*(torch.cat([getattr(low, f.name), getattr(high, f.name)])
                            for f in dataclasses.fields(Primitives)))

    def plus(self, top: EdgeModel, layer: int) -> LowerLayers:
        """These layers and `top` as layer `layer` (detached copies): the next layer's lower layers."""
        tensors = {name: torch.cat([getattr(self.model, name).detach(), getattr(top, name).detach()])
                   for name in GROUPS}
        layers = torch.cat([self.layers, torch.full((len(top),), layer, dtype=torch.long)])
        return LowerLayers(EdgeModel(**tensors), layers)

    def below(self, count: int) -> LowerLayers:
        """The primitives of layers 0 .. count - 1 only."""
        keep = self.layers < count
        rows = keep.to(self.model.device)
        tensors = {name: getattr(self.model, name).detach()[rows] for name in GROUPS}
        return LowerLayers(EdgeModel(**tensors), self.layers[keep])

    def to(self, device: torch.device) -> LowerLayers:
        """These layers with their parameters on `device` (the layer indices stay on the host)."""
        return LowerLayers(self.model.to(device), self.layers)

    def to_numpy(self) -> dict[str, np.ndarray]:
        return {**self.model.to_numpy(), "layers": self.layers.numpy().copy()}

    @classmethod
    def from_numpy(cls, arrays: dict[str, np.ndarray]) -> LowerLayers:
        return cls(EdgeModel.from_numpy(arrays), torch.from_numpy(np.asarray(arrays["layers"], np.int64)))


def lower_layer_config(config: TrainConfig) -> TrainConfig:
    """The schedule of the lower layers while a layer above trains: every learning rate scaled
    by `layers.lower_lr_scale` (fine-tuning at a low rate)."""
    s, rates = config.layers.lower_lr_scale, config.schedule
    schedule = dataclasses.replace(rates, lr_means=rates.lr_means * s, lr_scales=rates.lr_scales * s,
                                   lr_opacity=rates.lr_opacity * s, lr_quats=rates.lr_quats * s,
                                   lr_k=rates.lr_k * s)
    return dataclasses.replace(config, schedule=schedule)


def residual_maps(lower: LowerLayers, cameras: list[RasterCamera], targets: list[torch.Tensor],
                  raster: RasterConfig) -> list[torch.Tensor]:
    """(H, W) per view: the part of the target map the lower layers do not render,
    max(0, target - render)."""
    with torch.no_grad():
        return [(target - rasterize(lower.model.primitives(), camera, raster).image[..., 0]).clamp_min(0)
                for camera, target in zip(cameras, targets)]


def keep_on_residual(points: InitialPoints, pinholes: list[Camera], residuals: list[torch.Tensor],
                     threshold: float, min_share: float) -> InitialPoints:
    """The initial points that land on residual edges (>= threshold) in at least `min_share` of
    the views that see them. When none does (the layers below already explain the maps), the
    best 1 % are kept so that the layer can still grow where the residual is largest."""
    masks = [residual >= threshold for residual in residuals]
    share = edge_hit_share(points.positions, pinholes, masks).cpu().numpy()
    keep = share >= min_share
    reason = "on residual edges"
    if not keep.any():
        keep = np.zeros(len(points), dtype=bool)
        keep[np.argsort(-share, kind="stable")[:max(1, len(points) // 100)]] = True
        reason = "no point on residual edges: kept the best 1 %"
    report = {**points.report, "residual_filter": {"threshold": threshold, "min_share": min_share,
                                                   "candidates": len(points), "kept": int(keep.sum()),
                                                   "reason": reason}}
    return InitialPoints(points.positions[keep], points.scales[keep], points.method, report)
