"""Rates over a moving window, for the readouts: the training's steps per second and the window's
frames per second as they are now (a run's average hides a rate that fell or rose)."""

from __future__ import annotations

from collections import deque

RATE_SECONDS = 3.0
"""The window the readouts average over."""
READOUT_EVERY = 0.5
"""Seconds a readout holds its value (one that changed at every frame would make every frame
differ from the last: see redraw.py)."""


class MovingRate:
    """How fast a running count grows over the last `seconds`: `add` the count now and then,
    read `rate`."""

    def __init__(self, seconds: float = RATE_SECONDS):
        self.seconds = seconds
        self._samples: deque[tuple[float, float]] = deque()
        self._shown, self._shown_at = 0.0, -READOUT_EVERY

    def add(self, now: float, count: float) -> None:
        """Note `count` at time `now` (seconds, increasing); samples older than the window go,
        but for the last one before it (the window's start)."""
        self._samples.append((now, count))
        while len(self._samples) > 2 and now - self._samples[1][0] >= self.seconds:
            self._samples.popleft()

    @property
    def rate(self) -> float:
        """Growth per second over the window (0 before two samples)."""
        if len(self._samples) < 2:
            return 0.0
        (start, first), (end, last) = self._samples[0], self._samples[-1]
        return (last - first) / (end - start) if end > start else 0.0

    def readout(self, now: float) -> float:
        """`rate` as last read out, read again when it is READOUT_EVERY seconds old."""
        if now - self._shown_at >= READOUT_EVERY:
            self._shown, self._shown_at = self.rate, now
        return self._shown
