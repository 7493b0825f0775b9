"""Keep freed memory in the process for reuse instead of returning it to the system (glibc).

glibc serves every allocation above its mmap threshold (32 MB at most, by default) with a fresh
mapping and unmaps it when freed, so the next tensor of that size faults in all its pages again.
PiDiNet allocates about seventy such tensors (~150 MB each) per 800 x 800 image: measured on two
cores, the kernel's time then equals the computation's, and an image takes 2.6 s instead of 1.25
s. Raising the mmap and trim thresholds serves those blocks from the heap and keeps them there
when freed; the price is a higher peak (PiDiNet at 800 x 800: 0.94 GB -> 1.5 GB), since freed
blocks wait for reuse instead of going back.
"""

from __future__ import annotations

import ctypes
import platform

KEPT_BLOCK_BYTES = 1 << 30
"""Blocks up to this size come from the heap, and up to this much freed memory stays there."""
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
"""glibc's `mallopt` parameters (malloc.h)."""


def on_glibc() -> bool:
    """Whether this process runs on Linux's glibc, whose `mallopt` `keep_freed_memory` calls."""
    return platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"


def keep_freed_memory() -> bool:
    """Raise glibc's mmap and trim thresholds to `KEPT_BLOCK_BYTES` for this process; returns
    whether both took effect (False off Linux's glibc, where nothing changes). Call once, at a
    command's start."""
    if not on_glibc():
        return False
    libc = ctypes.CDLL(None)  # the process's own C library
    return bool(libc.mallopt(M_MMAP_THRESHOLD, KEPT_BLOCK_BYTES)) and bool(
        libc.mallopt(M_TRIM_THRESHOLD, KEPT_BLOCK_BYTES))


__all__ = ["KEPT_BLOCK_BYTES", "keep_freed_memory", "on_glibc"]
