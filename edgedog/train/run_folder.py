"""A run folder's config.json: the scene it trains on, the preset named and the full config.

`edgedog train`, the demo, the ablation bench and the studio all write and read it here, so
any of them can resume, extract or inspect a run another one made.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from edgedog.errors import InputError
from edgedog.files import atomic_write_json, read_json
from edgedog.train.config import TrainConfig, from_dict, to_dict

RUN_CONFIG = "config.json"


@dataclass(frozen=True)
class RunFolder:
    """path: the run folder; scene: the scene folder; preset: the preset the config started
    from ('paper' when a file does not say); config: the full resolved config."""

    path: Path
    scene: Path
    preset: str
    config: TrainConfig


def read_run(path: Path) -> RunFolder:
    data = read_json(path / RUN_CONFIG)
    if not isinstance(data, dict) or not {"scene", "config"} <= data.keys():
        raise InputError(path / RUN_CONFIG, "expected 'scene' and 'config' keys (written by edgedog train)")
    return RunFolder(path, Path(data["scene"]), data.get("preset", "paper"), from_dict(data["config"]))


def write_run(run: RunFolder) -> None:
    """Write config.json atomically, creating the run folder if needed."""
    atomic_write_json(run.path / RUN_CONFIG, {"scene": str(run.scene), "preset": run.preset,
                                              "config": to_dict(run.config)})


def config_digest(config: TrainConfig) -> str:
    """Eight hex digits naming a configuration: a default run folder named with them never meets a
    run that another version's defaults made (it would be refused by `check_same_run`)."""
    return hashlib.sha256(json.dumps(to_dict(config), sort_keys=True).encode()).hexdigest()[:8]


def check_same_run(run: RunFolder) -> None:
    """A run folder already there (from an earlier bench or demo) must hold this very run: same scene and
    configuration; a benchmark never mixes two runs in one folder."""
    if (run.path / RUN_CONFIG).is_file():
        existing = read_run(run.path)
        if existing.config != run.config or existing.scene != run.scene:
            raise InputError(run.path, "holds a run of another scene or configuration; choose another --out")
