"""`edgedog bench layers`: the multi-granularity model against the direct alternative (the
paper's Fig. 7) — a layered run L0, L1, L2 and a single run on the finest level's maps, their
per-layer and cumulative curves scored, a table and a figure of the levels.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from edgedog.bench.tables import cell
from edgedog.files import atomic_write_bytes, atomic_write_json, read_json
from edgedog.settings import with_values
from edgedog.train.config import TrainConfig
from edgedog.train.levels import Level

DIRECT = "direct"
LAYERS_FILES = ("layers.json", "layers.md", "layers.png")
"""What the bench writes into OUT beside its two runs, its record first."""


def _row(name: str, primitives: int, report: dict) -> dict:
    counts = report["counts"]
    return {"selection": name, "primitives": primitives, "curves": counts["lines"] + counts["beziers"],
            "metrics": report.get("metrics", {}).get("curves")}


def run_layers_bench(scene_path: Path, out: Path, preset_name: str, base: TrainConfig,
                     levels: tuple[Level, ...], progress: bool = True, figure: bool = True) -> dict:
    """Train (or reuse) the layered run and the direct run, extract, score; write
    OUT/layers.json, OUT/layers.md and (with `figure`) OUT/layers.png. Returns the results."""
    from edgedog.train.lifecycle import lock_folder

    with lock_folder(out):
        return _layers_bench(scene_path, out, preset_name, base, levels, progress, figure)


def _layers_bench(scene_path: Path, out: Path, preset_name: str, base: TrainConfig,
                  levels: tuple[Level, ...], progress: bool, figure: bool) -> dict:
    """`run_layers_bench` under the lock of `out`: OUT/layered is a new layered run, or the one
    an earlier bench left (which must be the same run), and OUT/direct likewise."""
    from edgedog.train.lifecycle import REUSE, execute, plan_run

    layered = execute(plan_run(out / "layered", scene_path, preset_name, base, REUSE, levels).check(),
                      progress=progress)
    run, scene, report = layered.plan.run, layered.plan.scene, layered.report
    rows = [_row(name, s["primitives"], s) for name, s in report["selections"].items()]
    finest = levels[-1]
    direct_config = with_values(base, {"maps.detector": finest.detector, "maps.floor": finest.floor})
    direct_plan = plan_run(out / DIRECT, run.scene, preset_name, direct_config, REUSE)
    direct_run = execute(direct_plan, progress=progress)
    log, direct = direct_run.log, direct_run.report
    rows.append(_row(f"direct ({finest.name} maps)", log["final_primitives"], direct))
    results = {"scene": str(run.scene), "preset": preset_name,
               "levels": [dataclasses.asdict(level) for level in levels], "rows": rows,
               "train_seconds": {**{lv.name: _seconds(run.layer_dir(i)) for i, lv in enumerate(levels)},
                                 DIRECT: log["train_seconds"]}}
    if figure:
        from edgedog.bench.layers_figure import render_layers_figure

        render_layers_figure(run, scene, out / LAYERS_FILES[2])
        results["figure"] = str(out / LAYERS_FILES[2])
    atomic_write_json(out / LAYERS_FILES[0], results)
    atomic_write_bytes(out / LAYERS_FILES[1], markdown(results).encode())
    return results


def _seconds(layer_dir: Path) -> float:
    return read_json(layer_dir / "log.json")["train_seconds"]


def markdown(results: dict) -> str:
    """The table: each layer alone, each cumulative stack and the direct run."""
    levels = ", ".join(f"{lv['name']} = {lv['detector']}"
                       + (f" (floor {lv['floor']:g})" if lv["floor"] else "")
                       for lv in results["levels"])
    lines = [f"Levels: {levels}. Training seconds: "
             + ", ".join(f"{k} {v:.0f}" for k, v in results["train_seconds"].items()) + ".", "",
             "| selection | primitives | curves | Acc (mm) | Comp (mm) | P10 | R10 | F10 | F20 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for row in results["rows"]:
        m = row["metrics"] or {}
        scores = [cell(m.get("acc_mm"), 2), cell(m.get("comp_mm"), 2)]
        scores += [cell(m.get(k), 1) for k in ("precision_10mm", "recall_10mm", "fscore_10mm", "fscore_20mm")]
        lines.append(f"| {row['selection']} | {row['primitives']} | {row['curves']} | {' | '.join(scores)} |")
    return "\n".join(lines) + "\n"
