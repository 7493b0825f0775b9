"""docs/CLI.md: generated from the parsers, current, complete and free of the machine's paths."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from edgedog.cli import build_parser
from edgedog.tools import cli_reference

REFERENCE = Path(__file__).resolve().parents[1] / cli_reference.REFERENCE_PATH
OPTION = re.compile(r"(?<![\w-])--?[A-Za-z][\w-]*")


def test_the_reference_is_current():
    assert REFERENCE.read_text(encoding="utf-8") == cli_reference.reference(), (
        f"{cli_reference.REFERENCE_PATH} is stale: regenerate it with "
        f"`{cli_reference.GENERATE_COMMAND}` (make docs)")


def test_the_reference_does_not_depend_on_the_machine(monkeypatch, tmp_path):
    monkeypatch.setenv("COLUMNS", "37")
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("EDGEDOG_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("EDGEDOG_PIDINET", str(tmp_path / "weights"))
    text = cli_reference.reference()
    assert text == REFERENCE.read_text(encoding="utf-8")
    assert str(tmp_path) not in text
    assert "~/.cache/edgedog" in text  # the user cache, as a user reads it
    for absolute in ("/work/", "/root/", "/home/", "/tmp/", str(Path.cwd())):
        assert absolute not in text


def _parsers(parser: argparse.ArgumentParser):
    """(parser, its option strings) for `parser` and every nested sub-parser, the options read
    from the argument lines of `--help` as a user sees it (not by the generator's walk)."""
    invocations = re.findall(r"^  (-\S.*?)(?:  |$)", parser.format_help(), flags=re.MULTILINE)
    yield parser, {name for invocation in invocations for name in OPTION.findall(invocation)}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in dict.fromkeys(action.choices.values()):
                yield from _parsers(child)


def _sections(text: str) -> dict[str, str]:
    """The reference's sections by heading (`## edgedog bench raster` -> its text)."""
    parts = re.split(r"^## (.+)$", text, flags=re.MULTILINE)
    return dict(zip(parts[1::2], parts[2::2]))


def test_every_command_and_option_is_in_the_reference():
    sections = _sections(REFERENCE.read_text(encoding="utf-8"))
    walked = list(_parsers(build_parser()))
    assert len(walked) > 15  # the top level, its commands and bench's benchmarks
    for parser, options in walked:
        assert parser.prog in sections, f"no section for `{parser.prog}`"
        listed = set(re.findall(r"^- `([^`]*)`", sections[parser.prog], flags=re.MULTILINE))
        listed_options = {name for entry in listed for name in OPTION.findall(entry)}
        missing = options - listed_options
        assert not missing, f"`{parser.prog}` options not in its section: {sorted(missing)}"
        assert f"#{parser.prog.replace(' ', '-')})" in sections["Contents"]


def test_an_option_added_to_a_parser_shows_in_its_section():
    parser = cli_reference.build_reference_parser()
    bench = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices["bench"]
    group = bench.add_argument_group("extra")
    group.add_argument("--frobnicate", metavar="HOW", choices=("a", "b"), default="a", help="odd <stuff>")
    sections = _sections(cli_reference.render(cli_reference.describe(parser)))
    assert "Extra:\n\n- `--frobnicate HOW`: odd \\<stuff> (one of `a`, `b`; default `a`)" in sections[
        "edgedog bench"]
