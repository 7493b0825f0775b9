"""The edge maps of each level of a multi-granularity model: which detector, which threshold.

Level L0 holds coarse, object-level edges; each next level finer ones. With PiDiNet weights the
levels are the paper's: NYUD (object level), BSDS500, Multicue (fine boundaries). Without them,
Canny at decreasing hysteresis thresholds stands in (strong edges first, then weaker ones).
"""

from __future__ import annotations

import re
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from edgedog.edges.registry import pidinet_available, require_detector
from edgedog.errors import ConfigError
from edgedog.settings import check_setting, parse_setting, setting_paths
from edgedog.train.config import MAX_LAYERS, TrainConfig

_NAME = re.compile(r"L(\d+)")


@dataclass(frozen=True)
class Level:
    """name: 'L0', 'L1', ...; detector: a detector or scene-map name (see make_detector);
    floor: map values below it are set to zero (a higher floor keeps only stronger edges)."""

    name: str
    detector: str
    floor: float = 0.0

    @property
    def index(self) -> int:
        return int(self.name[1:])


PIDINET_LEVELS = (Level("L0", "pidinet-nyud"), Level("L1", "pidinet"), Level("L2", "pidinet-multicue"))
CANNY_LEVELS = (Level("L0", "canny:150,300"), Level("L1", "canny:50,150"), Level("L2", "canny:20,60"))


def default_levels(weights: str | Path | None = None) -> dict[str, Level]:
    """The level table: PiDiNet's three training sets when its weights can be found, else Canny."""
    levels = PIDINET_LEVELS if pidinet_available(weights) else CANNY_LEVELS
    return {level.name: level for level in levels}


def parse_level(spec: str) -> Level:
    """'L1=pidinet' or 'L1=canny:50,150@0.3' (detector, then an optional floor after '@').

    The level's layer index, detector name and floor are checked as the settings they become
    (layers.layer, maps.detector, maps.floor); a name that is no detector's may be a scene's own maps, which
    `check_level_maps` checks once the scene is loaded.
    """
    name, sep, rest = spec.partition("=")
    detector, _, floor = rest.partition("@")
    if not sep or not _NAME.fullmatch(name) or not detector:
        raise ConfigError(f"--level {spec!r}: expected NAME=DETECTOR[@FLOOR] with NAME L0, L1, ...")
    kinds = setting_paths(TrainConfig)
    try:
        level = Level(name, check_setting("maps.detector", kinds["maps.detector"], detector),
                      parse_setting("maps.floor", kinds["maps.floor"], floor) if floor else 0.0)
        check_setting("layers.layer", kinds["layers.layer"], level.index)
    except ConfigError as error:
        raise ConfigError(f"--level {spec!r}: {error}") from None
    return level


def resolve_levels(names: list[str], specs: list[str] = (), weights: str | Path | None = None
                   ) -> tuple[Level, ...]:
    """The levels to train, bottom first: `names` ('L0', 'L1', ... consecutive from L0) looked up
    in the default table overridden by `specs` (see parse_level)."""
    if len(names) > MAX_LAYERS:
        raise ConfigError(f"--layers {','.join(names)}: at most {MAX_LAYERS} layers")
    given = {level.name: level for level in map(parse_level, specs)}
    table = {**default_levels(weights), **given}
    expected = [f"L{i}" for i in range(len(names))]
    if list(names) != expected:
        raise ConfigError(f"--layers {','.join(names)}: layers stack from L0 up, "
                          f"expected {','.join(expected)}")
    unused = [name for name in given if name not in names]
    if unused:
        raise ConfigError(f"--level {', '.join(unused)}: not among --layers {','.join(names)}")
    missing = [name for name in names if name not in table]
    if missing:
        raise ConfigError(f"no level {', '.join(missing)}: define it with --level NAME=DETECTOR[@FLOOR]")
    return tuple(table[name] for name in names)


def check_level_maps(levels: tuple[Level, ...], scene_maps: Collection[str],
                     weights: str | Path | None = None) -> None:
    """Every level's maps can be had: the scene's own maps of that name (`scene_maps`, as
    `Scene.detectors` lists them), or a detector edgedog can build (PiDiNet's weights found).
    Called once the scene is loaded, before any layer trains; raises ConfigError naming the
    level (InputError naming the missing weights file)."""
    for level in levels:
        if level.detector in scene_maps:
            continue
        try:
            require_detector(level.detector, weights)
        except ConfigError as error:
            raise ConfigError(f"level {level.name}={level.detector}: {error}; nor is it one of the scene's "
                              f"maps ({', '.join(scene_maps) or 'it has none'})") from None
