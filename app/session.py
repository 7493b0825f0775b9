"""What the studio has open: a scene, the run folder of each (re)start, and its training worker.

A run folder is what `edgedog train` writes (config.json: scene, preset, config), so
`edgedog train --resume`, `extract` and `eval` work on the studio's runs too. Opening a run
folder resumes it on the first start; every restart trains into a new folder beside it, so
no earlier run's checkpoint is ever overwritten.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from edgedog.app.worker import TrainingWorker

from edgedog.curve_files import EdgeCurves
from edgedog.scenes import Scene, load_scene
from edgedog.train.config import TrainConfig, preset, with_overrides
from edgedog.train.layered import is_layered, read_layered
from edgedog.train.run_folder import RUN_CONFIG, RunFolder, read_run, write_run
from edgedog.train.trainer import Trainer


def new_run_dir(root: Path, name: str) -> Path:
    """`root/<name>-<date>-<time>`, with a counter appended when that exists already."""
    stem = root / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    path, count = stem, 1
    while path.exists():
        count += 1
        path = stem.with_name(f"{stem.name}-{count}")
    return path


class Session:
    """A scene, its runs, and the worker training the current one.

    Attributes:
        preset, config: what the UI starts from (the opened run's, or the preset with the
            command line's overrides).
        worker: the current run's worker (None before the first start).
        ground_truth: (M, 3) ground-truth edge points in world coordinates, or None.
    """

    def __init__(self, scene_path: Path, runs_root: Path, preset_name: str = "paper",
                 overrides: Sequence[str] = (), resume: RunFolder | None = None):
        self.scene_path, self.runs_root, self.overrides = Path(scene_path), Path(runs_root), list(overrides)
        self.resume = resume
        self.preset = preset_name
        self.config = resume.config if resume else self.base_config(preset_name)
        self.run_config = self.config
        """The current run's config (before any start: the one opened)."""
        self.worker: TrainingWorker | None = None
        self.run_dir: Path | None = None
        """The folder the current run writes into."""
        self.runs = 0
        self._scenes: dict[int, Scene] = {}
        scene = self.scene_at(self.config.downscale)  # a bad folder fails here, before any window
        self.ground_truth = None
        if scene.ground_truth is not None:
            world = EdgeCurves(points=scene.ground_truth.load()).transformed(np.linalg.inv(scene.world_to_gt))
            self.ground_truth = world.points

    @classmethod
    def open(cls, path: str | Path, runs_root: Path | None = None, preset_name: str = "paper",
             overrides: Sequence[str] = ()) -> Session:
        """A scene folder, or a run folder (one with config.json) to resume; a layered run opens
        its top layer, which holds every layer.

        Runs go to `runs_root`: by default ./runs for a scene, the run's parent folder for a run.
        """
        path = Path(path).expanduser().resolve()
        if is_layered(path):
            layered = read_layered(path)
            path = layered.layer_dir(len(layered.levels) - 1)
        if (path / RUN_CONFIG).is_file():
            run = read_run(path)
            return cls(run.scene, runs_root or path.parent, run.preset, overrides, resume=run)
        return cls(path, runs_root or Path("runs").resolve(), preset_name, overrides)

    @property
    def opened(self) -> Path:
        """The folder the user opened."""
        return self.resume.path if self.resume else self.scene_path

    def base_config(self, preset_name: str) -> TrainConfig:
        """A preset with the command line's --set overrides."""
        return with_overrides(preset(preset_name), self.overrides)

    def scene_at(self, downscale: int) -> Scene:
        """The scene at a run's resolution (loaded once per downscale)."""
        if downscale not in self._scenes:
            self._scenes[downscale] = load_scene(self.scene_path, downscale=downscale)
        return self._scenes[downscale]

    @property
    def scene(self) -> Scene:
        """The scene at the resolution of the current run (or of the configuration opened)."""
        return self.scene_at(self.run_config.downscale)

    @property
    def resumable(self) -> bool:
        """Whether a start (not a restart) would continue the opened run folder."""
        return self.resume is not None and self.runs == 0

    def start(self, preset_name: str, config: TrainConfig, fresh: bool = False) -> TrainingWorker:
        """Stop the current run and start another: the opened run folder, resumed as it was saved,
        on the first start unless `fresh`; a new run folder with `config` otherwise."""
        self.stop()
        if self.resumable and not fresh:
            run = self.resume
        else:
            run = RunFolder(new_run_dir(self.runs_root, self.scene_path.name), self.scene_path.resolve(),
                            preset_name, config)
            write_run(run)
        self.runs += 1
        self.run_dir, self.run_config = run.path, run.config
        scene = self.scene_at(run.config.downscale)
        self.worker = TrainingWorker(lambda: Trainer(scene, run.config, run.path, progress=False), self.runs)
        self.worker.start()
        return self.worker

    def stop(self, timeout: float = 1.0) -> bool:
        """Stop the current run's worker; returns whether it stopped within `timeout` seconds."""
        return self.worker is None or self.worker.stop(timeout)
