"""Typed training configuration, its presets, and `--set key=value` overrides."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

from edgedog.errors import ConfigError

Weighting = Literal["one", "exp_neg", "one_minus", "up", "exp"]


@dataclass(frozen=True)
class TrainConfig:
    """Every setting of a run. Defaults are the paper preset for ABC (EdgeGaussians' schedule).

    Epochs count passes over the views, one view per step, in a seeded random order.
    """

    # --- data and initialisation
    detector: str = "auto"
    """Pseudo-edge maps to fit: a scene's own maps by name (e.g. 'pidinet'), or a detector name."""
    downscale: int = 1
    """Train at 1/downscale resolution."""
    init_method: str = "auto"
    """'auto' | 'triangulate' | 'sfm-points' | 'uniform' (see edgedog.init)."""
    init_count: int = 10000
    """Points of the uniform initialisation (EdgeGaussians start from 2500; with w = exp(-Up) the
    rims that are also depth jumps need the denser start: docs/BENCHMARKS.md)."""
    init_side: float | None = 1.1
    """Edge of the uniform cube (EdgeGaussians: 1.1 around the object for ABC); None: the bounds."""
    init_opacity: float = 0.08
    """Initial opacity of every primitive."""
    k_init: tuple[float, float] = (0.0, 0.0)
    """Raw DoG shape k at initialisation (the paper's 0)."""

    # --- rasterizer
    kernel: Literal["dog", "gaussian"] = "dog"
    """'dog' (EdgeDoG) or 'gaussian' (the EdgeGaussians baseline)."""
    k_activation: Literal["sigmoid", "exp"] = "sigmoid"
    """Activation of k: 'sigmoid' for ABC, 'exp' for other data (docs/METHOD.md)."""

    # --- schedule
    epochs: int = 400
    lr_means: float = 2e-3
    lr_means_decay_epochs: tuple[int, ...] = (10, 20, 30, 40, 50)
    lr_means_decay: float = 0.75
    lr_scales: float = 1e-4
    scales_from_epoch: int = 30
    lr_opacity: float = 0.03
    opacity_from_epoch: int = 20
    lr_quats: float = 1e-3
    quats_from_epoch: int = 30
    lr_k: float = 1e-4

    map_floor: float = 0.0
    """Map values below this are set to zero: a coarse layer keeps only the strong edges."""
    map_correction: Literal["none", "calibrated", "shift", "learned"] = "none"
    """Correct the maps' sub-pixel offset: 'calibrated' shifts them by the correction of their
    detector's record (`edgedog calibrate-detector`); 'shift' by `map_shift`; 'learned' fits
    one 2D shift of all maps jointly with the primitives, from `map_shift_from_epoch` on."""
    map_shift: tuple[float, float] = (0.0, 0.0)
    """The shift of 'shift' in px of the maps as stored (x right, y down: content moves by it)."""
    map_shift_from_epoch: int = 100
    """'learned': the shift is fitted once the primitives have settled (from this epoch)."""
    lr_map_shift: float = 0.002
    """'learned': Adam's learning rate of the shift, px per step."""
    silhouette_correction: Literal["auto", "measured", "none"] = "auto"
    """'measured': measure where the maps draw the object's outline against the scene's masks
    (alpha or mask files) and pull them onto it (edgedog.edges.silhouette). Maps made from
    RGBA images with the alpha dropped draw it 1-1.5 px outside, and the model grows outwards.
    'auto': 'measured' when the images carry an alpha channel (a render's exact outline), else
    'none' (hand-drawn mask files of photos are not exact enough to correct maps with)."""
    silhouette_reach: float = 3.0
    """'measured': px from the outline within which the full correction applies (fading to 0 at
    twice this)."""
    edge_profile: Literal["auto", "raw", "thin", "profile"] = "auto"
    """'auto': 'profile' for DexiNed maps, 'raw' for others (see `for_detector`); 'raw': fit the
    maps as they are; 'thin': fit their ridge drawn with a narrow Gaussian
    profile (edgedog.edges.thin), which removes the bias of thick, asymmetric detector bands;
    'profile': fit the render blurred by `profile_sigma` (the band's measured width) to the maps,
    so that thin primitives explain a thick band."""
    thin_sigma: float = 0.7
    """Width (px, standard deviation) of the 'thin' profile."""
    profile_sigma: float = 1.0
    """'profile': standard deviation (px at the training resolution) of the render's blur."""

    # --- losses
    edge_threshold: float = 0.5
    """Edge pixels of a map are those >= this value."""
    sampled_loss_from_epoch: int = 50
    """After this epoch, every `sampled_loss_every` steps the L1 is taken on the edge pixels plus
    as many random background pixels instead of the whole image."""
    sampled_loss_every: int = 5
    direction_from_epoch: int = 250
    ratio_from_epoch: int = 100
    orientation_every: int = 5
    """The direction and scale-ratio losses are applied every this many steps."""
    direction_neighbours: int = 5
    direction_factor: float | None = None
    """Direction loss weight: the term is scaled to this fraction of the running sum of the epoch's
    projection losses, as EdgeGaussians does; None: theirs for the maps' detector (0.01 for
    DexiNed maps, 0.1 for others: `for_detector`)."""
    ratio_factor: float | None = None
    """Scale-ratio loss weight, scaled like `direction_factor`; None: 0.01 for DexiNed maps, 0.05
    for others."""

    # --- EdgeDoG's uncertainties
    pixel_uncertainty: bool = True
    """Weight the L1 per pixel by w(Up), Up = normalised Sobel magnitude of the rendered depth."""
    weighting: Weighting = "exp_neg"
    """w(Up): 'one' 1, 'exp_neg' exp(-Up), 'one_minus' 1 - Up, 'up' Up, 'exp' exp(Up). The paper
    chose exp(Up); measured here, exp(Up) fits the occluding contours of curved surfaces (where the
    rendered depth jumps) and exp(-Up) scores higher (docs/BENCHMARKS.md, "the weighting of the
    pixel uncertainty")."""
    primitive_uncertainty: bool = True
    """Every `fisher_every` epochs keep the `keep_ratio` best primitives by Fisher information."""
    fisher_every: int = 50
    keep_ratio: float = 0.9
    """The pruning ratio p: the fraction of primitives kept at each Fisher pruning."""

    # --- density control (EdgeGaussians, PiDiNet settings)
    duplicate_epochs: tuple[int, ...] = (40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140, 150, 160,
                                         210, 220, 350, 375)
    duplicate_threshold: float = 0.5
    """Duplicate primitives whose min-max normalised accumulated absgrad norm (the per-pixel
    |dL/dmean2d| summed over pixels and steps, as gsplat's absgrad) exceeds this."""
    duplicate_copies: int = 2
    duplicate_noise: float = 0.05
    """Standard deviation of the noise added to the copies' means (scene units)."""
    cull_opacity_epochs: tuple[int, ...] = (125, 310)
    cull_opacity_below: float = 0.05
    cull_projection_epochs: tuple[int, ...] = (145, 175, 190)
    cull_projection_below: float = 0.1
    """Cull primitives whose centre lands on edge pixels in fewer than this share of the views
    that see it."""
    opacity_logit_cap: float = 0.08
    """After each cull the opacity logits are clamped to at most this (EdgeGaussians)."""
    max_primitives: int = 200_000
    """Duplication never grows the model beyond this."""

    # --- multi-granularity layers (edgedog.train.layers)
    layer: int = 0
    """Index of the layer this run adds; the layers below it are given to the trainer, fixed."""
    lower_lr_scale: float = 0.0
    """Fine-tune the layers below at this fraction of the learning rates (0: frozen)."""
    residual_min_share: float = 0.1
    """Above layer 0, initial points are kept where they land on the residual edges (the map
    minus the render of the layers below, >= edge_threshold) in at least this share of the
    views that see them."""

    # --- run
    seed: int = 0
    checkpoint_every: int = 50
    """Epochs between checkpoints (one is always written at the end)."""
    snapshot_every: int = 25
    """Steps between the snapshots published to a viewer."""

    def __post_init__(self):
        if not 0 < self.keep_ratio <= 1:
            raise ConfigError(f"keep_ratio must be in (0, 1], got {self.keep_ratio}")
        if self.weighting not in ("one", "exp_neg", "one_minus", "up", "exp"):
            raise ConfigError(f"weighting must be one, exp_neg, one_minus, up or exp, got {self.weighting!r}")
        if self.kernel not in ("dog", "gaussian"):
            raise ConfigError(f"kernel must be dog or gaussian, got {self.kernel!r}")
        if self.edge_profile not in ("auto", "raw", "thin", "profile"):
            raise ConfigError(f"edge_profile must be auto, raw, thin or profile, got {self.edge_profile!r}")
        if self.map_correction not in ("none", "calibrated", "shift", "learned"):
            raise ConfigError(f"map_correction must be none, calibrated, shift or learned, "
                              f"got {self.map_correction!r}")
        if self.silhouette_correction not in ("auto", "measured", "none"):
            raise ConfigError(f"silhouette_correction must be auto, measured or none, "
                              f"got {self.silhouette_correction!r}")
        if self.silhouette_reach <= 0:
            raise ConfigError("silhouette_reach must be positive")
        if self.profile_sigma <= 0 or len(self.map_shift) != 2:
            raise ConfigError("profile_sigma must be positive and map_shift two numbers (dx, dy)")
        if self.layer < 0 or self.lower_lr_scale < 0:
            raise ConfigError("layer and lower_lr_scale must not be negative")
        if self.epochs < 1 or self.downscale < 1:
            raise ConfigError("epochs and downscale must be positive")


DETECTOR_SETTINGS = {
    "dexined": {"direction_factor": 0.01, "ratio_factor": 0.01, "edge_profile": "profile"},
}
"""The settings a detector's maps need where they differ from `OTHER_MAPS`. DexiNed: EdgeGaussians'
factors for its maps, and the profile loss, which fits its thick bands with thin primitives (on ABC
00004926, paper preset: Comp 9.6 -> 5.1 mm, F10 94.9 -> 97.7; docs/BENCHMARKS.md)."""
OTHER_MAPS = {"direction_factor": 0.1, "ratio_factor": 0.05, "edge_profile": "raw"}
"""EdgeGaussians' settings for PiDiNet maps, used for every detector not in DETECTOR_SETTINGS."""


def for_detector(config: TrainConfig, detector: str) -> TrainConfig:
    """The config with its detector-dependent settings left open (None, or 'auto') set for the
    maps of `detector` (a name as the scene or registry gives it, any case)."""
    tuned = DETECTOR_SETTINGS.get(detector.lower(), OTHER_MAPS)
    return dataclasses.replace(config, **{key: tuned[key] for key in OTHER_MAPS
                                          if getattr(config, key) in (None, "auto")})


def _scale_epochs(config: TrainConfig, factor: float) -> dict:
    """Every epoch-valued setting multiplied by `factor` (a shorter run keeps the same shape)."""
    def scale(e: int) -> int:
        return max(1, round(e * factor))

    changes = {}
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if f.name.endswith("_epochs") and isinstance(value, tuple):
            changes[f.name] = tuple(sorted({scale(e) for e in value}))
        elif f.name.endswith("_from_epoch") or f.name in ("epochs", "fisher_every", "checkpoint_every"):
            changes[f.name] = scale(value)
    return changes


def with_epochs(config: TrainConfig, epochs: int) -> TrainConfig:
    """The config's whole schedule (decays, starts, density-control events, Fisher period,
    checkpoints) stretched or compressed to `epochs`."""
    if epochs < 1:
        raise ConfigError(f"epochs must be positive, got {epochs}")
    if epochs == config.epochs:
        return config
    return dataclasses.replace(config, **{**_scale_epochs(config, epochs / config.epochs), "epochs": epochs})


PRESETS = ("paper", "fast", "preview")
"""The named starting configurations, slowest first (see `preset`)."""


def preset(name: str) -> TrainConfig:
    """A named configuration.

    'paper': EdgeGaussians' 400 epochs at full resolution. 'fast': the same schedule compressed
    to 200 epochs, still at full resolution (at half resolution the 200 epochs cost ABC
    00000006 4 F10 points; docs/BENCHMARKS.md). 'preview': compressed to 100 epochs at half
    resolution, a quick look for the demo and the studio.
    """
    paper = TrainConfig()
    if name == "paper":
        return paper
    if name == "fast":
        return with_epochs(paper, 200)
    if name == "preview":
        return dataclasses.replace(with_epochs(paper, 100), downscale=2)
    raise ConfigError(f"unknown preset {name!r}; choose {', '.join(PRESETS)}")


def with_overrides(config: TrainConfig, assignments: list[str]) -> TrainConfig:
    """Apply `key=value` strings; values are parsed by the field's type."""
    fields = {f.name: f for f in dataclasses.fields(config)}
    changes = {}
    for assignment in assignments:
        key, sep, text = assignment.partition("=")
        if not sep or key not in fields:
            raise ConfigError(f"--set {assignment!r}: expected KEY=VALUE with KEY one of {', '.join(fields)}")
        current = getattr(config, key)
        try:
            if isinstance(current, bool):
                if text.lower() not in ("true", "false", "1", "0", "on", "off"):
                    raise ValueError(text)
                value = text.lower() in ("true", "1", "on")
            elif isinstance(current, tuple):
                items = [t for t in text.split(",") if t.strip()]
                kind = type(current[0]) if current else float
                value = tuple(kind(t) for t in items)
            elif current is None or isinstance(current, float):
                value = None if text.lower() == "none" else float(text)
            elif isinstance(current, int):
                value = int(text)
            else:
                value = text
        except ValueError:
            kind = type(current).__name__
            raise ConfigError(f"--set {assignment!r}: cannot read {text!r} as {kind}") from None
        changes[key] = value
    return dataclasses.replace(config, **changes)


def to_dict(config: TrainConfig) -> dict:
    return dataclasses.asdict(config)


def from_dict(values: dict) -> TrainConfig:
    fields = {f.name: f for f in dataclasses.fields(TrainConfig)}
    return TrainConfig(**{k: tuple(v) if isinstance(getattr(TrainConfig(), k), tuple) else v
                          for k, v in values.items() if k in fields})


__all__ = ["TrainConfig", "for_detector", "from_dict", "preset", "to_dict", "with_epochs", "with_overrides"]
