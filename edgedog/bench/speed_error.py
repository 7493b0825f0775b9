"""`edgedog bench speed-error`: how the error of the extracted curves falls as training time grows.

Each budget (a preset, possibly at another resolution or with fewer epochs) trains once per seed,
as a run of a batch (`edgedog.batch.runner.run_batch`, in this process or on Ray) in its own run
folder under OUT, through the task `EvaluatedTraining`: at evenly spaced epochs the trainer is
paused, its curves are extracted and scored, and the row (training seconds so far, primitives,
scores) is appended to the folder's speed_error.json. Once every run is done, OUT/speed_error.csv,
.md and .png summarise them, beside the batch's tables.

Seconds are the trainer's own clock (steps and density control): checkpoints, extraction and
scoring are not counted, so the numbers are what a plain `edgedog train` of that length costs.
"""

from __future__ import annotations

import dataclasses
import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from edgedog.batch.jobs import Job
from edgedog.batch.outcome import SKIPPED, RunOutcome
from edgedog.batch.runner import BatchResult, Executor, run_batch
from edgedog.batch.suite import RunSpec, spec_of_config
from edgedog.batch.table import BATCH_FILES, csv_text
from edgedog.bench.tables import cell
from edgedog.errors import ConfigError, InputError
from edgedog.files import atomic_write_bytes, atomic_write_json, read_json
from edgedog.settings import with_values
from edgedog.train.config import TrainConfig, preset, with_epochs, with_overrides
from edgedog.train.lifecycle import LOG

if TYPE_CHECKING:  # torch and the scene loaders load only when a bench runs
    from edgedog.scenes import Scene
    from edgedog.train.run import Run
    from edgedog.train.trainer import Trainer

RESULT = "speed_error.json"
MAX_EVALS = 1000
"""Evaluations per run (each extracts and scores the curves, seconds each); the loop over them is
bounded here, not by the run's epochs."""
"""A budget's evaluations, in its run folder."""
SUMMARY = ("speed_error.csv", "speed_error.md", "speed_error.png")
"""What the bench writes in OUT."""


@dataclass(frozen=True)
class Budget:
    """A named amount of training: a preset, optionally at another downscale, or with a share
    of its epochs (the whole schedule compressed with `with_epochs`)."""

    name: str
    preset: str
    description: str
    downscale: int | None = None
    epoch_share: float = 1.0

    def config(self, overrides: list[str]) -> TrainConfig:
        """The preset with `overrides` (--set) applied, then this budget's own change: the name
        stays true (preview-d4 trains at downscale 4 whatever --set says) and preview-50 has half
        the epochs of whatever preview has."""
        return self.applied(with_overrides(preset(self.preset), overrides))

    def applied(self, config: TrainConfig) -> TrainConfig:
        """`config` (the preset with the --set overrides) with this budget's own change."""
        if self.downscale is not None:
            config = with_values(config, {"maps.downscale": self.downscale})
        return with_epochs(config, max(1, round(config.schedule.epochs * self.epoch_share)))


BUDGETS = {b.name: b for b in (
    Budget("preview-d4", "preview", "preset preview at 1/4 resolution", downscale=4),
    Budget("preview-50", "preview", "preset preview with half its epochs", epoch_share=0.5),
    Budget("preview", "preview", "preset preview (100 epochs at 1/2 resolution)"),
    Budget("preview-d1", "preview", "preset preview at full resolution", downscale=1),
    Budget("quick", "quick", "preset quick (100 epochs, the first 70 at 1/2 resolution)"),
    Budget("fast", "fast", "preset fast (200 epochs at full resolution)"),
    Budget("full", "full", "preset full (400 epochs at full resolution)"),
)}
DEFAULT_BUDGETS = "preview-d4,preview,fast,full"


def parse_budgets(text: str) -> list[Budget]:
    """Budgets from a comma-separated list of names (e.g. 'preview-d4,fast')."""
    names = [name.strip() for name in text.split(",") if name.strip()]
    unknown = [name for name in names if name not in BUDGETS]
    if not names or unknown:
        raise ConfigError(f"--budgets must list some of {', '.join(BUDGETS)}, got {text!r}")
    return [BUDGETS[name] for name in dict.fromkeys(names)]


def evaluation_epochs(epochs: int, count: int) -> list[int]:
    """`count` epochs evenly spaced over a run of `epochs`, the last at the end (fewer when the
    run is shorter than `count` epochs)."""
    if not 1 <= count <= MAX_EVALS:
        raise ConfigError(f"--evals must be an integer in [1, {MAX_EVALS}], got {count}")
    return sorted({max(1, round(epochs * i / count)) for i in range(1, count + 1)})


@dataclass(frozen=True)
class EvalPoint:
    """The model at one evaluation epoch.

    seconds: training time so far (evaluation excluded); curves: lines + Béziers;
    curve_scores, point_scores: `EdgeMetrics.to_dict()` of the curves and of the filtered
    points, None when there was nothing to score.
    """

    epoch: int
    seconds: float
    primitives: int
    curves: int
    curve_scores: dict | None
    point_scores: dict | None


@dataclass
class BudgetResult:
    """One run's evaluations so far (a budget at a seed), as saved in its folder's speed_error.json.

    resolution: the training images' size, e.g. '200x200'; eval_epochs: where the run is (to
    be) evaluated; points: the evaluations done, in epoch order; seed: the run's seed.
    """

    budget: str
    epochs: int
    resolution: str
    eval_epochs: list[int]
    points: list[EvalPoint]
    seed: int = 0

    @property
    def finished(self) -> bool:
        return [p.epoch for p in self.points] == self.eval_epochs

    @classmethod
    def from_dict(cls, data: dict) -> BudgetResult:
        return cls(**{**data, "points": [EvalPoint(**p) for p in data["points"]]})


def read_result(folder: Path, eval_epochs: list[int]) -> BudgetResult | None:
    """The evaluations saved in `folder`, or None; an error when they were planned at other
    epochs (another --evals or --set epochs)."""
    path = folder / RESULT
    if not path.is_file():
        return None
    result = BudgetResult.from_dict(read_json(path))
    if result.eval_epochs != eval_epochs:
        raise InputError(path, f"holds evaluations at epochs {result.eval_epochs}, not {eval_epochs}; "
                               "use the same --evals, or another --out")
    return result


def evaluate(trainer: Trainer, scene: Scene) -> EvalPoint:
    """Checkpoint `trainer` (a resumed bench restarts from here), write its outputs, extract and
    score its curves (RUN/extract.json); returns the evaluation point."""
    from edgedog.curves.report import extract_with_report

    trainer.save_checkpoint()
    trainer.write_outputs()
    _, report = extract_with_report(trainer.out, scene, trainer.detector)
    metrics, counts = report["metrics"], report["counts"]
    return EvalPoint(trainer.epoch, round(trainer.seconds, 3), len(trainer.model),
                     counts["lines"] + counts["beziers"], metrics.get("curves"), metrics.get("points"))


@dataclass(frozen=True)
class EvaluatedTraining:
    """The bench's task (`edgedog.batch.jobs.Task`): train the job's run, evaluating it at
    `evals` evenly spaced epochs; its outcome's `extra` is the run's `BudgetResult` as a dict."""

    evals: int

    def run(self, job: Job) -> RunOutcome:
        from edgedog.train.run import open_run

        with open_run(job.plan, progress=False) as run:
            result = _train_budget(run, job.spec.row or "", job.spec.seed, self.evals)
        return _outcome(job, run.plan.state, run.plan.step, result)

    def reuse(self, job: Job) -> RunOutcome | None:
        """The outcome of a run evaluated at every epoch; InputError when its folder holds
        evaluations at other epochs (another --evals)."""
        run = job.plan.run
        result = read_result(run.path, evaluation_epochs(run.config.schedule.epochs, self.evals))
        if result is None or not result.finished:
            return None
        return _outcome(job, SKIPPED, job.plan.step, result)


def _outcome(job: Job, state: str, step: int, result: BudgetResult) -> RunOutcome:
    """The outcome of a run whose last evaluation wrote its log.json and extract.json."""
    from edgedog.curves.report import REPORT

    path = job.plan.run.path
    return RunOutcome(job.spec, state, step, read_json(path / LOG), read_json(path / REPORT),
                      extra=dataclasses.asdict(result))


def _train_budget(run: Run, budget: str, seed: int, evals: int) -> BudgetResult:
    """Train the open `run`, evaluating it at `evals` evenly spaced epochs (those not recorded
    yet); returns its evaluations."""
    from edgedog.train.trainer import CHECKPOINT

    config = run.plan.run.config
    eval_epochs = evaluation_epochs(config.schedule.epochs, evals)
    result = read_result(run.path, eval_epochs)
    if result is not None and result.finished:
        return result
    if result is None:
        camera = run.scene.camera(0)
        result = BudgetResult(budget, config.schedule.epochs, f"{camera.width}x{camera.height}",
                              eval_epochs, [], seed)
    recorded = {p.epoch for p in result.points}
    for epoch in (e for e in eval_epochs if e not in recorded):
        trainer = run.current()  # None: trained to its end before this epoch was evaluated
        if trainer is None or trainer.epoch > epoch:
            raise InputError(run.path / CHECKPOINT, f"is past epoch {epoch}, which was never "
                                                    f"evaluated; remove {run.path} to train it again")
        run.train(until=epoch)
        result.points.append(evaluate(trainer, run.scene))
        atomic_write_json(run.path / RESULT, dataclasses.asdict(result))
    return result


@dataclass(frozen=True)
class SpeedErrorResult:
    """results: each run's evaluations (the runs that did not fail), budgets in the order asked,
    seeds within; batch: the runs."""

    results: list[BudgetResult]
    batch: BatchResult


def budget_specs(scene: Path, budgets: list[Budget], overrides: list[str],
                 seeds: tuple[int, ...]) -> list[RunSpec]:
    """One run per budget and seed: the budget's preset with `overrides`, then its own change."""
    specs = []
    for budget in budgets:
        base = with_overrides(preset(budget.preset), overrides)
        config = budget.applied(base)
        specs += [spec_of_config(scene, budget.preset, budget.name, base, config, seed) for seed in seeds]
    return specs


def run_speed_error(scene_path: Path, out: Path, budgets: list[Budget], overrides: list[str],
                    executor: Executor, evals: int = 5, seeds: tuple[int, ...] = (0,),
                    report: Callable[[int, int, RunOutcome], None] | None = None) -> SpeedErrorResult:
    """Train and evaluate every budget at every seed (with `overrides` applied to each) as a
    batch in `out`, then write the batch's tables and the summary files `SUMMARY` there. A rerun
    reuses the runs evaluated to their end and resumes the others; `report` is the batch's
    progress callback."""
    from edgedog.groundtruth import ground_truth_for

    scene = Path(scene_path).resolve()
    specs = budget_specs(scene, budgets, overrides, seeds)
    if ground_truth_for(scene) is None:
        raise InputError(scene_path, "the speed-error bench needs a scene with ground truth")
    results: list[BudgetResult] = []

    def summarise(outcomes: list[RunOutcome]) -> list[Path]:
        results.extend(BudgetResult.from_dict(o.extra) for o in outcomes if o.extra is not None)
        return write_summary(out, scene.name, results)

    batch = run_batch(specs, out, executor, report=report,
                      task=EvaluatedTraining(evals), summarise=summarise, own_files=BATCH_FILES + SUMMARY)
    return SpeedErrorResult(results, batch)


# --- summary: CSV, Markdown, plot


def _thresholds_mm() -> list[int]:
    """The protocol's thresholds in mm (5, 10, 20); imported here to keep the CLI's start light."""
    from edgedog.metrics import THRESHOLDS

    return [round(tau * 1000) for tau in THRESHOLDS]


def _chamfer(scores: dict | None) -> float | None:
    return None if scores is None else (scores["acc_mm"] + scores["comp_mm"]) / 2


def csv_rows(results: list[BudgetResult]) -> list[dict]:
    """One flat row per budget and evaluation point (None where nothing was scored)."""
    rates = [f"{kind}_{mm}mm" for mm in _thresholds_mm() for kind in ("precision", "recall", "fscore")]
    rows = []
    for result in results:
        for p in result.points:
            curves, points = p.curve_scores or {}, p.point_scores or {}
            rows.append({"budget": result.budget, "seed": result.seed, "epoch": p.epoch, "seconds": p.seconds,
                         "primitives": p.primitives, "curves": p.curves, "acc_mm": curves.get("acc_mm"),
                         "comp_mm": curves.get("comp_mm"), "chamfer_mm": _chamfer(p.curve_scores),
                         **{key: curves.get(key) for key in rates},
                         "points_acc_mm": points.get("acc_mm"), "points_comp_mm": points.get("comp_mm"),
                         "points_fscore_10mm": points.get("fscore_10mm")})
    return rows


def _markdown_row(result: BudgetResult, p: EvalPoint) -> str:
    s = p.curve_scores or {}
    cells = [result.budget, str(result.seed), result.resolution, f"{p.epoch}/{result.epochs}",
             f"{p.seconds:.1f}", str(p.primitives), str(p.curves), cell(s.get("acc_mm"), 2),
             cell(s.get("comp_mm"), 2), cell(_chamfer(p.curve_scores), 2)]
    cells += [cell(s.get(f"fscore_{mm}mm"), 1) for mm in _thresholds_mm()]
    cells.append(cell((p.point_scores or {}).get("fscore_10mm"), 1))
    return "| " + " | ".join(cells) + " |"


def markdown(results: list[BudgetResult], scene_name: str) -> str:
    """Two Markdown tables for docs/BENCHMARKS.md: each run (budget and seed) at its end, then
    every point."""
    columns = ["budget", "seed", "resolution", "epoch", "train (s)", "primitives", "curves", "Acc (mm)",
               "Comp (mm)", "Chamfer (mm)", *(f"F{mm}" for mm in _thresholds_mm()), "points F10"]
    head = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    final = [_markdown_row(r, r.points[-1]) for r in results if r.points]
    every = [_markdown_row(r, p) for r in results for p in r.points]
    return "\n".join([f"**Speed against error on {scene_name}: each run at its end**", "", *head, *final,
                      "", "**Along training**", "", *head, *every, ""])


def plot_png(results: list[BudgetResult], scene_name: str) -> bytes:
    """Two panels, F10 and Chamfer against training seconds, one line per run (per budget when
    every budget has one seed); PNG bytes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import LogLocator, ScalarFormatter

    figure = Figure(figsize=(11, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    f_axis, chamfer_axis = figure.subplots(1, 2)
    seconds_seen = []
    several_seeds = len({result.seed for result in results}) > 1
    for result in results:
        name = f"{result.budget} seed {result.seed}" if several_seeds else result.budget
        seconds = [p.seconds for p in result.points]
        seconds_seen += seconds
        f10 = [(p.curve_scores or {}).get("fscore_10mm", math.nan) for p in result.points]
        chamfer = [math.nan if p.curve_scores is None else _chamfer(p.curve_scores)
                   for p in result.points]
        f_axis.plot(seconds, f10, marker="o", label=name)
        chamfer_axis.plot(seconds, chamfer, marker="o", label=name)
    # Budgets differ by tens of times in cost: a log axis keeps the fast ones readable.
    log_scale = bool(seconds_seen) and max(seconds_seen) >= 10 * min(seconds_seen)
    for axis, label in ((f_axis, "F-score at 10 mm (%)"), (chamfer_axis, "Chamfer, (Acc + Comp) / 2 (mm)")):
        axis.set_xlabel("training time (s)")
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
        axis.legend()
        if log_scale:
            axis.set_xscale("log")
            # Plain seconds at the decades and a few steps between, no crowded minor labels.
            axis.xaxis.set_major_formatter(ScalarFormatter())
            axis.xaxis.set_minor_locator(LogLocator(subs=(2, 5)))
            axis.xaxis.set_minor_formatter(ScalarFormatter())
    f_axis.set_ylim(0, 100)
    chamfer_axis.set_ylim(bottom=0)
    figure.suptitle(f"Speed against error on {scene_name}")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=110)
    return buffer.getvalue()


def write_summary(out: Path, scene_name: str, results: list[BudgetResult]) -> list[Path]:
    """Write OUT/speed_error.csv, .md and .png atomically; returns their paths."""
    csv_path, md_path, png_path = (out / name for name in SUMMARY)
    atomic_write_bytes(csv_path, csv_text(csv_rows(results)).encode())
    atomic_write_bytes(md_path, markdown(results, scene_name).encode())
    atomic_write_bytes(png_path, plot_png(results, scene_name))
    return [csv_path, md_path, png_path]
