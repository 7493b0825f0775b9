"""Where a batch's runs execute: one after another in this process, or as Ray tasks.

Both take jobs planned by the driver (`edgedog.batch.runner`), carry each out through its task
(`edgedog.batch.jobs`) and yield each run's `RunOutcome` as it finishes. A task works under its
run folder's lock and re-reads the folder: a task Ray retries after its worker died resumes from
the run's checkpoint. Each run gets `cpus_per_run` threads (torch, OpenMP, MKL, OpenBLAS), so
runs never oversubscribe the cores that Ray hands out by `num_cpus`.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import secrets
import socket
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass

from edgedog.batch.jobs import Job
from edgedog.batch.outcome import RunOutcome
from edgedog.errors import ConfigError, EdgeDogError

INSTALL_HINT = "pip install 'edgedog[cluster]'"
MAX_RETRIES = 3
"""Times Ray runs a task again after its worker process or node was lost (not after an error)."""
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def run_job(job: Job, threads: int) -> RunOutcome:
    """Carry out `job` through its task with `threads` torch threads; a user error (e.g. a
    detector with no calibration) ends the run with its message, not the batch."""
    import torch

    torch.set_num_threads(threads)
    try:
        return job.task.run(job)
    except EdgeDogError as error:
        return RunOutcome(job.spec, job.plan.state, error=str(error))


@dataclass(frozen=True)
class SequentialExecutor:
    """Runs the jobs one after another in this process (no Ray), each with `cpus_per_run` torch
    threads (restored afterwards)."""

    cpus_per_run: int = 1

    def run(self, jobs: Sequence[Job]) -> Iterator[RunOutcome]:
        import torch

        threads = torch.get_num_threads()
        try:
            for job in jobs:
                yield run_job(job, self.cpus_per_run)
        finally:
            torch.set_num_threads(threads)


def ray_installed() -> bool:
    """Whether Ray can be imported; imports nothing (Ray reads its token settings when it is
    imported)."""
    return importlib.util.find_spec("ray") is not None


def require_ray(needs: str = "edgedog batch runs on Ray") -> None:
    """ConfigError (`needs`, then how to install Ray) when Ray is not installed; imports nothing."""
    if not ray_installed():
        raise ConfigError(f"{needs}, which is not installed: {INSTALL_HINT}")


def choose_executor(address: str | None, cpus_per_run: int) -> SequentialExecutor | RayExecutor:
    """The benchmarks' executor: Ray at `address`; without one, Ray started on this machine when
    it is installed, else this process, one run after another (ConfigError: an address without Ray)."""
    if address is not None:
        require_ray(f"--address {address} needs Ray")
    if address is None and not ray_installed():
        return SequentialExecutor(cpus_per_run)
    return RayExecutor(address, cpus_per_run)


def import_ray():
    """The ray module; ConfigError saying how to install it when it is not installed."""
    require_ray()
    import ray

    return ray


@dataclass(frozen=True)
class RayExecutor:
    """Runs each job as a Ray task of `cpus_per_run` CPUs.

    address: None starts Ray on this machine for the batch (stopped after it); 'auto' joins the
    cluster started here with `ray start`; 'HOST:PORT' or 'ray://HOST:PORT' another one's head.
    Every node needs this Python environment and the scenes and the output folder at the same paths.
    """

    address: str | None = None
    cpus_per_run: int = 1

    def run(self, jobs: Sequence[Job]) -> Iterator[RunOutcome]:
        if not jobs:
            return
        with _private_token() if self.address is None else nullcontext():  # before Ray reads it
            yield from self._run_connected(import_ray(), jobs)

    def _run_connected(self, ray, jobs: Sequence[Job]) -> Iterator[RunOutcome]:
        self._connect(ray)
        try:
            cpus = ray.cluster_resources().get("CPU", 0)
            if cpus < self.cpus_per_run:
                raise ConfigError(f"--cpus-per-run {self.cpus_per_run}: the Ray cluster has {cpus:g} CPUs")
            threads = {name: str(self.cpus_per_run) for name in THREAD_VARIABLES}
            # max_calls=1: each run in a worker process of its own. A worker reused for run after
            # run kept growing (the 42 CAD designs, two workers: peak RSS 1.45 GiB at a worker's
            # first run, 2.0 GiB at its twenty-first), and a run's peak RSS was its worker's so far.
            task = ray.remote(max_calls=1)(run_job).options(
                num_cpus=self.cpus_per_run, max_retries=MAX_RETRIES, retry_exceptions=False,
                runtime_env={"env_vars": threads})  # read when the worker's torch loads
            jobs_of = {task.remote(job, self.cpus_per_run): job for job in jobs}
            pending = list(jobs_of)
            lost = (ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError,
                    ray.exceptions.OutOfMemoryError)
            while pending:
                (ready,), pending = ray.wait(pending, num_returns=1)
                try:
                    outcome = ray.get(ready)
                except lost as error:  # its last retry was lost too: the run fails, the others go on
                    job = jobs_of[ready]
                    outcome = RunOutcome(job.spec, job.plan.state, error=f"its worker was lost "
                                         f"{MAX_RETRIES + 1} times (last: {type(error).__name__})")
                yield outcome
        finally:
            ray.shutdown()

    def _connect(self, ray) -> None:
        if self.address not in (None, "auto"):
            check_reachable(self.address)
        quiet = {"logging_level": logging.WARNING, "log_to_driver": False}
        try:
            if self.address is None:
                ray.init(include_dashboard=False, **quiet)
            else:
                ray.init(address=self.address, **quiet)
        except Exception as error:  # Ray's own and the OS's (no memory under ulimit -v, no sockets)
            where = f"--address {self.address}: cannot join Ray" if self.address else "cannot start Ray"
            raise ConfigError(f"{where} ({type(error).__name__}: {' '.join(str(error).split())})") from None


@contextmanager
def _private_token() -> Iterator[None]:
    """A token of this batch's own for the Ray instance it starts here, unless one is configured:
    Ray (2.59 on) turns token authentication on for local instances and would otherwise write
    one into the user's home folder (~/.ray/auth_token)."""
    if os.environ.get("RAY_AUTH_TOKEN") or os.environ.get("RAY_AUTH_TOKEN_PATH"):
        yield
        return
    saved = {name: os.environ.get(name) for name in ("RAY_AUTH_MODE", "RAY_AUTH_TOKEN")}
    os.environ.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32))
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def check_reachable(address: str, timeout: float = 10.0) -> None:
    """ConfigError unless something listens at `address` ('HOST:PORT' or 'ray://HOST:PORT'): Ray
    itself retries an unreachable head for minutes before it gives up."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise ConfigError(f"--address {address}: expected auto, HOST:PORT or ray://HOST:PORT")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as error:
        raise ConfigError(f"--address {address}: cannot reach {host}:{port} "
                          f"({error.strerror or type(error).__name__})") from None
