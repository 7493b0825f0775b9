"""`edgedog studio [SCENE | RUN | PHOTOS]`: the desktop studio, training live with a 3D view,
inspectors and plots. A folder of photos opens as Open... opens it: the built-in scene is shown
while the studio offers to recover the photos' cameras (structure from motion)."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from edgedog.app import MIN_SIZE, STUDIO_PRESET
from edgedog.files import default_cache
from edgedog.train.config import PRESETS, presets_help

MAX_SIZE = 16384
"""A side longer than this is no screen's (and no GL framebuffer's)."""


def _size(text: str) -> tuple[int, int]:
    width, sep, height = text.partition("x")
    if not sep or not width.isdigit() or not height.isdigit() or not (
            MIN_SIZE[0] <= int(width) <= MAX_SIZE and MIN_SIZE[1] <= int(height) <= MAX_SIZE):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT from {MIN_SIZE[0]}x{MIN_SIZE[1]} to "
                                         f"{MAX_SIZE}x{MAX_SIZE}, got {text!r}")
    return int(width), int(height)


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "studio", help="the desktop studio: train live, inspect views, extract and export curves",
        description="Open a scene (training into a new run folder) or a run folder (resuming it) in "
                    "a window: live DoG splats, curves, cameras and ground truth in 3D; the selected "
                    "view's image, edge map, render, depth, Up and w(Up); loss, primitive and "
                    "F-score plots; run controls and curve export. A folder of plain photos is "
                    "offered structure from motion (edgedog sfm) first, as Open... offers it. "
                    "Needs a display; without one use `edgedog train`.")
    parser.add_argument("path", nargs="?", type=Path, metavar="SCENE | RUN | PHOTOS",
                        help="scene folder, run folder to resume, or folder of photos without cameras "
                             "(offers to recover them by structure from motion, then trains; the built-in "
                             "scene shows meanwhile) (default: the built-in scene)")
    parser.add_argument("--preset", choices=PRESETS, default=STUDIO_PRESET,
                        help=f"settings of new runs (default {STUDIO_PRESET}). {presets_help()}")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a setting of edgedog.train.config.TrainConfig for new runs "
                             "(repeatable; a resumed run keeps its own)")
    parser.add_argument("--runs", type=Path, default=None, metavar="DIR",
                        help="where new run folders go (default ./runs; beside RUN for a run folder)")
    parser.add_argument("--cache", type=Path, default=None, metavar="DIR",
                        help="folder for the built-in scene and computed edge maps (default: $EDGEDOG_CACHE "
                             f"or {default_cache()})")
    parser.add_argument("--size", type=_size, default=(1600, 1000), metavar="WxH",
                        help="window size in screen coordinates (default 1600x1000)")
    parser.add_argument("--script", type=Path, default=None, metavar="FILE",
                        help="drive the UI from a JSON script (see edgedog.app.script), for tests and demos")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from edgedog.app.display import init_glfw

    init_glfw()  # no display: fail before loading (or generating) anything
    if args.cache is not None:  # where edgedog.files.default_cache puts computed edge maps too
        os.environ["EDGEDOG_CACHE"] = str(args.cache)
    from edgedog.app.folder_dialog import PHOTOS, folder_kind
    from edgedog.app.session import Session
    from edgedog.app.window import run_studio
    from edgedog.builtin.scene import builtin_scene_path

    path, photos = args.path, None
    if path is not None and folder_kind(path.expanduser()) == PHOTOS:  # as Open... on it: SfM is offered
        path, photos = None, path.expanduser()
    if path is None:
        path = builtin_scene_path(args.cache, progress=True)
    session = Session.open(path, args.runs, args.preset, args.overrides)
    return run_studio(session, args.runs, args.script, args.size, opening=photos)
