"""The maps a run fits, as the config asks: floored, shifted by the detector's correction,
pulled onto the object's outline, thinned; and the shift fitted with the primitives ('learned')."""

from __future__ import annotations

import cv2
import numpy as np
import torch

from edgedog.edges.calibration import load_calibration
from edgedog.edges.correct import shift_edge_map, warp_target
from edgedog.edges.registry import make_detector
from edgedog.edges.silhouette import Outline, OutlinePull, distances_read, measure_silhouette_profile
from edgedog.edges.thin import thin_edge_map
from edgedog.errors import ConfigError, InputError
from edgedog.scenes import Scene
from edgedog.train.config import TrainConfig


def fixed_shift(config: TrainConfig, scene: Scene, maps_name: str, own_maps: bool) -> tuple[float, float]:
    """The shift (dx, dy) in px of the training resolution that 'shift' or 'calibrated' applies.

    A scene's own maps (`own_maps`) were made at its full resolution and are resized on load,
    so their offsets shrink with the downscale; maps computed by edgedog are made at the
    training resolution, where the detector's calibration holds as measured.
    """
    scale = scene.downscale if own_maps else 1
    if config.maps.correction == "shift":
        return config.maps.shift[0] / scale, config.maps.shift[1] / scale
    if config.maps.correction != "calibrated":
        return 0.0, 0.0
    detector = make_detector(maps_name)
    calibration = load_calibration(detector)
    if calibration is None:
        raise ConfigError(f"no calibration of detector {maps_name!r} ({detector.fingerprint}): run "
                          f"`edgedog calibrate-detector --detector {maps_name}` first")
    dx, dy = calibration.correction
    return dx / scale, dy / scale


def images_carry_alpha(scene: Scene) -> bool:
    """Whether the scene's masks come from its images' alpha (the first readable view decides)."""
    for index, view in enumerate(scene.views):
        if view.mask_path is not None:
            return False
        try:
            return scene.load_coverage(index) is not None
        except InputError:  # an unreadable image: ask the next view
            continue
    return False


def corrects_silhouettes(config: TrainConfig, scene: Scene) -> bool:
    """Whether the run pulls its maps onto the masks' outline (`maps.silhouette_correction`)."""
    if config.maps.silhouette_correction == "auto":
        return images_carry_alpha(scene)
    return config.maps.silhouette_correction == "measured"


def scene_outlines(scene: Scene, reach_px: float) -> tuple[list[Outline | None], list[str]]:
    """The object's outline in every view, from the scene's masks; None for a view whose mask or
    image cannot be read, named in the second list (its map then stays as it is).

    `reach_px`: the pull's `maps.silhouette_reach`; the distances are made only as far from
    the outline as the correction reads them.

    Raises:
        InputError when the scene has no masks (no mask files and no alpha).
    """
    outlines: list[Outline | None] = []
    unreadable: list[str] = []
    for index in range(len(scene)):
        try:
            coverage = scene.load_coverage(index)
        except InputError as error:
            outlines.append(None)
            unreadable.append(str(error))
            continue
        if coverage is None:
            raise InputError(scene.root, "silhouette_correction=measured needs object masks "
                                         "(mask files or RGBA images), and this scene has none")
        outlines.append(Outline.from_coverage(coverage, distances_read(reach_px)))
    return outlines, unreadable


def correct_silhouettes(maps: list[np.ndarray], masks: list[np.ndarray], outlines: list[Outline | None],
                        reach_px: float) -> tuple[list[np.ndarray], list[np.ndarray], dict]:
    """Measure where the (H, W) maps draw the outlines and pull the maps and their (H, W) bool
    edge masks onto them (views without an outline stay as they are); returns the maps, the
    masks and a report (measured offset in px, pixels averaged, residual offset after).

    The masks move with the maps but by nearest pixel: thresholding the interpolated maps
    instead lost the thin lines of low-resolution maps (at 200 px, two thirds of 00004926's
    DexiNed edge pixels, and the run collapsed in the projection cull)."""
    present = [i for i, outline in enumerate(outlines) if outline is not None]
    if not present:
        raise ConfigError("silhouette_correction=measured: no view has a readable mask")
    known = [outlines[i] for i in present]
    measured = measure_silhouette_profile([maps[i] for i in present], known)
    corrected, moved = list(maps), list(masks)
    for i in present:
        pull = OutlinePull.towards(outlines[i], measured.offset_px, reach_px)
        corrected[i], moved[i] = pull.apply(maps[i]), pull.apply(masks[i], nearest=True)
    residual = measure_silhouette_profile([corrected[i] for i in present], known)
    return corrected, moved, {"offset_px": round(measured.offset_px, 3), "pixels": measured.pixels,
                              "residual_px": round(residual.offset_px, 3)}


CONTRAST_WINDOW = 5
"""Side in pixels of the neighbourhood whose largest value normalises a map value
(`maps.contrast`): a thin edge's ridge and the two pixels of falloff on each side."""


def contrast_normalised(edge_map: np.ndarray, lowest: float) -> np.ndarray:
    """(H, W) float32: each value of the (H, W) map divided by the largest in its
    CONTRAST_WINDOW x CONTRAST_WINDOW neighbourhood, or by `lowest` where that is smaller, capped
    at 1. A faintly drawn edge's ridge reaches 1 as a strong edge's does; responses weaker than
    `lowest` (shading, noise) are lifted by at most 1 / `lowest`."""
    peaks = cv2.dilate(edge_map, np.ones((CONTRAST_WINDOW, CONTRAST_WINDOW), np.uint8))
    return np.minimum(1.0, edge_map / np.maximum(peaks, lowest)).astype(np.float32)


def prepare_maps(maps: list[np.ndarray], config: TrainConfig, shift: tuple[float, float],
                 outlines: list[Outline | None] | None = None
                 ) -> tuple[list[np.ndarray], list[np.ndarray], dict | None]:
    """Targets and edge masks from (H, W) maps: values under `maps.floor` zeroed, contrast
    normalised (`maps.contrast`, the targets only), the shift applied, then the silhouettes
    pulled onto the views' `outlines` when given (see `corrects_silhouettes`); the masks (map >=
    maps.edge_threshold, for the sampled loss and the projection cull) are taken before the
    contrast, the shift and the pull and moved with the maps by nearest pixel (interpolation dims
    thin lines below the threshold); the 'thin' profile is drawn last, for the targets only. The
    third value is the silhouette report (None when not corrected)."""
    if config.maps.floor > 0:
        maps = [np.where(m >= config.maps.floor, m, 0).astype(np.float32) for m in maps]
    masks = [m >= config.maps.edge_threshold for m in maps]
    if config.maps.contrast > 0:
        maps = [contrast_normalised(m, config.maps.contrast) for m in maps]
    if shift != (0.0, 0.0):
        maps = [shift_edge_map(m, *shift) for m in maps]
        masks = [shift_edge_map(k, *shift, nearest=True) for k in masks]
    silhouette = None
    if outlines is not None:
        maps, masks, silhouette = correct_silhouettes(maps, masks, outlines, config.maps.silhouette_reach)
    if config.maps.edge_profile == "thin":
        maps = [thin_edge_map(m, config.maps.thin_sigma) for m in maps]
    return maps, masks, silhouette


class LearnedShift:
    """One 2D shift (px, the maps' convention) of every target, fitted by its own Adam with the
    primitives from `maps.shift_from_epoch` on: a dataset's detector offset, estimated from the
    views' agreement (a 2D shift of every view is no 3D motion of the primitives)."""

    def __init__(self, config: TrainConfig, device: torch.device):
        self.from_epoch = config.maps.shift_from_epoch
        self.shift = torch.zeros(2, device=device, requires_grad=True)
        self.adam = torch.optim.Adam([self.shift], lr=config.maps.lr_shift)

    def target(self, target: torch.Tensor, epoch: int, factor: int = 1) -> torch.Tensor:
        """(H, W) target as fitted at `epoch`: shifted (differentiably) once the shift is on;
        `factor`: the target's downscale from the maps (the shift is in the maps' px)."""
        return warp_target(target, self.shift / factor) if epoch >= self.from_epoch else target

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
