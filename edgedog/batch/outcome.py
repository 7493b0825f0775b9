"""What one run of a batch gave back: the part every executor returns and the tables read."""

from __future__ import annotations

from dataclasses import dataclass

from edgedog.batch.suite import RunSpec

SKIPPED = "skipped"
"""The state of a run found finished and extracted when the batch was planned: no worker ran it."""


@dataclass(frozen=True)
class RunOutcome:
    """One run's result.

    spec: the run; state: how its worker found the folder under its lock ('new', 'resume': from
    its checkpoint at `step`, 'finished': only extracted) or SKIPPED; step: the step training
    started from; log: its log.json ({} when it failed); report: its extract.json ({} when it
    failed); error: the one-line user error that stopped it ('' when it ran); extra: what its
    task gave back besides (plain data, e.g. a benchmark's evaluations along training; None for
    the batch's own task and a failed run).
    """

    spec: RunSpec
    state: str
    step: int = 0
    log: dict | None = None
    report: dict | None = None
    error: str = ""
    extra: dict | None = None
