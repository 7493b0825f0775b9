"""The training thread: builds a Trainer, steps it, and publishes immutable snapshots.

Only this thread calls the trainer's methods. The window reads what it publishes (`latest`,
`series`, `info`, `error`) and asks for control changes, which this thread applies between two
steps. Stopping is checked between steps, so it takes at most one step; a stopped run keeps
its last checkpoint (the trainer writes those atomically at epoch ends) and writes nothing more.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from edgedog.renderer.config import RasterConfig

    from edgedog.train.trainer import Snapshot, Trainer

STARTING, TRAINING, PAUSED = "starting", "training", "paused"
FINISHED, STOPPED, FAILED = "finished", "stopped", "failed"
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


class TrainingWorker:
    """Runs `make_trainer()` and then `trainer.step()` in a daemon thread until done or stopped.

    The trainer needs `step() -> loss`, `done`, `snapshot(loss)`, `controls` (read/update),
    `write_outputs()`, `detector`, `raster`, `out`, `config.epochs`, `cameras`, `step_index`.
    """

    def __init__(self, make_trainer: Callable[[], Trainer], run: int = 0,
                 publish_every: float = PUBLISH_EVERY):
        self.run, self.publish_every = run, publish_every
        self._make_trainer = make_trainer
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._pending: dict = {}
        self._trainer: Trainer | None = None
        self._latest: Published | None = None
        self._series: list[tuple[float, float, int]] = []
        self._steps, self._training_seconds = 0, 0.0
        self.phase = STARTING
        self.info: RunInfo | None = None
        self.error: str | None = None
        """One line, "Type: message", when the trainer raised; `traceback` has the rest."""
        self.traceback: str | None = None
        self._thread = threading.Thread(target=self._run, name=f"edgedog-train-{run}", daemon=True)
        self._started = self._last_publish = 0.0

    # --- the window's side
    def start(self) -> None:
        self._started = time.perf_counter()
        self._thread.start()

    def update_controls(self, **changes) -> None:
        """keep_ratio, weighting, paused: applied by the training thread before its next step."""
        with self._lock:
            self._pending.update(changes)

    def stop(self, timeout: float = 1.0) -> bool:
        """Ask the thread to stop after its current step; returns whether it ended in `timeout` s."""
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
        trainer = self._make_trainer()
        self._trainer = trainer
        self.info = RunInfo(trainer.detector, trainer.raster, Path(trainer.out), trainer.config.epochs,
                            len(trainer.cameras), trainer.step_index)
        self._publish(trainer.snapshot(), [])
        losses: list[float] = []
        stepped = False
        while not self._stop.is_set():
            with self._lock:
                changes, self._pending = self._pending, {}
            if changes:
                trainer.controls.update(**changes)
            if trainer.done:
                if stepped:
                    trainer.write_outputs()
                self.phase = FINISHED
                return
            if trainer.controls.read()[2]:
                self.phase = PAUSED
                self._stop.wait(PAUSE_POLL)
                continue
            self.phase = TRAINING
            started = time.perf_counter()
            losses.append(trainer.step())
            stepped = True
            now = time.perf_counter()
            with self._lock:
                self._steps += 1
                self._training_seconds += now - started
            if trainer.done or now - self._last_publish >= self.publish_every:
                self._publish(trainer.snapshot(losses[-1]), losses)
                losses = []
        self.phase = STOPPED

    def _publish(self, snapshot, losses: list[float]) -> None:
        self._last_publish = time.perf_counter()
        elapsed = self._last_publish - self._started
        with self._lock:
            version = 1 if self._latest is None else self._latest.version + 1
            self._latest = Published(self.run, version, snapshot, elapsed)
            if losses:
                self._series.append((elapsed, float(np.mean(losses)), len(snapshot.means)))
