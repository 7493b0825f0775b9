"""The built-in scenes, written by `edgedog.builtin` in the ABC-NEF layout.

- The default scene (`builtin_scene_path`): a CAD part with a cylindrical boss, its edge maps
  by a weight-free detector (Canny) whatever PiDiNet weights are configured, so that `edgedog
  demo` gives everyone the same, documented result; generated on first use in the cache.
- The exact box: an axis-aligned box with exact edge maps (its visible edges drawn), which
  tests and benchmarks use as a fixture with known answers. Unlike the catalogue's parts it is
  not normalised: it sits in [0.2, 0.8] x [0.3, 0.7] x [0.35, 0.65].
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from edgedog.builtin.writer import write_scene
from edgedog.edges.registry import DEFAULT_WEIGHT_FREE
from edgedog.errors import InputError
from edgedog.files import default_cache
from edgedog.scenes.camera import Camera
from edgedog.synthetic.exact import EXACT, exact_edge_map
from edgedog.synthetic.render import Renderer
from edgedog.synthetic.shapes import Part, make_part

__all__ = ["BOX_MAX", "BOX_MIN", "CORNERS", "EDGES", "box_part", "builtin_scene_path", "ground_truth_points",
           "render_view", "write_box_scene"]

DEFAULT_SHAPE = "boss"
DEFAULT_SEED = 0
DEFAULT_VIEWS = 50
DEFAULT_SIZE = 400
"""ABC-NEF's 50 views at half its resolution, for a first run in about a minute."""
DEFAULT_DETECTOR = DEFAULT_WEIGHT_FREE
"""Not "auto": PiDiNet maps of this scene train badly (docs/BENCHMARKS.md, the built-in part:
F10 44 against 93 with Canny, measured), and the demo's result must not depend on which
weights happen to be configured."""

BOX_MIN = np.array([0.2, 0.3, 0.35])
BOX_MAX = np.array([0.8, 0.7, 0.65])
# Corner i has coordinate bits (x, y, z) = (i & 1, i >> 1 & 1, i >> 2 & 1) of min/max.
CORNERS = np.array([[(BOX_MIN, BOX_MAX)[(i >> a) & 1][a] for a in range(3)] for i in range(8)])
EDGES = sorted({(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1})


@functools.cache
def box_part() -> Part:
    """The exact box as a part (its 12 edges as feature curves), built once per process."""
    from edgedog.synthetic.brep import part_from_solid  # the CAD kernel: seconds to import
    from edgedog.synthetic.designs import box_between

    dimensions = dict(zip(("width", "depth", "height"), BOX_MAX - BOX_MIN))
    return part_from_solid("box", box_between(BOX_MIN, BOX_MAX), dimensions, normalise=False)


def render_view(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """The exact box seen by `camera`.

    Returns:
        rgba: (H, W, 4) uint8, grey Lambertian faces on a transparent background.
        edges: (H, W) uint8, the visible box edges as anti-aliased lines, white on black.
    """
    part = box_part()
    with Renderer(part.mesh, camera.width, camera.height) as renderer:
        render = renderer.render(camera)
    edges = exact_edge_map(part.curves, camera, render)
    return render.rgba, np.round(edges * 255).astype(np.uint8)


def ground_truth_points() -> np.ndarray:
    """(N, 3) the box's edges sampled by the ABC protocol (every GT_SPACING)."""
    return box_part().ground_truth()


def write_box_scene(folder: Path, views: int = 50, size: int = 400) -> Path:
    """Write the exact box scene (edge maps named "exact") into `folder`, which must not exist."""
    return write_scene(folder, box_part(), views, size, detector=EXACT)


def builtin_scene_path(cache: Path | None = None, progress: bool = False) -> Path:
    """The default scene's folder, `<cache>/scenes/boss-canny`, generated on first use.

    The folder is named after the maps' detector: a scene cached by an older version with other
    maps (PiDiNet ones, made by versions whose default followed the configured weights) is never
    taken for this one.

    Generation goes through a temporary folder renamed when complete: a concurrent or
    interrupted run never leaves half a scene, and whichever run finishes first wins.
    """
    folder = (cache or default_cache()) / "scenes" / f"{DEFAULT_SHAPE}-{DEFAULT_DETECTOR}"
    if not (folder / "transforms_train.json").is_file():
        try:
            write_scene(folder, make_part(DEFAULT_SHAPE, DEFAULT_SEED), DEFAULT_VIEWS, DEFAULT_SIZE,
                        seed=DEFAULT_SEED, detector=DEFAULT_DETECTOR, progress=progress)
        except (InputError, OSError):  # another process may have finished it meanwhile
            if not (folder / "transforms_train.json").is_file():
                raise
    return folder
