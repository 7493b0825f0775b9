"""What the studio has open: a scene, the run folder of each (re)start, and its training worker.

A run folder is what `edgedog train` writes (config.json: scene, preset, config), so
`edgedog train --resume`, `extract` and `eval` work on the studio's runs too, and a run the
studio finishes ends with the same files (curves and extract.json with scores). Opening a run
folder resumes it on the first start (a finished one is shown as it ended: `SavedRun`); every
restart trains into a new folder beside it, so no earlier run's checkpoint is ever overwritten.

A run holds its folder's lock (`RunLock`) from its start until its worker has ended, so no other
edgedog process writes into it meanwhile; a new folder left without a checkpoint (a start
stopped during the trainer's set-up, or one that failed) is removed when it ends.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from edgedog.app.saved_run import SavedRun, curves_folder, layer_detectors
from edgedog.app.worker import TrainingWorker

from edgedog.curve_files import EdgeCurves
from edgedog.curves.report import extract_with_report
from edgedog.edges.cache import attach_edge_maps
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import Scene
from edgedog.train.config import DEFAULT_PRESET, TrainConfig, preset, with_overrides
from edgedog.train.layered import (
    LAYERS_FILE,
    LayeredRun,
    continue_layered,
    extract_layered,
    is_layered,
    layer_trainers,
    plan_layered,
    read_layered,
    write_layered,
)
from edgedog.train.layers import layer_name
from edgedog.train.levels import resolve_levels
from edgedog.train.lifecycle import CONTINUE, START, is_finished, load_run_scene, plan_run
from edgedog.train.run_folder import LOCK_FILE, RUN_CONFIG, RunFolder, RunLock, read_run, write_run
from edgedog.train.trainer import Trainer

Run = RunFolder | LayeredRun
"""A run folder, or a layered one (a run folder per layer, `edgedog train --layers`)."""
SCAFFOLD = {RUN_CONFIG, LAYERS_FILE, LOCK_FILE}
"""The files a start writes before any training: a folder holding only these holds no run."""


def new_run_dir(root: Path, name: str) -> Path:
    """`root/<name>-<date>-<time>`, with a counter appended when that exists already."""
    stem = root / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    path, count = stem, 1
    while path.exists():
        count += 1
        path = stem.with_name(f"{stem.name}-{count}")
    return path


@dataclass
class ActiveRun:
    """A run being trained: its folder(s), the lock held on it, and its worker.

    Attributes:
        new: the folder was made for this run (removed if it ends without a checkpoint).
    """

    run: Run
    lock: RunLock
    worker: TrainingWorker
    new: bool

    @property
    def path(self) -> Path:
        return self.run.path

    def end(self) -> None:
        """Once the worker has ended: drop a new folder that holds nothing, release the lock."""
        if self.new:
            discard_empty_run(self.path)
        self.lock.release()


def discard_empty_run(path: Path) -> None:
    """Remove a run folder (a layered one with its layers' folders) when every file in it is one a
    start writes before training (SCAFFOLD); anything else, e.g. a checkpoint, keeps it all."""
    folders = [path, *sorted((p for p in path.rglob("*") if p.is_dir()), reverse=True)]
    files = [p for p in path.rglob("*") if not p.is_dir()]
    if any(file.name not in SCAFFOLD for file in files):
        return
    for file in files:
        file.unlink()
    for folder in folders[1:] + folders[:1]:  # the deepest first, the run folder last
        folder.rmdir()


def run_config(run: Run) -> TrainConfig:
    """The configuration a run starts from (a layered run's base, which every layer shares but
    for its maps)."""
    return run.base if isinstance(run, LayeredRun) else run.config


def top_layer(run: LayeredRun) -> Path:
    return run.layer_dir(len(run.levels) - 1)


class Session:
    """A scene, its runs, and the worker training the current one.

    Attributes:
        preset, config: what the UI starts from (the opened run's, or the preset with the
            command line's overrides).
        active: the latest run started (None before the first start), stopped or not.
        saved: the opened run when it is finished, shown until a start.
        ground_truth: (M, 3) ground-truth edge points in world coordinates, or None.
    """

    def __init__(self, scene_path: Path, runs_root: Path, preset_name: str = DEFAULT_PRESET,
                 overrides: Sequence[str] = (), resume: Run | None = None):
        self.scene_path, self.runs_root, self.overrides = Path(scene_path), Path(runs_root), list(overrides)
        self.resume = resume
        self.preset = preset_name
        self.config = run_config(resume) if resume else self.base_config(preset_name)
        self.run_config = self.config
        """The current run's config (before any start: the one opened)."""
        self.active: ActiveRun | None = None
        self._ending: list[ActiveRun] = []
        self.runs = 0
        self._scenes: dict[tuple[int, str], Scene] = {}
        scene = self.training_scene(self.config)  # a bad folder fails here, before any window
        self.saved = None if resume is None else self._saved(resume, scene)
        self.ground_truth = None
        source = ground_truth_for(scene.root)
        if source is not None:
            world = EdgeCurves(points=source.load()).transformed(np.linalg.inv(scene.world_to_gt))
            self.ground_truth = world.points

    @classmethod
    def open(cls, path: str | Path, runs_root: Path | None = None, preset_name: str = DEFAULT_PRESET,
             overrides: Sequence[str] = ()) -> Session:
        """A scene folder, or a run folder (one with config.json, or a layered run's layers.json)
        to resume, or to show when finished; a layer's folder opens its layered run.

        Runs go to `runs_root`: by default ./runs for a scene, the run's parent folder for a run.
        """
        path = Path(path).expanduser().resolve()
        if not is_layered(path) and is_layered(path.parent) and (path / RUN_CONFIG).is_file():
            path = path.parent
        if is_layered(path):
            layered = read_layered(path)
            return cls(layered.scene, runs_root or path.parent, layered.preset, overrides, resume=layered)
        if (path / RUN_CONFIG).is_file():
            run = read_run(path)
            return cls(run.scene, runs_root or path.parent, run.preset, overrides, resume=run)
        return cls(path, runs_root or Path("runs").resolve(), preset_name, overrides)

    @property
    def opened(self) -> Path:
        """The folder the user opened."""
        return self.resume.path if self.resume else self.scene_path

    @property
    def worker(self) -> TrainingWorker | SavedRun | None:
        """What the window shows: the current run's worker, or the finished run opened."""
        return self.active.worker if self.active is not None else self.saved

    @property
    def run_dir(self) -> Path | None:
        """The folder of the run shown."""
        if self.active is not None:
            return self.active.path
        return None if self.saved is None else self.resume.path

    @property
    def curves_folder(self) -> Path | None:
        """Where the run shown keeps the curves of its whole model once finished."""
        run = self.resume if self.active is None else self.active.run
        if run is None:
            return None
        layered = run if isinstance(run, LayeredRun) else None
        return curves_folder(run.path, layered)

    def _saved(self, run: Run, scene: Scene) -> SavedRun | None:
        """The opened run as it ended, when it is finished (None otherwise), its maps loaded."""
        layered = run if isinstance(run, LayeredRun) else None
        folder = run.path if layered is None else top_layer(layered)
        if not is_finished(folder):
            return None
        saved = SavedRun(read_run(folder) if layered else run, len(scene), layered)
        for detector in saved.detectors.values():
            attach_edge_maps(scene, detector)  # for the inspectors and the curves' filter
        return saved

    def base_config(self, preset_name: str) -> TrainConfig:
        """A preset with the command line's --set overrides."""
        return with_overrides(preset(preset_name), self.overrides)

    def training_scene(self, config: TrainConfig) -> Scene:
        """The scene as a run of `config` trains on it (`lifecycle.load_run_scene`: its resolution,
        damaged views refused or skipped), loaded once per resolution and choice."""
        key = (config.maps.downscale, config.run.damaged_views)
        if key not in self._scenes:
            self._scenes[key] = load_run_scene(self.scene_path, config)
        return self._scenes[key]

    @property
    def scene(self) -> Scene:
        """The scene of the current run (or of the configuration opened)."""
        return self.training_scene(self.run_config)

    @property
    def resumable(self) -> bool:
        """Whether a start (not a restart) would continue the opened run folder."""
        return self.resume is not None and self.runs == 0 and self.saved is None

    def start(self, preset_name: str, config: TrainConfig, fresh: bool = False, layers: int = 1
              ) -> TrainingWorker:
        """Stop the current run and start another: the opened run folder, resumed as it was saved,
        on the first start unless `fresh`; a new run folder with `config` otherwise, layered with
        levels L0 .. L<layers - 1> (their default maps) when `layers` > 1. A folder another
        process is writing is an InputError naming it; levels whose maps cannot be had are a
        ConfigError, before any folder is made."""
        self.stop()
        new = not (self.resumable and not fresh)
        run = self._new_run(preset_name, config, layers) if new else self._continued(self.resume)
        lock = RunLock.acquire(run.path)
        try:
            if new:
                (write_layered if isinstance(run, LayeredRun) else write_run)(run)
        except BaseException:
            ActiveRun(run, lock, None, new).end()
            raise
        self.runs += 1
        self.run_config, self.saved = run_config(run), None
        worker = self._worker(run)
        self.active = ActiveRun(run, lock, worker, new)
        worker.start()
        return worker

    def _new_run(self, preset_name: str, config: TrainConfig, layers: int) -> Run:
        """A new run folder planned as `edgedog train` plans one (scene checked, fingerprinted)."""
        path = new_run_dir(self.runs_root, self.scene_path.name)
        if layers <= 1:
            return plan_run(path, self.scene_path, preset_name, config, START).check().run
        levels = resolve_levels([layer_name(i) for i in range(layers)])
        return plan_layered(path, self.scene_path, preset_name, config, levels)[0]

    def _continued(self, run: Run) -> Run:
        """The opened run, checked as `edgedog train --resume` checks it (its scene unchanged)."""
        if isinstance(run, LayeredRun):
            return continue_layered(run.path, self.scene_path)[0]
        return plan_run(run.path, self.scene_path, policy=CONTINUE).check().run

    def _worker(self, run: Run) -> TrainingWorker:
        """The worker that trains `run` and then writes what `edgedog train` writes after training."""
        scene = self.training_scene(run_config(run))
        if isinstance(run, LayeredRun):
            return TrainingWorker(lambda: layer_trainers(run, scene, progress=False), self.runs,
                                  finish=lambda _: extract_layered(run, scene),
                                  detectors=layer_detectors(run))

        def trainers() -> Iterator[Trainer]:
            yield Trainer(scene, run.config, run.path, progress=False)

        return TrainingWorker(trainers, self.runs,
                              finish=lambda trainer: extract_with_report(run.path, scene, trainer.detector))

    def stop(self, timeout: float | None = 1.0) -> bool:
        """Stop the current run's worker; returns whether every run stopped so far has ended
        within `timeout` seconds (None: however long a trainer's set-up takes). One that has
        not ends in the background: `reap` finishes it."""
        if self.active is not None and self.active not in self._ending:
            self._ending.append(self.active)
        for run in self._ending:
            run.worker.stop(timeout)
        return self.reap()

    def reap(self) -> bool:
        """Finish the stopped runs whose workers have ended; returns whether none is left."""
        for run in [run for run in self._ending if not run.worker.alive]:
            run.end()
            self._ending.remove(run)
        return not self._ending
