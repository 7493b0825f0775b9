"""Curves from a snapshot, scored against the ground truth and exported, off the UI thread.

The snapshot's primitives go through `edgedog extract`'s own pipeline (filters, grouping,
fitting) in memory, so the studio's curves are the ones the command line would give. The
snapshot may be a selection of a layered model's layers (those shown): as `edgedog train
--layers` does for its selections, the projection filter then uses the maps of the finest
layer selected.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from edgedog.curve_files import EdgeCurves, write_edges
from edgedog.curves.config import ExtractConfig
from edgedog.curves.extract import extract_primitives
from edgedog.edges.cache import attach_edge_maps
from edgedog.groundtruth import ground_truth_for
from edgedog.metrics import evaluate
from edgedog.primitives import EdgePrimitives
from edgedog.scenes import Scene


@dataclass(frozen=True)
class Extraction:
    """Curves of one snapshot.

    Attributes:
        step: the training step of the snapshot; elapsed: its time in the run (seconds).
        counts: primitives left after each filter, chains, lines, Béziers.
        fscore: threshold in mm -> F-score in %, when the scene has ground truth and curves.
        written: the files exported with it.
        unwritten: the formats asked for but not written, as there were no curves.
        selection: the layers extracted, e.g. 'L0+L1' ('' when the whole model).
    """

    step: int
    elapsed: float
    curves: EdgeCurves
    counts: dict[str, int]
    fscore: dict[int, float] | None = None
    written: tuple[Path, ...] = field(default_factory=tuple)
    selection: str = ""
    unwritten: tuple[str, ...] = ()


def export_path(run_dir: Path, step: int, fmt: str, selection: str = "") -> Path:
    """Where an export of the curves at `step` goes: <run>/exports/curves_step<step>.<fmt>, or
    curves_step<step>_<selection>.<fmt> for some of a layered model's layers."""
    suffix = f"_{selection}" if selection else ""
    return run_dir / "exports" / f"curves_step{step:06d}{suffix}.{fmt}"


def extract_snapshot(snapshot, elapsed: float, scene: Scene, detector: str, run_dir: Path,
                     formats: Sequence[str] = (), config: ExtractConfig = ExtractConfig(),
                     selection: str = "") -> Extraction:
    """Extract curves from `snapshot` (the layers `selection` of a model, '' for all of it),
    score them when the scene has ground truth, and write them in each of `formats` (see
    `export_path`) unless there are none. `detector` names the maps of the projection filter."""
    attach_edge_maps(scene, detector)  # a finished run's maps may not be loaded yet
    result = extract_primitives(EdgePrimitives.from_arrays(snapshot.primitives), config, scene, detector)
    fscore = None
    samples = result.curves.transformed(scene.world_to_gt).sample()
    ground_truth = ground_truth_for(scene.root) if len(samples) else None  # none from curves all under 5 mm
    if ground_truth is not None:
        fscore = evaluate(samples, ground_truth.load()).fscore
    if not result.curves.num_curves:  # an empty file would pass for an export
        return Extraction(snapshot.step, elapsed, result.curves, result.counts, fscore, (), selection,
                          tuple(formats))
    written = tuple(write_edges(export_path(run_dir, snapshot.step, fmt, selection), result.curves)
                    for fmt in formats)
    return Extraction(snapshot.step, elapsed, result.curves, result.counts, fscore, written, selection)
