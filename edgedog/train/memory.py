"""The memory a run's views need, checked against what the machine has before anything is loaded.

Each image is capped at 134 megapixels when a scene loads, but not their sum: 12 views of 11000 px
square pass one by one and then exhaust the memory while training prepares its targets. A run
keeps every view's edge map and edge mask (at the run's downscale) for the whole training, and
works on one view at a time on top of them (its image decoded, its silhouette's distance
transform, the rasterizer's buffers); both are estimated here from the views' sizes alone.
"""

from __future__ import annotations

import os
import resource
from typing import TYPE_CHECKING

from edgedog.errors import InputError
from edgedog.train.config import MAX_DOWNSCALE

if TYPE_CHECKING:  # the scene readers load only when a scene is
    from edgedog.scenes import Scene

KEPT_BYTES_PER_PIXEL = 12
"""Bytes per pixel of every view kept while training: the edge map as read and as targeted
(float32 each), its edge mask and the coarse level's copies."""
WORKING_BYTES_PER_PIXEL = 64
"""Bytes per pixel of the one view being worked on: its decoded RGB(A) image and float copies,
the silhouette's distance transforms, the rendered image, its gradients and the rasterizer's
per-pixel buffers."""
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
    return sum(pixels) * KEPT_BYTES_PER_PIXEL + max(pixels, default=0) * WORKING_BYTES_PER_PIXEL


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
