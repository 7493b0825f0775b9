"""`edgedog extract RUN`: filter a run's primitives and fit lines and Béziers to them."""

from __future__ import annotations

import argparse
from pathlib import Path

from edgedog.commands.reports import print_layers_report, print_report
from edgedog.errors import InputError


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "extract", help="fit parametric curves (lines, cubic Béziers) to a trained run's edge points",
        description="Filter the primitives of a run (opacity, mean edge value over all views, "
                    "statistical outliers, outside the object's masks), group them into curves "
                    "and fit lines and cubic Béziers. Writes curves.json (EMAP format), "
                    "curves.obj, curves.ply, edge_points.ply and extract.json into the run "
                    "folder; when the scene has ground truth, prints the scores of the filtered "
                    "points and of the curves. A layered run (edgedog train --layers) gets curves "
                    "per layer and per cumulative stack in RUN/curves/NAME (L0, L1, L0+L1, ...).")
    parser.add_argument("run_dir", metavar="RUN", type=Path, help="run folder written by `edgedog train`")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a setting of edgedog.curves.config.ExtractConfig (repeatable): "
                             "KEY is extract.FIELD (extract.min_opacity=0.3), or the bare FIELD")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    from edgedog.curves.config import ExtractConfig, with_overrides
    from edgedog.curves.extract import OUTPUTS, run_scene
    from edgedog.curves.report import REPORT, extract_with_report
    from edgedog.train.layered import is_layered
    from edgedog.train.run_folder import RunLock, is_run_folder

    if not args.run_dir.is_dir():
        raise InputError(args.run_dir, "run folder not found")
    config = with_overrides(ExtractConfig(), args.overrides)
    if is_layered(args.run_dir):
        with RunLock.acquire(args.run_dir):
            return extract_layered_run(args.run_dir, config)
    if not is_run_folder(args.run_dir):
        raise InputError(args.run_dir, "is not an edgedog run folder (no config.json of ours)")
    with RunLock.acquire(args.run_dir):
        scene, detector = run_scene(args.run_dir, maps=config.filter_projection)
        _, report = extract_with_report(args.run_dir, scene, detector, config)
    print_report(report)
    print(f"wrote {', '.join(OUTPUTS + (REPORT,))} in {args.run_dir}")


def extract_layered_run(path: Path, config) -> None:
    """Every layer alone and every cumulative stack of a layered run, with a table."""
    from edgedog.scenes import load_scene
    from edgedog.train.layered import REPORT, extract_layered, read_layered

    run = read_layered(path)
    report = extract_layered(run, load_scene(run.scene, downscale=run.base.maps.downscale), config)
    print_layers_report(report)
    print(f"wrote {path / 'curves'}/NAME/ for {', '.join(report['selections'])} and {path / REPORT}")
