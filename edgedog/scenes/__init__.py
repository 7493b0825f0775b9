"""Multi-view scenes: one `Scene` type and loaders auto-detected from the folder's contents.

Formats: NeRF/Blender (`transforms_train.json`, ABC-NEF), nerfstudio (`transforms.json`), EMAP
(`meta_data.json`), NeuS/IDR (`cameras_sphere.npz`, DTU), COLMAP (`sparse/0/`).
"""

from __future__ import annotations

import dataclasses
from collections import Counter
from pathlib import Path

from edgedog.errors import ConfigError, InputError
from edgedog.scenes.camera import Camera
from edgedog.scenes.colmap import is_colmap, load_colmap
from edgedog.scenes.common import ALLOW_OUTSIDE, confine_files, inspect_images, resolved
from edgedog.scenes.emap import is_emap, load_emap
from edgedog.scenes.images import Background
from edgedog.scenes.nerf import is_nerf, load_nerf
from edgedog.scenes.nerfstudio import is_nerfstudio, load_nerfstudio
from edgedog.scenes.neus import is_neus, load_neus
from edgedog.scenes.scene import Scene, View
from edgedog.scenes.undistort import undistort_scene

# Checked in this order; the first whose marker file is present loads the folder.
FORMATS = (
    ("emap", is_emap, load_emap),
    ("nerf", is_nerf, load_nerf),
    ("nerfstudio", is_nerfstudio, load_nerfstudio),
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
        "not a scene folder: expected transforms_train.json (NeRF/Blender), transforms.json "
        "(nerfstudio), meta_data.json (EMAP), cameras_sphere.npz (NeuS/DTU) or a COLMAP sparse/0 model",
    )


MIN_LOADED_SIDE = 8
"""Fewest pixels across a downscaled image: smaller ones hold no edges to train on."""


def load_scene(path: str | Path, downscale: int = 1, background: Background = (0.0, 0.0, 0.0),
               setting: str = "downscale") -> Scene:
    """Load a scene folder of any supported format, and check its files before anything uses
    them: every image, mask and edge map inside the folder (unless $EDGEDOG_ALLOW_OUTSIDE_FILES
    is set), every image present and of its camera's size (from the headers), unique view names.
    Views of distorted cameras are undistorted (once, into the user cache: `undistort_scene`).

    Args:
        path: the scene folder (a symlink to one is fine).
        downscale: integer factor; images, edge maps, masks and intrinsics are scaled on load.
        background: RGB in [0, 1] that RGBA images are composited on; None drops the alpha.
        setting: how the caller's user sets `downscale` (e.g. "--downscale"), for its errors.
    Raises:
        InputError naming the file at fault; ConfigError naming `setting` for a downscale that
        is not a positive integer or leaves images under MIN_LOADED_SIDE pixels.
    """
    if not float(downscale).is_integer() or downscale < 1:
        raise ConfigError(f"{setting} {downscale}: must be a positive integer")
    root = resolved(Path(path).expanduser())
    name = detect_format(root)
    loader = next(load for fmt, _, load in FORMATS if fmt == name)
    scene = loader(root)
    confine_files(scene)
    _check_names(scene)
    scene = undistort_scene(inspect_images(scene))
    _check_downscale(scene, int(downscale), setting)
    return dataclasses.replace(scene, downscale=int(downscale), background=background)


def _check_names(scene: Scene) -> None:
    """Views are told apart by name (cached edge maps are stored under it)."""
    for name, count in Counter(view.name for view in scene.views).most_common(1):
        if count > 1:
            raise InputError(scene.root, f"{count} views are named '{name}' (the same image listed twice, "
                                         "or images of one name in several folders)")


def _check_downscale(scene: Scene, downscale: int, setting: str) -> None:
    smallest = min((min(view.camera.width, view.camera.height) for view in scene.views), default=None)
    if smallest is not None and smallest < MIN_LOADED_SIDE:
        raise InputError(scene.root, f"its smallest images are {smallest} pixels across; edgedog needs at "
                                     f"least {MIN_LOADED_SIDE}")
    if smallest is not None and smallest // downscale < MIN_LOADED_SIDE:
        raise ConfigError(f"{setting} {downscale}: leaves the scene's smallest images "
                          f"{smallest // downscale} pixels across (at least {MIN_LOADED_SIDE}); use at most "
                          f"{smallest // MIN_LOADED_SIDE}")


__all__ = ["ALLOW_OUTSIDE", "Camera", "Scene", "View", "detect_format", "load_scene"]
