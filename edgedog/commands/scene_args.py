"""Command-line options shared by the commands that open a scene."""

from __future__ import annotations

import argparse

from edgedog.scenes import Scene, load_scene
from edgedog.scenes.images import Background, parse_background


def _background(text: str) -> Background:
    """parse_background for argparse: its message becomes the one-line usage error."""
    try:
        return parse_background(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_scene_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--downscale", type=int, default=1, metavar="N",
                        help="load images at 1/N resolution (intrinsics scaled with them)")
    parser.add_argument("--background", type=_background, default=(0.0, 0.0, 0.0),
                        help="what RGBA images are composited on: black (default), white, "
                             "none (drop alpha) or R,G,B in [0, 1]")


def open_scene(path: str, args: argparse.Namespace) -> Scene:
    """The scene at `path` with the scene options; a bad --downscale is a ConfigError naming it."""
    return load_scene(path, downscale=args.downscale, background=args.background, setting="--downscale")
