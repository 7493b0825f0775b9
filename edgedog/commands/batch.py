"""`edgedog batch SUITE.yaml --out DIR`: a benchmark suite's runs on Ray, gathered into one table."""

from __future__ import annotations

import argparse
import textwrap
import time
from pathlib import Path

from edgedog.batch.suite import EXAMPLE
from edgedog.commands.arguments import bounded_integer
from edgedog.errors import InputError

EPILOG = "suite file (YAML):\n" + textwrap.indent(EXAMPLE, "  ") + """
Each run trains, extracts and scores into DIR/<scene>_<preset>[_<row>]_<digest>_seed<N>/.
Rerunning the command skips finished runs and resumes killed ones from their checkpoints.
DIR gets batch.json, batch.csv (per configuration: mean and sample standard deviation over
its runs), batch_runs.csv, batch.md and batch.png. Needs Ray: pip install 'edgedog[cluster]'.
See docs/BATCH.md for clusters."""


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "batch", help="run a benchmark suite's training runs (on Ray) and tabulate their scores",
        description="Train, extract and score every run of a suite (scenes x presets x grid x rows x "
                    "seeds), each a Ray task in its own run folder under --out, then write the tables.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("suite", type=Path, help="suite file (YAML)")
    parser.add_argument("--out", type=Path, required=True, help="batch folder (locked while the batch runs)")
    parser.add_argument("--address", default=None, metavar="auto|HOST:PORT|ray://HOST:PORT",
                        help="a Ray cluster to run on: 'auto' for the one started on this machine with "
                             "`ray start`; default: Ray started on this machine for this batch")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a training setting in every run, after the suite's `set` "
                             "(repeatable; part of the runs' folder names)")
    parser.add_argument("--cpus-per-run", type=bounded_integer(1, 1024), default=1, metavar="N",
                        help="CPUs (and torch/OpenMP threads) of each run (default 1)")
    parser.set_defaults(run=run, resume_hint=resume_hint)


def resume_hint(args: argparse.Namespace) -> str:
    return "run the same command again: finished runs are kept and killed ones resume from their checkpoints"


def run(args: argparse.Namespace) -> None:
    from edgedog.batch.executors import RayExecutor, require_ray
    from edgedog.batch.runner import run_batch
    from edgedog.batch.suite import expand, load_suite
    from edgedog.batch.table import BATCH_FILES
    from edgedog.outputs import check_output_folder

    suite = load_suite(args.suite, tuple(args.overrides))
    specs = expand(suite)
    check_output_folder(args.out, BATCH_FILES)  # run_batch checks it too; this is before Ray starts
    require_ray()  # after the suite's and the folder's checks: they need no Ray
    started = time.monotonic()
    result = run_batch(specs, args.out, RayExecutor(args.address, args.cpus_per_run), suite.path,
                       report=print_progress)
    counts = ", ".join(f"{result.count(state)} {state}" for state in ("new", "resume", "finished", "skipped"))
    print(f"{len(specs)} runs in {time.monotonic() - started:.1f} s ({counts}); "
          f"tables: {', '.join(str(path) for path in result.files)}")
    if result.failed:
        first = result.failed[0]
        raise InputError(args.out, f"{len(result.failed)} of {len(specs)} runs failed (see batch.md); "
                                   f"{first.spec.name}: {first.error}")


def print_progress(done: int, total: int, outcome) -> None:
    """One line per finished run: its state and, when it ran, its primitives, time and F10."""
    from edgedog.batch.table import run_rows

    row = run_rows([outcome])[0]
    if outcome.error:
        detail = f"failed: {outcome.error}"
    else:
        f10 = "–" if row["f10"] is None else f"{row['f10']:.1f}"
        detail = f"{row['primitives']} primitives, {row['train_seconds']:.1f} s training, F10 {f10}"
    print(f"[{done}/{total}] {outcome.spec.name}: {outcome.state}; {detail}", flush=True)
