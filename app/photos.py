"""A folder of plain photos (images, no cameras): what the studio offers for it, structure from
motion (`edgedog sfm`) into a scene folder of the studio's own beside its runs, never inside the
photos' folder (`edgedog sfm` writes only where --out says)."""

from __future__ import annotations

import os
from pathlib import Path

from edgedog.app.sfm_job import unique_folder

from edgedog.errors import InputError
from edgedog.scenes.colmap import COLMAP_SUFFIXES

SCENE_SUFFIX = "-sfm"
"""The scene folder of photos `P` is `<runs>/P-sfm` (or `-sfm-2`, ... when taken)."""


def has_photos(path: Path) -> bool:
    """Whether `path` holds an image file directly (what `edgedog sfm` reads); False when it
    cannot be read."""
    try:
        with os.scandir(path) as entries:
            return any(Path(entry.name).suffix.lower() in COLMAP_SUFFIXES and entry.is_file()
                       for entry in entries)
    except OSError:
        return False


def sfm_scene_folder(runs_root: Path, photos: Path) -> Path:
    """Where the cameras of `photos` go: a new folder under `runs_root`. An InputError when the
    runs folder lies inside the photos' folder (the studio never writes there)."""
    runs_root, photos = Path(runs_root).resolve(), Path(photos).resolve()
    if runs_root == photos or photos in runs_root.parents:
        raise InputError(runs_root, f"the runs folder lies inside the photo folder {photos}; start the "
                                    "studio elsewhere or with --runs DIR outside it")
    return unique_folder(runs_root, f"{photos.name}{SCENE_SUFFIX}")


def offer(photos: Path, count: int, out: Path, stops: str | None) -> str:
    """The question that offers structure from motion; `stops`: what starting it would stop."""
    lines = [f"{photos} holds {count} photos and no cameras.",
             "Recover the cameras by structure from motion (edgedog sfm: features, matching,",
             f"mapping, undistortion) into {out},", "then show them and train?"]
    if stops:
        lines.append(f"This stops {stops}.")
    return "\n".join(lines)
