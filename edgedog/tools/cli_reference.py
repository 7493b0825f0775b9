"""docs/CLI.md, the command-line reference, generated from the argparse parsers of `edgedog.cli`.

`python -m edgedog.tools.cli_reference --out docs/CLI.md` writes it (`make docs`); `--check` exits 1 when
the file differs from a fresh generation. The text is the same on every machine: the parser is built
as for a user with no EDGEDOG_* variables and a placeholder home written `~` (help texts that name
the user cache read `~/.cache/edgedog`), and usage lines are wrapped at a fixed width, not the
terminal's.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import functools
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from edgedog.cli import build_parser

REFERENCE_PATH = "docs/CLI.md"
"""Where the reference lives, relative to the repository root."""

GENERATE_COMMAND = f"python -m edgedog.tools.cli_reference --out {REFERENCE_PATH}"

USAGE_WIDTH = 100
"""Columns of the usage lines (argparse wraps them)."""

NEUTRAL_HOME = "/home-of-the-user"
"""HOME while the parser is built: paths under it are written `~/...` in the reference."""


@dataclass(frozen=True)
class Argument:
    """One positional or option of a parser.

    invocation: how it is written, e.g. `--preset {paper,fast,preview}`, `-h, --help`, `[SCENE | RUN]`.
    option_strings: the option's names (`("-h", "--help")`); empty for a positional.
    help: its help text, `%(default)s`-style fields filled in; empty when it has none.
    default: its default as written on the command line; None when it has none worth showing
        (None, a flag's False, an empty list) or when `help` already states it.
    choices: the values it accepts when they are not already in `invocation`; empty otherwise.
    required: whether an option must be given (positionals are required unless `invocation` is
        in brackets).
    """

    invocation: str
    option_strings: tuple[str, ...]
    help: str
    default: str | None
    choices: tuple[str, ...]
    required: bool


@dataclass(frozen=True)
class ArgumentGroup:
    """A titled group of arguments as `--help` shows them ("options", "positional arguments", or a
    group of the command's own)."""

    title: str
    description: str
    arguments: tuple[Argument, ...]


@dataclass(frozen=True)
class ExclusiveGroup:
    """Options of which at most one (exactly one when `required`) may be given."""

    option_strings: tuple[str, ...]
    required: bool


@dataclass(frozen=True)
class Command:
    """One parser: the top-level `edgedog` or a (nested) sub-command.

    path: its full name, e.g. `edgedog bench raster` (argparse's prog).
    summary: the one-line help its parent lists it with; empty for the top level.
    usage: argparse's usage text, wrapped at USAGE_WIDTH.
    description, epilog: the parser's texts as written; empty when absent.
    raw_texts: whether description and epilog keep their line breaks (argparse's
        RawDescriptionHelpFormatter) rather than being reflowed.
    groups: its arguments, by group, in `--help` order, without the sub-command selector.
    exclusive: its mutually exclusive options.
    subcommands: its sub-commands, in their order in `--help`.
    """

    path: str
    summary: str
    usage: str
    description: str
    epilog: str
    raw_texts: bool
    groups: tuple[ArgumentGroup, ...]
    exclusive: tuple[ExclusiveGroup, ...]
    subcommands: tuple[Command, ...]


@dataclass(frozen=True)
class _ParserParts:
    """What argparse keeps only in private attributes (see `_parser_parts`)."""

    groups: list[tuple[str, str, list[argparse.Action]]]
    exclusive: list[tuple[bool, list[argparse.Action]]]
    subcommands: list[tuple[str, str, argparse.ArgumentParser]]
    subcommand_selectors: list[argparse.Action]


def _parser_parts(parser: argparse.ArgumentParser) -> _ParserParts:
    """The groups, mutually exclusive groups and sub-parsers of `parser`.

    argparse has no public API to walk a parser; these attributes are the ones its own help
    formatter reads, and this is the one place that touches them.
    """
    groups = [(group.title or "", group.description or "", list(group._group_actions))
              for group in parser._action_groups]
    exclusive = [(group.required, list(group._group_actions))
                 for group in parser._mutually_exclusive_groups]
    subcommands, selectors = [], []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            selectors.append(action)
            # The one-line helps exist only for sub-commands added with help=; aliases share a parser.
            helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
            children = {}
            for name, child in action.choices.items():
                children.setdefault(id(child), (name, helps.get(name, ""), child))
            subcommands += children.values()
    return _ParserParts(groups, exclusive, subcommands, selectors)


@contextlib.contextmanager
def _neutral_environment():
    """Build parsers as for any user: no EDGEDOG_* variables, home NEUTRAL_HOME.

    Help texts may be computed from the environment when the parser is built (the user cache's
    `$EDGEDOG_CACHE or ~/.cache/edgedog`); this keeps the machine's paths out of the reference.
    (pathlib refuses a home of `~` itself, hence a placeholder that `reference` writes as `~`.)
    """
    saved = dict(os.environ)
    try:
        for name in [name for name in os.environ if name.startswith("EDGEDOG_")]:
            del os.environ[name]
        os.environ["HOME"] = NEUTRAL_HOME
        yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


def build_reference_parser() -> argparse.ArgumentParser:
    """`edgedog.cli.build_parser()`, built in the neutral environment."""
    with _neutral_environment():
        return build_parser()


def describe(parser: argparse.ArgumentParser, summary: str = "") -> Command:
    """The `Command` tree of `parser` and all its sub-parsers."""
    parts = _parser_parts(parser)
    groups = []
    for title, description, actions in parts.groups:
        # As in --help: no hidden arguments, and the sub-commands get a list of their own.
        shown = [action for action in actions
                 if action.help is not argparse.SUPPRESS and action not in parts.subcommand_selectors]
        arguments = tuple(_argument(parser, action) for action in shown)
        if arguments:
            groups.append(ArgumentGroup(title, description, arguments))
    exclusive = tuple(ExclusiveGroup(tuple(action.option_strings[-1] for action in actions), required)
                      for required, actions in parts.exclusive)
    return Command(
        path=parser.prog,
        summary=summary,
        usage=_usage(parser),
        description=parser.description or "",
        epilog=parser.epilog or "",
        raw_texts=issubclass(parser.formatter_class, argparse.RawDescriptionHelpFormatter),
        groups=tuple(groups),
        exclusive=exclusive,
        subcommands=tuple(describe(child, help_line) for _, help_line, child in parts.subcommands),
    )


def _usage(parser: argparse.ArgumentParser) -> str:
    """argparse's usage text at USAGE_WIDTH columns, whatever the terminal."""
    fixed = copy.copy(parser)
    fixed.formatter_class = functools.partial(parser.formatter_class, width=USAGE_WIDTH)
    return fixed.format_usage().strip()


def _argument(parser: argparse.ArgumentParser, action: argparse.Action) -> Argument:
    metavar = _metavar(action)
    value = _with_nargs(metavar, action.nargs)
    if action.option_strings:
        invocation = ", ".join(action.option_strings) + (f" {value}" if value else "")
    else:
        invocation = value
    choices_shown = action.choices is not None and action.metavar is None
    help_text = _help_text(parser, action)
    return Argument(
        invocation=invocation,
        option_strings=tuple(action.option_strings),
        help=help_text,
        # A help text that states its default (often with why) is left to say it alone.
        default=None if "default" in help_text else _default(action),
        choices=() if action.choices is None or choices_shown else tuple(map(str, action.choices)),
        required=bool(action.option_strings) and action.required,
    )


def _metavar(action: argparse.Action) -> str:
    """The name argparse shows for the argument's value (a tuple metavar joined by spaces)."""
    if action.metavar is not None:
        return " ".join(action.metavar) if isinstance(action.metavar, tuple) else action.metavar
    if action.choices is not None:
        return "{" + ",".join(map(str, action.choices)) + "}"
    return action.dest.upper() if action.option_strings else action.dest


def _with_nargs(metavar: str, nargs) -> str:
    """The value part of an invocation, as argparse writes it for `nargs`."""
    if nargs == 0:
        return ""
    if nargs == argparse.OPTIONAL:
        return f"[{metavar}]"
    if nargs == argparse.ZERO_OR_MORE:
        return f"[{metavar} ...]"
    if nargs == argparse.ONE_OR_MORE:
        return f"{metavar} [{metavar} ...]"
    if nargs == argparse.REMAINDER:
        return "..."
    if isinstance(nargs, int):
        return " ".join([metavar] * nargs)
    return metavar


def _help_text(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The help text with argparse's `%(name)s` fields filled in, as `--help` shows it."""
    if not action.help or action.help == argparse.SUPPRESS:
        return ""
    if "%" not in action.help:
        return action.help
    fields = {name: value for name, value in vars(action).items() if value is not argparse.SUPPRESS}
    fields["prog"] = parser.prog
    return action.help % fields


def _default(action: argparse.Action) -> str | None:
    """The default as a user would write it, or None when there is nothing to show."""
    value = action.default
    if action.nargs == 0 or value is None or value is argparse.SUPPRESS or value == []:
        return None
    if isinstance(value, (list, tuple)):
        return ",".join(map(str, value))
    return str(value)


def render(command: Command) -> str:
    """The Markdown reference of `command` (the top-level parser) and every sub-command."""
    lines = [
        "# Command-line reference",
        "",
        f"Generated from the argparse parsers by `{GENERATE_COMMAND}` (`make docs`); do not edit by "
        "hand: `tests/test_cli_reference.py` fails when this file is stale.",
        "",
        "## Contents",
        "",
    ]
    lines += _contents(command, depth=0)
    for each in _walk(command):
        lines += [""] + _section(each)
    return "\n".join(lines) + "\n"


def _walk(command: Command):
    yield command
    for child in command.subcommands:
        yield from _walk(child)


def _contents(command: Command, depth: int) -> list[str]:
    summary = f": {_prose(command.summary)}" if command.summary else ""
    lines = [f"{'  ' * depth}- [{command.path}](#{_anchor(command.path)}){summary}"]
    for child in command.subcommands:
        lines += _contents(child, depth + 1)
    return lines


def _anchor(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, spaces to hyphens, other punctuation dropped."""
    return re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")


def _section(command: Command) -> list[str]:
    lines = [f"## {command.path}", "", "```", command.usage, "```"]
    if command.description or command.summary:
        lines += [""] + _text_block(command.description or command.summary, command.raw_texts)
    if command.subcommands:
        lines += ["", "Commands:", ""]
        lines += [f"- [`{child.path.rsplit(' ', 1)[-1]}`](#{_anchor(child.path)}): {_prose(child.summary)}"
                  for child in command.subcommands]
    for group in command.groups:
        lines += ["", f"{_prose(group.title[:1].upper() + group.title[1:])}:", ""]
        if group.description:
            lines += [_prose(group.description), ""]
        lines += [_argument_line(argument) for argument in group.arguments]
    for group in command.exclusive:
        names = ", ".join(f"`{name}`" for name in group.option_strings)
        rule = "Exactly one of" if group.required else "At most one of"
        lines += ["", f"{rule} {names}."]
    if command.epilog:
        lines += [""] + _text_block(command.epilog, command.raw_texts)
    return lines


def _text_block(text: str, raw: bool) -> list[str]:
    """A description or epilog: a paragraph, or a code block when its line breaks matter (a raw
    text of several lines)."""
    text = text.strip("\n")
    return ["```", text, "```"] if raw and "\n" in text else [_prose(text)]


def _argument_line(argument: Argument) -> str:
    notes = []
    if argument.required:
        notes.append("required")
    if argument.choices:
        notes.append("one of " + ", ".join(f"`{choice}`" for choice in argument.choices))
    if argument.default is not None:
        notes.append(f"default `{argument.default}`")
    text = f"- `{argument.invocation}`"
    if argument.help:
        text += f": {_prose(argument.help)}"
    if notes:
        text += f" ({'; '.join(notes)})"
    return text


def _prose(text: str) -> str:
    """Help text as Markdown prose: one line, with `<...>` and `*` kept literal (not HTML,
    not emphasis) outside code spans."""
    pieces = re.split(r"(`[^`]*`)", " ".join(text.split()))
    return "".join(piece if piece.startswith("`") else re.sub(r"([\\<*])", r"\\\1", piece)
                   for piece in pieces)


def reference() -> str:
    """docs/CLI.md as it should read now."""
    return render(describe(build_reference_parser())).replace(NEUTRAL_HOME, "~")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m edgedog.tools.cli_reference",
                                     description="Write or check the command-line reference.")
    parser.add_argument("--out", type=Path, default=Path(REFERENCE_PATH),
                        help=f"the reference to write or check (default {REFERENCE_PATH})")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 when the file differs from a fresh generation")
    args = parser.parse_args(argv)
    text = reference()
    if args.check:
        current = args.out.read_text(encoding="utf-8") if args.out.is_file() else None
        if current != text:
            print(f"{args.out}: stale; regenerate it with `{GENERATE_COMMAND}` (make docs)", file=sys.stderr)
            return 1
        print(f"{args.out}: up to date")
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8", newline="\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
