"""A batch's unit of work: a planned run and the task that carries it out.

A task is a frozen dataclass at module level, so Ray sends it to a worker by reference (its
class's module and name, and its fields). `TrainAndExtract` is the batch's: train what is left
of the run, then extract and score its curves. A benchmark may name another (e.g. training with
evaluations along the way); whatever it returns beyond the log and the report goes in
`RunOutcome.extra`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

from edgedog.batch.outcome import SKIPPED, RunOutcome
from edgedog.batch.suite import RunSpec
from edgedog.files import read_json
from edgedog.train.lifecycle import FINISHED, LOG, RunPlan


class Task(Protocol):
    """What a job does: `run` in a worker, `reuse` in the driver when the batch is planned."""

    def run(self, job: Job) -> RunOutcome:
        """Carry out the job under its folder's lock; a user error raises EdgeDogError."""

    def reuse(self, job: Job) -> RunOutcome | None:
        """The outcome of a job found done when it was planned (state SKIPPED), read from its
        folder; None when it has work left. May raise InputError when the folder holds work
        this task cannot continue."""


@dataclass(frozen=True)
class TrainAndExtract:
    """Train (or resume) the run, then extract and score its curves when their report is missing."""

    def run(self, job: Job) -> RunOutcome:
        from edgedog.train.lifecycle import execute

        result = execute(job.plan, progress=False)
        return RunOutcome(job.spec, result.plan.state, result.plan.step, result.log, result.report)

    def reuse(self, job: Job) -> RunOutcome | None:
        from edgedog.curves.report import REPORT

        plan = job.plan
        if plan.state != FINISHED or not plan.extracted:
            return None
        path = plan.run.path
        return RunOutcome(job.spec, SKIPPED, plan.step, read_json(path / LOG), read_json(path / REPORT))


@dataclass(frozen=True)
class Job:
    """A run to execute: its spec, the plan the driver made for it and the task that executes it."""

    spec: RunSpec
    plan: RunPlan
    task: Task = field(default_factory=TrainAndExtract)
