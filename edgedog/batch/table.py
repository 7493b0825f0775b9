"""A batch's results: one row per run, one per configuration (its seeds' mean and spread), and
one per setting that ran on several scenes (the scenes' mean, spread and worst), as CSV, Markdown,
JSON and a PNG plot.

The spread is the sample standard deviation over a configuration's runs (n - 1 in the
denominator; none for a single run). Means and spreads are over the runs that have the value: a
failed run, or one whose extraction found no curve to score, adds nothing.
"""

from __future__ import annotations

import csv
import io
import math
import textwrap
from dataclasses import dataclass
from pathlib import Path

from edgedog.batch.outcome import RunOutcome
from edgedog.files import atomic_write_bytes, atomic_write_json

BATCH_FILES = ("batch.json", "batch.csv", "batch_runs.csv", "batch.md", "batch.png")
"""What a batch writes into its folder: every table in JSON, the configurations' and the runs'
tables in CSV, both in Markdown, and the plot."""


@dataclass(frozen=True)
class Column:
    """A value of a run: its key in the rows, its header in Markdown and its decimals there."""

    key: str
    header: str
    digits: int


VALUES = (Column("f5", "F5", 1), Column("f10", "F10", 1), Column("f20", "F20", 1),
          Column("acc_mm", "Acc (mm)", 2), Column("comp_mm", "Comp (mm)", 2),
          Column("train_seconds", "train (s)", 1), Column("primitives", "primitives", 0),
          Column("peak_rss_mib", "peak RSS (MiB)", 0))
TIMINGS = ("train_seconds", "peak_rss_mib")
"""Values that differ between two runs of the same batch: everything else is reproducible."""
_SCORES = {"f5": "fscore_5mm", "f10": "fscore_10mm", "f20": "fscore_20mm", "acc_mm": "acc_mm",
           "comp_mm": "comp_mm"}


def run_rows(outcomes: list[RunOutcome]) -> list[dict]:
    """One flat row per run in the order given: run, configuration, scene, preset, row, changes
    (';'-joined), seed, the VALUES (None where there is none) and error ('' when it ran)."""
    rows = []
    for outcome in outcomes:
        spec, log = outcome.spec, outcome.log or {}
        curves = ((outcome.report or {}).get("metrics") or {}).get("curves") or {}
        rows.append({"run": spec.name, "configuration": spec.configuration, "scene": spec.scene.name,
                     "preset": spec.preset, "row": spec.row or "", "changes": ";".join(spec.changes),
                     "seed": spec.seed, **{key: curves.get(name) for key, name in _SCORES.items()},
                     "train_seconds": log.get("train_seconds"), "primitives": log.get("final_primitives"),
                     "peak_rss_mib": log.get("peak_rss_mib"), "error": outcome.error})
    return rows


def mean_and_spread(values: list[float]) -> tuple[float | None, float | None]:
    """The mean and the sample standard deviation of `values` (None for the mean of no value and
    the spread of fewer than two)."""
    if not values:
        return None, None
    mean = math.fsum(values) / len(values)
    if len(values) < 2:
        return mean, None
    return mean, math.sqrt(math.fsum((v - mean) ** 2 for v in values) / (len(values) - 1))


def configuration_rows(runs: list[dict]) -> list[dict]:
    """One row per configuration, in order of first appearance: its description, runs (that
    ran), failed, and `<value>_mean`, `<value>_std` for each of the VALUES."""
    groups: dict[str, list[dict]] = {}
    for row in runs:
        groups.setdefault(row["configuration"], []).append(row)
    summary = []
    for name, rows in groups.items():
        first, ran = rows[0], [row for row in rows if not row["error"]]
        entry = {"configuration": name, **{key: first[key] for key in ("scene", "preset", "row", "changes")},
                 "seeds": " ".join(str(row["seed"]) for row in rows), "runs": len(ran),
                 "failed": len(rows) - len(ran)}
        for column in VALUES:
            mean, spread = mean_and_spread([row[column.key] for row in ran if row[column.key] is not None])
            entry[f"{column.key}_mean"], entry[f"{column.key}_std"] = mean, spread
        summary.append(entry)
    return summary


def across_scenes(configurations: list[dict]) -> list[dict]:
    """One row per setting (preset, row and changes) that ran on two scenes or more: its scenes,
    the mean and sample standard deviation over scenes of the configurations' means of each of the
    VALUES (`<value>_mean`, `<value>_std`), and the scene of the lowest mean F10 (`worst`, with
    `worst_f10`): a suite's result is its mean and its worst object, never one object."""
    groups: dict[tuple, list[dict]] = {}
    for row in configurations:
        groups.setdefault((row["preset"], row["row"], row["changes"]), []).append(row)
    summary = []
    for (preset, row_name, changes), rows in groups.items():
        if len({row["scene"] for row in rows}) < 2:
            continue
        entry = {"preset": preset, "row": row_name, "changes": changes, "scenes": len(rows)}
        for column in VALUES:
            means = [row[f"{column.key}_mean"] for row in rows if row[f"{column.key}_mean"] is not None]
            entry[f"{column.key}_mean"], entry[f"{column.key}_std"] = mean_and_spread(means)
        scored = [row for row in rows if row["f10_mean"] is not None]
        worst = min(scored, key=lambda row: row["f10_mean"]) if scored else None
        entry["worst"], entry["worst_f10"] = (worst["scene"], worst["f10_mean"]) if worst else ("", None)
        summary.append(entry)
    return summary


def csv_text(rows: list[dict]) -> str:
    """`rows` (dicts with the same keys) as CSV; None is an empty cell."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]) if rows else [], lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def _number(value: float | None, digits: int) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def _mean_spread(mean: float | None, spread: float | None, digits: int) -> str:
    return _number(mean, digits) + ("" if spread is None else f" ± {_number(spread, digits)}")


def label(row: dict) -> str:
    """A configuration as people read it: scene, preset, row and changes."""
    parts = (row["scene"], row["preset"], row["row"], row["changes"].replace(";", " "))
    return " ".join(part for part in parts if part)


def markdown(runs: list[dict], configurations: list[dict]) -> str:
    """The settings' table over scenes (where a setting ran on several), the configurations'
    (mean ± sample std over seeds), then the runs'."""
    headers = [column.header for column in VALUES]
    lines = []
    settings = across_scenes(configurations)
    if settings:
        lines += ["**Per setting, over scenes: mean ± sample standard deviation of the scenes' means, "
                  "and the worst scene by F10**", "",
                  "| setting | scenes | " + " | ".join(headers) + " | worst (F10) |",
                  "|---|---|" + "---|" * (len(headers) + 1)]
        for row in settings:
            cells = [_mean_spread(row[f"{c.key}_mean"], row[f"{c.key}_std"], c.digits) for c in VALUES]
            lines.append(f"| {label({'scene': '', **row})} | {row['scenes']} | " + " | ".join(cells)
                         + f" | {row['worst']} ({_number(row['worst_f10'], 1)}) |")
        lines.append("")
    lines += ["**Per configuration: mean ± sample standard deviation over its runs**", "",
             "| configuration | seeds | runs | failed | " + " | ".join(headers) + " |",
             "|---|---|---|---|" + "---|" * len(headers)]
    for row in configurations:
        cells = [_mean_spread(row[f"{c.key}_mean"], row[f"{c.key}_std"], c.digits) for c in VALUES]
        lines.append(f"| {label(row)} | {row['seeds']} | {row['runs']} | {row['failed']} | "
                     + " | ".join(cells) + " |")
    lines += ["", "**Per run**", "", "| run | seed | " + " | ".join(headers) + " | error |",
              "|---|---|" + "---|" * (len(headers) + 1)]
    for row in runs:
        cells = [_number(row[c.key], c.digits) for c in VALUES]
        lines.append(f"| {row['run']} | {row['seed']} | " + " | ".join(cells) + f" | {row['error']} |")
    return "\n".join(lines + [""])


def plot_png(configurations: list[dict]) -> bytes:
    """Two panels, F10 and training seconds per configuration (mean, sample std as error bars); PNG."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    count = len(configurations)
    figure = Figure(figsize=(max(7.0, 1.0 + 1.2 * count), 5.5), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(1, 2)
    positions = list(range(count))
    for axis, key, title in ((axes[0], "f10", "F-score at 10 mm (%)"), (axes[1], "train_seconds",
                                                                        "training time (s)")):
        means = [row[f"{key}_mean"] for row in configurations]
        spreads = [row[f"{key}_std"] or 0.0 for row in configurations]
        axis.bar(positions, [math.nan if m is None else m for m in means], yerr=spreads, capsize=3)
        # Wrapped: a label of a row and its changes is long, and would squeeze the panels to nothing.
        axis.set_xticks(positions, [textwrap.fill(label(row), 28) for row in configurations], rotation=30,
                        ha="right", fontsize=8)
        axis.set_ylabel(title)
        axis.grid(True, axis="y", alpha=0.3)
        if all(m is None for m in means):
            axis.text(0.5, 0.5, "no scores (scenes without ground truth)", transform=axis.transAxes,
                      ha="center")
    figure.suptitle("Batch: mean and sample standard deviation per configuration")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


def write_tables(out: Path, outcomes: list[RunOutcome]) -> list[Path]:
    """Write the BATCH_FILES into `out` atomically; returns their paths."""
    runs = run_rows(outcomes)
    configurations = configuration_rows(runs)
    paths = [out / name for name in BATCH_FILES]
    atomic_write_json(paths[0], {"settings": across_scenes(configurations), "configurations": configurations,
                                 "runs": runs})
    atomic_write_bytes(paths[1], csv_text(configurations).encode())
    atomic_write_bytes(paths[2], csv_text(runs).encode())
    atomic_write_bytes(paths[3], markdown(runs, configurations).encode())
    atomic_write_bytes(paths[4], plot_png(configurations))
    return paths
