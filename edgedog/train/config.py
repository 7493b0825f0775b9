"""Typed training configuration, its presets, and `--set key=value` overrides.

Every setting's allowed values are written once, in its type: `Annotated[int, Range(1, 400)]`,
a `Literal` of its choices, `OneOf` a list kept elsewhere, or a `Check`. `check_setting` reads
them; `TrainConfig.__post_init__` checks every field with it (so presets, `--set`, and the
config.json of a run folder read by `from_dict` all are checked), and `with_overrides` parses a
`--set` value by the same type.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import numbers
import reprlib
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from edgedog.errors import ConfigError


@dataclass(frozen=True)
class Range:
    """The interval a number setting lies in: `low` and `high` included unless open; None: no bound."""

    low: float | None = None
    high: float | None = None
    open_low: bool = False
    open_high: bool = False

    def __contains__(self, value: float) -> bool:
        above = self.low is None or (value > self.low if self.open_low else value >= self.low)
        below = self.high is None or (value < self.high if self.open_high else value <= self.high)
        return above and below

    def __str__(self) -> str:
        """'>= 1', '> 0', '<= 5', 'in (0, 1]'."""
        low, high = _number(self.low), _number(self.high)
        if self.high is None:
            return f"{'>' if self.open_low else '>='} {low}"
        if self.low is None:
            return f"{'<' if self.open_high else '<='} {high}"
        return f"in {'(['[not self.open_low]}{low}, {high}{')]'[not self.open_high]}"


def _number(x: float | None) -> str:
    """An int as written, a float in its short form (32.0 -> '32', 1e-3 -> '0.001')."""
    return f"{x:g}" if isinstance(x, float) else str(x)


@dataclass(frozen=True)
class OneOf:
    """A string setting's choices, kept by the module that uses them: `choices()` gives them
    (imported when first checked, not when this module is)."""

    choices: Callable[[], Sequence[str]]


@dataclass(frozen=True)
class Check:
    """A test of a setting beyond its type and range: `test(value)` raises ConfigError naming
    the setting when the value cannot be used."""

    test: Callable[[Any], None]


def _init_methods() -> Sequence[str]:
    from edgedog.init import INIT_METHODS

    return INIT_METHODS


def _maps_name(name: str) -> None:
    """A detector's name must be one `make_detector` builds, with options it takes ('canny:5' is
    refused). Other names may be a scene's own maps (e.g. 'dexined'): the scene is checked when
    it is loaded."""
    from edgedog.edges.registry import is_detector_name

    if not name.strip():
        raise ConfigError(f"detector must name a detector or a scene's maps, got {_shown(name)}")
    is_detector_name(name)


# Bounds of the settings that size an allocation or a loop, or past which a value means nothing.
MAX_EPOCHS = 10_000
"""25 times the paper's 400; every epoch is one step per view."""
MAX_PRIMITIVES = 2_000_000
"""Ten times the paper's budget (max_primitives); each primitive costs about 0.3 KB with its Adam
moments and gradients, and every step renders all of them."""
MAX_DOWNSCALE = 16
"""An 800 px view becomes 50 px: coarser, the views hold no edges worth fitting."""
MAX_WIDTH_PX = 32.0
"""Widths and shifts in px: the measured bands and offsets are 1-3 px. The blur kernels grow
with their width (profile_sigma: 6 sigma + 1 taps, each a pass over the image per step); one
reaching 3 x 32 px to each side spans much of a view and merges its edges into one smear."""
MAX_NEIGHBOURS = 32
"""Each orientation step builds (N, k, 3) offsets; EdgeGaussians use 5."""
MAX_COPIES = 8
"""Copies of one primitive at one place: EdgeGaussians make 2; the copies share their source's
parameters, so many more add nothing but noise."""
MAX_LAYERS = 8
"""Multi-granularity levels (the paper uses 3); each trains a whole run."""
MAX_SEED = 2**32 - 1
"""Seeds are 32-bit integers, which torch's and numpy's generators all take."""
MAX_LOGIT = 20.0
"""Raw values that go through a sigmoid or exp: sigmoid(20) is 1 in float32, and exp overflows
past 88."""
MAX_RATE = 1.0
"""Adam moves a parameter by about its learning rate per step whatever the gradient: 1 scene unit
(or 1 px, 1 log-scale unit) per step is already far past any useful rate."""

Epoch = Annotated[int, Range(0, MAX_EPOCHS)]
"""An epoch (0-based) at which something starts or happens."""
Every = Annotated[int, Range(1)]
"""A period, in epochs or steps."""
Count = Annotated[int, Range(1, MAX_PRIMITIVES)]
"""A number of primitives."""
Share = Annotated[float, Range(0, 1)]
Rate = Annotated[float, Range(0, MAX_RATE)]
Logit = Annotated[float, Range(-MAX_LOGIT, MAX_LOGIT)]
Width = Annotated[float, Range(0, MAX_WIDTH_PX, open_low=True)]
Shift = Annotated[float, Range(-MAX_WIDTH_PX, MAX_WIDTH_PX)]

Weighting = Literal["one", "exp_neg", "one_minus", "up", "exp"]


@dataclass(frozen=True)
class TrainConfig:
    """Every setting of a run. Defaults are the paper preset for ABC (EdgeGaussians' schedule).

    Epochs count passes over the views, one view per step, in a seeded random order.
    """

    # --- data and initialisation
    detector: Annotated[str, Check(_maps_name)] = "auto"
    """Pseudo-edge maps to fit: a scene's own maps by name (e.g. 'pidinet'), or a detector name."""
    downscale: Annotated[int, Range(1, MAX_DOWNSCALE)] = 1
    """Train at 1/downscale resolution."""
    init_method: Annotated[str, OneOf(_init_methods)] = "auto"
    """How the initial points are found: one of edgedog.init.INIT_METHODS (see `initialize`)."""
    init_count: Count = 10000
    """Points of the uniform initialisation (EdgeGaussians start from 2500; with w = exp(-Up) the
    rims that are also depth jumps need the denser start: docs/BENCHMARKS.md)."""
    init_side: Annotated[float | None, Range(0, open_low=True)] = 1.1
    """Edge of the uniform cube (EdgeGaussians: 1.1 around the object for ABC); None: the bounds."""
    init_opacity: Annotated[float, Range(0, 1, open_low=True, open_high=True)] = 0.08
    """Initial opacity of every primitive."""
    k_init: tuple[Logit, Logit] = (0.0, 0.0)
    """Raw DoG shape k at initialisation (the paper's 0)."""

    # --- rasterizer
    kernel: Literal["dog", "gaussian"] = "dog"
    """'dog' (EdgeDoG) or 'gaussian' (the EdgeGaussians baseline)."""
    k_activation: Literal["sigmoid", "exp"] = "sigmoid"
    """Activation of k: 'sigmoid' for ABC, 'exp' for other data (docs/METHOD.md)."""

    # --- schedule
    epochs: Annotated[int, Range(1, MAX_EPOCHS)] = 400
    lr_means: Rate = 2e-3
    lr_means_decay_epochs: tuple[Epoch, ...] = (10, 20, 30, 40, 50)
    lr_means_decay: Share = 0.75
    """Factor of lr_means at each of lr_means_decay_epochs."""
    lr_scales: Rate = 1e-4
    scales_from_epoch: Epoch = 30
    lr_opacity: Rate = 0.03
    opacity_from_epoch: Epoch = 20
    lr_quats: Rate = 1e-3
    quats_from_epoch: Epoch = 30
    lr_k: Rate = 1e-4

    map_floor: Annotated[float, Range(0, 1, open_high=True)] = 0.0
    """Map values below this are set to zero: a coarse layer keeps only the strong edges."""
    map_correction: Literal["none", "calibrated", "shift", "learned"] = "none"
    """Correct the maps' sub-pixel offset: 'calibrated' shifts them by the correction of their
    detector's record (`edgedog calibrate-detector`); 'shift' by `map_shift`; 'learned' fits
    one 2D shift of all maps jointly with the primitives, from `map_shift_from_epoch` on."""
    map_shift: tuple[Shift, Shift] = (0.0, 0.0)
    """The shift of 'shift' in px of the maps as stored (x right, y down: content moves by it)."""
    map_shift_from_epoch: Epoch = 100
    """'learned': the shift is fitted once the primitives have settled (from this epoch)."""
    lr_map_shift: Rate = 0.002
    """'learned': Adam's learning rate of the shift, px per step."""
    silhouette_correction: Literal["auto", "measured", "none"] = "auto"
    """'measured': measure where the maps draw the object's outline against the scene's masks
    (alpha or mask files) and pull them onto it (edgedog.edges.silhouette). Maps made from
    RGBA images with the alpha dropped draw it 1-1.5 px outside, and the model grows outwards.
    'auto': 'measured' when the images carry an alpha channel (a render's exact outline), else
    'none' (hand-drawn mask files of photos are not exact enough to correct maps with)."""
    silhouette_reach: Width = 3.0
    """'measured': px from the outline within which the full correction applies (fading to 0 at
    twice this)."""
    edge_profile: Literal["auto", "raw", "thin", "profile"] = "auto"
    """'auto': 'profile' for DexiNed maps, 'raw' for others (see `for_detector`); 'raw': fit the
    maps as they are; 'thin': fit their ridge drawn with a narrow Gaussian
    profile (edgedog.edges.thin), which removes the bias of thick, asymmetric detector bands;
    'profile': fit the render blurred by `profile_sigma` (the band's measured width) to the maps,
    so that thin primitives explain a thick band."""
    thin_sigma: Width = 0.7
    """Width (px, standard deviation) of the 'thin' profile."""
    profile_sigma: Width = 1.0
    """'profile': standard deviation (px at the training resolution) of the render's blur."""

    # --- losses
    edge_threshold: Annotated[float, Range(0, 1, open_low=True)] = 0.5
    """Edge pixels of a map are those >= this value."""
    sampled_loss_from_epoch: Epoch = 50
    """After this epoch, every `sampled_loss_every` steps the L1 is taken on the edge pixels plus
    as many random background pixels instead of the whole image."""
    sampled_loss_every: Every = 5
    direction_from_epoch: Epoch = 250
    ratio_from_epoch: Epoch = 100
    orientation_every: Every = 5
    """The direction and scale-ratio losses are applied every this many steps."""
    direction_neighbours: Annotated[int, Range(2, MAX_NEIGHBOURS)] = 5
    """Neighbours whose directions a primitive's major axis is aligned with (the extraction's
    principal axes take as many, the point itself included)."""
    direction_factor: Annotated[float | None, Range(0)] = None
    """Direction loss weight: the term is scaled to this fraction of the running sum of the epoch's
    projection losses, as EdgeGaussians does; None: theirs for the maps' detector (0.01 for
    DexiNed maps, 0.1 for others: `for_detector`)."""
    ratio_factor: Annotated[float | None, Range(0)] = None
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
    fisher_every: Every = 50
    keep_ratio: Annotated[float, Range(0, 1, open_low=True)] = 0.9
    """The pruning ratio p: the fraction of primitives kept at each Fisher pruning."""

    # --- density control (EdgeGaussians, PiDiNet settings)
    duplicate_epochs: tuple[Epoch, ...] = (40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140, 150, 160,
                                         210, 220, 350, 375)
    duplicate_threshold: Share = 0.5
    """Duplicate primitives whose min-max normalised accumulated absgrad norm (the per-pixel
    |dL/dmean2d| summed over pixels and steps, as gsplat's absgrad) exceeds this."""
    duplicate_copies: Annotated[int, Range(1, MAX_COPIES)] = 2
    """Copies made of each primitive chosen for duplication."""
    duplicate_noise: Annotated[float, Range(0)] = 0.05
    """Standard deviation of the noise added to the copies' means (scene units)."""
    cull_opacity_epochs: tuple[Epoch, ...] = (125, 310)
    cull_opacity_below: Share = 0.05
    cull_projection_epochs: tuple[Epoch, ...] = (145, 175, 190)
    cull_projection_below: Share = 0.1
    """Cull primitives whose centre lands on edge pixels in fewer than this share of the views
    that see it."""
    opacity_logit_cap: Logit = 0.08
    """After each cull the opacity logits are clamped to at most this (EdgeGaussians)."""
    max_primitives: Count = 200_000
    """Duplication never grows the model beyond this."""

    # --- multi-granularity layers (edgedog.train.layers)
    layer: Annotated[int, Range(0, MAX_LAYERS - 1)] = 0
    """Index of the layer this run adds; the layers below it are given to the trainer, fixed."""
    lower_lr_scale: Share = 0.0
    """Fine-tune the layers below at this fraction of the learning rates (0: frozen)."""
    residual_min_share: Share = 0.1
    """Above layer 0, initial points are kept where they land on the residual edges (the map
    minus the render of the layers below, >= edge_threshold) in at least this share of the
    views that see them."""

    # --- run
    seed: Annotated[int, Range(0, MAX_SEED)] = 0
    checkpoint_every: Every = 50
    """Epochs between checkpoints (one is always written at the end)."""
    snapshot_every: Every = 25
    """Steps between the snapshots published to a viewer."""

    def __post_init__(self):
        for name, value in checked_settings(self).items():
            object.__setattr__(self, name, value)  # frozen: the checked value (a list made a tuple)


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
    epochs = check_setting("epochs", setting_types(TrainConfig)["epochs"], epochs)
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


@functools.cache
def setting_types(settings: type) -> dict[str, Any]:
    """Field name -> its type with its Annotated rules, for a dataclass of settings."""
    return typing.get_type_hints(settings, include_extras=True)


def checked_settings(settings) -> dict[str, Any]:
    """Every field of the dataclass `settings` -> its value checked by `check_setting`."""
    kinds = setting_types(type(settings))
    return {f.name: check_setting(f.name, kinds[f.name], getattr(settings, f.name))
            for f in dataclasses.fields(settings)}


def check_setting(name: str, kind: Any, value: Any) -> Any:
    """`value` as setting `name` of type `kind` holds it (an int for a float made a float, a list
    made a tuple, numpy scalars made Python's); raises ConfigError naming the setting and what it
    must be. Floats must be finite."""
    base, rules = _split(kind)
    if value is None and _optional(base):
        return None
    checked = _typed(name, _without_none(base), value)
    if checked is _WRONG:
        raise ConfigError(f"{name} must be {describe(kind)}, got {_shown(value)}")
    for rule in rules:
        if (isinstance(rule, Range) and checked not in rule) or (isinstance(rule, OneOf)
                                                                  and checked not in rule.choices()):
            raise ConfigError(f"{name} must be {describe(kind)}, got {_shown(value)}")
        if isinstance(rule, Check):
            rule.test(checked)
    return checked


def describe(kind: Any) -> str:
    """What a value of type `kind` must be, in words: 'an integer >= 1', 'a number in (0, 1) or
    None', 'one of dog, gaussian', '2 values, each a number in [-20, 20]'."""
    base, rules = _split(kind)
    inner = _without_none(base)
    origin, args = typing.get_origin(inner), typing.get_args(inner)
    choices = [c for rule in rules if isinstance(rule, OneOf) for c in rule.choices()]
    if origin is Literal or choices:
        words = f"one of {', '.join(map(str, choices or args))}"
    elif origin is tuple:
        count = "a list" if args[-1] is Ellipsis else f"{len(args)} values"
        words = f"{count}, each {describe(args[0])}"
    else:
        words = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}.get(
            inner, getattr(inner, "__name__", str(inner)))
    words += "".join(f" {rule}" for rule in rules if isinstance(rule, Range))
    return words + (", or none" if _optional(base) else "")


_WRONG = object()
"""`_typed`'s answer for a value of the wrong type."""


def _typed(name: str, kind: Any, value: Any) -> Any:
    """`value` as a plain Python value of `kind` (no Annotated, no None), or _WRONG."""
    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if origin is Literal:
        return value if isinstance(value, str) and value in args else _WRONG
    if origin is tuple:
        if isinstance(value, str) or not isinstance(value, Sequence):
            return _WRONG
        if args[-1] is not Ellipsis and len(value) != len(args):
            return _WRONG
        try:
            return tuple(check_setting(name, _item_kind(args, i), item) for i, item in enumerate(value))
        except ConfigError:
            return _WRONG
    if kind is bool:
        return value if isinstance(value, bool) else _WRONG
    if isinstance(value, bool):  # True is an int to Python, not to a setting
        return _WRONG
    if kind is int:
        return int(value) if isinstance(value, numbers.Integral) else _WRONG
    if kind is float:
        try:
            return float(value) if isinstance(value, numbers.Real) and math.isfinite(value) else _WRONG
        except OverflowError:  # an int past float's range (a config.json's 10**400)
            return _WRONG
    return value if isinstance(value, kind) else _WRONG


def _item_kind(args: tuple, index: int) -> Any:
    """The type of item `index` of a tuple type with arguments `args` (tuple[X, ...] or tuple[X, Y])."""
    return args[0] if args[-1] is Ellipsis or index >= len(args) else args[index]


def _split(kind: Any) -> tuple[Any, tuple]:
    """(the type, its Annotated rules)."""
    if typing.get_origin(kind) is Annotated:
        return kind.__origin__, kind.__metadata__
    return kind, ()


def _optional(kind: Any) -> bool:
    return typing.get_origin(kind) in (typing.Union, types.UnionType) and type(None) in typing.get_args(kind)


def _without_none(kind: Any) -> Any:
    if not _optional(kind):
        return kind
    rest = [arg for arg in typing.get_args(kind) if arg is not type(None)]
    return rest[0] if len(rest) == 1 else typing.Union[tuple(rest)]


_SHORT = reprlib.Repr()
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlist, _SHORT.maxtuple = 40, 40, 6, 6


def _shown(value: Any) -> str:
    """A value as an error message shows it: short, on one line."""
    return _SHORT.repr(value)


def parse_setting(name: str, kind: Any, text: str) -> Any:
    """The value `text` (as given to --set) means for setting `name` of type `kind`; raises
    ConfigError when it cannot be read as one or is out of range.

    Numbers as Python reads them; booleans true/false, on/off, yes/no, 1/0; 'none' where None is
    allowed; lists comma-separated ('' is the empty list).
    """
    base, _ = _split(kind)
    try:
        if _optional(base) and text.strip().lower() == "none":
            value = None
        else:
            value = _parsed(_without_none(base), text)
    except (ValueError, KeyError):
        raise ConfigError(f"{name} must be {describe(kind)}, got {_shown(text)}") from None
    return check_setting(name, kind, value)


_BOOLEANS = {**dict.fromkeys(("true", "on", "yes", "1"), True),
             **dict.fromkeys(("false", "off", "no", "0"), False)}


def _parsed(kind: Any, text: str) -> Any:
    """`text` read as a `kind` (no None); ValueError or KeyError when it cannot be."""
    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if origin is tuple:
        items = [item for item in text.split(",") if item.strip()]
        return tuple(_parsed(_split(_item_kind(args, i))[0], item) for i, item in enumerate(items))
    if kind is bool:
        return _BOOLEANS[text.strip().lower()]
    if kind in (int, float):
        return kind(text)
    return text


def with_overrides(config, assignments: list[str]):
    """`config` (a dataclass of settings) with the `KEY=VALUE` strings applied, each value read
    by its field's type (`parse_setting`). A bad one raises ConfigError naming it as given."""
    kinds = setting_types(type(config))
    changes = {}
    for assignment in assignments:
        key, sep, text = assignment.partition("=")
        given = f"--set {assignment!r}"
        if not sep:
            raise ConfigError(f"{given}: expected KEY=VALUE")
        if key not in kinds:
            close = "".join(f" (did you mean {name}?)" for name in difflib.get_close_matches(key, kinds, n=1))
            raise ConfigError(f"{given}: unknown setting {key!r}{close}; expected KEY=VALUE with KEY one of "
                              f"{', '.join(kinds)}")
        try:
            changes[key] = parse_setting(key, kinds[key], text)
        except ConfigError as error:
            raise ConfigError(f"{given}: {error}") from None
    return dataclasses.replace(config, **changes)


def to_dict(config: TrainConfig) -> dict:
    return dataclasses.asdict(config)


def from_dict(values: dict) -> TrainConfig:
    """A config from `to_dict`'s output (e.g. a run folder's config.json). Settings it lacks
    (written before they existed) take their defaults; an unknown or bad one raises ConfigError."""
    if not isinstance(values, dict):
        raise ConfigError(f"expected an object of settings, got {_shown(values)}")
    unknown = sorted(map(str, set(values) - {f.name for f in dataclasses.fields(TrainConfig)}))
    if unknown:
        raise ConfigError(f"unknown setting{'s' * (len(unknown) > 1)} {', '.join(unknown)}")
    return TrainConfig(**values)


__all__ = ["Check", "OneOf", "Range", "TrainConfig", "check_setting", "checked_settings", "describe",
           "for_detector", "from_dict", "parse_setting", "preset", "setting_types", "to_dict", "with_epochs",
           "with_overrides"]
