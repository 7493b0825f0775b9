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


def make_detector(name: str, weights: str | Path | None = None) -> EdgeDetector:
    """Build a detector from its name.

    Args:
        name: "sobel", "canny" (or "canny:LOW,HIGH" with its thresholds), "pidinet" (BSDS500),
            "pidinet-nyud", "pidinet-multicue", optionally with ":side1" ... ":side4" for a
            PiDiNet side output, or "auto":
            PiDiNet when its weights can be found, else the weight-free default (canny).
        weights: PiDiNet weights file or folder; defaults to $EDGEDOG_PIDINET.
    """
    if name == "auto":
        name = "pidinet" if pidinet_available(weights) else DEFAULT_WEIGHT_FREE
    if name in WEIGHT_FREE:
        return WEIGHT_FREE[name]()
    base, _, output = name.partition(":")
    if base == "canny" and output:
        return _canny_with_thresholds(name, output)
    if base in PIDINET_VARIANTS and (output or "fused") in PIDINET_OUTPUTS:
        from edgedog.edges.pidinet import PidinetDetector, pidinet_weights  # imports torch

        detector = PidinetDetector(pidinet_weights(PIDINET_VARIANTS[base], weights), output=output or "fused")
        detector.name = name
        return detector
    raise ConfigError(f"unknown detector {name!r}; choose from {', '.join(detector_names())} "
                     f"(PiDiNet names take :{'/:'.join(PIDINET_OUTPUTS[1:])}, canny takes :LOW,HIGH)")


def _canny_with_thresholds(name: str, thresholds: str) -> EdgeDetector:
    """'canny:LOW,HIGH': Canny with its hysteresis thresholds (grey levels); higher thresholds
    keep only the stronger edges (the weight-free coarse levels of a layered model)."""
    try:
        low, high = (int(t) for t in thresholds.split(","))
    except ValueError:
        raise ConfigError(f"detector {name!r}: expected canny:LOW,HIGH with two integers") from None
    if not 0 <= low <= high:
        raise ConfigError(f"detector {name!r}: expected 0 <= LOW <= HIGH")
    detector = CannyDetector(low, high)
    detector.name = name
    return detector
