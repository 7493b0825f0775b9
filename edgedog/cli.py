"""The `edgedog` command line: one sub-command per module in edgedog/commands/."""

from __future__ import annotations

import argparse
import sys

from edgedog import __version__
from edgedog.commands import (
    bench,
    calibrate,
    demo,
    edges,
    evaluate,
    export,
    extract,
    info,
    init,
    make_scene,
    sfm,
    studio,
    train,
)
from edgedog.errors import EdgeDogError

COMMANDS = (info, edges, calibrate, init, sfm, train, extract, export, evaluate, bench, demo, make_scene,
            studio)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="edgedog",
        description="EdgeDoG Studio: 3D edges from posed images with DoG splatting.",
    )
    parser.add_argument("--version", action="version", version=f"edgedog {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run a command; user errors print one line `edgedog: error: <file>: <problem>`, exit 2."""
    args = build_parser().parse_args(argv)
    try:
        return args.run(args) or 0
    except EdgeDogError as exc:
        print(f"edgedog: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
