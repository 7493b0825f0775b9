"""Errors users see as one line: which file, and what is wrong with it."""

from __future__ import annotations

from pathlib import Path


class EdgeDogError(Exception):
    """Base of the errors the command line reports as a single line (no traceback)."""


class PathError(EdgeDogError):
    """An error about one file or folder; the message always names it first:
    ``"<path>: <problem>"``."""

    def __init__(self, path: str | Path, problem: str):
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class InputError(PathError):
    """A user's file is missing or malformed."""


class ConfigError(EdgeDogError):
    """An option or setting that cannot be used (unknown name, value out of range)."""


class OutputError(PathError):
    """A file or folder we were asked to write cannot be written (permissions, a full disk, a
    path that is a folder or whose parent is a file)."""
