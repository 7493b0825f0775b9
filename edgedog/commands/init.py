"""`edgedog init SCENE`: the initial primitive positions and scales, and how they were chosen."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

from edgedog.commands.scene_args import add_scene_options, open_scene
from edgedog.errors import ConfigError
from edgedog.files import atomic_write


def add_parser(subparsers) -> None:
    from edgedog.init import DEFAULTS, INIT_METHODS

    parser = subparsers.add_parser(
        "init",
        help="initial points: SfM triangulation with the known poses, an edge vote, or a uniform cube",
        description="Compute the initial primitives' positions and scales and say which method was "
                    "used and why: the scene's SfM points, SIFT points triangulated with the known "
                    "cameras and kept on pseudo edges, the cells where the views' edge maps agree "
                    "(edge-vote), or EdgeGaussians' uniform cube.")
    parser.add_argument("scene", help="scene folder")
    parser.add_argument("--method", choices=INIT_METHODS, default=DEFAULTS.method,
                        help=f"how the points are found (default {DEFAULTS.method}, as `edgedog train`)")
    parser.add_argument("--detector", default=None,
                        help="keep only points that project onto this detector's edge maps in 2+ views "
                             "(edge-vote: the maps that vote; default the scene's first)")
    parser.add_argument("--min-points", type=int, default=500, help="fewest points 'auto' accepts")
    parser.add_argument("--uniform-count", type=int, default=DEFAULTS.count,
                        help=f"points of the uniform cube, the most edge-vote keeps (default "
                             f"{DEFAULTS.count}, as `edgedog train`; EdgeGaussians uses 2500)")
    parser.add_argument("--uniform-side", type=_side, default=DEFAULTS.side,
                        help=f"edge of the uniform cube, or 'none' for the scene bounds' largest extent "
                             f"(default {DEFAULTS.side}, as `edgedog train` and EdgeGaussians for ABC)")
    parser.add_argument("--edge-threshold", type=float, default=DEFAULTS.edge_threshold,
                        help="edge-map value a kept point lands on in 2+ views (default "
                             f"{DEFAULTS.edge_threshold}, as `edgedog train`)")
    parser.add_argument("--match-neighbours", type=int, default=DEFAULTS.match_neighbours,
                        help="triangulation matches each view with this many nearest views facing its way; "
                             f"0: every pair (default {DEFAULTS.match_neighbours}, as `edgedog train`)")
    parser.add_argument("--out", type=Path, default=None, help="write the points as a PLY (x, y, z, scale); "
                        "never over a run's own file nor inside a scene folder")
    parser.add_argument("--force", action="store_true", help="replace the --out file if it exists")
    add_scene_options(parser)
    parser.set_defaults(run=run)


def _side(text: str) -> float | None:
    """--uniform-side: a number, or 'none' (the scene bounds' largest extent)."""
    return None if text.strip().lower() == "none" else float(text)


def settings_of(args: argparse.Namespace):
    """The init settings the options give: ConfigErrors naming the option, before the scene is
    opened."""
    from edgedog.init import InitSettings

    if args.min_points < 0:
        raise ConfigError(f"--min-points {args.min_points}: must not be negative")
    options = {"method": "--method", "count": "--uniform-count", "side": "--uniform-side",
               "edge_threshold": "--edge-threshold", "match_neighbours": "--match-neighbours"}
    values = {"method": args.method, "count": args.uniform_count, "side": args.uniform_side,
              "edge_threshold": args.edge_threshold, "match_neighbours": args.match_neighbours}
    for name, value in values.items():
        try:
            InitSettings(**{name: value})
        except ConfigError as error:
            raise ConfigError(f"{options[name]} {value}: {error}") from None
    return InitSettings(**values)


def run(args: argparse.Namespace) -> None:
    from edgedog.init import initialize
    from edgedog.outputs import check_new_file, output_file

    settings = settings_of(args)
    if args.out is not None:
        check_new_file(args.out, args.force)  # before the work, not after it
    scene = open_scene(args.scene, args)
    points = initialize(scene, settings, detector=args.detector, min_points=args.min_points)
    print(json.dumps({"method": points.method, "points": len(points), **points.report}, indent=2,
                     default=str))
    if args.out is not None:
        rows = np.empty(len(points), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("scale", "f4")])
        rows["x"], rows["y"], rows["z"] = points.positions.T
        rows["scale"] = points.scales
        ply = PlyData([PlyElement.describe(rows, "vertex")])
        with output_file(args.out, args.force):
            atomic_write(args.out, ply.write)
        print(f"{len(points)} points written to {args.out}")
