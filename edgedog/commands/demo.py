"""`edgedog demo`: the main job on the built-in scene, generated on first use."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from edgedog.builtin_scene import builtin_scene_path
from edgedog.commands.info import summary
from edgedog.files import default_cache
from edgedog.scenes import load_scene


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser("demo", help="run on the built-in scene (generated on first use)",
                                   description="Generate the built-in scene (a CAD part with exact "
                                               "ground truth) if needed and run the main job on it.")
    parser.add_argument("--cache", type=Path, default=None,
                        help=f"folder for generated scenes (default: $EDGEDOG_CACHE or {default_cache()})")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    start = time.perf_counter()
    folder = builtin_scene_path(args.cache, progress=True)
    print(summary(load_scene(folder)))
    print(f"done in {time.perf_counter() - start:.1f} s")
