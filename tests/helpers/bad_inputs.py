"""The harness of the bad-input tables: a command given bad input must fail as a trusted tool does.

Each table (tests/test_bad_inputs*.py) is a list of `Case`s. A case builds its files in a fresh
folder and returns the command line and the words its error must contain; `assert_fails_cleanly`
runs it through `edgedog.cli.main` in this process (what `python -m edgedog` runs, without a
second of interpreter start-up per case; tests/test_cli_errors.py runs the real subprocess) and
checks:
- exit code 2 (or the case's own code, e.g. 130 for Ctrl-C);
- stderr is one line `edgedog: error: ...` holding every expected word (a file or a setting),
  beside progress bars (a command that computes edge maps shows one before it fails);
  a case whose code is 0 (hostile input that is fine, e.g. a moved scene) prints no error line
  and its output holds every expected word;
- no traceback anywhere in the output;
- no file that existed before the command was changed or removed (run folders' lock files, which
  hold the pid of their last writer, aside, and the files a succeeding case names as its own
  outputs, e.g. a resumed run's log.json).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import re
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from edgedog.cli import main
from edgedog.train.run_folder import LOCK_FILE


@dataclass(frozen=True)
class Case:
    """name: the test id; build(folder) makes the files and returns (argv, expected words);
    the words may name the folder's paths (the message must contain them verbatim)."""

    name: str
    build: Callable[[Path], tuple[list, list[str]]]
    returncode: int = 2
    rewrites: tuple[str, ...] = ()
    """Files (relative to the case's folder) a succeeding command writes as its own output."""


PROGRESS = re.compile(r"^[^:]+: +\d+%\|")
"""A progress bar's line on stderr (tqdm's `desc:  40%|####  | 4/10 ...`)."""


def cases_as_params(cases: list[Case]) -> list:
    return [pytest.param(case, id=case.name) for case in cases]


def edgedog(*args, cwd: Path | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    """`python -m edgedog ARGS` with captured text output, no progress bars' terminal."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run([sys.executable, "-m", "edgedog", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def edgedog_in_process(argv: list, cwd: Path) -> subprocess.CompletedProcess:
    """`edgedog.cli.main(argv)` run in `cwd` with empty stdin, its exit code and captured output
    returned as a subprocess would return them."""
    stdout, stderr, previous = io.StringIO(), io.StringIO(), Path.cwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            stdin, sys.stdin = sys.stdin, io.StringIO()
            try:
                code = main([str(arg) for arg in argv])
            except SystemExit as exit:  # argparse's errors
                code = exit.code
            finally:
                sys.stdin = stdin
    finally:
        os.chdir(previous)
    return subprocess.CompletedProcess(argv, code, stdout.getvalue(), stderr.getvalue())


def snapshot(root: Path) -> dict[str, str]:
    """Relative path -> sha256 of every regular file under `root` (symlinks not followed)."""
    files = {}
    for folder, _, names in os.walk(root):
        for name in names:
            if name == LOCK_FILE:
                continue
            path = Path(folder) / name
            if path.is_symlink() or not path.is_file():
                continue
            try:
                files[str(path.relative_to(root))] = hashlib.sha256(path.read_bytes()).hexdigest()
            except OSError:  # unreadable on purpose (a case's permission trap)
                files[str(path.relative_to(root))] = "unreadable"
    return files


def assert_fails_cleanly(case: Case, folder: Path) -> subprocess.CompletedProcess:
    """Build `case` in `folder`, run it there, and check the four promises above."""
    folder.mkdir(parents=True, exist_ok=True)
    argv, words = case.build(folder)
    before = snapshot(folder)
    result = edgedog_in_process(argv, folder)
    output = result.stdout + result.stderr
    assert "Traceback" not in output, output
    assert result.returncode == case.returncode, output
    if case.returncode == 0:
        assert "edgedog: error" not in output, output
        checked = output
    else:
        lines = [line for line in result.stderr.strip().splitlines() if not PROGRESS.match(line)]
        assert len(lines) == 1 and lines[0].startswith("edgedog: error: "), result.stderr
        checked = lines[0]
    for word in words:
        assert str(word) in checked, f"{word!r} not in {checked!r}"
    after = snapshot(folder)
    changed = [path for path, digest in before.items()
               if after.get(path) != digest and path not in case.rewrites]
    assert not changed, f"changed or removed: {changed}"
    return result
