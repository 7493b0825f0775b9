"""A helper thread for work the UI must not wait for (inspector renders, curve extraction)."""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Done:
    """A finished job: its `key`, and its `value` or the `error` line it raised; `seconds`: how
    long it ran."""

    key: Any
    value: Any = None
    error: str | None = None
    seconds: float = 0.0


class BackgroundJob:
    """Runs one callable at a time in a daemon thread; the UI polls for the outcome.

    Attributes:
        key: what the running (or last) job was submitted for, e.g. a snapshot key.
    """

    def __init__(self, name: str):
        self.name = name
        self.key: Any = None
        self._thread: threading.Thread | None = None
        self._done: Done | None = None
        self._lock = threading.Lock()

    @property
    def busy(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def submit(self, key: Any, function: Callable[[], Any]) -> bool:
        """Start `function()` unless a job is running; returns whether it started."""
        if self.busy:
            return False
        self.key = key

        def run() -> None:
            started = time.perf_counter()
            try:
                value, error = function(), None
            except Exception as exception:  # reported in the UI's status line
                traceback.print_exc()
                value, error = None, f"{type(exception).__name__}: {exception}"
            done = Done(key, value, error, time.perf_counter() - started)
            with self._lock:
                self._done = done

        self._thread = threading.Thread(target=run, name=f"edgedog-{self.name}", daemon=True)
        self._thread.start()
        return True

    @property
    def pending(self) -> bool:
        """Whether a job runs or its outcome waits to be polled."""
        with self._lock:
            return self.busy or self._done is not None

    def poll(self) -> Done | None:
        """The outcome of the last job once it has finished (each outcome is returned once)."""
        with self._lock:
            done, self._done = self._done, None
        return done

    def wait(self, timeout: float) -> None:
        """Wait for the running job (if any), at most `timeout` seconds."""
        if self._thread is not None:
            self._thread.join(timeout)
