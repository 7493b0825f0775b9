"""The edge maps of each level of a multi-granularity model: which detector, which threshold.

Level L0 holds coarse, object-level edges; each next level finer ones. With PiDiNet weights the
levels are the paper's: NYUD (object level), BSDS500, Multicue (fine boundaries). Without them,
Canny at decreasing hysteresis thresholds stands in (strong edges first, then weaker ones).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from edgedog.edges.registry import pidinet_available
from edgedog.errors import ConfigError

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
    """'L1=pidinet' or 'L1=canny:50,150@0.3' (detector, then an optional floor after '@')."""
    name, sep, rest = spec.partition("=")
    detector, _, floor = rest.partition("@")
    if not sep or not _NAME.fullmatch(name) or not detector:
        raise ConfigError(f"--level {spec!r}: expected NAME=DETECTOR[@FLOOR] with NAME L0, L1, ...")
    try:
        return Level(name, detector, float(floor) if floor else 0.0)
    except ValueError:
        raise ConfigError(f"--level {spec!r}: cannot read the floor {floor!r} as a number") from None


def resolve_levels(names: list[str], specs: list[str] = (), weights: str | Path | None = None
                   ) -> tuple[Level, ...]:
    """The levels to train, bottom first: `names` ('L0', 'L1', ... consecutive from L0) looked up
    in the default table overridden by `specs` (see parse_level)."""
    table = {**default_levels(weights), **{level.name: level for level in map(parse_level, specs)}}
    expected = [f"L{i}" for i in range(len(names))]
    if list(names) != expected:
        raise ConfigError(f"--layers {','.join(names)}: layers stack from L0 up, "
                          f"expected {','.join(expected)}")
    missing = [name for name in names if name not in table]
    if missing:
        raise ConfigError(f"no level {', '.join(missing)}: define it with --level NAME=DETECTOR[@FLOOR]")
    return tuple(table[name] for name in names)
