"""Extraction settings against each other on finished runs (`edgedog bench extraction`).

Curve extraction is cheap next to training (seconds against minutes), so a setting of it is
measured on runs already trained: each run is extracted twice with today's code, once with the
base settings and once with the variant's, into a folder of ours (the runs are only read), and
the two extractions' curves are scored against the scene's ground truth. The table pairs them
run by run: a run's own extract.json may come from older code, and re-extracting both sides
keeps the comparison to the settings alone.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

from edgedog.batch.table import mean_and_spread
from edgedog.bench.edge_length import run_folders
from edgedog.curves.config import ExtractConfig
from edgedog.errors import InputError
from edgedog.scenes.scene import Scene

SCORES = ("fscore_5mm", "fscore_10mm", "fscore_20mm", "acc_mm", "comp_mm")
"""The curves' scores compared (`edgedog.metrics.EdgeMetrics.to_dict` keys)."""
LABELS = {"fscore_5mm": "F5", "fscore_10mm": "F10", "fscore_20mm": "F20", "acc_mm": "Acc (mm)",
          "comp_mm": "Comp (mm)"}
HIGHER_IS_BETTER = {"fscore_5mm": True, "fscore_10mm": True, "fscore_20mm": True, "acc_mm": False,
                    "comp_mm": False}
SIDES = ("base", "variant")
EXTRACTION_FILES = ("extraction.json", "extraction.md")
"""What the bench writes in its --out besides the extractions (OUT/runs/NNN-NAME/base|variant)."""
CHANGE = 0.05
"""A run counts as better or worse when a score moves by more than this."""


@dataclass(frozen=True)
class Pair:
    """One run's curves extracted with the base and the variant settings.

    run: the run folder; scene: its scene's folder name; base, variant: `SCORES` of each
    extraction's curves; curves: how many curves each extraction fitted.
    """

    run: str
    scene: str
    base: dict[str, float]
    variant: dict[str, float]
    curves: tuple[int, int]


def extract_scored(run: Path, scene: Scene, detector: str, config: ExtractConfig,
                   out: Path) -> tuple[dict[str, float], int]:
    """Extract the finished `run` of `scene` (its maps `detector`, as `run_scene` gives them) with
    `config` into the folder `out` (created) and score its curves: (`SCORES`, curves fitted).
    InputError naming the run when its scene has no ground truth or no curve came out to score."""
    from edgedog.curves.report import extract_with_report

    out.mkdir(parents=True)
    result, report = extract_with_report(run, scene, detector, config, out_dir=out)
    if "ground_truth" not in report:
        raise InputError(run, "its scene has no ground truth to score the curves against")
    curves = report.get("metrics", {}).get("curves")
    if curves is None:
        raise InputError(run, "the extraction fitted no curve to score")
    return {key: float(curves[key]) for key in SCORES}, len(result.curves.lines) + len(result.curves.beziers)


def compare(folders: list[Path], base: ExtractConfig, variant: ExtractConfig, out: Path,
            finished=None, progress=print) -> tuple[list[Pair], list[str]]:
    """Every finished run in `folders` (run folders, or folders of them: a batch's --out)
    extracted with `base` and with `variant` into out/runs/NNN-NAME/{base,variant}; the pairs
    and notes on the runs left out (not finished). `finished(path) -> bool` decides (default
    `edgedog.train.lifecycle.is_finished`); `progress(line)` hears of each run."""
    from edgedog.curves.extract import run_scene

    if finished is None:
        from edgedog.train.lifecycle import is_finished as finished
    pairs, notes = [], []
    runs = [run for folder in folders for run in run_folders(folder)]
    for number, run in enumerate(runs):
        if not finished(run):
            notes.append(f"{run} is not finished; left out")
            continue
        folder = out / "runs" / f"{number:03d}-{run.name}"
        scene, detector = run_scene(run, maps=True)  # read once, for both extractions
        base_scores, base_curves = extract_scored(run, scene, detector, base, folder / SIDES[0])
        variant_scores, variant_curves = extract_scored(run, scene, detector, variant, folder / SIDES[1])
        pairs.append(Pair(str(run), scene.root.name, base_scores, variant_scores,
                          (base_curves, variant_curves)))
        progress(f"{len(pairs)}/{len(runs)} {run.name}: F10 {base_scores['fscore_10mm']:.1f} -> "
                 f"{variant_scores['fscore_10mm']:.1f}")
    return pairs, notes


def _mean_std(values: list[float]) -> tuple[float, float]:
    """`mean_and_spread` of `values` (not empty), the spread of a single value taken as 0."""
    mean, spread = mean_and_spread(values)
    return mean, 0.0 if spread is None else spread


def summary(pairs: list[Pair]) -> dict:
    """Per score: each side's mean and sample standard deviation over the runs, the paired
    difference (variant - base) as mean and standard error, the runs it made better and worse
    (by more than `CHANGE`, in the score's good direction), and each side's worst run."""
    if not pairs:
        raise ValueError("no pair to summarise")
    scores = {}
    for key in SCORES:
        base = [p.base[key] for p in pairs]
        variant = [p.variant[key] for p in pairs]
        differences = [v - b for b, v in zip(base, variant)]
        mean, std = _mean_std(differences)
        sign = 1.0 if HIGHER_IS_BETTER[key] else -1.0
        worst = min if HIGHER_IS_BETTER[key] else max
        scores[key] = {
            "base": _mean_std(base), "variant": _mean_std(variant),
            "difference": (mean, std / math.sqrt(len(pairs))),
            "better": sum(sign * d > CHANGE for d in differences),
            "worse": sum(sign * d < -CHANGE for d in differences),
            "worst": (worst(base), worst(variant)),
        }
    return scores


def record(pairs: list[Pair], notes: list[str], base_set: list[str], variant_set: list[str]) -> dict:
    """What extraction.json holds: the settings, every pair and the summary."""
    return {"base_set": list(base_set), "variant_set": list(variant_set), "runs": len(pairs),
            "pairs": [asdict(p) for p in pairs], "summary": summary(pairs), "notes": list(notes)}


def markdown(result: dict) -> str:
    """extraction.md: the settings, a row per run (base -> variant), then the summary."""
    base = " ".join(result["base_set"]) or "the defaults"
    variant = " ".join(result["variant_set"]) or "the defaults"
    lines = [f"Curve extraction of {result['runs']} finished runs: base ({base}) against variant "
             f"({variant}).", "", "| run | scene | " + " | ".join(LABELS[k] for k in SCORES) + " | curves |",
             "|---|---|" + "---|" * (len(SCORES) + 1)]
    for pair in result["pairs"]:
        cells = [f"{pair['base'][k]:.2f} → {pair['variant'][k]:.2f}" for k in SCORES]
        lines.append(f"| {Path(pair['run']).name} | {pair['scene']} | " + " | ".join(cells)
                     + f" | {pair['curves'][0]} → {pair['curves'][1]} |")
    lines += ["", "| score | base: mean ± std | variant: mean ± std | variant - base: mean ± s.e. | "
              "better | worse | worst: base → variant |", "|---|---|---|---|---|---|---|"]
    for key in SCORES:
        s = result["summary"][key]
        lines.append(f"| {LABELS[key]} | {s['base'][0]:.2f} ± {s['base'][1]:.2f} | {s['variant'][0]:.2f} ± "
                     f"{s['variant'][1]:.2f} | {s['difference'][0]:+.2f} ± {s['difference'][1]:.2f} | "
                     f"{s['better']} | {s['worse']} | {s['worst'][0]:.2f} → {s['worst'][1]:.2f} |")
    lines += [f"- {note}" for note in result["notes"]]
    return "\n".join(lines) + "\n"


__all__ = ["EXTRACTION_FILES", "Pair", "SCORES", "compare", "extract_scored", "markdown", "record", "summary"]
