"""Argument types shared by the commands: every number that sizes a loop or an allocation is bounded
where it is parsed, so a typo (`--evals 1000000000`) is one line, never an hour of work."""

from __future__ import annotations

import argparse

from edgedog.settings import Range

MAX_SIZE = 4096
"""Image width and height in px of the views a command renders: a 4K view (the datasets' largest
are 1600 px)."""


def bounded_integer(low: int, high: int):
    """An argparse type: an integer in [low, high] (argparse names the option in its error)."""
    bounds = Range(low, high)

    def integer(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value not in bounds:
            raise argparse.ArgumentTypeError(f"must be an integer {bounds}, got {text!r}")
        return value

    return integer
