"""`edgedog extract RUN`: filter a run's primitives and fit lines and Béziers to them."""

from __future__ import annotations

import argparse
from pathlib import Path

from edgedog.commands.reports import print_layers_report, print_report


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
    from edgedog.train.lifecycle import open_record

    config = with_overrides(ExtractConfig(), args.overrides)
    with open_record(args.run_dir) as record:
        report = record.extract(record.extraction_scene(config), config)
    print_extraction(args.run_dir, report)


def print_extraction(path: Path, report: dict) -> None:
    """The extraction's table and the files written: a layered run's report holds every
    selection's (curves per layer and per cumulative stack, in RUN/curves/NAME)."""
    from edgedog.curves.extract import OUTPUTS
    from edgedog.curves.report import REPORT
    from edgedog.train.layered import REPORT as LAYERS_REPORT

    if "selections" in report:
        print_layers_report(report)
        names = ", ".join(report["selections"])
        print(f"wrote {path / 'curves'}/NAME/ for {names} and {path / LAYERS_REPORT}")
        return
    print_report(report)
    print(f"wrote {', '.join(OUTPUTS + (REPORT,))} in {path}")
