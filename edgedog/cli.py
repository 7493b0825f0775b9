"""The `edgedog` command line: one sub-command per module in edgedog/commands/."""

from __future__ import annotations

import argparse
import sys
import traceback

from edgedog import __version__
from edgedog.allocator import keep_freed_memory
from edgedog.commands import (
    batch,
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

COMMANDS = (info, edges, calibrate, init, sfm, train, extract, export, evaluate, bench, batch, demo,
            make_scene, studio)


INTERRUPTED = 130
"""Exit code after Ctrl-C (128 + SIGINT), as shells report it."""


class OneLineParser(argparse.ArgumentParser):
    """argparse with its errors in the one-line form of every other error (and exit code 2);
    `--help` still prints the usage."""

    def error(self, message: str):
        self.exit(2, f"edgedog: error: {self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="edgedog",
        description="EdgeDoG Studio: 3D edges from posed images with DoG splatting.",
    )
    parser.add_argument("--version", action="version", version=f"edgedog {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run a command.

    A user's error (a bad file or setting, a path that cannot be written) prints one line
    `edgedog: error: <file or setting>: <problem>` and exits 2; Ctrl-C stops with a line saying
    how to continue and exits 130; anything else is a bug of ours: its traceback, then a line
    asking to report it, exit 1.
    """
    args = build_parser().parse_args(argv)
    keep_freed_memory()
    try:
        return args.run(args) or 0
    except EdgeDogError as exc:
        return _fail(str(exc))
    except OSError as exc:  # the environment: permissions, a full disk, a vanished file
        where = f"{exc.filename}: " if exc.filename else ""
        return _fail(f"{where}{exc.strerror or exc}")
    except KeyboardInterrupt:
        return _interrupted(args)
    except Exception as exc:
        if _masks_an_interrupt(exc):  # e.g. torch's zip writer failing as Ctrl-C unwinds it
            return _interrupted(args)
        traceback.print_exc()
        print("edgedog: internal error: this is a bug in edgedog; please report it with the command "
              "line and the traceback above", file=sys.stderr)
        return 1


def _interrupted(args: argparse.Namespace) -> int:
    hint = getattr(args, "resume_hint", None)
    return _fail("interrupted" + (f"; {hint(args)}" if hint else ""), INTERRUPTED)


def _masks_an_interrupt(exc: BaseException) -> bool:
    """Whether `exc` was raised while a KeyboardInterrupt was being handled."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__context__
    return False


def _fail(message: str, code: int = 2) -> int:
    print(f"edgedog: error: {message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
