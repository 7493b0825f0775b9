"""The training thread: builds the trainers of a run's layers (`edgedog.train.run.Run.trainers`:
one per layer, bottom up; a run of one layer has one), steps them, and publishes immutable
snapshots.

Only this thread calls the trainers' methods. The window reads what it publishes (`latest`,
`series`, `info`, `error`) and asks for control changes, which this thread applies between two
steps and records in the trainer's events (so in log.json). Stopping is checked between steps,
so it takes at most one step once training runs; a trainer's set-up (edge maps, initial points)
cannot be interrupted, and `join` waits for it. A stopped run keeps its last checkpoint (the
trainer writes those atomically at epoch ends) and writes nothing more; a finished one writes
its outputs, then runs `finish` (the curves and their report, as `edgedog train` does).
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from edgedog.renderer.config import RasterConfig

    from edgedog.train.trainer import Snapshot, Trainer

STARTING, TRAINING, PAUSED = "starting", "training", "paused"
FINISHING, FINISHED, STOPPED, FAILED = "extracting curves", "finished", "stopped", "failed"
"""What the worker is doing (`TrainingWorker.phase`)."""
PAUSE_POLL = 0.05
"""Seconds between two looks at the stop flag while paused."""
PUBLISH_EVERY = 0.5
"""Seconds between two snapshots: about the window's idle frame rate (a faster one would only
cost copies that are never shown)."""


@dataclass(frozen=True)
class Published:
    """One snapshot as the window sees it.

    Attributes:
        run: which run of the session (a restart starts another); version: counts this run's
            publications; snapshot: the trainer's immutable Snapshot; elapsed: seconds since
            the run started.
    """

    run: int
    version: int
    snapshot: Snapshot
    elapsed: float

    @property
    def key(self) -> tuple[int, int]:
        """Identifies the snapshot across restarts (what caches compare)."""
        return self.run, self.version


@dataclass(frozen=True)
class RunInfo:
    """What the trainer settled on when it was built."""

    detector: str
    raster: RasterConfig
    run_dir: Path
    epochs: int
    views: int
    resumed_at_step: int


@dataclass(frozen=True)
class Resumed:
    """Where a resumed run's worker starts from: the snapshot shown (elapsed: the seconds trained
    before) and the (K, 3) series so far (see `TrainingWorker.series`)."""

    latest: Published
    series: np.ndarray


LIVE_EVENT = "live_controls"
"""The event (in the trainer's events, so in log.json) recording a live change of p or w(Up)."""


class TrainingWorker:
    """Trains the trainers `make_trainers()` yields, one after the other, in a daemon thread
    until done or stopped, then calls `finish(last trainer)`.

    A trainer needs `step() -> loss`, `done`, `snapshot(loss)`, `controls` (read/update),
    `events`, `write_outputs()`, `detector`, `raster`, `out`, `config.schedule.epochs`, `cameras`,
    `step_index`, `epoch`. The generator builds the next trainer after the last one finished
    (a layered run's next layer starts from the layers below).
    """

    def __init__(self, make_trainers: Callable[[], Iterator[Trainer]], run: int = 0,
                 publish_every: float = PUBLISH_EVERY, finish: Callable[[Trainer], object] | None = None,
                 detectors: dict[int, str] | None = None, resumed: Resumed | None = None):
        """`resumed`: what the run showed before (a run folder opened at its last checkpoint): its
        snapshot is shown until the first publication, its series continues, and elapsed
        seconds count on from its."""
        self.run, self.publish_every = run, publish_every
        self._make_trainers, self._finish = make_trainers, finish
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._pending: dict = {}
        self._trainer: Trainer | None = None
        self._latest: Published | None = None
        self._series: list[tuple[float, float, int]] = []
        self._elapsed_before = 0.0
        if resumed is not None:
            self._latest = Published(run, 0, resumed.latest.snapshot, resumed.latest.elapsed)
            self._series = [tuple(row) for row in resumed.series.tolist()]
            self._elapsed_before = resumed.latest.elapsed
        self._steps, self._training_seconds = 0, 0.0
        self.phase = STARTING
        self.info: RunInfo | None = None
        """The trainer's settled choices (of the layer training now, in a layered run)."""
        self.detectors: dict[int, str] = dict(detectors or {})
        """Layer index -> the maps it was fitted to: of the layers finished before (given) and of
        each trained since."""
        self.error: str | None = None
        """One line, "Type: message", when the trainer raised; `traceback` has the rest."""
        self.traceback: str | None = None
        self._thread = threading.Thread(target=self._run, name=f"edgedog-train-{run}", daemon=True)
        self._started = self._last_publish = 0.0

    # --- the window's side
    def start(self) -> None:
        self._started = time.perf_counter() - self._elapsed_before
        self._thread.start()

    def update_controls(self, **changes) -> None:
        """keep_ratio, weighting, paused: applied by the training thread before its next step."""
        with self._lock:
            self._pending.update(changes)

    def stop(self, timeout: float | None = 1.0) -> bool:
        """Ask the thread to stop after its current step; returns whether it ended within `timeout`
        seconds (None: wait however long a trainer's set-up or the final extraction takes)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)
        return not self._thread.is_alive()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    @property
    def latest(self) -> Published | None:
        with self._lock:
            return self._latest

    def series(self) -> np.ndarray:
        """(K, 3) one row per publication: elapsed seconds, mean loss since the last one, primitives."""
        with self._lock:
            return np.array(self._series, np.float64).reshape(-1, 3)

    @property
    def steps_per_second(self) -> float:
        """Steps per second of training time (paused time not counted)."""
        with self._lock:
            return self._steps / self._training_seconds if self._training_seconds > 0 else 0.0

    @property
    def steps(self) -> int:
        with self._lock:
            return self._steps

    def trainer_controls(self) -> dict | None:
        """The controls the trainer holds now (None before it is built)."""
        trainer = self._trainer
        if trainer is None:
            return None
        keep_ratio, weighting, paused = trainer.controls.read()  # Controls is thread-safe
        return {"keep_ratio": keep_ratio, "weighting": weighting, "paused": paused}

    # --- the training thread
    def _run(self) -> None:
        try:
            self._train()
        except Exception as error:  # shown in the window; the app keeps running
            self.error = f"{type(error).__name__}: {error}"
            self.traceback = traceback.format_exc()
            self.phase = FAILED

    def _train(self) -> None:
        trainer = None
        for trainer in self._make_trainers():
            if not self._train_one(trainer):
                self.phase = STOPPED
                return
        if self._finish is not None and trainer is not None:
            self.phase = FINISHING
            self._finish(trainer)
        self.phase = FINISHED

    def _train_one(self, trainer: Trainer) -> bool:
        """Step `trainer` to its end and write its outputs; False when stopped first."""
        self._trainer = trainer
        self.detectors[trainer.config.layers.layer] = trainer.detector
        self.info = RunInfo(trainer.detector, trainer.raster, Path(trainer.out),
                            trainer.config.schedule.epochs, len(trainer.cameras), trainer.step_index)
        self._publish(trainer.snapshot(), [])
        losses: list[float] = []
        stepped = False
        while not self._stop.is_set():
            with self._lock:
                changes, self._pending = self._pending, {}
            if changes:
                self._apply(trainer, changes)
            if trainer.done:
                if stepped or not (Path(trainer.out) / "log.json").is_file():
                    trainer.write_outputs()
                return True
            if trainer.controls.read()[2]:
                self.phase = PAUSED
                self._stop.wait(PAUSE_POLL)
                continue
            self.phase = TRAINING
            started = time.perf_counter()
            trainer.step()
            losses.append(trainer.last_loss)
            stepped = True
            now = time.perf_counter()
            with self._lock:
                self._steps += 1
                self._training_seconds += now - started
            if trainer.done or now - self._last_publish >= self.publish_every:
                self._publish(trainer.snapshot(losses[-1]), losses)
                losses = []
        return False

    @staticmethod
    def _apply(trainer: Trainer, changes: dict) -> None:
        """Hand control changes to the trainer; a change of p or w(Up) becomes one of its events."""
        before = dict(zip(("keep_ratio", "weighting"), trainer.controls.read()[:2]))
        trainer.controls.update(**changes)
        live = {key: value for key, value in changes.items() if key in before and value != before[key]}
        if live:
            trainer.events.append({"event": LIVE_EVENT, "epoch": trainer.epoch, "step": trainer.step_index,
                                   **live})

    def _publish(self, snapshot, losses: list[float]) -> None:
        self._last_publish = time.perf_counter()
        elapsed = self._last_publish - self._started
        with self._lock:
            version = 1 if self._latest is None else self._latest.version + 1
            self._latest = Published(self.run, version, snapshot, elapsed)
            if losses:
                self._series.append((elapsed, float(np.mean(losses)), len(snapshot.means)))
