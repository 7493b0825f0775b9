"""The maps a run fits, as the config asks: floored, shifted by the detector's correction,
thinned; and the shift fitted with the primitives ('learned')."""

from __future__ import annotations

import numpy as np
import torch

from edgedog.edges.calibrate import load_calibration
from edgedog.edges.correct import shift_edge_map, warp_target
from edgedog.edges.registry import make_detector
from edgedog.edges.thin import thin_edge_map
from edgedog.errors import ConfigError
from edgedog.scenes import Scene
from edgedog.train.config import TrainConfig


def fixed_shift(config: TrainConfig, scene: Scene, maps_name: str, own_maps: bool) -> tuple[float, float]:
    """The shift (dx, dy) in px of the training resolution that 'shift' or 'calibrated' applies.

    A scene's own maps (`own_maps`) were made at its full resolution and are resized on load,
    so their offsets shrink with the downscale; maps computed by edgedog are made at the
    training resolution, where the detector's calibration holds as measured.
    """
    scale = scene.downscale if own_maps else 1
    if config.map_correction == "shift":
        return config.map_shift[0] / scale, config.map_shift[1] / scale
    if config.map_correction != "calibrated":
        return 0.0, 0.0
    detector = make_detector(maps_name)
    calibration = load_calibration(detector)
    if calibration is None:
        raise ConfigError(f"no calibration of detector {maps_name!r} ({detector.fingerprint}): run "
                          f"`edgedog calibrate-detector --detector {maps_name}` first")
    dx, dy = calibration.correction
    return dx / scale, dy / scale


def prepare_maps(maps: list[np.ndarray], config: TrainConfig, shift: tuple[float, float]
                 ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Targets and edge masks from (H, W) maps: values under `map_floor` zeroed, then the
    shift applied; the masks (map >= edge_threshold, for the sampled loss and the projection
    cull) come from those maps, and the 'thin' profile is drawn last, for the targets only."""
    if config.map_floor > 0:
        maps = [np.where(m >= config.map_floor, m, 0).astype(np.float32) for m in maps]
    if shift != (0.0, 0.0):
        maps = [shift_edge_map(m, *shift) for m in maps]
    masks = [m >= config.edge_threshold for m in maps]
    if config.edge_profile == "thin":
        maps = [thin_edge_map(m, config.thin_sigma) for m in maps]
    return maps, masks


class LearnedShift:
    """One 2D shift (px, the maps' convention) of every target, fitted by its own Adam with the
    primitives from `map_shift_from_epoch` on: a dataset's detector offset, estimated from the
    views' agreement (a 2D shift of every view is no 3D motion of the primitives)."""

    def __init__(self, config: TrainConfig):
        self.from_epoch = config.map_shift_from_epoch
        self.shift = torch.zeros(2, requires_grad=True)
        self.adam = torch.optim.Adam([self.shift], lr=config.lr_map_shift)

    def target(self, target: torch.Tensor, epoch: int) -> torch.Tensor:
        """(H, W) target as fitted at `epoch`: shifted (differentiably) once the shift is on."""
        return warp_target(target, self.shift) if epoch >= self.from_epoch else target

    def step(self) -> None:
        if self.shift.grad is not None and torch.isfinite(self.shift.grad).all():
            self.adam.step()

    def zero_grad(self) -> None:
        self.adam.zero_grad(set_to_none=True)

    def value(self) -> list[float]:
        return [float(v) for v in self.shift.detach()]

    def state_dict(self) -> dict:
        return {"shift": self.shift.detach().clone(), "adam": self.adam.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        with torch.no_grad():
            self.shift.copy_(state["shift"])
        self.adam.load_state_dict(state["adam"])
