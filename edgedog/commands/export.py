"""`edgedog export RUN --format ply|obj|json`: a run's curves in another format or frame."""

from __future__ import annotations

import argparse
from pathlib import Path

from edgedog.errors import InputError


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "export", help="export a run's extracted curves as PLY, OBJ or EMAP JSON",
        description="Write the curves of `edgedog extract` (the run's curves.json) as an OBJ of "
                    "polylines (one object per curve), a PLY with an edge element, or EMAP's "
                    "parametric_edges.json, in the scene's world frame or its ground-truth frame.")
    parser.add_argument("run_dir", metavar="RUN", type=Path, help="run folder holding curves.json")
    parser.add_argument("--format", choices=("ply", "obj", "json"), required=True)
    parser.add_argument("--frame", choices=("world", "gt"), default="world",
                        help="world: the scene's frame (default); gt: mapped with the scene's "
                             "world-to-ground-truth transform")
    parser.add_argument("--layers", default=None, metavar="NAME",
                        help="for a layered run: the selection to export, a layer (L1) or a "
                             "cumulative stack (L0+L1); default the whole stack")
    parser.add_argument("--out", type=Path, default=None,
                        help="output file (default: RUN/curves_<frame>.<format>, replaced by each export); "
                             "never a run's own file nor inside a scene folder")
    parser.add_argument("--force", action="store_true", help="replace the --out file if it exists")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    from edgedog.curve_files import read_edges, write_edges
    from edgedog.curves.extract import run_scene
    from edgedog.outputs import output_file
    from edgedog.train.lifecycle import curves_of

    folder, frame_run = curves_of(args.run_dir, args.layers)
    source = folder / "curves.json"
    if not source.is_file():
        raise InputError(source, "no curves yet: run `edgedog extract RUN` first")
    curves = read_edges(source)
    if args.frame == "gt":
        curves = curves.transformed(run_scene(frame_run, maps=False)[0].world_to_gt)
    default = folder / f"curves_{args.frame}.{args.format}"
    out = args.out or default
    if out.suffix.lower() != f".{args.format}":
        raise InputError(out, f"the file name must end in .{args.format} for --format {args.format}")
    with output_file(out, args.force, default):
        write_edges(out, curves)
    print(f"{curves.num_curves} curves ({len(curves.lines)} lines, {len(curves.beziers)} Béziers) "
          f"written to {out}")
