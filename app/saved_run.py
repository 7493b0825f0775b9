"""A finished run folder on screen: its primitives, curves and history as the window reads a
training worker's, so that opening a finished run shows its result at once.

The model comes from checkpoint.pt (every layer of a layered run), the history (loss and
primitive count per epoch, against training seconds) from log.json, the curves and their scores
from curves.json and extract.json when `edgedog extract` (or the end of training) wrote them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from edgedog.app.extraction import Extraction
from edgedog.app.worker import FINISHED, Published, RunInfo
from edgedog.renderer.config import RasterConfig

from edgedog.curve_files import read_edges
from edgedog.curves.report import REPORT
from edgedog.errors import InputError
from edgedog.files import read_json
from edgedog.train.lifecycle import LOG, RunRecord
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


class SavedRun:
    """What a TrainingWorker publishes, read from a finished run folder (nothing runs).

    Attributes:
        latest: the final model; info: its detector, raster, folder, epochs, views;
        detectors: layer index -> its maps; extraction: the curves of the whole model (None
        before `edgedog extract`); history: log.json's rows (of the top layer's training).
    """

    phase = FINISHED
    error = traceback = None
    alive = False

    def __init__(self, record: RunRecord, views: int):
        """`record`: a finished run (its top layer is read: its checkpoint holds every layer)."""
        run = read_run(record.layers()[-1].path)
        log = read_json(run.path / LOG)
        history = log.get("history")
        if not isinstance(history, list) or not isinstance(log.get("detector"), str):
            raise InputError(run.path / LOG, "expected 'history' and 'detector' (written by edgedog train)")
        self.history = history
        self.steps = len(history) * views
        seconds = float(log.get("train_seconds", 0.0))
        self.steps_per_second = self.steps / seconds if seconds > 0 else 0.0
        loss = float(history[-1]["loss"]) if history else float("nan")
        snapshot = stack_snapshot(read_stack(run.path), self.steps, len(history), loss)
        self.latest = Published(0, 1, snapshot, seconds)
        config = run.config
        raster = RasterConfig(kernel=config.model.kernel, k_activation=config.model.k_activation)
        self.info = RunInfo(log["detector"], raster,
                            run.path, config.schedule.epochs, views, self.steps)
        self.detectors = layer_detectors(record.layers())
        self.extraction = read_extraction(record.curves_folder, snapshot.step, seconds)

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
