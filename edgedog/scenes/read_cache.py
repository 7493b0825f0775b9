"""A bounded memo of a scene's decoded files, for passes that read every view several times.

Extraction's filters each go over the views (the projection and contour filters, the line
completion, the shading and drawing-plane tests): without a memo every one decodes the same
edge maps and masks again, about a third of an extraction. `Scene.with_read_cache` gives a scene
whose edge maps and coverage come from one of these; the arrays it hands out are read-only, so
a caller that would change one in place fails instead of changing every later reader's copy.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable

import numpy as np

DEFAULT_MAX_BYTES = 512 * 2**20
"""Enough for the edge maps and masks of 50 views at 800x800 (float32: 2.56 MB each), twice over."""


class ReadCache:
    """Decoded arrays by key, least recently used first out once `max_bytes` would be exceeded.

    Safe to share between threads (the studio's worker extracts while the window reads): one
    lock guards the entries; a file is decoded outside it, so two threads asking for one missing
    key may both decode it, and one copy is kept.
    """

    def __init__(self, max_bytes: int = DEFAULT_MAX_BYTES):
        self.max_bytes = max_bytes
        self._entries: OrderedDict[Hashable, np.ndarray | None] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def __reduce__(self):
        # A pickled scene (a plan sent to another process) takes an empty memo of the same size.
        return ReadCache, (self.max_bytes,)

    @property
    def nbytes(self) -> int:
        """Bytes held now (at most `max_bytes`)."""
        return self._bytes

    def get(self, key: Hashable, read: Callable[[], np.ndarray | None]) -> np.ndarray | None:
        """The array kept under `key`, or else `read()`'s, made read-only and kept (None is kept
        too: a view without a mask). An array larger than `max_bytes` is handed out, read-only,
        without being kept."""
        with self._lock:
            if key in self._entries:
                self._entries.move_to_end(key)
                return self._entries[key]
        value = read()
        if value is not None:
            value.setflags(write=False)
        size = 0 if value is None else value.nbytes
        if size > self.max_bytes:
            return value
        with self._lock:
            if key not in self._entries:
                self._entries[key] = value
                self._bytes += size
            while self._bytes > self.max_bytes:
                _, dropped = self._entries.popitem(last=False)
                self._bytes -= 0 if dropped is None else dropped.nbytes
            return self._entries.get(key, value)
