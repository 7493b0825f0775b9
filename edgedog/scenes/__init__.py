"""Multi-view scenes: one `Scene` type and loaders auto-detected from the folder's contents.

Formats: NeRF/Blender (`transforms_train.json`, ABC-NEF), EMAP (`meta_data.json`), NeuS/IDR
(`cameras_sphere.npz`, DTU), COLMAP (`sparse/0/`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from edgedog.errors import InputError
from edgedog.scenes.camera import Camera
from edgedog.scenes.colmap import is_colmap, load_colmap
from edgedog.scenes.emap import is_emap, load_emap
from edgedog.scenes.images import Background
from edgedog.scenes.nerf import is_nerf, load_nerf
from edgedog.scenes.neus import is_neus, load_neus
from edgedog.scenes.scene import Scene, View

# Checked in this order; the first whose marker file is present loads the folder.
FORMATS = (
    ("emap", is_emap, load_emap),
    ("nerf", is_nerf, load_nerf),
    ("neus", is_neus, load_neus),
    ("colmap", is_colmap, load_colmap),
)


def detect_format(root: Path) -> str:
    """Name of the scene format of a folder, or an InputError listing what was looked for."""
    if not root.exists():
        raise InputError(root, "scene folder not found")
    if not root.is_dir():
        raise InputError(root, "is a file, not a scene folder")
    for name, test, _ in FORMATS:
        if test(root):
            return name
    raise InputError(
        root,
        "not a scene folder: expected transforms_train.json (NeRF/Blender), meta_data.json "
        "(EMAP), cameras_sphere.npz (NeuS/DTU) or a COLMAP sparse/0 model",
    )


def load_scene(path: str | Path, downscale: int = 1,
               background: Background = (0.0, 0.0, 0.0)) -> Scene:
    """Load a scene folder of any supported format.

    Args:
        path: the scene folder.
        downscale: integer factor; images, edge maps, masks and intrinsics are scaled on load.
        background: RGB in [0, 1] that RGBA images are composited on; None drops the alpha.
    """
    if not float(downscale).is_integer() or downscale < 1:
        raise ValueError(f"downscale must be a positive integer, got {downscale}")
    root = Path(path).expanduser().resolve()
    name = detect_format(root)
    loader = next(load for fmt, _, load in FORMATS if fmt == name)
    scene = loader(root)
    return dataclasses.replace(scene, downscale=int(downscale), background=background)


__all__ = ["Camera", "Scene", "View", "detect_format", "load_scene"]
