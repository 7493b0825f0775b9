"""A batch from start to table: plan every run of a suite here, hand the runs left to an executor,
gather what they give back and write the tables.

Planning reads each run's folder (`lifecycle.plan_run`, policy REUSE) before anything runs, so a
suite whose settings cannot be applied, or an output folder holding other runs, stops the batch
with one line and no work done. A run found finished and extracted is read, not executed: rerunning
a batch runs only what is left. The batch folder is locked for the whole batch, each run folder by
the worker executing it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from edgedog.batch.jobs import Job, Task, TrainAndExtract
from edgedog.batch.outcome import RunOutcome
from edgedog.batch.suite import RunSpec
from edgedog.batch.table import BATCH_FILES, write_tables
from edgedog.errors import ConfigError, InputError
from edgedog.outputs import check_output_folder
from edgedog.train.lifecycle import REUSE, lock_folder, plan_run


class Executor(Protocol):
    def run(self, jobs: list[Job]): ...


@dataclass(frozen=True)
class BatchResult:
    """outcomes: one per run, in the suite's order; files: the tables written."""

    outcomes: list[RunOutcome]
    files: list[Path]

    def count(self, state: str) -> int:
        return sum(outcome.state == state for outcome in self.outcomes)

    @property
    def failed(self) -> list[RunOutcome]:
        return [outcome for outcome in self.outcomes if outcome.error]


def plan_jobs(specs: list[RunSpec], out: Path, suite_path: Path | None = None,
              task: Task | None = None) -> list[Job]:
    """Each run's plan in out/<run name>, to be carried out by `task` (default: train and
    extract); the first run that cannot be planned is one error naming the suite (a setting; a
    ConfigError without a suite) or the folder (a folder holding something else)."""
    jobs = []
    for spec in specs:
        try:
            config = spec.config()
        except ConfigError as error:
            if suite_path is None:
                raise
            raise InputError(suite_path, f"run {spec.name}: {error}") from None
        plan = plan_run(out / spec.name, spec.scene, spec.preset, config, REUSE).check()
        jobs.append(Job(spec, plan, task or TrainAndExtract()))
    return jobs


def run_batch(specs: list[RunSpec], out: Path, executor: Executor, suite_path: Path | None = None,
              report: Callable[[int, int, RunOutcome], None] | None = None,
              task: Task | None = None,
              summarise: Callable[[list[RunOutcome]], list[Path]] | None = None,
              own_files: tuple[str, ...] = BATCH_FILES) -> BatchResult:
    """Plan, execute (each run through `task`, default train and extract) and tabulate `specs`
    (their names unique) into `out` (locked throughout); `report(done, total, outcome)` is
    called as each run finishes (skipped ones first). `summarise(outcomes)`, a benchmark's own
    tables, is called with `out` still locked; the files it returns are the result's too.
    `out` may hold runs and `own_files` (the tables) of an earlier batch, nothing else of anyone's
    (`check_output_folder`)."""
    out = Path(out).resolve()
    check_output_folder(out, own_files)
    with lock_folder(out):
        jobs = plan_jobs(specs, out, suite_path, task)
        outcomes: dict[str, RunOutcome] = {}
        left = []
        for job in jobs:
            done = job.task.reuse(job)
            if done is None:
                left.append(job)
            else:
                outcomes[job.spec.name] = done
        if report is not None:
            for index, outcome in enumerate(outcomes.values()):
                report(index + 1, len(jobs), outcome)
        for outcome in executor.run(left):
            outcomes[outcome.spec.name] = outcome
            if report is not None:
                report(len(outcomes), len(jobs), outcome)
        ordered = [outcomes[spec.name] for spec in specs]
        files = write_tables(out, ordered)
        return BatchResult(ordered, files + (summarise(ordered) if summarise is not None else []))
