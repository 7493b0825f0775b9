"""A benchmark suite: its YAML file, checked, and the runs it expands to (`EXAMPLE` shows the
format).

The runs are every scene x preset x grid combination x row x seed, in that nesting order (the
file's order within each), so the same file always gives the same list. Each run's overrides are
`set`, then its grid values, then its row's, then `seed=N`.
"""

from __future__ import annotations

import glob
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

from edgedog.errors import ConfigError, InputError
from edgedog.files import read_yaml
from edgedog.settings import setting_paths, value_at
from edgedog.train.config import DEFAULT_PRESET, MAX_SEED, PRESETS, TrainConfig, preset, with_overrides

EXAMPLE = """\
scenes: [../data/abc_nef/00004926, scenes/*]   # folders or globs, relative to this file
presets: [fast]                                # default [full]
grid:                                          # every combination (optional)
  weighting: [exp_neg, exp]
rows:                                          # named override lists (optional)
  full: []
  no-fisher: [primitive_uncertainty=false]
seeds: [0, 1, 2]                               # default [0]
set: [detector=canny]                          # applied to every run (optional)
"""
"""A suite file: what `edgedog batch --help` shows."""

MAX_RUNS = 10_000
"""Runs one suite may expand to: a grid of a few settings with several values each multiplies fast."""

KEYS = ("scenes", "presets", "grid", "rows", "seeds", "set")
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]*")
"""Row names become part of folder names."""


@dataclass(frozen=True)
class Suite:
    """A checked suite file.

    path: the file; scenes: absolute scene folders (globs expanded, duplicates dropped);
    presets: preset names; grid: (setting, values as --set text) in the file's order;
    rows: (row name, KEY=VALUE overrides); empty when the file has none;
    seeds: training seeds; common: the `set` overrides, applied to every run.
    """

    path: Path
    scenes: tuple[Path, ...]
    presets: tuple[str, ...]
    grid: tuple[tuple[str, tuple[str, ...]], ...]
    rows: tuple[tuple[str, tuple[str, ...]], ...]
    seeds: tuple[int, ...]
    common: tuple[str, ...]


@dataclass(frozen=True)
class RunSpec:
    """One run of a suite.

    name: its folder name under the batch folder, `<scene>_<preset>[_<row>]_<digest>_seed<N>`
    (the digest: 8 hex digits of the overrides before the seed, so a rerun finds its folder);
    configuration: the name without the seed (runs differing only by seed share it);
    scene: the scene folder; preset: the preset; row: the row name (None without rows);
    changes: the grid values and the row's overrides (what sets this configuration apart);
    overrides: every KEY=VALUE applied to the preset, `seed=N` last; seed: N.
    """

    name: str
    configuration: str
    scene: Path
    preset: str
    row: str | None
    changes: tuple[str, ...]
    overrides: tuple[str, ...]
    seed: int

    def config(self):
        """The run's training config (ConfigError when an override cannot be applied)."""
        return with_overrides(preset(self.preset), list(self.overrides))


def load_suite(path: str | Path, overrides: tuple[str, ...] = ()) -> Suite:
    """Read and check a suite file, with `overrides` (the command's --set) applied to every run
    after its `set`; any problem is one InputError naming the file and the key."""
    return suite_from_dict(read_yaml(path), Path(path), overrides)


def suite_from_dict(data, path: Path, overrides: tuple[str, ...] = ()) -> Suite:
    """A Suite from the parsed YAML of the file `path` (scenes resolved relative to its folder),
    with `overrides` after its `set`."""
    path = Path(path)
    if not isinstance(data, dict):
        raise InputError(path, "expected a mapping with keys " + ", ".join(KEYS))
    unknown = [str(key) for key in data if key not in KEYS]
    if unknown:
        raise InputError(path, f"unknown key {unknown[0]!r}; the keys are {', '.join(KEYS)}")
    if "scenes" not in data:
        raise InputError(path, "'scenes' is missing: list scene folders or globs")
    suite = Suite(
        path=path,
        scenes=_scenes(_strings(data["scenes"], path, "scenes"), path),
        presets=_presets(data.get("presets", [DEFAULT_PRESET]), path),
        grid=_grid(data.get("grid", {}), path),
        rows=_rows(data.get("rows", {}), path),
        seeds=_seeds(data.get("seeds", [0]), path),
        common=_strings(data.get("set", []), path, "set", allow_empty=True) + tuple(overrides),
    )
    _check_overrides(suite, len(overrides))
    return suite


def expand(suite: Suite, limit: int = MAX_RUNS) -> list[RunSpec]:
    """Every run of the suite, in a fixed order; InputError when there are more than `limit`."""
    count = math.prod((len(suite.scenes), len(suite.presets), len(suite.rows) or 1, len(suite.seeds),
                       *(len(values) for _, values in suite.grid)))
    if count > limit:
        raise InputError(suite.path, f"expands to {count} runs, more than {limit}; split the suite or "
                                     "shorten its lists")
    names = [key for key, _ in suite.grid]
    combinations = itertools.product(*(values for _, values in suite.grid))
    grid = [tuple(f"{key}={value}" for key, value in zip(names, combination)) for combination in combinations]
    rows = suite.rows or ((None, ()),)
    specs = [make_spec(scene, preset_name, row, suite.common, grid_changes + row_changes, seed)
             for scene, preset_name, grid_changes, (row, row_changes), seed in itertools.product(
                 suite.scenes, suite.presets, grid, rows, suite.seeds)]
    _check_unique_names(specs, suite.path)
    return specs


def make_spec(scene: Path, preset_name: str, row: str | None, common: tuple[str, ...],
              changes: tuple[str, ...], seed: int) -> RunSpec:
    """The run of `preset_name` with the overrides `common`, then `changes`, then the seed (its
    name as `RunSpec` says)."""
    overrides = common + changes
    configuration = "_".join([_folder_name(scene.name), preset_name, *([row] if row else []),
                              _digest(overrides)])
    return RunSpec(f"{configuration}_seed{seed}", configuration, scene, preset_name, row, changes,
                   (*overrides, f"seed={seed}"), seed)


def config_changes(config: TrainConfig, base: TrainConfig) -> tuple[str, ...]:
    """The KEY=VALUE overrides that turn `base` into `config`: each setting whose value differs,
    by dotted name, in the settings' order."""
    return tuple(f"{path}={setting_text(value_at(config, path))}" for path in setting_paths(TrainConfig)
                 if value_at(config, path) != value_at(base, path))


def spec_of_config(scene: Path, preset_name: str, row: str, base: TrainConfig, config: TrainConfig,
                   seed: int) -> RunSpec:
    """The run of `config` (seed aside) as a suite row `row` on top of `base`: its common
    overrides turn the preset into `base`, its changes `base` into `config`, so runs of equal
    configs get one name whatever overrides made them."""
    return make_spec(scene, preset_name, row, config_changes(base, preset(preset_name)),
                     config_changes(config, base), seed)


def _check_unique_names(specs: list[RunSpec], path: Path) -> None:
    """Two scene folders of one name (in different parents) would share run folders."""
    scenes: dict[str, Path] = {}
    for spec in specs:
        other = scenes.setdefault(spec.name, spec.scene)
        if other != spec.scene:
            raise InputError(path, f"scenes: {other} and {spec.scene} have one folder name; their runs "
                                   "would share folders (rename one, or run them in two batches)")


def _digest(overrides: tuple[str, ...]) -> str:
    return hashlib.sha256(json.dumps(list(overrides)).encode()).hexdigest()[:8]


def _folder_name(name: str) -> str:
    """`name` with anything but letters, digits, '.', '+' and '-' replaced by '-'."""
    return re.sub(r"[^A-Za-z0-9.+-]", "-", name) or "scene"


def _strings(value, path: Path, key: str, allow_empty: bool = False) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, list) or (not value and not allow_empty):
        raise InputError(path, f"'{key}' must be a {'' if allow_empty else 'non-empty '}list of strings")
    bad = [item for item in value if not isinstance(item, str) or not item.strip()]
    if bad:
        raise InputError(path, f"'{key}': {bad[0]!r} is not a non-empty string")
    return tuple(value)


def _scenes(entries: tuple[str, ...], path: Path) -> tuple[Path, ...]:
    """Scene folders from folder names and globs, relative to the suite's folder; each entry must
    name at least one folder. A folder named twice (e.g. by two globs) is run once."""
    base = path.parent
    folders: dict[Path, None] = {}
    for entry in entries:
        pattern = base / Path(entry).expanduser()
        if glob.has_magic(entry):
            matches = [Path(match) for match in sorted(glob.glob(str(pattern))) if Path(match).is_dir()]
            if not matches:
                raise InputError(path, f"scenes: {entry!r} matches no folder (relative to {base})")
        elif pattern.is_dir():
            matches = [pattern]
        else:
            raise InputError(path, f"scenes: {entry!r} is not a folder (relative to {base})")
        folders.update(dict.fromkeys(match.resolve() for match in matches))
    return tuple(folders)


def _presets(value, path: Path) -> tuple[str, ...]:
    names = _strings(value, path, "presets")
    unknown = [name for name in names if name not in PRESETS]
    if unknown:
        raise InputError(path, f"presets: unknown preset {unknown[0]!r}; choose {', '.join(PRESETS)}")
    return tuple(dict.fromkeys(names))


def setting_text(value) -> str:
    """A setting's value (or a YAML scalar) as --set text that reads back as it: booleans
    true/false, lists comma-separated, numbers, strings and None as Python writes them."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (tuple, list)):
        return ",".join(setting_text(item) for item in value)
    return str(value)


def _grid(value, path: Path) -> tuple[tuple[str, tuple[str, ...]], ...]:
    if not isinstance(value, dict):
        raise InputError(path, "'grid' must map settings to lists of values")
    grid = []
    for key, values in value.items():
        if not isinstance(values, list) or not values or any(
                isinstance(item, list | dict) or item is None for item in values):
            raise InputError(path, f"grid.{key}: expected a non-empty list of values (numbers, strings, "
                                   "true/false)")
        texts = tuple(dict.fromkeys(setting_text(item) for item in values))
        grid.append((str(key), texts))
    return tuple(grid)


def _rows(value, path: Path) -> tuple[tuple[str, tuple[str, ...]], ...]:
    if not isinstance(value, dict):
        raise InputError(path, "'rows' must map row names to lists of KEY=VALUE overrides")
    rows = []
    for name, overrides in value.items():
        if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
            raise InputError(path, f"rows: name {name!r} must be letters, digits, '.', '_', '+' or '-'")
        rows.append((name, _strings(overrides if overrides is not None else [], path, f"rows.{name}",
                                    allow_empty=True)))
    return tuple(rows)


def _seeds(value, path: Path) -> tuple[int, ...]:
    if not isinstance(value, list) or not value:
        raise InputError(path, "'seeds' must be a non-empty list of integers")
    bad = [seed for seed in value if isinstance(seed, bool) or not isinstance(seed, int)
           or not 0 <= seed <= MAX_SEED]
    if bad:
        raise InputError(path, f"seeds: {bad[0]!r} is not an integer in [0, {MAX_SEED}]")
    return tuple(dict.fromkeys(value))


def _check_overrides(suite: Suite, given_on_command_line: int) -> None:
    """Each override applies on its own to the first preset (unknown settings, values out of
    range), and none sets the seed (that is `seeds`). The last `given_on_command_line` common
    ones came from --set: their errors are ConfigErrors (with no file to name)."""
    base = preset(suite.presets[0])
    from_file = len(suite.common) - given_on_command_line
    given = [("set" if index < from_file else None, item) for index, item in enumerate(suite.common)]
    given += [(f"grid.{key}", f"{key}={value}") for key, values in suite.grid for value in values]
    given += [(f"rows.{name}", item) for name, items in suite.rows for item in items]
    for where, assignment in given:
        try:
            if assignment.partition("=")[0].strip().rpartition(".")[2] == "seed":
                raise ConfigError(f"--set {assignment!r}: list seeds under the suite's 'seeds'")
            with_overrides(base, [assignment])
        except ConfigError as error:
            if where is None:
                raise
            raise InputError(suite.path, f"{where}: {error}") from None
