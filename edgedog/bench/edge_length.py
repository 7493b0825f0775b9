"""`edgedog bench edge-length`: final primitives and training seconds against the ground-truth
edge length of each scene (issue 43: a primitive budget that follows the edges).

It trains nothing: it reads finished run folders (a batch's --out, or single runs) grouped by the
variant a user names, and each run's scene's ground truth. The edge length of a scene is the total
length of its sharp-edge ground-truth curves in the ground-truth frame (the object normalised into
[0, 1]^3: 1 unit = 1000 mm): a generated scene's `gt/<scene>_curves.json`, an ABC object's sharp
feature curves (`groundtruth.abc_curves`), or, for a scene with sampled points alone, their count
times the sampling step (an estimate, named as such in the table).

Per variant: the ratio of final primitives to edge length per scene (runs of one scene averaged),
its median, each scene's ratio as a share of that median, how many scenes lie within
RATIO_BAND of it (the issue's target), and a least-squares line and Pearson correlation of
primitives and of seconds against length (a count that follows the edges correlates; a constant
count does not). Written to OUT/edge_length.json, .md and .png.
"""

from __future__ import annotations

import json
import math
import statistics
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from edgedog.bench.tables import cell
from edgedog.errors import ConfigError, InputError
from edgedog.files import read_json
from edgedog.groundtruth import GT_SPACING, abc_curves, ground_truth_for

EDGE_LENGTH_FILES = ("edge_length.json", "edge_length.md", "edge_length.png")
"""What the bench writes into OUT, its record first."""
RATIO_BAND = 0.30
"""Issue 43's target: every scene's primitives per unit of edge length within +-30 % of the median."""


@dataclass(frozen=True)
class EdgeLength:
    """A scene's ground-truth edge length (scene units) and how it was found: 'curves' (exact
    curves) or 'points' (sampled points x spacing, an estimate)."""

    length: float
    source: str
    curves: int | None


@dataclass(frozen=True)
class RunPoint:
    """One finished run: its variant, folder, scene (folder and name), design name (a generated
    scene's shape, else ''), edge length, final primitives and training seconds."""

    variant: str
    run: str
    scene: str
    scene_name: str
    design: str
    length: float
    length_source: str
    primitives: int
    train_seconds: float


@dataclass(frozen=True)
class ScenePoint:
    """A variant's runs of one scene, averaged: ratio is primitives per unit of edge length and
    share its ratio over the variant's median ratio."""

    variant: str
    scene: str
    scene_name: str
    design: str
    length: float
    length_source: str
    runs: int
    primitives: float
    train_seconds: float
    ratio: float
    share: float


@dataclass(frozen=True)
class VariantSummary:
    """A variant over its scenes: the ratio's median, min and max, each as primitives per unit;
    the lowest and highest share of the median; scenes within RATIO_BAND of it, and how many would
    be with one count for every scene (`constant_within_band`: how far the lengths alone spread,
    the criterion's power to tell a count that follows the edges from a constant one); the least-squares
    slope and intercept and Pearson r of primitives and of seconds against length (None with
    fewer than two lengths)."""

    variant: str
    scenes: int
    ratio_median: float
    ratio_min: float
    ratio_max: float
    share_min: float
    share_max: float
    within_band: int
    constant_within_band: int
    median_primitives: float
    primitives_slope: float | None
    primitives_intercept: float | None
    primitives_r: float | None
    seconds_slope: float | None
    seconds_intercept: float | None
    seconds_r: float | None


# --- reading --------------------------------------------------------------------------------

def edge_length(scene_root: Path) -> EdgeLength:
    """The total length of the sharp-edge ground truth of the scene in `scene_root`, in the
    ground-truth frame. InputError when the scene has no ground truth."""
    source = ground_truth_for(scene_root)
    if source is None:
        raise InputError(scene_root, "no ground truth found for this scene: no edge length")
    curves = abc_curves(source)
    if curves is not None:
        return EdgeLength(math.fsum(curve.length for curve in curves), "curves", len(curves))
    if source.sampled_ply is not None:
        stem = source.sampled_ply.name.removesuffix(f"_{GT_SPACING}.ply")
        path = source.sampled_ply.with_name(f"{stem}_curves.json")
        if path.is_file():
            from edgedog.synthetic.features import curve_from_json

            try:
                records = json.loads(path.read_text(encoding="utf-8"))["curves"]
            except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError):
                raise InputError(path, "not a curves file (a JSON object with 'curves')") from None
            lengths = [curve_from_json(record, path).length for record in records]
            return EdgeLength(math.fsum(lengths), "curves", len(lengths))
    # Points sampled every GT_SPACING along each curve in this frame (a generated scene's own
    # ground truth): their count times the step is the length within a step per curve.
    return EdgeLength(len(source.load()) * GT_SPACING, "points", None)


def _design(scene_root: Path) -> str:
    """A generated scene's shape name from its manifest, else ''."""
    from edgedog.builtin.writer import MANIFEST

    manifest = scene_root / MANIFEST
    if not manifest.is_file():
        return ""
    try:
        shape = read_json(manifest).get("shape")
    except (InputError, AttributeError):
        return ""
    return shape if isinstance(shape, str) else ""


def run_folders(path: Path) -> list[Path]:
    """`path` itself when it is a run folder (a log.json and a config.json), else the run folders
    directly inside it (a batch's --out), sorted by name. InputError for a missing folder."""
    path = Path(path)
    if not path.is_dir():
        raise InputError(path, "not a folder of runs")
    if _is_run(path):
        return [path]
    return sorted(entry for entry in path.iterdir() if entry.is_dir() and _is_run(entry))


def _is_run(folder: Path) -> bool:
    return (folder / "log.json").is_file() and (folder / "config.json").is_file()


def read_runs(variants: list[tuple[str, Path]], finished=None,
              lengths: dict[Path, EdgeLength] | None = None) -> tuple[list[RunPoint], list[str]]:
    """The finished runs of each (variant, folder) pair and notes on what was left out (runs not
    trained to their end). `finished(path) -> bool` decides (default
    `edgedog.train.lifecycle.is_finished`); `lengths` caches the scenes' edge lengths."""
    if finished is None:
        from edgedog.train.lifecycle import is_finished as finished
    lengths = {} if lengths is None else lengths
    points, notes = [], []
    for variant, folder in variants:
        runs = run_folders(folder)
        if not runs:
            notes.append(f"{variant}: no run in {folder}")
        for run in runs:
            if not finished(run):
                notes.append(f"{variant}: {run} is not finished; left out")
                continue
            log = read_json(run / "log.json")
            scene = Path(log["scene"])
            if scene not in lengths:
                lengths[scene] = edge_length(scene)
            found = lengths[scene]
            points.append(RunPoint(variant, str(run), str(scene), scene.name, _design(scene), found.length,
                                   found.source, int(log["final_primitives"]), float(log["train_seconds"])))
    return points, notes


# --- the ratio and its spread -----------------------------------------------------------------

def scene_points(points: list[RunPoint]) -> list[ScenePoint]:
    """One point per variant and scene (its runs' mean), with its ratio and its share of the
    variant's median ratio; in the variants' order of first appearance, scenes by length."""
    groups: dict[tuple[str, str], list[RunPoint]] = {}
    for point in points:
        groups.setdefault((point.variant, point.scene), []).append(point)
    by_variant: dict[str, list[tuple[list[RunPoint], float, float]]] = {}
    for (variant, _), runs in groups.items():
        primitives = statistics.fmean(run.primitives for run in runs)
        seconds = statistics.fmean(run.train_seconds for run in runs)
        by_variant.setdefault(variant, []).append((runs, primitives, seconds))
    result = []
    for variant, entries in by_variant.items():
        ratios = [primitives / runs[0].length for runs, primitives, _ in entries]
        median = statistics.median(ratios)
        ordered = sorted(zip(entries, ratios), key=lambda entry: entry[0][0][0].length)
        for (runs, primitives, seconds), ratio in ordered:
            first = runs[0]
            result.append(ScenePoint(variant, first.scene, first.scene_name, first.design, first.length,
                                     first.length_source, len(runs), primitives, seconds, ratio,
                                     ratio / median if median > 0 else math.nan))
    return result


def _line(x: list[float], y: list[float]) -> tuple[float | None, float | None, float | None]:
    """Least-squares slope and intercept of y on x, and Pearson r (None where undefined)."""
    if len(x) < 2 or len(set(x)) < 2:
        return None, None, None
    xs, ys = np.asarray(x, float), np.asarray(y, float)
    slope, intercept = np.polyfit(xs, ys, 1)
    r = None if np.std(ys) == 0 else float(np.corrcoef(xs, ys)[0, 1])
    return float(slope), float(intercept), r


def _within(shares: list[float]) -> int:
    """How many shares of a median lie within RATIO_BAND of 1."""
    return sum(abs(share - 1.0) <= RATIO_BAND + 1e-12 for share in shares)


def summaries(scenes: list[ScenePoint]) -> list[VariantSummary]:
    """One VariantSummary per variant of `scenes` (from `scene_points`), in their order."""
    result = []
    for variant in dict.fromkeys(point.variant for point in scenes):
        mine = [point for point in scenes if point.variant == variant]
        ratios = [point.ratio for point in mine]
        lengths = [point.length for point in mine]
        shares = [point.share for point in mine]
        # One count C for all: ratio C / L, median C / median(L), share median(L) / L.
        constant = [statistics.median(lengths) / length for length in lengths]
        result.append(VariantSummary(
            variant, len(mine), statistics.median(ratios), min(ratios), max(ratios), min(shares), max(shares),
            _within(shares), _within(constant), statistics.median(point.primitives for point in mine),
            *_line(lengths, [point.primitives for point in mine]),
            *_line(lengths, [point.train_seconds for point in mine])))
    return result


# --- the outputs ------------------------------------------------------------------------------

def record(points: list[RunPoint], notes: list[str]) -> dict:
    """The bench's JSON record: runs, scenes, summaries, notes."""
    scenes = scene_points(points)
    return {"unit": "scene units of the ground-truth frame (1 = 1000 mm)", "band": RATIO_BAND,
            "runs": [asdict(point) for point in points], "scenes": [asdict(point) for point in scenes],
            "variants": [asdict(summary) for summary in summaries(scenes)], "notes": notes}


def _label(point: dict) -> str:
    return point["scene_name"] + (f" {point['design']}" if point["design"] else "")


def markdown(result: dict) -> str:
    """The per-scene table and the per-variant summary, as Markdown."""
    band = round(100 * result["band"])
    rows = ["| scene | variant | edge length | runs | primitives | train (s) | primitives per unit | "
            "of the median |", "|---|---|---|---|---|---|---|---|"]
    for point in result["scenes"]:
        estimate = " (points)" if point["length_source"] == "points" else ""
        rows.append(f"| {_label(point)} | {point['variant']} | {point['length']:.2f}{estimate} | "
                    f"{point['runs']} | {point['primitives']:.0f} | {point['train_seconds']:.0f} | "
                    f"{point['ratio']:.0f} | {100 * point['share']:.0f} % |")
    rows += ["", f"| variant | scenes | median primitives per unit | min - max | of the median | "
             f"within ±{band} % | one count for all | primitives ~ length | r | seconds ~ length | r |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in result["variants"]:
        def fit(slope, intercept):
            return "–" if slope is None else f"{intercept:.0f} {'-' if slope < 0 else '+'} {abs(slope):.0f} L"
        rows.append(f"| {s['variant']} | {s['scenes']} | {s['ratio_median']:.0f} | {s['ratio_min']:.0f} - "
                    f"{s['ratio_max']:.0f} | {100 * s['share_min']:.0f} - {100 * s['share_max']:.0f} % | "
                    f"{s['within_band']} of {s['scenes']} | {s['constant_within_band']} of {s['scenes']} | "
                    f"{fit(s['primitives_slope'], s['primitives_intercept'])} | "
                    f"{cell(s['primitives_r'], 2)} | {fit(s['seconds_slope'], s['seconds_intercept'])} | "
                    f"{cell(s['seconds_r'], 2)} |")
    rows += ["", f"Edge length L: {result['unit']}. Primitives per unit: final primitives / L, a scene's "
             f"runs averaged; the target: every scene within ±{band} % of its variant's median. One "
             f"count for all: the scenes that would be within it if every scene had the same count "
             f"(the lengths' own spread). Lines: least squares over the scenes, r: Pearson's."]
    rows += [f"note: {note}" for note in result["notes"]]
    return "\n".join(rows) + "\n"


def plot_png(result: dict) -> bytes:
    """Two panels against edge length: final primitives (with each variant's median ratio as a
    line through the origin and its ±RATIO_BAND band) and training seconds; one marker colour per
    variant, ABC-like scenes without a design name drawn as squares and named. PNG bytes."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(11, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    primitives_axis, seconds_axis = figure.subplots(1, 2)
    colours = [f"C{i}" for i in range(10)]
    summaries_by_variant = {s["variant"]: s for s in result["variants"]}
    lengths = [point["length"] for point in result["scenes"]] or [1.0]
    span = np.linspace(0.0, max(lengths) * 1.05, 50)
    for index, variant in enumerate(summaries_by_variant):
        colour = colours[index % len(colours)]
        mine = [point for point in result["scenes"] if point["variant"] == variant]
        for axis, key in ((primitives_axis, "primitives"), (seconds_axis, "train_seconds")):
            for named, marker in ((False, "o"), (True, "s")):
                chosen = [p for p in mine if (not p["design"]) == named]
                if chosen:
                    axis.scatter([p["length"] for p in chosen], [p[key] for p in chosen], color=colour,
                                 marker=marker, s=28, alpha=0.85,
                                 label=None if named else f"{variant} ({len(mine)} scenes)")
            for p in mine:
                if not p["design"]:
                    axis.annotate(p["scene_name"], (p["length"], p[key]), fontsize=7, color=colour,
                                  xytext=(4, 4), textcoords="offset points")
        median = summaries_by_variant[variant]["ratio_median"]
        primitives_axis.plot(span, median * span, color=colour, linewidth=1, linestyle="--")
        primitives_axis.axhline(summaries_by_variant[variant]["median_primitives"], color=colour,
                                linewidth=0.8, linestyle=":")
        primitives_axis.fill_between(span, (1 - result["band"]) * median * span,
                                     (1 + result["band"]) * median * span, color=colour, alpha=0.08)
    band = round(100 * result["band"])
    primitives_axis.set_title(f"final primitives; dashed: the median per unit length (band ±{band} %), "
                              "dotted: the median count", fontsize=9)
    seconds_axis.set_title("training seconds (one run a scene; a shared machine's load varies)", fontsize=9)
    for axis, label in ((primitives_axis, "final primitives"), (seconds_axis, "training time (s)")):
        axis.set_xlabel("ground-truth edge length (scene units, 1 = 1000 mm)")
        axis.set_ylabel(label)
        axis.set_xlim(left=0)
        axis.set_ylim(bottom=0)
        axis.grid(True, alpha=0.3)
        axis.scatter([], [], color="grey", marker="s", s=28, label="ABC objects (named)")
        axis.legend(fontsize=8, loc="upper left")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110)
    return buffer.getvalue()


def parse_variants(items: list[str]) -> list[tuple[str, Path]]:
    """`NAME=FOLDER` items -> (name, folder) pairs; ConfigError for a malformed item."""
    pairs = []
    for item in items:
        name, sep, folder = item.partition("=")
        if not sep or not name.strip() or not folder.strip():
            raise ConfigError(f"--runs {item!r}: give NAME=FOLDER (a variant's name, a run or batch folder)")
        pairs.append((name.strip(), Path(folder.strip())))
    return pairs
