"""Detectors by name: what `--detector NAME` accepts, and what each detector's maps need.

One `DetectorEntry` per detector family owns everything edgedog knows about it: its name and
summary, the `:OPTIONS` it takes, the factory that builds it, and the training settings its maps
need. Entries without a factory describe maps that scenes bring and edgedog cannot compute
(DexiNed's). A name is `FAMILY` or `FAMILY:OPTIONS` (e.g. 'canny:50,150', 'pidinet-nyud:side2'),
or 'auto'.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from edgedog.edges.classical import CannyDetector, SobelDetector
from edgedog.edges.detector import EdgeDetector
from edgedog.errors import ConfigError, InputError

Weights = str | Path | None
"""A PiDiNet weights file or folder; None: $EDGEDOG_PIDINET, else the shipped BSDS weights."""

WEIGHTS_HELP = "PiDiNet weights file or folder (default: $EDGEDOG_PIDINET, else the BSDS ones edgedog ships)"
"""The help text of the commands' --weights option."""

AUTO = "auto"
"""Stands for `DEFAULT_DETECTOR` on every machine: its weights ship with edgedog."""
DEFAULT_DETECTOR = "pidinet"
DEFAULT_WEIGHT_FREE = "canny"
"""The detector of maps that must not depend on any weights file (the built-in scene's)."""

PIDINET_SIDES = ("side1", "side2", "side3", "side4")

PIDINET_MAP_DEFAULTS = MappingProxyType({"loss.direction_factor": 0.1, "loss.ratio_factor": 0.05,
                                         "maps.edge_profile": "raw"})
"""EdgeGaussians' settings for PiDiNet maps: the raw map as the photometric target. Used for every
detector edgedog builds and for scene maps no entry names."""

DEXINED_MAP_DEFAULTS = MappingProxyType({"loss.direction_factor": 0.01, "loss.ratio_factor": 0.01,
                                         "maps.edge_profile": "profile"})
"""EdgeGaussians' factors for DexiNed maps, and the profile loss, which fits their thick bands with
thin primitives (on ABC 00004926, paper preset: Comp 9.6 -> 5.1 mm, F10 94.9 -> 97.7;
docs/BENCHMARKS.md)."""


def _no_options(family: str, options: str) -> dict[str, object]:
    if options:
        raise ValueError(f"{family} takes no options")
    return {}


@dataclass(frozen=True)
class DetectorEntry:
    """One detector family.

    Attributes:
        name: the family's name, lower case ('canny', 'pidinet-nyud').
        summary: one line for help texts.
        training_defaults: dotted setting name ('loss.ratio_factor') -> the value its maps need,
            used where a config leaves that setting open.
        options: the syntax of ':OPTIONS' for help and errors ('LOW,HIGH'); '' when it takes none.
        parse_options: (family name, option text, '' without options) -> the factory's keyword
            arguments; raises ValueError saying what is wrong (the registry names the detector).
        factory: (weights, **options) -> the detector; None for maps only scenes bring.
        require: weights -> (ignored), raising InputError when what the factory needs is
            missing (checked before anything heavy is built); None when it needs nothing.
    """

    name: str
    summary: str
    training_defaults: Mapping[str, object] = field(default_factory=lambda: PIDINET_MAP_DEFAULTS)
    options: str = ""
    parse_options: Callable[[str, str], dict[str, object]] = _no_options
    factory: Callable[..., EdgeDetector] | None = None
    require: Callable[[Weights], object] | None = None

    @property
    def usage(self) -> str:
        """'canny[:LOW,HIGH]', or the bare name when it takes no options."""
        return f"{self.name}[:{self.options}]" if self.options else self.name


def _canny_options(family: str, options: str) -> dict[str, object]:
    """'LOW,HIGH': Canny's hysteresis thresholds (grey levels); higher thresholds keep only the
    stronger edges (the weight-free coarse levels of a layered model)."""
    if not options:
        return {}
    try:
        low, high = (int(t) for t in options.split(","))
    except ValueError:
        raise ValueError(f"expected {family}:LOW,HIGH with two integers") from None
    if not 0 <= low <= high:
        raise ValueError("expected 0 <= LOW <= HIGH")
    return {"low": low, "high": high}


def _pidinet_options(family: str, options: str) -> dict[str, object]:
    """'' or 'fused': the network's final map; 'side1' (finest) .. 'side4': a side output."""
    if options not in ("", "fused", *PIDINET_SIDES):
        raise ValueError(f"{family} takes :{'/:'.join(PIDINET_SIDES)}")
    return {"output": options or "fused"}


def _pidinet_weights(variant: str, weights: Weights) -> Path:
    from edgedog.edges.pidinet import pidinet_weights  # imports torch

    return pidinet_weights(variant, weights)


def _build_pidinet(variant: str, weights: Weights, output: str) -> EdgeDetector:
    from edgedog.edges.pidinet import PidinetDetector  # imports torch

    return PidinetDetector(_pidinet_weights(variant, weights), output=output)


OFFICIAL_WEIGHTS = "official weights: --weights, $EDGEDOG_PIDINET"


def _pidinet_entry(name: str, variant: str, trained_on: str, weights: str) -> DetectorEntry:
    return DetectorEntry(
        name=name, summary=f"PiDiNet trained on {trained_on} ({weights})",
        options="side1..side4", parse_options=_pidinet_options,
        factory=functools.partial(_build_pidinet, variant),
        require=functools.partial(_pidinet_weights, variant))


ENTRIES = (
    DetectorEntry(name="sobel", summary="gradient magnitude of the smoothed grey image (weight-free, soft)",
                  factory=lambda weights: SobelDetector()),
    DetectorEntry(name="canny", summary="Canny's thin edges softened by a Gaussian (weight-free; LOW,HIGH "
                                        "default to 50,150)",
                  options="LOW,HIGH", parse_options=_canny_options,
                  factory=lambda weights, **thresholds: CannyDetector(**thresholds)),
    _pidinet_entry("pidinet", "bsds", "BSDS500", "weights shipped with edgedog; --weights, $EDGEDOG_PIDINET "
                                                 "override them"),
    _pidinet_entry("pidinet-nyud", "nyud", "NYUD", OFFICIAL_WEIGHTS),
    _pidinet_entry("pidinet-multicue", "multicue", "Multicue", OFFICIAL_WEIGHTS),
    DetectorEntry(name="dexined", summary="DexiNed maps that scenes bring (EMAP's edge_DexiNed/); not "
                                          "computed by edgedog",
                  training_defaults=DEXINED_MAP_DEFAULTS),
)
"""Every detector family; those with a factory are the ones `make_detector` builds."""


def detector_entry(name: str) -> DetectorEntry | None:
    """The entry of `name`'s family (any case; options ignored), or None when no entry is called
    that (a scene's own maps of another name). 'auto' is resolved first."""
    family = name.partition(":")[0].lower()
    if family == AUTO:
        family = DEFAULT_DETECTOR
    return next((entry for entry in ENTRIES if entry.name == family), None)


def detector_names() -> list[str]:
    """Every family `make_detector` builds, then 'auto' (see `detector_entry` for their options)."""
    return [entry.name for entry in ENTRIES if entry.factory is not None] + [AUTO]


def detectors_help() -> str:
    """One line per buildable family, 'usage: summary', then 'auto', for help texts."""
    lines = [f"{entry.usage}: {entry.summary}" for entry in ENTRIES if entry.factory is not None]
    auto = f"{AUTO}: {DEFAULT_DETECTOR} (its weights ship with edgedog)"
    return "\n".join([*lines, auto])


def available_detectors(weights: Weights = None) -> list[str]:
    """The families `make_detector(name, weights)` can build now (PiDiNet's other variants when
    their weights are found)."""
    return [entry.name for entry in ENTRIES if entry.factory is not None and _met(entry, weights)]


def _met(entry: DetectorEntry, weights: Weights) -> bool:
    try:
        if entry.require is not None:
            entry.require(weights)
    except InputError:
        return False
    return True


def training_defaults(detector: str) -> dict[str, object]:
    """The settings the maps of `detector` need, keyed by dotted setting name: its entry's (any
    case, a name with options uses its family), or `PIDINET_MAP_DEFAULTS` for maps no entry names."""
    entry = detector_entry(detector)
    return dict(PIDINET_MAP_DEFAULTS if entry is None else entry.training_defaults)


def pidinet_available(weights: Weights = None) -> bool:
    """Whether weights beyond the shipped BSDS ones may be found (explicitly, or through
    EDGEDOG_PIDINET): those of PiDiNet's NYUD and Multicue variants."""
    return weights is not None or bool(os.environ.get("EDGEDOG_PIDINET"))


def is_detector_name(name: str) -> bool:
    """Whether `make_detector` builds `name` (True), or no detector is called that (False: it may
    name a scene's own maps, e.g. 'dexined'). Names are lower case, as scenes' map names are.
    Builds nothing.

    Raises ConfigError for a detector's name with options it does not take ('canny:5',
    'pidinet:side9', 'sobel:2').
    """
    return _parsed(name) is not None


def make_detector(name: str, weights: Weights = None) -> EdgeDetector:
    """Build a detector from its name (see `detectors_help`; e.g. 'canny:50,150', 'pidinet:side2',
    'auto'), named `name` ('auto' resolved).

    Args:
        weights: PiDiNet weights file or folder; defaults to $EDGEDOG_PIDINET.
    Raises:
        ConfigError naming the choices for an unknown name; InputError for missing weights.
    """
    name = _resolved(name)
    entry, options = _parsed(name)
    detector = entry.factory(weights, **options)
    detector.name = name
    return detector


def require_detector(name: str, weights: Weights = None) -> None:
    """Check, without building it, that `make_detector(name, weights)` can build `name`: a
    known name whose weights (PiDiNet's) are found. Raises ConfigError or InputError."""
    entry, _ = _parsed(_resolved(name))
    if entry.require is not None:
        entry.require(weights)


def _parsed(name: str) -> tuple[DetectorEntry, dict[str, object]] | None:
    """(entry, factory options) of a buildable `name`; None when no buildable family is called
    that. ConfigError for options the family does not take."""
    if name == AUTO:
        return _parsed(DEFAULT_DETECTOR)
    family, sep, options = name.partition(":")
    entry = next((e for e in ENTRIES if e.name == family and e.factory is not None), None)
    if entry is None:
        return None
    if sep and not options:
        raise ConfigError(f"detector {name!r}: nothing after ':' (expected {entry.usage})")
    try:
        return entry, entry.parse_options(family, options)
    except ValueError as error:
        raise ConfigError(f"detector {name!r}: {error}") from None


def _resolved(name: str) -> str:
    """`name` with 'auto' replaced by the detector it stands for; ConfigError naming the choices
    when no detector is called `name`."""
    if not is_detector_name(name):
        usages = ", ".join(e.usage for e in ENTRIES if e.factory is not None)
        raise ConfigError(f"unknown detector {name!r}; choose from {usages} or {AUTO}")
    return DEFAULT_DETECTOR if name == AUTO else name
