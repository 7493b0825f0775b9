"""`edgedog bench ablation`: the paper's Table 3 (EdgeDoG's components, baseline to full),
Table 4 (pixel-uncertainty weighting functions) and the corrections of the pseudo-edge maps'
bias, each row a training run whose extracted curves are scored against the ground truth.

Rows whose configurations train identically (weighting 1 with the pixel-level term on is the
same loss as with it off) share one run, so a table never reports two numbers for one model.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from edgedog.bench.tables import cell
from edgedog.errors import ConfigError, InputError
from edgedog.files import atomic_write_bytes, atomic_write_json
from edgedog.settings import with_values
from edgedog.train.config import TrainConfig
from edgedog.train.run_folder import RunFolder, RunLock

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
    """A folder name for a run, from the components it uses."""
    maps, loss = config.maps, config.loss
    parts = [config.model.kernel, f"pix-{loss.weighting}" if loss.pixel_uncertainty else "nopix",
             "fisher" if config.strategy.primitive_uncertainty else "nofisher"]
    parts += [maps.correction] if maps.correction != "none" else []
    parts += [maps.edge_profile] if maps.edge_profile not in ("auto", "raw") else []
    parts += {"none": [], "measured": ["outline"], "auto": ["outline-auto"]}[maps.silhouette_correction]
    return "_".join(parts)


def train_and_extract(run: RunFolder, progress: bool) -> tuple[dict, dict]:
    """Train (or resume, or reuse a finished) `run`, then extract and score its curves unless a
    finished run has them; returns its log.json and extraction report."""
    from edgedog.train.lifecycle import REUSE, execute, plan_run

    result = execute(plan_run(run.path, run.scene, run.preset, run.config, REUSE), progress=progress)
    return result.log, result.report


def run_ablation(scene_path: Path, out: Path, preset_name: str, base: TrainConfig,
                 tables: tuple[str, ...] = TABLES, progress: bool = True,
                 keys: tuple[str, ...] | None = None) -> list[dict]:
    """Train and score every row of the chosen tables, or the rows with `keys` among them (runs
    shared where configs coincide) in out/<run name>/; `base` is the preset `preset_name` with
    any overrides. Writes out/ablation.json and out/ablation.md once every row is done (a killed
    bench resumes from the rows' run folders); returns the rows' results. `out` is locked
    throughout: one bench writes its tables at a time."""
    with RunLock.acquire(out):
        results = _run_rows(select_rows(tables, keys), scene_path, out, preset_name, base, progress)
        write_report(out, results)
    return results


def _run_rows(rows: list[AblationRow], scene_path: Path, out: Path, preset_name: str, base: TrainConfig,
              progress: bool) -> list[dict]:
    results = []
    for row in rows:
        config = effective_config(with_values(base, row.changes))
        folder = out / run_name(config)
        run = RunFolder(folder, scene_path.resolve(), preset_name, config)
        try:
            log, report = train_and_extract(run, progress)
        except ConfigError as error:  # e.g. no calibration record for these maps' detector
            results.append({"table": row.table, "label": row.label, "run": folder.name,
                            "skipped": str(error)})
            continue
        if "metrics" not in report:
            raise InputError(scene_path, "the ablation needs a scene with ground truth")
        results.append({"table": row.table, "label": row.label, "run": folder.name,
                        "metrics": report["metrics"].get("curves"),  # None: no curve to score
                        "points_fscore_10mm": report["metrics"].get("points", {}).get("fscore_10mm"),
                        "curves": report["counts"]["lines"] + report["counts"]["beziers"],
                        "train_seconds": log["train_seconds"], "primitives": log["final_primitives"],
                        "map_shift_px": log.get("map_shift_px"),
                        "outline_offset_px": (log.get("silhouette_correction") or {}).get("offset_px")})
    return results


def markdown(results: list[dict]) -> str:
    """The tables as Markdown, rows in the order given; a skipped row says why."""
    lines = []
    for table in TABLES:
        rows = [r for r in results if r["table"] == table]
        if not rows:
            continue
        shifts = table == CORRECTIONS
        lines += [f"**{TITLES[table]}**", "",
                  "| row | R5 | P5 | F5 | F10 | F20 | Acc (mm) | Comp (mm) | points F10 | curves | train (s) "
                  "| primitives |" + (" map shift (px) | outline offset (px) |" if shifts else ""),
                  "|---|---|---|---|---|---|---|---|---|---|---|---|" + ("---|---|" if shifts else "")]
        for r in rows:
            if "skipped" in r:
                lines.append(f"| {r['label']} | skipped: {r['skipped']} |")
                continue
            m = r["metrics"] or {}
            scores = [cell(m.get(key), 1) for key in
                      ("recall_5mm", "precision_5mm", "fscore_5mm", "fscore_10mm", "fscore_20mm")]
            scores += [cell(m.get("acc_mm"), 2), cell(m.get("comp_mm"), 2),
                       cell(r["points_fscore_10mm"], 1)]
            shift = r.get("map_shift_px") or [0.0, 0.0]
            lines.append(f"| {r['label']} | {' | '.join(scores)} | {r['curves']} | "
                         f"{r['train_seconds']:.0f} | {r['primitives']} |"
                         + (f" {shift[0]:+.2f}, {shift[1]:+.2f} | {cell(r.get('outline_offset_px'), 2)} |"
                            if shifts else ""))
        lines.append("")
    return "\n".join(lines)


def write_report(out: Path, results: list[dict]) -> None:
    atomic_write_json(out / "ablation.json", results)
    atomic_write_bytes(out / "ablation.md", markdown(results).encode())
