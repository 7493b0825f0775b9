"""Typed settings: frozen dataclasses whose fields carry their allowed values in their types.

Every setting's allowed values are written once, in its type: `Annotated[int, Range(1, 400)]`,
a `Literal` of its choices, or a `Check`. `check_setting` reads them; a dataclass of settings
checks its fields with `checked_settings` in its `__post_init__`, and `with_overrides` parses a
`--set` value by the same type.

A field whose type is itself a dataclass is a section: its settings are named `section.field`
(dotted), and a bare field name stands for the one section's field that has it.
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
from collections.abc import Callable, Iterable, Mapping, Sequence
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
class Check:
    """A test of a setting beyond its type and range: `test(value)` raises ConfigError naming
    the setting when the value cannot be used."""

    test: Callable[[Any], None]


@functools.cache
def setting_types(settings: type) -> dict[str, Any]:
    """Field name -> its type with its Annotated rules, for a dataclass of settings."""
    return typing.get_type_hints(settings, include_extras=True)


def is_section(kind: Any) -> bool:
    """Whether a field of type `kind` is a section (a dataclass of settings) rather than a setting."""
    return isinstance(kind, type) and dataclasses.is_dataclass(kind)


@functools.cache
def setting_paths(settings: type) -> dict[str, Any]:
    """Every setting of a dataclass of settings, sections entered: its name ('epochs' in a flat
    dataclass, 'schedule.epochs' in a sectioned one) -> its type, in field order."""
    paths = {}
    for name, kind in setting_types(settings).items():
        if is_section(kind):
            paths.update({f"{name}.{inner}": kind for inner, kind in setting_paths(kind).items()})
        else:
            paths[name] = kind
    return paths


def rules(kind: Any) -> tuple:
    """The Annotated rules of a setting's type (Range, Check, markers), () for a plain type."""
    return _split(kind)[1]


def value_at(settings: Any, path: str) -> Any:
    """The value of the setting `path` ('maps.floor') of a dataclass of settings."""
    for name in path.split("."):
        settings = getattr(settings, name)
    return settings


def with_values(settings: Any, changes: Mapping[str, Any], where: str = "") -> Any:
    """`settings` with the settings named by the dotted paths of `changes` replaced, each value
    checked by `check_setting` under its dotted name (`where`: the prefix of this section's)."""
    kinds = setting_types(type(settings))
    here, inner = {}, {}
    for path, value in changes.items():
        name, dot, rest = path.partition(".")
        if name not in kinds or bool(dot) != is_section(kinds[name]):
            raise ConfigError(f"unknown setting {where + path!r}")
        if dot:
            inner.setdefault(name, {})[rest] = value
        else:
            here[name] = value if is_section(kinds[name]) else check_setting(where + name, kinds[name], value)
    for name, section_changes in inner.items():
        here[name] = with_values(getattr(settings, name), section_changes, f"{where}{name}.")
    return dataclasses.replace(settings, **here) if here else settings


class Settings:
    """The base of a frozen dataclass of settings: every field is checked by `check_setting` when
    one is made (so defaults, presets, `--set` and files read by `from_dict` all are), and holds
    the checked value (a list made a tuple)."""

    def __post_init__(self):
        for name, value in checked_settings(self).items():
            object.__setattr__(self, name, value)  # frozen dataclasses are set this way


def checked_settings(settings) -> dict[str, Any]:
    """Every field of the dataclass `settings` -> its value checked by `check_setting`."""
    kinds = setting_types(type(settings))
    return {f.name: check_setting(f.name, kinds[f.name], getattr(settings, f.name))
            for f in dataclasses.fields(settings)}


def check_setting(name: str, kind: Any, value: Any) -> Any:
    """`value` as setting `name` of type `kind` holds it (an int for a float made a float, a list
    made a tuple, numpy scalars made Python's); raises ConfigError naming the setting and what it
    must be. Floats must be finite."""
    base, annotations = _split(kind)
    if value is None and _optional(base):
        return None
    checked = _typed(name, _without_none(base), value)
    if checked is _WRONG:
        raise ConfigError(f"{name} must be {describe(kind)}, got {shown(value)}")
    for rule in annotations:
        if isinstance(rule, Range) and checked not in rule:
            raise ConfigError(f"{name} must be {describe(kind)}, got {shown(value)}")
        if isinstance(rule, Check):
            rule.test(checked)
    return checked


def describe(kind: Any) -> str:
    """What a value of type `kind` must be, in words: 'an integer >= 1', 'a number in (0, 1) or
    None', 'one of dog, gaussian', '2 values, each a number in [-20, 20]'."""
    base, annotations = _split(kind)
    inner = _without_none(base)
    origin, args = typing.get_origin(inner), typing.get_args(inner)
    if origin is Literal:
        words = f"one of {', '.join(map(str, args))}"
    elif origin is tuple:
        count = "a list" if args[-1] is Ellipsis else f"{len(args)} values"
        words = f"{count}, each {describe(args[0])}"
    else:
        words = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}.get(
            inner, getattr(inner, "__name__", str(inner)))
    words += "".join(f" {rule}" for rule in annotations if isinstance(rule, Range))
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


def item_kind(kind: Any) -> Any | None:
    """The item type of a tuple setting's type (its first for tuple[X, Y]); None for others."""
    base = _without_none(_split(kind)[0])
    return typing.get_args(base)[0] if typing.get_origin(base) is tuple else None


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


def shown(value: Any) -> str:
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
        raise ConfigError(f"{name} must be {describe(kind)}, got {shown(text)}") from None
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


def setting_name(settings: type, key: str, renamed: Mapping[str, str] | None = None) -> str:
    """The dotted name of the setting `key` names in a dataclass of settings: its dotted name, a
    bare field name that exactly one section has, or an old name that `renamed` maps to its
    dotted name. Raises ConfigError (unknown, with a close match; or ambiguous, with the
    candidates)."""
    paths = setting_paths(settings)
    if key in paths:
        return key
    if renamed and key in renamed:
        return renamed[key]
    owners = [path for path in paths if path.rpartition(".")[2] == key]
    if len(owners) == 1:
        return owners[0]
    if owners:
        raise ConfigError(f"setting {key!r} is in several sections; name one of {', '.join(owners)}")
    names = [*paths, *{path.rpartition(".")[2] for path in paths}]
    close = "".join(f" (did you mean {name}?)" for name in difflib.get_close_matches(key, names, n=1))
    raise ConfigError(f"unknown setting {key!r}{close}; settings: {', '.join(paths)}")


def with_overrides(settings, assignments: Iterable[str], renamed: Mapping[str, str] | None = None):
    """`settings` (a dataclass of settings) with the `KEY=VALUE` strings applied, each KEY named
    as `setting_name` takes it and each value read by its setting's type (`parse_setting`). A bad
    one raises ConfigError naming it as given."""
    paths = setting_paths(type(settings))
    changes = {}
    for assignment in assignments:
        key, sep, text = assignment.partition("=")
        given = f"--set {assignment!r}"
        try:
            if not sep:
                raise ConfigError("expected KEY=VALUE")
            path = setting_name(type(settings), key.strip(), renamed)
            changes[path] = parse_setting(path, paths[path], text)
        except ConfigError as error:
            raise ConfigError(f"{given}: {error}") from None
    return with_values(settings, changes)


def to_dict(settings) -> dict:
    """A dataclass of settings as JSON-ready nested dicts (a section: a dict of its settings)."""
    return dataclasses.asdict(settings)


def from_dict(settings: type, values: Any, absent: Mapping[str, Any] | None = None):
    """A dataclass of settings (whose every field has a default) from `to_dict`'s output.
    Settings it lacks (written before they existed) take their value in `absent` (dotted name ->
    value), else their defaults; an unknown or bad one raises ConfigError naming it."""
    paths = _paths(settings, values)
    return with_values(settings(), {**{k: v for k, v in (absent or {}).items() if k not in paths}, **paths})


def _paths(settings: type, values: Any, where: str = "") -> dict[str, Any]:
    """The nested dict `values` of a dataclass of settings as {dotted name: value}."""
    if not isinstance(values, dict):
        raise ConfigError(f"{where.rstrip('.') or 'settings'}: expected an object of settings, "
                          f"got {shown(values)}")
    kinds = setting_types(settings)
    unknown = sorted(map(str, set(values) - kinds.keys()))
    if unknown:
        names = ", ".join(where + name for name in unknown)
        raise ConfigError(f"unknown setting{'s' * (len(unknown) > 1)} {names}")
    paths = {}
    for name, value in values.items():
        if is_section(kinds[name]):
            inner = _paths(kinds[name], value, f"{where}{name}.")
            paths.update({f"{name}.{path}": v for path, v in inner.items()})
        else:
            paths[name] = value
    return paths


__all__ = ["Check", "Range", "Settings", "check_setting", "checked_settings", "describe", "from_dict",
           "is_section", "item_kind", "parse_setting", "rules", "setting_name", "setting_paths",
           "setting_types", "shown", "to_dict", "value_at", "with_overrides", "with_values"]
