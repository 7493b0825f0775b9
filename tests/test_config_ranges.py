"""Every training setting is checked where it is made (presets, --set, a run's config.json), against
the range or choices its type declares; the --level and detector names as far as the command line
can tell without the scene."""

from __future__ import annotations

import json
import math
import typing
from dataclasses import dataclass, field
from typing import Annotated

import pytest
from edgedog.renderer.config import KActivation, Kernel, RasterConfig

from edgedog.curves.config import ExtractConfig, ExtractSettings
from edgedog.curves.config import with_overrides as extract_overrides
from edgedog.edges.registry import is_detector_name, make_detector, require_detector
from edgedog.errors import ConfigError, InputError
from edgedog.settings import Check, Range, Settings, setting_paths, setting_types
from edgedog.settings import with_overrides as settings_with_overrides
from edgedog.train.config import (
    MAX_EPOCHS,
    MAX_LAYERS,
    PRESETS,
    RENAMED,
    ModelSettings,
    TrainConfig,
    from_dict,
    preset,
    to_dict,
    with_epochs,
    with_overrides,
)
from edgedog.train.levels import check_level_maps, parse_level, resolve_levels
from tests.helpers.old_runs import flat_config

KINDS = setting_paths(TrainConfig)
PATHS = list(KINDS)
"""Every setting by dotted name: 'schedule.epochs'."""


def with_setting(path: str, value):
    """The section of setting `path` made with `value` (checked there); returns the value kept."""
    section, name = path.split(".")
    return getattr(setting_types(TrainConfig)[section](**{name: value}), name)


def _parts(kind) -> tuple:
    """(type without Annotated and None, its rules, whether None is allowed)."""
    rules = ()
    if typing.get_origin(kind) is typing.Annotated:
        kind, rules = kind.__origin__, kind.__metadata__
    args = typing.get_args(kind)
    optional = type(None) in args
    if optional:
        (kind,) = [arg for arg in args if arg is not type(None)]
    return kind, rules, optional


def _outside(bounds: Range, kind) -> list:
    """Values just outside `bounds` (an open end itself is outside)."""
    step = 1 if kind is int else 1e-6
    values = []
    if bounds.low is not None:
        values.append(bounds.low if bounds.open_low else bounds.low - step)
    if bounds.high is not None:
        values.append(bounds.high if bounds.open_high else bounds.high + step)
    return [kind(v) for v in values]


def bad_values(kind) -> list:
    """Values a setting of type `kind` must refuse: wrong types, non-finite numbers, values just
    outside its range, choices it does not have, tuples of the wrong length or with a bad item."""
    base, rules, optional = _parts(kind)
    origin, args = typing.get_origin(base), typing.get_args(base)
    wrong = [] if optional else [None]
    if origin is typing.Literal:
        return wrong + ["bogus", 1, [args[0]]]
    if origin is tuple:
        item = args[0]
        good = _parts(item)[0](0)
        shapes = [[good] * (len(args) + 1), "0,0", 0] if args[-1] is not Ellipsis else ["1,2", 3]
        if args[-1] is not Ellipsis:
            shapes.append([good] * (len(args) - 1))
        return wrong + shapes + [(bad,) + (good,) * (len(args) - 1 if args[-1] is not Ellipsis else 0)
                                 for bad in bad_values(item) if bad is not None]
    if base is bool:
        return wrong + ["true", 1, 0.0]
    if base is str:
        checked = [""] if any(isinstance(r, Check) for r in rules) else []
        return wrong + [1, ["auto"]] + checked
    numbers = [v for rule in rules if isinstance(rule, Range) for v in _outside(rule, base)]
    if base is int:
        return wrong + numbers + [1.5, "1", True, [1]]
    return wrong + numbers + [math.nan, math.inf, -math.inf, "0.5", [0.5], True]


# --- every field
def test_every_setting_declares_what_it_accepts():
    """A number has a Range, a string a Literal or Check: a new field cannot go unchecked."""
    for name in PATHS:
        base, rules, _ = _parts(KINDS[name])
        if typing.get_origin(base) is tuple:
            base, rules, _ = _parts(typing.get_args(base)[0])
        if base in (int, float):
            assert any(isinstance(rule, Range) for rule in rules), name
        elif base is str:
            assert any(isinstance(rule, Check) for rule in rules), name
        else:
            assert base is bool or typing.get_origin(base) is typing.Literal, name


@pytest.mark.parametrize("path", PATHS)
def test_every_setting_refuses_bad_values(path):
    values = bad_values(KINDS[path])
    assert values
    for value in values:
        with pytest.raises(ConfigError, match=path.split(".")[1]):
            with_setting(path, value)


@pytest.mark.parametrize("path", PATHS)
def test_every_setting_takes_its_closed_bounds(path):
    base, rules, optional = _parts(KINDS[path])
    for rule in (r for r in rules if isinstance(r, Range)):
        for bound, is_open in ((rule.low, rule.open_low), (rule.high, rule.open_high)):
            if bound is not None and not is_open:
                assert with_setting(path, base(bound)) == bound
    if optional:
        assert with_setting(path, None) is None


def test_values_are_stored_as_their_type():
    """A JSON 1 for a float setting, a list for a tuple: stored as float and tuple (hashable,
    equal to the preset's)."""
    config = from_dict({"schedule": {"lr_means": 1}, "init": {"k": [0, 1]},
                        "strategy": {"duplicate_epochs": [5, 10]}})
    assert type(config.schedule.lr_means) is float and type(config.init.k[0]) is float and hash(config)
    assert config.init.k == (0.0, 1.0) and config.strategy.duplicate_epochs == (5, 10)


def test_every_setting_has_one_name():
    """Every old flat name leads to a setting; the one bare name two sections share is an old
    flat name, which keeps its meaning (maps.edge_threshold)."""
    assert set(RENAMED.values()) <= set(PATHS)
    bare = [path.split(".")[1] for path in PATHS]
    assert {name for name in bare if bare.count(name) > 1} == {"edge_threshold"}
    assert with_overrides(TrainConfig(), ["edge_threshold=0.4"]).maps.edge_threshold == 0.4
    assert with_overrides(TrainConfig(), ["init.edge_threshold=0.4"]).init.edge_threshold == 0.4


@dataclass(frozen=True)
class _Small(Settings):
    size: Annotated[int, Range(1)] = 1


@dataclass(frozen=True)
class _Large(Settings):
    size: Annotated[int, Range(1)] = 2
    shown: bool = True


@dataclass(frozen=True)
class _Sections(Settings):
    small: _Small = field(default_factory=_Small)
    large: _Large = field(default_factory=_Large)


def test_a_bare_name_stands_for_the_one_section_that_has_it():
    assert settings_with_overrides(_Sections(), ["shown=off"]).large.shown is False
    assert settings_with_overrides(_Sections(), ["large.size=3"]) == _Sections(large=_Large(size=3))
    with pytest.raises(ConfigError, match=r"--set 'size=3': setting 'size' is in several sections; name one "
                                          r"of small.size, large.size"):
        settings_with_overrides(_Sections(), ["size=3"])
    with pytest.raises(ConfigError, match=r"unknown setting 'sise' \(did you mean size\?\)"):
        settings_with_overrides(_Sections(), ["sise=3"])
    with pytest.raises(ConfigError, match=r"large.size must be an integer >= 1, got 0"):
        settings_with_overrides(_Sections(), ["large.size=0"])


# --- the problems of issue 23, as messages
@pytest.mark.parametrize("assignment, words", [
    ("checkpoint_every=0", "run.checkpoint_every must be an integer >= 1, got 0"),
    ("fisher_every=0", "fisher_every must be an integer >= 1"),
    ("orientation_every=0", "orientation_every must be"),
    ("neighbours_every=0", "loss.neighbours_every must be"),
    ("sampled_loss_every=0", "loss.sampled_every must be"),
    ("epochs=0", f"schedule.epochs must be an integer in [1, {MAX_EPOCHS}], got 0"),
    ("init_opacity=1.5", "init.opacity must be a number in (0, 1), got 1.5"),
    ("init_count=-1", "init.count must be an integer in [1, "),
    ("init.count=0", "init.count must be"),
    ("init_side=0", "init.side must be a number > 0, or none, got 0.0"),
    ("seed=-1", "seed must be an integer in [0, "),
    ("k_init=0.5", "init.k must be 2 values, each a number in [-20, 20], got (0.5,)"),
    ("max_primitives=0", "max_primitives must be"),
    ("edge_threshold=nan", "maps.edge_threshold must be a number in (0, 1], got nan"),
    ("lr_means=inf", "schedule.lr_means must be a number in [0, 1], got inf"),
    ("profile_sigma=1e9", "profile_sigma must be a number in (0, 32]"),
    ("duplicate_copies=0", "duplicate_copies must be an integer in [1, 8]"),
    ("direction_neighbours=100000", "direction_neighbours must be an integer in [2, 32]"),
    ("epochs=two", "epochs must be an integer in [1, 10000], got 'two'"),
    ("pixel_uncertainty=maybe", "pixel_uncertainty must be true or false, got 'maybe'"),
    ("model.kernel=box", "model.kernel must be one of dog, gaussian, got 'box'"),
    ("init_method=random", "init.method must be one of auto, triangulate, sfm-points, uniform"),
    ("duplicate_epochs=10,-1", "duplicate_epochs must be a list, each an integer in [0, 10000]"),
    ("detector=canny:5", "detector 'canny:5': expected canny:LOW,HIGH"),
    ("maps.detector=", "maps.detector must name a detector or a scene's maps"),
    ("epoch=3", "unknown setting 'epoch' (did you mean epochs?)"),
    ("loss.weight=exp", "unknown setting 'loss.weight' (did you mean loss.weighting?)"),
    ("epochs", "expected KEY=VALUE"),
])
def test_a_bad_override_names_the_assignment_and_the_range(assignment, words):
    with pytest.raises(ConfigError) as error:
        with_overrides(TrainConfig(), [assignment])
    assert str(error.value).startswith(f"--set {assignment!r}: ") and words in str(error.value)


def test_overrides_read_values_by_type():
    config = with_overrides(TrainConfig(), ["init.side=none", "duplicate_epochs=", "pixel_uncertainty=off",
                                            "init.k=1,-2", "direction_factor=0.5", "run.seed=7"])
    assert config.init.side is None and config.strategy.duplicate_epochs == ()
    assert not config.loss.pixel_uncertainty and config.init.k == (1.0, -2.0)
    assert config.loss.direction_factor == 0.5 and config.run.seed == 7
    assert with_overrides(TrainConfig(), ["direction_factor=none"]).loss.direction_factor is None


# --- the extraction's and the rasterizer's settings: the same types, parser and errors
@pytest.mark.parametrize(("assignment", "message"), [
    ("extract.min_opacity=bad", "extract.min_opacity must be a number in [0, 1], got 'bad'"),
    ("min_opacity=nan", "extract.min_opacity must be a number in [0, 1], got nan"),
    ("extract.link_angle=95", "extract.link_angle must be a number in (0, 90), got 95.0"),
    ("extract.outlier_neighbours=1", "extract.outlier_neighbours must be an integer in [2, 256], got 1"),
    ("extract.node_spacing=0", "extract.node_spacing must be a number in (0, 1], got 0.0"),
    ("extract.max_outlier_share=1", "extract.max_outlier_share must be a number in [0, 1), got 1.0"),
    ("extract.filter_outliers=maybe", "extract.filter_outliers must be one of auto, on, off, got 'maybe'"),
    ("extract.filter_opacity=2", "extract.filter_opacity must be true or false, got '2'"),
    ("extract.bogus=1", "unknown setting 'extract.bogus'"),
])
def test_a_bad_extraction_override_is_one_line_naming_the_key_and_the_range(assignment, message):
    with pytest.raises(ConfigError) as error:
        extract_overrides(ExtractConfig(), [assignment])
    text = str(error.value)
    assert text.startswith(f"--set {assignment!r}: {message}") and "\n" not in text


def test_extraction_overrides_take_dotted_and_bare_names():
    config = extract_overrides(ExtractConfig(), ["extract.min_opacity=0.3", "link_distance=0.03",
                                                 "filter_outliers=auto", "extract.filter_silhouette=off"])
    assert config == ExtractConfig(min_opacity=0.3, link_distance=0.03, filter_outliers="auto",
                                   filter_silhouette=False)
    assert setting_paths(ExtractSettings)["extract.seed"] is setting_types(ExtractConfig)["seed"]


def test_extraction_and_raster_settings_are_checked_when_made():
    with pytest.raises(ConfigError, match=r"^corner_angle must be a number in \(0, 90\), got 90$"):
        ExtractConfig(corner_angle=90)
    with pytest.raises(ConfigError, match=r"^eps2d must be a number >= 0, got -0.1$"):
        RasterConfig(eps2d=-0.1)
    with pytest.raises(ConfigError, match=r"^kernel must be one of dog, gaussian, got 'box'$"):
        RasterConfig(kernel="box")
    with pytest.raises(ConfigError, match=r"^background must be a list, each a number, or none, got \["):
        RasterConfig(background=[0.1, math.nan])
    assert RasterConfig(background=[0, 0.5], eps2d=1).background == (0.0, 0.5)


def test_the_kernel_literals_are_defined_once():
    """The training settings' model.kernel and model.k_activation are the rasterizer's own types."""
    model, raster = setting_types(ModelSettings), setting_types(RasterConfig)
    assert model["kernel"] is raster["kernel"] is Kernel
    assert model["k_activation"] is raster["k_activation"] is KActivation


# --- presets and schedules
@pytest.mark.parametrize("name", PRESETS)
def test_presets_pass_and_survive_their_json(name):
    config = preset(name)
    assert from_dict(json.loads(json.dumps(to_dict(config)))) == config


def test_stretched_schedules_stay_in_range():
    for name in PRESETS:
        for epochs in (1, 3, MAX_EPOCHS):
            assert with_epochs(preset(name), epochs).schedule.epochs == epochs
    with pytest.raises(ConfigError, match="epochs must be an integer in"):
        with_epochs(preset("full"), MAX_EPOCHS + 1)
    with pytest.raises(ConfigError, match="epochs must be"):
        with_epochs(preset("full"), 0)


# --- config.json
def test_a_config_json_of_an_older_version_reads_with_defaults():
    """Settings added since a run was written are absent from its config.json: defaults apply."""
    config = from_dict({"schedule": {"epochs": 30}, "model": {"kernel": "gaussian"}})
    assert (config.schedule.epochs, config.model.kernel) == (30, "gaussian")
    assert config.strategy == TrainConfig().strategy and config.init == TrainConfig().init


def test_a_setting_whose_default_changed_reads_as_it_was_where_a_config_lacks_it():
    """The view-dependent opacity is on by default, but a run written before it existed trained
    without it: its config reads as it trained, in either layout; one that holds it keeps it."""
    assert TrainConfig().model.view_opacity
    assert not from_dict({"model": {"kernel": "dog"}}).model.view_opacity
    assert not from_dict({"epochs": 30}).model.view_opacity
    assert from_dict({"model": {"view_opacity": True}}).model.view_opacity
    assert from_dict(to_dict(TrainConfig())) == TrainConfig()


def test_a_retired_setting_in_a_saved_config_is_dropped():
    """`run.snapshot_every` (snapshots nobody read) is gone: run folders that hold it still load,
    in either layout, as today's config; naming it in --set is an unknown setting."""
    saved = to_dict(TrainConfig())
    saved["run"] = {**saved["run"], "snapshot_every": 25}
    assert from_dict(saved) == TrainConfig()
    assert from_dict({"epochs": 30, "snapshot_every": 25}) == from_dict({"epochs": 30})
    with pytest.raises(ConfigError, match="snapshot_every"):
        with_overrides(TrainConfig(), ["run.snapshot_every=5"])


def test_a_flat_config_of_format_2_migrates_to_the_same_config():
    """A run folder written before the sections holds flat names, the renamed ones among them."""
    old = {"epochs": 30, "kernel": "gaussian", "k_init": [0.5, 0.5], "init_count": 2500, "map_floor": 0.2,
           "edge_threshold": 0.4, "sampled_loss_every": 3, "keep_ratio": 0.8, "layer": 1}
    expected = with_overrides(TrainConfig(), ["schedule.epochs=30", "model.kernel=gaussian", "init.k=0.5,0.5",
                                              "model.view_opacity=false",  # written before it existed
                                              "init.count=2500", "maps.floor=0.2", "maps.edge_threshold=0.4",
                                              "loss.sampled_every=3", "strategy.keep_ratio=0.8",
                                              "layers.layer=1"])
    assert from_dict(old) == expected
    assert from_dict(to_dict(expected)) == expected
    assert from_dict(flat_config(to_dict(TrainConfig()))) == TrainConfig()


@pytest.mark.parametrize("values, words", [
    ({"epochs": "two"}, "epochs must be an integer in [1, 10000], got 'two'"),
    ({"epochs": [2]}, "epochs must be an integer"),
    ({"epochs": None}, "epochs must be an integer"),
    ({"epochs": 2.0}, "epochs must be an integer"),
    ({"lr_means": "0.001"}, "lr_means must be a number"),
    ({"lr_means": {"value": 1}}, "lr_means must be a number"),
    ({"k_init": [0.0]}, "init.k must be 2 values"),
    ({"init": {"k": "0,0"}}, "init.k must be 2 values"),
    ({"cull_opacity_epochs": [125, "310"]}, "cull_opacity_epochs must be a list"),
    ({"pixel_uncertainty": "yes"}, "pixel_uncertainty must be true or false"),
    ({"weighting": "Exp"}, "weighting must be one of one, exp_neg, one_minus, up, exp"),
    ({"profile_sigma": 1e9}, "profile_sigma must be a number in (0, 32]"),
    ({"schedule": {"epochs": 5, "learning_rate": 1, "colour": 2}},
     "unknown settings schedule.colour, schedule.learning_rate"),
    ({"schedule": {"epochs": 0}}, "schedule.epochs must be an integer in [1, 10000], got 0"),
    ({"schedule": 3}, "schedule: expected an object of settings, got 3"),
    ({"maps": {}, "colour": {}}, "unknown setting colour"),
    ({"epochs": 5, "colour": 2}, "unknown setting 'colour'"),
    ([1, 2], "expected an object of settings"),
])
def test_a_bad_config_json_is_a_config_error(values, words):
    with pytest.raises(ConfigError) as error:
        from_dict(values)
    assert words in str(error.value)


# --- levels and detector names
@pytest.mark.parametrize("name, known", [
    ("auto", True), ("canny", True), ("sobel", True), ("canny:50,150", True), ("pidinet", True),
    ("pidinet-nyud:side2", True), ("dexined", False), ("my maps", False),
])
def test_detector_names_are_told_from_scene_map_names(name, known):
    assert is_detector_name(name) is known


@pytest.mark.parametrize("name, words", [
    ("canny:5", "expected canny:LOW,HIGH"), ("canny:9,2", "0 <= LOW <= HIGH"), ("canny:", "LOW,HIGH"),
    ("pidinet:side9", "pidinet takes :side1"), ("sobel:3", "sobel takes no options"),
])
def test_a_detector_name_with_bad_options_is_refused_without_the_scene(name, words):
    with pytest.raises(ConfigError, match=words):
        is_detector_name(name)
    with pytest.raises(ConfigError, match=words):
        make_detector(name)


@pytest.mark.parametrize("names, specs, words", [
    (["L0", "L1"], ["L1=canny@2"], "--level 'L1=canny@2': maps.floor must be a number in [0, 1), got 2.0"),
    (["L0", "L1"], ["L1=canny@nan"], "maps.floor must be"),
    (["L0", "L1"], ["L1=canny:5"], "--level 'L1=canny:5': detector 'canny:5'"),
    (["L0", "L1"], ["L1=pidinet:fused2"], "pidinet takes"),
    (["L0", "L1"], [f"L{MAX_LAYERS}=canny"], f"layer must be an integer in [0, {MAX_LAYERS - 1}]"),
    (["L0", "L1"], ["L2=canny"], "--level L2: not among --layers L0,L1"),
    ([f"L{i}" for i in range(MAX_LAYERS + 1)], [], f"at most {MAX_LAYERS} layers"),
])
def test_bad_levels_are_found_before_the_scene_is_read(names, specs, words):
    with pytest.raises(ConfigError) as error:
        resolve_levels(names, specs)
    assert words in str(error.value)


def test_level_maps_are_checked_against_the_scene_before_training(monkeypatch):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    levels = resolve_levels(["L0", "L1"], ["L1=dexined"])
    check_level_maps(levels, ["dexined"])  # the scene's own maps: fine
    with pytest.raises(ConfigError, match=r"level L1=dexined: unknown detector 'dexined'.*maps \(canny\)"):
        check_level_maps(levels, ["canny"])
    with pytest.raises(InputError, match="PiDiNet weights not found"):
        check_level_maps((parse_level("L0=pidinet-nyud"),), ["canny"])
    with pytest.raises(InputError, match="PiDiNet weights not found"):
        require_detector("pidinet-multicue")  # only the BSDS weights ship
