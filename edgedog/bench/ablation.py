"""`edgedog bench ablation`: the paper's Table 3 (EdgeDoG's components, baseline to full),
Table 4 (pixel-uncertainty weighting functions) and the corrections of the pseudo-edge maps'
bias, each row a training run per seed whose extracted curves are scored against the ground truth.

The rows become the runs of a batch (`edgedog.batch.runner.run_batch`), executed in this process
or on Ray like `edgedog batch`, each in its own run folder under OUT. Rows whose configurations
train identically (weighting 1 with the pixel-level term on is the same loss as with it off)
share one run per seed, so a table never reports two numbers for one model.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from edgedog.batch.outcome import RunOutcome
from edgedog.batch.runner import BatchResult, Executor, run_batch
from edgedog.batch.suite import RunSpec, spec_of_config
from edgedog.batch.table import BATCH_FILES, mean_and_spread
from edgedog.bench.tables import spread_cell
from edgedog.errors import ConfigError, InputError
from edgedog.files import atomic_write_bytes, atomic_write_json
from edgedog.settings import with_values
from edgedog.train.config import TrainConfig, preset, with_overrides

COMPONENTS = "components"
WEIGHTING = "weighting"
CORRECTIONS = "corrections"
TABLES = (COMPONENTS, WEIGHTING, CORRECTIONS)
TITLES = {COMPONENTS: "Components (Table 3)", WEIGHTING: "Weighting of the pixel uncertainty (Table 4)",
          CORRECTIONS: "Corrections of the maps' bias (map shift: px at the training resolution; "
                       "outline offset: where the maps drew the masks' outline, px outside)"}


@dataclass(frozen=True)
class AblationRow:
    """One row: which table, its short key (`--rows`), its label, and the settings it changes
    from the base config (dotted setting name -> value)."""

    table: str
    key: str
    label: str
    changes: dict


def component_rows() -> list[AblationRow]:
    """Table 3: the baseline, each of the DoG kernel and the two uncertainties alone, each pair,
    and the full model. Pixel U weights by the base config's w(Up) (the paper's was exp(Up):
    `--set loss.weighting=exp`, or `--preset paper`)."""
    combos = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1), (1, 1, 1)]
    rows = []
    for dog, pixel, primitive in combos:
        parts = [name for name, on in (("DoG", dog), ("pixel U", pixel), ("Fisher U", primitive)) if on]
        label = "baseline (EdgeGaussians)" if not parts else "+ " + " + ".join(parts)
        key = "+".join(k for k, on in (("dog", dog), ("pixel", pixel), ("fisher", primitive)) if on)
        key = {"": "baseline", "dog+pixel+fisher": "full"}.get(key, key)
        rows.append(AblationRow(COMPONENTS, key, "full EdgeDoG" if len(parts) == 3 else label, {
            "model.kernel": "dog" if dog else "gaussian", "loss.pixel_uncertainty": bool(pixel),
            "strategy.primitive_uncertainty": bool(primitive)}))
    return rows


FULL_MODEL = {"model.kernel": "dog", "loss.pixel_uncertainty": True, "strategy.primitive_uncertainty": True}
"""The settings of the full EdgeDoG model."""


def weighting_rows() -> list[AblationRow]:
    """Table 4: the full model with each weighting function w(Up)."""
    names = {"one": "w = 1", "exp_neg": "w = exp(-Up)", "one_minus": "w = 1 - Up", "up": "w = Up",
             "exp": "w = exp(Up)"}
    return [AblationRow(WEIGHTING, name, label, {**FULL_MODEL, "loss.weighting": name})
            for name, label in names.items()]


def correction_rows() -> list[AblationRow]:
    """The full model on the raw maps and with each correction of the maps' bias."""
    plain = {"maps.silhouette_correction": "none", "maps.edge_profile": "raw"}  # one correction at a time
    rows = [("raw", "raw maps", plain),
            ("calibrated", "shift by the detector's calibration", {**plain, "maps.correction": "calibrated"}),
            ("learned", "shift learned with the primitives", {**plain, "maps.correction": "learned"}),
            ("thin", "thinned (NMS + narrow profile)", {**plain, "maps.edge_profile": "thin"}),
            ("profile", "profile loss (render blurred to the band)",
             {**plain, "maps.edge_profile": "profile"}),
            ("outline", "outline pulled onto the masks", {**plain, "maps.silhouette_correction": "measured"}),
            ("outline+profile", "outline pulled onto the masks + profile loss",
             {"maps.silhouette_correction": "measured", "maps.edge_profile": "profile"})]
    return [AblationRow(CORRECTIONS, key, label, {**FULL_MODEL, **changes}) for key, label, changes in rows]


def select_rows(tables: tuple[str, ...], keys: tuple[str, ...] | None = None) -> list[AblationRow]:
    """The rows of `tables` in table order; with `keys`, only the rows with those keys (a
    ConfigError names any key that is no row of the tables)."""
    rows = [r for r in component_rows() + weighting_rows() + correction_rows() if r.table in tables]
    if keys is None:
        return rows
    unknown = set(keys) - {r.key for r in rows}
    if unknown:
        raise ConfigError(f"--rows: no row {', '.join(sorted(unknown))} in the tables {', '.join(tables)}; "
                          f"rows: {', '.join(dict.fromkeys(r.key for r in rows))}")
    return [r for r in rows if r.key in keys]


def effective_config(config: TrainConfig) -> TrainConfig:
    """The config with settings that cannot change training normalised away (for sharing runs)."""
    defaults = TrainConfig()
    if config.loss.pixel_uncertainty and config.loss.weighting == "one":
        config = with_values(config, {"loss.pixel_uncertainty": False})
    if not config.loss.pixel_uncertainty:
        config = with_values(config, {"loss.weighting": defaults.loss.weighting})
    if not config.strategy.primitive_uncertainty:
        config = with_values(config, {"strategy.keep_ratio": defaults.strategy.keep_ratio})
    if config.model.kernel == "gaussian":
        config = with_values(config, {"init.k": defaults.init.k, "schedule.lr_k": defaults.schedule.lr_k})
    return config


def run_name(config: TrainConfig) -> str:
    """A run's row in its folder name (`<scene>_<preset>_<row>_<digest>_seed<N>`), from the
    components it uses."""
    maps, loss = config.maps, config.loss
    parts = [config.model.kernel, f"pix-{loss.weighting}" if loss.pixel_uncertainty else "nopix",
             "fisher" if config.strategy.primitive_uncertainty else "nofisher"]
    parts += [maps.correction] if maps.correction != "none" else []
    parts += [maps.edge_profile] if maps.edge_profile not in ("auto", "raw") else []
    parts += {"none": [], "measured": ["outline"], "auto": ["outline-auto"]}[maps.silhouette_correction]
    return "_".join(parts)


ABLATION_FILES = ("ablation.json", "ablation.md")
"""The bench's own tables in OUT, beside the batch's."""
VALUES = ("recall_5mm", "precision_5mm", "fscore_5mm", "fscore_10mm", "fscore_20mm", "acc_mm", "comp_mm",
          "points_fscore_10mm", "curves", "train_seconds", "primitives", "map_shift_x", "map_shift_y",
          "outline_offset_px")
"""A run's values that a row reports, each as its mean and spread over the row's seeds."""
_CURVE_SCORES = VALUES[:7]


@dataclass(frozen=True)
class AblationResult:
    """rows: each ablation row's results (`row_result`), in table order; batch: the runs."""

    rows: list[dict]
    batch: BatchResult


def row_specs(scene: Path, preset_name: str, base: TrainConfig, row: AblationRow,
              seeds: tuple[int, ...]) -> list[RunSpec]:
    """The row's runs, one per seed: `base` with the row's changes, normalised by
    `effective_config`, so rows of one effective configuration name the same runs."""
    config = effective_config(with_values(base, row.changes))
    return [spec_of_config(scene, preset_name, run_name(config), base, config, seed) for seed in seeds]


def run_ablation(scene_path: Path, out: Path, preset_name: str, overrides: list[str], rows: list[AblationRow],
                 seeds: tuple[int, ...], executor: Executor,
                 report: Callable[[int, int, RunOutcome], None] | None = None) -> AblationResult:
    """Train and score each of `rows` once per seed (`preset_name` with `overrides`, then the
    row's changes, then the seed) as a batch in `out`, each distinct run once, and write the
    batch's tables and ABLATION_FILES there. A rerun reuses the finished runs and resumes the
    others; `report` is the batch's progress callback."""
    from edgedog.groundtruth import ground_truth_for

    base = with_overrides(preset(preset_name), overrides)
    scene = Path(scene_path).resolve()
    if ground_truth_for(scene) is None:
        raise InputError(scene_path, "the ablation needs a scene with ground truth")
    specs = {row.key: row_specs(scene, preset_name, base, row, seeds) for row in rows}
    runs = list({spec.name: spec for row_runs in specs.values() for spec in row_runs}.values())
    results: list[dict] = []

    def summarise(outcomes: list[RunOutcome]) -> list[Path]:
        by_name = {outcome.spec.name: outcome for outcome in outcomes}
        results.extend(row_result(row, [by_name[spec.name] for spec in specs[row.key]]) for row in rows)
        return write_report(out, results)

    batch = run_batch(runs, out, executor, report=report, summarise=summarise,
                      own_files=BATCH_FILES + ABLATION_FILES)
    return AblationResult(results, batch)


def run_values(outcome: RunOutcome) -> dict:
    """The VALUES of a run that ran (None where there is none: no curve to score, no map shift)."""
    metrics = (outcome.report or {}).get("metrics") or {}
    curves, log = metrics.get("curves") or {}, outcome.log or {}
    counts = (outcome.report or {}).get("counts") or {}
    shift = log.get("map_shift_px") or [None, None]
    return {**{key: curves.get(key) for key in _CURVE_SCORES},
            "points_fscore_10mm": (metrics.get("points") or {}).get("fscore_10mm"),
            "curves": counts.get("lines", 0) + counts.get("beziers", 0),
            "train_seconds": log.get("train_seconds"), "primitives": log.get("final_primitives"),
            "map_shift_x": shift[0], "map_shift_y": shift[1],
            "outline_offset_px": (log.get("silhouette_correction") or {}).get("offset_px")}


def row_result(row: AblationRow, outcomes: list[RunOutcome]) -> dict:
    """A row from its runs (one per seed): table, key, label, configuration, runs (folder names),
    seeds, errors (of the runs that failed), and `<value>_mean`, `<value>_std` for each of the
    VALUES over the runs that ran and have it (std: the sample standard deviation, None for
    fewer than two)."""
    ran = [run_values(outcome) for outcome in outcomes if not outcome.error]
    result = {"table": row.table, "key": row.key, "label": row.label,
              "configuration": outcomes[0].spec.configuration,
              "runs": [outcome.spec.name for outcome in outcomes], "seeds": [o.spec.seed for o in outcomes],
              "errors": [outcome.error for outcome in outcomes if outcome.error]}
    for key in VALUES:
        result[f"{key}_mean"], result[f"{key}_std"] = mean_and_spread(
            [values[key] for values in ran if values[key] is not None])
    return result


def _cells(result: dict, keys: tuple[str, ...], digits: int) -> list[str]:
    return [spread_cell(result[f"{key}_mean"], result[f"{key}_std"], digits) for key in keys]


def _shift_cell(result: dict) -> str:
    """The map shift (x, y) in px, signed; no shift learned or calibrated reads as 0."""
    return ", ".join(spread_cell(result[f"map_shift_{axis}_mean"] or 0.0, result[f"map_shift_{axis}_std"], 2,
                                 sign="+") for axis in "xy")


def markdown(results: list[dict]) -> str:
    """The tables as Markdown, rows in the order given, each cell the mean ± the sample standard
    deviation over the row's seeds (the value alone for one seed); a row whose runs all failed
    says why."""
    lines = []
    for table in TABLES:
        rows = [r for r in results if r["table"] == table]
        if not rows:
            continue
        shifts = table == CORRECTIONS
        seeds = rows[0]["seeds"]
        over = f" (mean ± sample standard deviation over seeds {', '.join(map(str, seeds))})" \
            if len(seeds) > 1 else ""
        lines += [f"**{TITLES[table]}**{over}", "",
                  "| row | R5 | P5 | F5 | F10 | F20 | Acc (mm) | Comp (mm) | points F10 | curves | train (s) "
                  "| primitives |" + (" map shift (px) | outline offset (px) |" if shifts else ""),
                  "|---|---|---|---|---|---|---|---|---|---|---|---|" + ("---|---|" if shifts else "")]
        for r in rows:
            if len(r["errors"]) == len(r["runs"]):
                lines.append(f"| {r['label']} | skipped: {r['errors'][0]} |")
                continue
            failed = (f" ({len(r['errors'])} of {len(r['runs'])} runs failed: {r['errors'][0]})"
                      if r["errors"] else "")
            cells = (_cells(r, VALUES[:5], 1) + _cells(r, ("acc_mm", "comp_mm"), 2)
                     + _cells(r, ("points_fscore_10mm",), 1)
                     + _cells(r, ("curves", "train_seconds", "primitives"), 0))
            if shifts:
                cells += [_shift_cell(r), *_cells(r, ("outline_offset_px",), 2)]
            lines.append(f"| {r['label']}{failed} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def write_report(out: Path, results: list[dict]) -> list[Path]:
    """Write the ABLATION_FILES into `out` atomically; returns their paths."""
    json_path, md_path = (Path(out) / name for name in ABLATION_FILES)
    atomic_write_json(json_path, results)
    atomic_write_bytes(md_path, markdown(results).encode())
    return [json_path, md_path]
