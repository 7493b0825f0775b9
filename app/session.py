"""What the studio has open: a scene, the run folder of each (re)start, and its training worker.

A run folder is what `edgedog train` writes (config.json: scene, preset, config; a layered run's
layers.json), so `edgedog train --resume`, `extract` and `eval` work on the studio's runs too,
and a run the studio finishes ends with the same files (curves and extract.json with scores).
Opening a run folder shows it as saved (`SavedRun`: a finished run as it ended, an interrupted
one at its last checkpoint, with its history) and resumes an interrupted one on the first start,
its plots continued; every restart trains into a new folder beside it, so no earlier run's
checkpoint is ever overwritten.

Each start plans its run as `edgedog train` does (`lifecycle.plan_run`, on a copy of the scene
as the session loaded it: maps computed since for the window are not the scene's own) and opens
it (`edgedog.train.run.open_run`): the run holds its folder's lock from its start until its
worker has ended, so no other edgedog process writes into it meanwhile, and a new folder left
without a checkpoint (a start stopped during the trainer's set-up, or one that failed) is removed
when it ends. A run of one layer and a layered run are the same object.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from edgedog.app.saved_run import SavedRun, layer_detectors
from edgedog.app.worker import FINISHED, Resumed, TrainingWorker

from edgedog.curve_files import EdgeCurves
from edgedog.edges.cache import attach_edge_maps
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import Scene
from edgedog.train.checkpoint import CHECKPOINT
from edgedog.train.config import DEFAULT_PRESET, TrainConfig, preset, with_overrides
from edgedog.train.layers import layer_name
from edgedog.train.levels import resolve_levels
from edgedog.train.lifecycle import (
    CONTINUE,
    START,
    RunPlan,
    RunRecord,
    holds_run,
    load_run_scene,
    plan_run,
    read_record,
)
from edgedog.train.run import Run, open_run
from edgedog.train.run_folder import RUN_CONFIG


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
    """A run being trained: the open run (its folder locked) and the worker training it."""

    run: Run
    worker: TrainingWorker

    @property
    def path(self) -> Path:
        return self.run.path

    def end(self) -> None:
        """Once the worker has ended: close the run (a new folder that holds nothing is removed,
        the lock released)."""
        self.run.close()


class Session:
    """A scene, its runs, and the worker training the current one.

    Attributes:
        preset, config: what the UI starts from (the opened run's, or the preset with the
            command line's overrides).
        resume: the run opened (a run folder, or a layered run), None for a scene.
        active: the latest run started (None before the first start), stopped or not.
        saved: the opened run as saved (finished, or at its last checkpoint), shown until a
            start; None for a scene, or a run that saved nothing yet.
        ground_truth: (M, 3) ground-truth edge points in world coordinates, or None.
    """

    def __init__(self, scene_path: Path, runs_root: Path, preset_name: str = DEFAULT_PRESET,
                 overrides: Sequence[str] = (), resume: RunRecord | None = None):
        self.scene_path, self.runs_root, self.overrides = Path(scene_path), Path(runs_root), list(overrides)
        self.resume = resume
        self.preset = preset_name
        self.config = resume.config if resume else self.base_config(preset_name)
        self.run_config = self.config
        """The current run's config (before any start: the one opened)."""
        self.active: ActiveRun | None = None
        self._ending: list[ActiveRun] = []
        self.runs = 0
        self._scenes: dict[tuple[int, str], Scene] = {}
        """The scenes as loaded: what runs are planned on (fingerprinted with the maps they ship)."""
        self._shown: dict[tuple[int, str], Scene] = {}
        """The same scenes as the window and the trainers use them, other maps attached."""
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
        if holds_run(path.parent):
            path = path.parent
        if not (holds_run(path) or (path / RUN_CONFIG).is_file()):  # a config.json not ours: its error
            return cls(path, runs_root or Path("runs").resolve(), preset_name, overrides)
        run = read_record(path)
        return cls(run.scene, runs_root or path.parent, run.preset, overrides, resume=run)

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
        run = self.resume if self.active is None else self.active.run.plan.run
        return None if run is None else run.curves_folder

    def _saved(self, run: RunRecord, scene: Scene) -> SavedRun | None:
        """The opened run as saved, its maps loaded; None when no layer wrote a checkpoint yet."""
        if not (run.layers()[0].path / CHECKPOINT).is_file():  # the lowest layer trains first
            return None
        saved = SavedRun(run, len(scene))
        for detector in saved.detectors.values():
            attach_edge_maps(scene, detector)  # for the inspectors and the curves' filter
        return saved

    def base_config(self, preset_name: str) -> TrainConfig:
        """A preset with the command line's --set overrides."""
        return with_overrides(preset(preset_name), self.overrides)

    def training_scene(self, config: TrainConfig) -> Scene:
        """The scene as a run of `config` trains on it (`lifecycle.load_run_scene`: its resolution,
        damaged views refused or skipped), loaded once per resolution and choice; the inspectors,
        extractions and trainers attach the maps they compute to it."""
        key = (config.maps.downscale, config.run.damaged_views)
        if key not in self._shown:
            self._shown[key] = dataclasses.replace(self._loaded(key, config))
        return self._shown[key]

    def _planned_scene(self, config: TrainConfig) -> Scene:
        """A copy of the scene as loaded, for a plan: its maps fingerprint is that of the maps the
        scene ships (attaching computed maps to the shown scene would change it, and a resume
        would then be refused as trained on other maps)."""
        return dataclasses.replace(self._loaded((config.maps.downscale, config.run.damaged_views), config))

    def _loaded(self, key: tuple[int, str], config: TrainConfig) -> Scene:
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
        finished = self.saved is not None and self.saved.phase == FINISHED
        return self.resume is not None and self.runs == 0 and not finished

    def start(self, preset_name: str, config: TrainConfig, fresh: bool = False, layers: int = 1
              ) -> TrainingWorker:
        """Stop the current run and start another: the opened run folder, resumed as it was saved,
        on the first start unless `fresh`; a new run folder with `config` otherwise, layered with
        levels L0 .. L<layers - 1> (their default maps) when `layers` > 1. A folder another
        process is writing is an InputError naming it; levels whose maps cannot be had are a
        ConfigError, before any folder is made."""
        self.stop()
        resumed = None
        if self.resumable and not fresh:  # checked as `edgedog train --resume` checks it
            plan = plan_run(self.resume.path, self._planned_scene(self.config), policy=CONTINUE)
            if self.saved is not None:  # the plots go on from the checkpoint
                resumed = Resumed(self.saved.latest, self.saved.series())
        else:
            plan = self._new_plan(preset_name, config, layers)
        run = open_run(plan.check(), progress=False)
        self.runs += 1
        self.run_config, self.saved = plan.run.config, None
        worker = TrainingWorker(run.trainers, self.runs, finish=lambda _: run.finish(),
                                detectors=layer_detectors(run.layers), resumed=resumed)
        self.active = ActiveRun(run, worker)
        worker.start()
        return worker

    def _new_plan(self, preset_name: str, config: TrainConfig, layers: int) -> RunPlan:
        """A new run folder planned as `edgedog train` plans one (scene checked, fingerprinted),
        layered with levels L0 .. L<layers - 1> (their default maps) when `layers` > 1."""
        path = new_run_dir(self.runs_root, self.scene_path.name)
        levels = resolve_levels([layer_name(i) for i in range(layers)]) if layers > 1 else ()
        return plan_run(path, self._planned_scene(config), preset_name, config, START, levels)

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
