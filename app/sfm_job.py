"""Cameras for a folder of photos, off the UI thread: `edgedog sfm PHOTOS --out SCENE` in a child
process, its progress read from what it prints, and a cancel that stops it at once.

Why a child process: pycolmap's feature extraction, matching and mapping are long C++ calls that
nothing can interrupt from Python; a thread could only stop at the next stage boundary (a minute
or more into mapping on a few dozen photos), whereas a process ends the moment it is terminated.
It also runs the command exactly as the command line does (its checks, its one-line errors) and
keeps pycolmap's memory and threads out of the studio's process.

Nothing half-written is left: `run_sfm` builds the scene in a temporary folder beside `out` and
renames it into place only once it loads; a cancelled job removes that temporary folder (a
terminated child cannot) and `out` too when the child got as far as renaming it (a cancelled
job leaves nothing, whenever the cancel came).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from edgedog.app.sfm_progress import SfmProgress, advance

from edgedog.errors import EdgeDogError
from edgedog.scenes.sfm import partial_folders

DONE, FAILED, CANCELLED = "done", "failed", "cancelled"
"""How a job ended (`SfmOutcome.status`)."""
ERROR_PREFIX = "edgedog: error: "
TAIL_LINES = 40
"""Lines of the child's output kept for the failure's details."""
KILL_AFTER = 5.0
"""Seconds a terminated child has to end before it is killed."""


@dataclass(frozen=True)
class SfmOutcome:
    """A finished job: `status` (DONE, FAILED or CANCELLED), the scene folder written (DONE only),
    the one-line `error` (FAILED), the last progress, how long it ran, and the output's last lines."""

    photos: Path
    out: Path
    status: str
    progress: SfmProgress
    seconds: float
    error: str | None = None
    tail: tuple[str, ...] = ()


def unique_folder(root: Path, name: str) -> Path:
    """`root/name`, or `root/name-2`, `-3`, ... the first that does not exist."""
    path, count = root / name, 1
    while path.exists() or path.is_symlink():
        count += 1
        path = root / f"{name}-{count}"
    return path


def error_line(lines: list[str] | tuple[str, ...], returncode: int) -> str:
    """The command's one-line error (without "edgedog: error: "), else its last line, else its
    exit status."""
    for line in reversed(lines):
        if line.startswith(ERROR_PREFIX):
            return line[len(ERROR_PREFIX):]
    last = next((line for line in reversed(lines) if line.strip()), None)
    return last if last is not None else f"edgedog sfm exited with status {returncode}"


class SfmJob:
    """One run of `edgedog sfm` in a child process, read by a daemon thread.

    The UI thread calls `start`, reads `progress` and `busy`, may `cancel`, and takes the
    outcome once with `poll`.
    """

    def __init__(self, photos: Path, out: Path, matcher: str = "exhaustive", max_image_size: int = 1600):
        self.photos, self.out = Path(photos), Path(out)
        self.command = [sys.executable, "-m", "edgedog", "sfm", str(self.photos), "--out", str(self.out),
                        "--max-image-size", str(int(max_image_size)), "--matcher", matcher]
        self._lock = threading.Lock()
        self._progress = SfmProgress()
        self._outcome: SfmOutcome | None = None
        self._cancelled = threading.Event()
        self._process: subprocess.Popen | None = None
        self._thread = threading.Thread(target=self._run, name="edgedog-sfm", daemon=True)
        self.started = 0.0
        self._out_existed = False

    def start(self) -> None:
        """Start the child (an EdgeDogError when it cannot be) and the thread reading it."""
        self.started = time.monotonic()
        self._out_existed = self.out.exists() or self.out.is_symlink()
        try:
            self._process = subprocess.Popen(self.command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                             stderr=subprocess.STDOUT, text=True, errors="replace")
        except OSError as error:
            raise EdgeDogError(f"cannot start edgedog sfm: {error.strerror or error}") from None
        self._thread.start()

    @property
    def progress(self) -> SfmProgress:
        with self._lock:
            return self._progress

    @property
    def busy(self) -> bool:
        """Whether the child runs or its outcome is being settled."""
        return self._thread.is_alive()

    @property
    def elapsed(self) -> float:
        return time.monotonic() - self.started

    def cancel(self, timeout: float | None = 0.0) -> bool:
        """Terminate the child (it ends at once: pycolmap holds no Python signal handler); the
        thread then removes what it left. Waits up to `timeout` seconds (None: until all is
        removed) and returns whether the job has ended."""
        self._cancelled.set()
        if self._process is not None and self._process.poll() is None:
            self._process.terminate()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def poll(self) -> SfmOutcome | None:
        """The outcome once the job has ended (returned once)."""
        with self._lock:
            outcome, self._outcome = self._outcome, None
        return outcome

    # --- the reading thread
    def _run(self) -> None:
        process = self._process
        tail: deque[str] = deque(maxlen=TAIL_LINES)
        for line in process.stdout:
            tail.append(line.rstrip("\n"))
            with self._lock:
                self._progress = advance(self._progress, line)
        try:
            returncode = process.wait(KILL_AFTER if self._cancelled.is_set() else None)
        except subprocess.TimeoutExpired:
            process.kill()
            returncode = process.wait()
        process.stdout.close()
        if self._cancelled.is_set():
            status, error = CANCELLED, None
            self._remove_partial(with_out=not self._out_existed)
        elif returncode == 0 and self.out.is_dir():
            status, error = DONE, None
        else:
            status, error = FAILED, error_line(list(tail), returncode)
            self._remove_partial(with_out=False)
        outcome = SfmOutcome(self.photos, self.out, status, self.progress, self.elapsed, error, tuple(tail))
        with self._lock:
            self._outcome = outcome

    def _remove_partial(self, with_out: bool) -> None:
        """Remove the temporary folders a killed child left beside `out`, and `out` itself when
        `with_out` (cancelled after the child renamed it into place: it did not exist before)."""
        for folder in partial_folders(self.out):
            shutil.rmtree(folder, ignore_errors=True)
        if with_out and self.out.is_dir() and not self.out.is_symlink():
            shutil.rmtree(self.out, ignore_errors=True)
