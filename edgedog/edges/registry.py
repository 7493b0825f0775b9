"""Detectors by name: what `--detector NAME` accepts."""

from __future__ import annotations

import os
from pathlib import Path

from edgedog.edges.classical import CannyDetector, SobelDetector
from edgedog.edges.detector import EdgeDetector
from edgedog.errors import ConfigError

# PiDiNet variants: name -> the training set of the official weights.
PIDINET_VARIANTS = {"pidinet": "bsds", "pidinet-nyud": "nyud", "pidinet-multicue": "multicue"}
PIDINET_OUTPUTS = ("fused", "side1", "side2", "side3", "side4")
WEIGHT_FREE = {"sobel": SobelDetector, "canny": CannyDetector}
DEFAULT_WEIGHT_FREE = "canny"


def detector_names() -> list[str]:
    """Every name `make_detector` accepts (PiDiNet names also take ':side1' ... ':side4')."""
    return sorted(WEIGHT_FREE) + sorted(PIDINET_VARIANTS) + ["auto"]


def pidinet_available(weights: str | Path | None = None) -> bool:
    """Whether PiDiNet weights can be found (explicitly, or through EDGEDOG_PIDINET)."""
    return weights is not None or bool(os.environ.get("EDGEDOG_PIDINET"))


def is_detector_name(name: str) -> bool:
    """Whether `make_detector` builds `name` (True), or no detector is called that (False: it may
    name a scene's own maps, e.g. 'dexined'). Builds nothing.

    Raises ConfigError for a detector's name with options it does not take ('canny:5',
    'pidinet:side9', 'sobel:2').
    """
    base, sep, options = name.partition(":")
    if name == "auto" or (base in WEIGHT_FREE and not sep):
        return True
    if base == "canny":
        _canny_thresholds(name, options)
        return True
    if base in PIDINET_VARIANTS and (options or "fused") in PIDINET_OUTPUTS:
        return True
    if base in WEIGHT_FREE or base in PIDINET_VARIANTS:
        takes = "takes no options" if base in WEIGHT_FREE else f"takes :{'/:'.join(PIDINET_OUTPUTS[1:])}"
        raise ConfigError(f"detector {name!r}: {base} {takes}")
    return False


def make_detector(name: str, weights: str | Path | None = None) -> EdgeDetector:
    """Build a detector from its name.

    Args:
        name: "sobel", "canny" (or "canny:LOW,HIGH" with its thresholds), "pidinet" (BSDS500),
            "pidinet-nyud", "pidinet-multicue", optionally with ":side1" ... ":side4" for a
            PiDiNet side output, or "auto":
            PiDiNet when its weights can be found, else the weight-free default (canny).
        weights: PiDiNet weights file or folder; defaults to $EDGEDOG_PIDINET.
    """
    name = _resolved(name, weights)
    base, _, options = name.partition(":")
    if base == "canny" and options:
        detector = CannyDetector(*_canny_thresholds(name, options))
        detector.name = name
        return detector
    if base in WEIGHT_FREE:
        return WEIGHT_FREE[base]()
    from edgedog.edges.pidinet import PidinetDetector, pidinet_weights  # imports torch

    detector = PidinetDetector(pidinet_weights(PIDINET_VARIANTS[base], weights), output=options or "fused")
    detector.name = name
    return detector


def require_detector(name: str, weights: str | Path | None = None) -> None:
    """Check, without building it, that `make_detector(name, weights)` can build `name`: a
    known name whose weights (PiDiNet's) are found. Raises ConfigError or InputError."""
    base = _resolved(name, weights).partition(":")[0]
    if base in PIDINET_VARIANTS:
        from edgedog.edges.pidinet import pidinet_weights

        pidinet_weights(PIDINET_VARIANTS[base], weights)


def _resolved(name: str, weights: str | Path | None) -> str:
    """`name` with 'auto' replaced by the detector it stands for; ConfigError naming the choices
    when no detector is called `name`."""
    if not is_detector_name(name):
        raise ConfigError(f"unknown detector {name!r}; choose from {', '.join(detector_names())} "
                          f"(PiDiNet names take :{'/:'.join(PIDINET_OUTPUTS[1:])}, canny takes :LOW,HIGH)")
    if name == "auto":
        return "pidinet" if pidinet_available(weights) else DEFAULT_WEIGHT_FREE
    return name


def _canny_thresholds(name: str, thresholds: str) -> tuple[int, int]:
    """'canny:LOW,HIGH': Canny's hysteresis thresholds (grey levels); higher thresholds keep only
    the stronger edges (the weight-free coarse levels of a layered model)."""
    try:
        low, high = (int(t) for t in thresholds.split(","))
    except ValueError:
        raise ConfigError(f"detector {name!r}: expected canny:LOW,HIGH with two integers") from None
    if not 0 <= low <= high:
        raise ConfigError(f"detector {name!r}: expected 0 <= LOW <= HIGH")
    return low, high
