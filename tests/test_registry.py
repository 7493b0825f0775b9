"""The detector registry: one entry per family owns its options, factory, fingerprint and
training defaults; every list of detectors comes from it."""

from __future__ import annotations

import argparse
import inspect
from pathlib import Path

import pytest

from edgedog.commands import edges
from edgedog.edges.classical import CannyDetector
from edgedog.edges.pidinet import OUTPUTS
from edgedog.edges.registry import (
    ENTRIES,
    PIDINET_MAP_DEFAULTS,
    available_detectors,
    detector_entry,
    detector_names,
    is_detector_name,
    make_detector,
    require_detector,
    training_defaults,
)
from edgedog.errors import ConfigError
from tests.helpers.paths import shared_path

BUILT = [entry for entry in ENTRIES if entry.factory is not None]
CHOICES = {"output": OUTPUTS}
"""Parameters that take one of a few strings: their choices."""


@pytest.fixture(scope="module")
def weights() -> Path:
    return shared_path("../models/pidinet")


def changed(parameter: str, value, weights: Path):
    """Another valid value of a detector's constructor parameter."""
    if isinstance(value, bool):
        return not value
    if isinstance(value, int | float):
        return value + 1
    if isinstance(value, Path):
        return next(path for path in sorted(weights.glob("*.pth")) if path.name != value.name)
    if parameter in CHOICES:
        return next(choice for choice in CHOICES[parameter] if choice != value)
    pytest.fail(f"no other value for {parameter}={value!r}: teach this test")


@pytest.mark.parametrize("entry", BUILT, ids=lambda entry: entry.name)
def test_every_constructor_parameter_is_in_the_fingerprint(entry, weights):
    detector = make_detector(entry.name, weights)
    kind = type(detector)
    parameters = [name for name in inspect.signature(kind.__init__).parameters if name != "self"]
    current = {name: getattr(detector, name) for name in parameters}  # kept under the parameter's name
    assert parameters and kind(**current).fingerprint == detector.fingerprint
    for name in parameters:
        other = kind(**{**current, name: changed(name, current[name], weights)})
        assert other.fingerprint != detector.fingerprint, f"{kind.__name__}({name}=...) keeps the fingerprint"


def test_names_and_help_come_from_the_entries(capsys):
    assert detector_names() == [entry.name for entry in BUILT] + ["auto"]
    parser = argparse.ArgumentParser()
    edges.add_parser(parser.add_subparsers())
    with pytest.raises(SystemExit):
        parser.parse_args(["edges", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for entry in BUILT:
        assert f"{entry.usage}: {entry.summary}" in text
    with pytest.raises(ConfigError) as error:
        make_detector("sobell")
    assert all(entry.usage in str(error.value) for entry in BUILT) and "dexined" not in str(error.value)


def test_maps_only_entries_are_no_detector_names():
    dexined = detector_entry("DexiNed")
    assert dexined.name == "dexined" and dexined.factory is None
    assert not is_detector_name("dexined") and detector_entry("my maps") is None
    with pytest.raises(ConfigError, match="unknown detector 'dexined'"):
        require_detector("dexined")


@pytest.mark.parametrize("name, expected", [
    ("dexined", {"loss.direction_factor": 0.01, "loss.ratio_factor": 0.01, "maps.edge_profile": "profile"}),
    ("DEXINED", {"loss.direction_factor": 0.01, "loss.ratio_factor": 0.01, "maps.edge_profile": "profile"}),
    ("pidinet-nyud:side2", {"loss.direction_factor": 0.1, "loss.ratio_factor": 0.05,
                            "maps.edge_profile": "raw"}),
    ("canny:20,60", dict(PIDINET_MAP_DEFAULTS)), ("auto", dict(PIDINET_MAP_DEFAULTS)),
    ("my maps", dict(PIDINET_MAP_DEFAULTS)),
])
def test_training_defaults_by_family(name, expected):
    assert training_defaults(name) == expected


def test_options_reach_the_factory_and_the_name():
    detector = make_detector("canny:20,60")
    assert isinstance(detector, CannyDetector) and (detector.low, detector.high) == (20, 60)
    assert detector.name == "canny:20,60" and detector.fingerprint != make_detector("canny").fingerprint
    with pytest.raises(ConfigError, match=r"'canny:': nothing after ':' \(expected canny\[:LOW,HIGH\]\)"):
        make_detector("canny:")


def test_available_detectors_need_their_weights(weights, monkeypatch):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    weight_free = [entry.name for entry in BUILT if entry.require is None]
    assert weight_free == ["sobel", "canny"]
    assert available_detectors() == [*weight_free, "pidinet"]  # the shipped BSDS weights
    assert available_detectors(weights) == [entry.name for entry in BUILT]
    require_detector("pidinet-multicue:side1", weights)
