"""A run folder as it was saved, read into the same primitives, curves and history as the window
reads a training worker's, so that opening a run shows what it holds at once: a finished run as
it ended, an interrupted one at its last checkpoint.

The model comes from the checkpoint.pt of the highest layer that wrote one (it holds every layer
below it too). The history (loss and primitive count per epoch, against training seconds) is each
layer's in turn, bottom first: a finished layer's from its log.json, the interrupted layer's from
its checkpoint (which stores the history so far). The curves and their scores come from
curves.json and extract.json when `edgedog extract` (or the end of training) wrote them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from edgedog.app.extraction import Extraction
from edgedog.app.worker import FINISHED, STOPPED, Published, RunInfo
from edgedog.renderer.config import RasterConfig

from edgedog.curve_files import read_edges
from edgedog.curves.report import REPORT
from edgedog.errors import InputError
from edgedog.files import read_json
from edgedog.train.checkpoint import CHECKPOINT, read_checkpoint
from edgedog.train.lifecycle import LOG, RunRecord, is_finished
from edgedog.train.run_folder import RunFolder, read_run
from edgedog.train.trainer import read_stack, stack_snapshot

CURVES = "curves.json"


def layer_detectors(layers: tuple[RunFolder, ...]) -> dict[int, str]:
    """Layer index -> the maps it was fitted to, for the layers (bottom first) that wrote their log.json."""
    found = {}
    for index, layer in enumerate(layers):
        log = layer.path / LOG
        if log.is_file():
            found[index] = read_json(log).get("detector")
    return {index: name for index, name in found.items() if isinstance(name, str)}


def _fscore(report_path: Path) -> dict[int, float] | None:
    """{threshold mm: F-score %} of the curves in an extract.json, None without scores."""
    if not report_path.is_file():
        return None
    metrics = read_json(report_path).get("metrics", {}).get("curves", {})
    scores = {int(key[len("fscore_"):-len("mm")]): float(value) for key, value in metrics.items()
              if key.startswith("fscore_") and key.endswith("mm")}
    return scores or None


def read_extraction(path: Path, step: int, elapsed: float) -> Extraction | None:
    """The curves a run folder holds (curves.json, with extract.json's counts and scores), as
    the studio's own extractions; None when it holds none."""
    if not (path / CURVES).is_file():
        return None
    curves = read_edges(path / CURVES)
    counts = read_json(path / REPORT).get("counts", {}) if (path / REPORT).is_file() else {}
    return Extraction(step, elapsed, curves, counts, _fscore(path / REPORT))


@dataclass(frozen=True)
class SavedLayer:
    """What one layer's folder recorded of its training.

    Attributes:
        history: its rows (epoch, loss, primitives, seconds of this layer's training);
        detector: the maps it was fitted to; step: its steps trained; seconds: its training time.
    """

    history: list[dict]
    detector: str
    step: int
    seconds: float


def saved_layer(layer: RunFolder, views: int) -> SavedLayer | None:
    """A layer as saved: finished (its log.json), interrupted (its checkpoint, read as data only),
    or None when it has not written a checkpoint yet."""
    if is_finished(layer.path):
        log = read_json(layer.path / LOG)
        history = log.get("history")
        if not isinstance(history, list) or not isinstance(log.get("detector"), str):
            raise InputError(layer.path / LOG, "expected 'history' and 'detector' (written by edgedog train)")
        seconds = float(log.get("train_seconds", 0.0))
        return SavedLayer(history, log["detector"], len(history) * views, seconds)
    if not (layer.path / CHECKPOINT).is_file():
        return None
    saved = read_checkpoint(layer.path / CHECKPOINT)
    history, detector, step = saved["history"], saved["detector"], saved["step_index"]
    if not isinstance(history, list) or not isinstance(detector, str) or not isinstance(step, int):
        raise InputError(layer.path / CHECKPOINT, "malformed checkpoint: its 'history', 'detector' or "
                                                  "'step_index'")
    return SavedLayer(history, detector, step, float(saved["seconds"]))


def saved_layers(record: RunRecord, views: int) -> list[tuple[RunFolder, SavedLayer]]:
    """The layers of a run that saved something, bottom first (a layer trains only once those
    below it finished, so these are the lowest ones)."""
    found = []
    for layer in record.layers():
        saved = saved_layer(layer, views)
        if saved is None:
            break
        found.append((layer, saved))
    return found


class SavedRun:
    """What a TrainingWorker publishes, read from a run folder as saved (nothing runs).

    Attributes:
        phase: FINISHED, or STOPPED for a run interrupted before its end;
        latest: the model of the highest layer saved (elapsed: the training seconds of every
            layer so far); info: its detector, raster, folder, epochs, views;
        detectors: layer index -> its maps, for every layer saved; extraction: the curves of the
            whole model (None before `edgedog extract`, and for an interrupted run);
        history: every saved layer's rows in turn, their seconds counted from the run's start;
        steps: the steps of every layer saved.
    """

    error = traceback = None
    alive = False

    def __init__(self, record: RunRecord, views: int):
        """`record`: a run whose lowest layer wrote a checkpoint (an InputError otherwise)."""
        layers = saved_layers(record, views)
        if not layers:
            raise InputError(record.path, "holds no checkpoint yet: nothing to show")
        self.phase = FINISHED if len(layers) == len(record.layers()) and is_finished(layers[-1][0].path) \
            else STOPPED
        self.history, seconds = [], 0.0
        for _, layer in layers:  # each layer's seconds count from its own start
            self.history += [{**row, "seconds": seconds + float(row["seconds"])} for row in layer.history]
            seconds += layer.seconds
        self.steps = sum(layer.step for _, layer in layers)
        self.steps_per_second = self.steps / seconds if seconds > 0 else 0.0
        folder, top = layers[-1]
        loss = float(top.history[-1]["loss"]) if top.history else float("nan")
        snapshot = stack_snapshot(read_stack(folder.path), top.step, len(top.history), loss)
        self.latest = Published(0, 1, snapshot, seconds)
        config = read_run(folder.path).config
        raster = RasterConfig(kernel=config.model.kernel, k_activation=config.model.k_activation)
        self.info = RunInfo(top.detector, raster, folder.path, config.schedule.epochs, views, top.step)
        self.detectors = {index: layer.detector for index, (_, layer) in enumerate(layers)}
        self.extraction = (read_extraction(record.curves_folder, snapshot.step, seconds)
                           if self.phase == FINISHED else None)

    def series(self) -> np.ndarray:
        """(K, 3) per epoch: training seconds, mean loss, primitives (as the worker's series)."""
        rows = [(row["seconds"], row["loss"], row["primitives"]) for row in self.history]
        return np.array(rows, np.float64).reshape(-1, 3)

    def stop(self, timeout: float | None = None) -> bool:
        return True

    def update_controls(self, **changes) -> None:
        """Nothing trains: changes apply to the next start."""

    def trainer_controls(self) -> None:
        return None
