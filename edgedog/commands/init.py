"""`edgedog init SCENE`: the initial primitive positions and scales, and how they were chosen."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

from edgedog.commands.scene_args import add_scene_options, open_scene
from edgedog.errors import ConfigError
from edgedog.files import atomic_write


def add_parser(subparsers) -> None:
    from edgedog.init import INIT_METHODS
    from edgedog.train.config import TrainConfig

    parser = subparsers.add_parser(
        "init", help="initial points: SfM triangulation with the known poses, or a uniform cube",
        description="Compute the initial primitives' positions and scales and say which method was "
                    "used and why: the scene's SfM points, SIFT points triangulated with the known "
                    "cameras and kept on pseudo edges, or EdgeGaussians' uniform cube.")
    parser.add_argument("scene", help="scene folder")
    parser.add_argument("--method", choices=INIT_METHODS, default="auto")
    parser.add_argument("--detector", default=None,
                        help="keep only points that project onto this detector's edge maps in 2+ views")
    parser.add_argument("--min-points", type=int, default=500, help="fewest points 'auto' accepts")
    parser.add_argument("--uniform-count", type=int, default=TrainConfig.init_count,
                        help=f"points of the uniform cube (default {TrainConfig.init_count}, as "
                             "`edgedog train`; EdgeGaussians uses 2500)")
    parser.add_argument("--uniform-side", type=float, default=None,
                        help="edge of the uniform cube (default: the scene bounds' largest extent; "
                             "EdgeGaussians uses 1.1 for ABC objects)")
    parser.add_argument("--out", type=Path, default=None, help="write the points as a PLY (x, y, z, scale)")
    add_scene_options(parser)
    parser.set_defaults(run=run)


def check_options(args: argparse.Namespace) -> None:
    """ConfigErrors naming the option, before the scene is opened."""
    from edgedog.train.config import MAX_PRIMITIVES

    if not 1 <= args.uniform_count <= MAX_PRIMITIVES:
        raise ConfigError(f"--uniform-count {args.uniform_count}: must be between 1 and {MAX_PRIMITIVES}")
    if args.uniform_side is not None and not (math.isfinite(args.uniform_side) and args.uniform_side > 0):
        raise ConfigError(f"--uniform-side {args.uniform_side}: must be a positive number")
    if args.min_points < 0:
        raise ConfigError(f"--min-points {args.min_points}: must not be negative")


def run(args: argparse.Namespace) -> None:
    from edgedog.init import initialize

    check_options(args)
    scene = open_scene(args.scene, args)
    points = initialize(scene, args.method, detector=args.detector, min_points=args.min_points,
                        uniform_count=args.uniform_count, uniform_side=args.uniform_side)
    print(json.dumps({"method": points.method, "points": len(points), **points.report}, indent=2,
                     default=str))
    if args.out is not None:
        rows = np.empty(len(points), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("scale", "f4")])
        rows["x"], rows["y"], rows["z"] = points.positions.T
        rows["scale"] = points.scales
        ply = PlyData([PlyElement.describe(rows, "vertex")])
        atomic_write(args.out, ply.write)
        print(f"{len(points)} points written to {args.out}")
