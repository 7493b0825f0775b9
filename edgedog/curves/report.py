"""Extraction of a run folder with its report: counts, and scores when the scene has ground truth.

Shared by `edgedog extract`, the end of `edgedog train` and the benchmarks, so that every number
about a run's curves comes from one place and lands in the run's extract.json.
"""

from __future__ import annotations

from pathlib import Path

from edgedog.curve_files import EdgeCurves
from edgedog.curves.config import ExtractConfig, to_dict
from edgedog.curves.extract import RunExtraction, extract_run
from edgedog.errors import InputError
from edgedog.files import atomic_write_json, read_json
from edgedog.groundtruth import GroundTruthSource, ground_truth_for
from edgedog.metrics import EdgeMetrics, evaluate
from edgedog.scenes import Scene

REPORT = "extract.json"


def has_current_report(run_dir: Path) -> bool:
    """Whether the run's extract.json is there and was written with the default extraction
    settings of this version: a batch or a resumed run extracts again when it was not (missing,
    unreadable, or written before a default changed), so that reused runs score like new ones."""
    try:
        report = read_json(Path(run_dir) / REPORT)
    except InputError:
        return False
    return isinstance(report, dict) and report.get("config") == to_dict(ExtractConfig())


def score_extraction(result: RunExtraction, scene: Scene,
                     ground_truth: GroundTruthSource) -> dict[str, EdgeMetrics]:
    """Scores of the filtered points and of the curves against the scene's ground truth (a set
    with nothing to score, e.g. every curve under 5 mm, is left out)."""
    gt = ground_truth.load()
    samples = {"points": EdgeCurves(points=result.points.points).transformed(scene.world_to_gt).points,
               "curves": result.curves.transformed(scene.world_to_gt).sample()}
    return {name: evaluate(points, gt) for name, points in samples.items() if len(points)}


def extract_with_report(run_dir: Path, scene: Scene, detector: str, config: ExtractConfig = ExtractConfig(),
                        layers: set[int] | None = None,
                        out_dir: Path | None = None) -> tuple[RunExtraction, dict]:
    """Extract a run's curves (see `extract_run`, which also takes `layers` and `out_dir`), score
    them, and write extract.json beside them.

    Returns the extraction and the report: {"config", "counts", and with ground truth
    "ground_truth" and "metrics"}, metrics keyed "points" / "curves" (each only when there is
    something to score) as `EdgeMetrics.to_dict()`.
    """
    result = extract_run(run_dir, config, scene, detector, layers, out_dir)
    report = {"config": to_dict(config), "counts": result.counts}
    ground_truth = ground_truth_for(scene.root)
    if ground_truth is not None:
        report["ground_truth"] = ground_truth.description
        scores = score_extraction(result, scene, ground_truth)
        report["metrics"] = {name: m.to_dict() for name, m in scores.items()}
    atomic_write_json(Path(out_dir or run_dir) / REPORT, report)
    return result, report
