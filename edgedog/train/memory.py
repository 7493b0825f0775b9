"""The memory a run's views need, checked against what the machine has before anything is loaded.

Each image is capped at 134 megapixels when a scene loads, but not their sum: 12 views of 11000 px
square pass one by one and then exhaust the memory while training prepares its targets. A run
keeps every view's targets and masks (at the run's downscale) for the whole training, and reads
one view's files at a time at their own resolution; both are estimated here from the views'
sizes alone, with bytes per pixel measured (peak RSS of `train --preset preview --set epochs=1`
on 12 views of 1536 px square, less that of a 96 px scene: 2.0 GB at downscale 1, 490 MB at 2,
195 MB at 4; the estimate gives 2.1 GB, 585 MB and 202 MB).
"""

from __future__ import annotations

import os
import resource
from typing import TYPE_CHECKING

from edgedog.errors import InputError
from edgedog.train.config import MAX_DOWNSCALE

if TYPE_CHECKING:  # the scene readers load only when a scene is
    from edgedog.scenes import Scene

KEPT_BYTES_PER_PIXEL = 72
"""Bytes per training pixel of every view, kept while training (measured 69-74): its maps as read
and as targeted, masks, silhouette buffers and the per-view tensors of the trainer."""
WORKING_BYTES_PER_FILE_PIXEL = 32
"""Bytes per pixel, at the files' resolution, of the one view being read (measured about 29): the
decoded map or image and its float copies before the downscale."""
MEMORY_SHARE = 0.5
"""The share of the machine's memory (or of the process's address-space limit, `ulimit -v`,
when lower) that a run's views may take; the rest is left to torch, the primitives and others."""


def memory_limit() -> int:
    """The bytes a run's views may take: MEMORY_SHARE of the physical memory, or of the address
    space limit when one is set and lower."""
    physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        physical = min(physical, soft)
    return int(physical * MEMORY_SHARE)


def views_memory(scene: Scene, downscale: int) -> int:
    """Estimated bytes for training on `scene`'s views at `downscale` (of the files' size)."""
    pixels = [(view.camera.width // downscale) * (view.camera.height // downscale) for view in scene.views]
    largest_file = max((view.camera.width * view.camera.height for view in scene.views), default=0)
    return sum(pixels) * KEPT_BYTES_PER_PIXEL + largest_file * WORKING_BYTES_PER_FILE_PIXEL


def check_memory(scene: Scene, downscale: int, limit: int | None = None) -> None:
    """InputError naming the scene when its views at `downscale` need more than `limit` bytes
    (default `memory_limit()`); the message gives the smallest downscale that fits."""
    limit = memory_limit() if limit is None else limit
    needed = views_memory(scene, downscale)
    if needed <= limit:
        return
    fits = next((d for d in range(downscale + 1, MAX_DOWNSCALE + 1) if views_memory(scene, d) <= limit),
                None)
    largest = max(scene.views, key=lambda view: view.camera.width * view.camera.height).camera
    how = (f"--set maps.downscale={fits} fits" if fits else
           f"even maps.downscale={MAX_DOWNSCALE} does not fit: train on fewer views")
    raise InputError(scene.root, f"its {len(scene.views)} views (up to {largest.width}x{largest.height} px) "
                                 f"at downscale {downscale} need about {needed / 2**30:.1f} GiB of memory, "
                                 f"more than the {limit / 2**30:.1f} GiB a run may take here "
                                 f"({MEMORY_SHARE:.0%} of the memory); {how}")
