"""An open run: one object that owns a run folder while it trains, whatever its number of layers.

`open_run(plan)` takes the folder's lock, checks the folder again under it (another process may
have started or finished a run there since it was planned), writes the run's record when it is
new (config.json, or a layered run's layers.json) and returns a `Run`. A run is a stack of
layers, trained bottom up, each by its own `Trainer` with the layers below fixed: a run of one
layer is the same object with a stack of one. The caller trains it (`Run.train`, `Run.step`, or
the trainers one by one, `Run.trainers`, as the studio's worker does), extracts its curves
(`Run.finish`) and closes it (`Run.close`, or a `with` block): the lock is released, and a new
folder that holds nothing trained (a start that failed or stopped before its first checkpoint) is
removed.

A viewer takes immutable snapshots of a trainer (`Trainer.snapshot`), never the run's live tensors.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

from edgedog.files import read_json
from edgedog.scenes import Scene
from edgedog.train.checkpoint import CHECKPOINT
from edgedog.train.layered import LAYERS_FILE
from edgedog.train.lifecycle import (
    CONTINUE,
    NEW,
    RunPlan,
    RunResult,
    is_finished,
    load_run_scene,
    lock_folder,
    replan,
)
from edgedog.train.run_folder import LOCK_FILE, LOG, RUN_CONFIG, RunFolder, RunLock, write_run
from edgedog.train.trainer import Trainer, read_stack

SCAFFOLD = {RUN_CONFIG, LAYERS_FILE, LOCK_FILE}
"""The files a run writes before any training: a folder holding only these holds no run."""


def discard_scaffold(path: Path, remove_folder: bool = True) -> bool:
    """Remove what a start wrote into the run folder `path` (a layered one's layer folders too)
    when every file in it is SCAFFOLD, and the folder itself when `remove_folder`; anything else,
    e.g. a checkpoint, keeps it all. Returns whether it was removed."""
    folders = sorted((p for p in path.rglob("*") if p.is_dir()), reverse=True)  # the deepest first
    files = [p for p in path.rglob("*") if not p.is_dir()]
    if any(file.name not in SCAFFOLD for file in files):
        return False
    for file in files:
        file.unlink()
    for folder in folders + ([path] if remove_folder else []):
        folder.rmdir()
    return True


class Run:
    """A run being trained, its folder locked (made by `open_run`).

    Attributes:
        plan: the plan as read again under the lock (its state and step are the folder's now).
        scene: the scene at the run's resolution, which every layer trains on.
        layers: the run folder of each layer, bottom first (one for a run of one layer).
        trainer: the trainer built last (None before the first; finished layers get none).
        trained: whether a trainer was built, i.e. a layer trained or was loaded to be written again.
    """

    def __init__(self, plan: RunPlan, scene: Scene, lock: RunLock, made: bool, progress: bool):
        self.plan, self.scene, self.progress = plan, scene, progress
        self.layers: tuple[RunFolder, ...] = plan.run.layers()
        self.trainer: Trainer | None = None
        self.trained = False
        self._lock, self._made = lock, made
        self._left = self.trainers()
        self._ended = False  # whether `trainer` was trained to its end and wrote its outputs

    @property
    def path(self) -> Path:
        return self.plan.run.path

    def trainers(self) -> Iterator[Trainer]:
        """The trainers of the layers left, bottom up, each built once the layers below are
        trained; a finished layer is reused (its checkpoint holds the stack up to it), but the
        top layer of a finished run continued (CONTINUE) is loaded all the same: its checkpoint is
        checked and its outputs written again. The caller trains each to its end and writes its
        outputs before asking for the next (`Trainer.run` does both)."""
        lower = None
        top = len(self.layers) - 1
        for index, layer in enumerate(self.layers):
            if is_finished(layer.path) and not (index == top and self.plan.policy == CONTINUE):
                lower = read_stack(layer.path)
                continue
            if not (layer.path / RUN_CONFIG).is_file():
                write_run(layer)
            trainer = Trainer(self.scene, layer.config, layer.path, progress=self.progress, lower=lower)
            self.trainer, self._ended, self.trained = trainer, False, True
            yield trainer
            lower = trainer.stack()

    def current(self) -> Trainer | None:
        """The trainer of the lowest layer not trained to its end by this run (built when first
        asked for); None when no layer is left."""
        if self.trainer is None or self._ended:
            return next(self._left, None)
        return self.trainer

    @property
    def done(self) -> bool:
        """Whether every layer is trained (asking builds the next layer's trainer when one is left)."""
        return self.current() is None

    def step(self) -> float:
        """One training step of the lowest layer left; a layer that reaches its end writes its
        outputs (as `Trainer.run`) and the next step builds the trainer of the layer above.
        Returns the step's projection loss (NaN for a layer loaded at its end). ValueError when
        no layer is left."""
        trainer = self.current()
        if trainer is None:
            raise ValueError(f"{self.path}: every layer is trained")
        loss = float("nan")
        if not trainer.done:
            trainer.step()
            loss = trainer.last_loss
        if trainer.done:
            trainer.write_outputs()
            self._ended = True
        return loss

    def train(self, until: int | None = None, on_trainer: Callable[[Trainer], None] | None = None) -> None:
        """Train the layers left bottom up, each to its end with its outputs written; with
        `until`, stop once the layer training reaches its epoch `until` (the outputs of a layer
        stopped before its end are not written: `Trainer.write_outputs`).

        Args:
            on_trainer: called with each layer's trainer before it trains (e.g. to print where it starts).
        """
        announced = None
        while (trainer := self.current()) is not None:
            if on_trainer is not None and trainer is not announced:
                on_trainer(trainer)
                announced = trainer
            if until is None:
                trainer.run()
                self._ended = True
                continue
            while not self._ended and trainer.epoch < until:
                self.step()
            if not self._ended:
                return

    def finish(self) -> RunResult:
        """Once every layer is trained: extract the curves (every selection of a layered run)
        when a layer trained or their report is missing; the result holds the top layer's
        log.json and the extraction report (of a layered run: every selection's)."""
        log = read_json(self.layers[-1].path / LOG)
        run = self.plan.run
        extract = self.trained or not self.plan.extracted
        report = run.extract(self.scene) if extract else read_json(run.report_file)
        return RunResult(self.plan, log, report)

    def close(self) -> None:
        """Release the lock; a new run's folder that holds nothing trained (no checkpoint: a start
        that failed or stopped before it) is removed first, the folder itself when this run made it."""
        if self.plan.state == NEW and not any((layer.path / CHECKPOINT).is_file() for layer in self.layers):
            discard_scaffold(self.path, remove_folder=self._made)
        self._lock.release()

    def __enter__(self) -> Run:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def open_run(plan: RunPlan, progress: bool = True) -> Run:
    """Open the run of `plan`: lock its folder, read the folder again under the lock, take the
    scene the plan carries (loaded here when it carries none) and write the run's record when
    the run is new.

    Raises:
        InputError: the plan is refused, the folder is locked by another process, or it changed
            since it was planned (a new folder is then left as it was).
    """
    run = plan.check().run
    made = not run.path.exists()
    lock = lock_folder(run.path)
    try:
        current = replan(plan).check()
        scene = plan.scene if plan.scene is not None else load_run_scene(run.scene, run.config)
        if current.state == NEW:
            run.write()
    except BaseException:
        if plan.state == NEW:  # refused before training: leave the folder as it was
            lock.discard(remove_folder=made)
        raise
    return Run(current, scene, lock, made, progress)
