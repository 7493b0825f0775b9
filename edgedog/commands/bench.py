"""`edgedog bench ...`: measured speed (and later accuracy); results go to docs/BENCHMARKS.md."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from edgedog.files import atomic_write_json


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser("bench", help="run a benchmark and print its JSON")
    kinds = parser.add_subparsers(dest="benchmark", required=True, metavar="BENCHMARK")
    raster = kinds.add_parser("raster", help="rasterizer speed: C++ path against the torch reference",
                              description="Render 800x800 views of an ABC-like scene of thin primitives "
                                          "and time forward, backward and Fisher per view.")
    raster.add_argument("--primitives", type=int, default=20000)
    raster.add_argument("--size", type=int, default=800, help="image width and height")
    raster.add_argument("--views", type=int, default=50)
    raster.add_argument("--reference-views", type=int, default=1)
    raster.add_argument("--kernel", choices=("dog", "gaussian"), default="dog")
    raster.add_argument("--seed", type=int, default=0)
    raster.add_argument("--json", type=Path, default=None, help="also write the result here")
    raster.set_defaults(run=run_raster)


def run_raster(args: argparse.Namespace) -> None:
    from edgedog.bench.raster import RasterBenchConfig, run, summary

    result = run(RasterBenchConfig(args.primitives, args.size, args.views, args.reference_views, args.kernel,
                                   args.seed))
    print(json.dumps(result, indent=2))
    print(summary(result))
    if args.json is not None:
        atomic_write_json(args.json, result)
