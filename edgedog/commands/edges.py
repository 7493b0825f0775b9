"""`edgedog edges SCENE --detector NAME`: compute (or reuse) the scene's pseudo-edge maps."""

from __future__ import annotations

import argparse
from pathlib import Path

from edgedog.commands.scene_args import add_scene_options, open_scene
from edgedog.edges.registry import WEIGHTS_HELP, detectors_help


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "edges", help="compute pseudo-edge maps with a 2D detector (cached beside the scene)",
        description="Compute the scene's pseudo-edge maps once and cache them, keyed by detector, "
                    "weights and resolution. Maps a scene ships with are used as they are unless "
                    "--recompute.",
        epilog="detectors:\n" + "\n".join(f"  {line}" for line in detectors_help().splitlines()),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", help="scene folder")
    parser.add_argument("--detector", default="auto",
                        help="one of the detectors listed below (default: auto)")
    parser.add_argument("--weights", type=Path, default=None,
                        help=WEIGHTS_HELP)
    parser.add_argument("--recompute", action="store_true", help="ignore cached or provided maps")
    add_scene_options(parser)
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    from edgedog.edges.cache import ensure_edge_maps
    from edgedog.edges.registry import make_detector

    scene = open_scene(args.scene, args)
    if args.detector in scene.detectors and not args.recompute:
        print(f"{scene.root}: using the scene's own '{args.detector}' maps ({len(scene)} views)")
        return
    result = ensure_edge_maps(scene, make_detector(args.detector, args.weights), recompute=args.recompute)
    speed = result.seconds_per_megapixel
    timing = f", {speed:.2f} s per megapixel" if speed else ""
    print(f"{result.detector}: {len(scene)} maps in {result.folder} "
          f"({result.computed} computed now{timing})")
