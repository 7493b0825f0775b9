"""File I/O shared by every module: bounded JSON and YAML reads with one-line errors, atomic writes.

Atomic writes mean a reader (or a crash) never sees a half-written file. Bounded reads mean a
user's file (a run's config.json, a scene's transforms, a suite) can hold anything and still
end in data or in one InputError naming it: never a traceback, a hang or all the memory."""

from __future__ import annotations

import functools
import json
import math
import os
import re
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

from edgedog.errors import InputError, OutputError

_TEMPORARY = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")
"""The name `atomic_write` gives its temporary file: '.NAME.' + mkstemp's 8 characters + '.tmp'."""


def remove_stale_temporaries(folder: Path) -> None:
    """Remove the temporary files that `atomic_write` left in `folder` when its process was killed
    while writing (kill -9 skips its clean-up). Only for a folder whose lock the caller holds:
    no writer of it is alive then."""
    for entry in folder.iterdir():
        if _TEMPORARY.fullmatch(entry.name) and entry.is_file() and not entry.is_symlink():
            entry.unlink(missing_ok=True)


def atomic_write(path: str | Path, write: Callable[[BinaryIO], None]) -> Path:
    """Call `write(file)` on a temporary file beside `path`, fsync it, then rename it over `path`.

    The rename is atomic on POSIX file systems; on any error the temporary file is removed
    and `path` keeps its previous content. An OSError (no permission, a full disk, `path` a
    folder, a parent that is a file) becomes an OutputError naming `path`.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(path, "is a folder; give a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise OutputError(path, f"cannot write ({exc.strerror or exc})") from None
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files; give the usual permissions
        with os.fdopen(fd, "wb") as file:
            write(file)
            file.flush()
            os.fsync(file.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(path, f"cannot write ({exc.strerror or exc})") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def create_folder(path: str | Path, exist_ok: bool = True, named: str | Path | None = None) -> Path:
    """`mkdir -p path`; an OSError (no permission, a parent that is a file, a full disk) becomes
    an OutputError naming `named` (the folder the user asked for) or `path`."""
    try:
        Path(path).mkdir(parents=True, exist_ok=exist_ok)
    except OSError as exc:
        raise OutputError(named or path, f"cannot create the folder ({exc.strerror or exc})") from None
    return Path(path)


@functools.cache  # read once: setting the umask to read it is not thread-safe
def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    return atomic_write(path, lambda f: f.write(data))


def atomic_write_json(path: str | Path, value: Any) -> Path:
    return atomic_write_bytes(path, (json.dumps(value, indent=2) + "\n").encode("utf-8"))


def default_cache() -> Path:
    """Where generated data is kept (built-in scenes, edge maps of read-only scenes):
    $EDGEDOG_CACHE, else ~/.cache/edgedog."""
    return Path(os.environ.get("EDGEDOG_CACHE", Path.home() / ".cache" / "edgedog"))


MAX_DOCUMENT_BYTES = 64 * 2**20
"""The most a JSON or YAML file may hold (64 MiB); edgedog's own are a few MiB at most (the curves
of a large run). Reading stops there, so /dev/zero or a 100 GB file costs 64 MiB, not the machine."""
MAX_DEPTH = 64
"""The deepest nesting of lists and objects a document may have; edgedog's own files nest 4 levels.
Bounded well below Python's recursion limit, so no parser or reader of the data ever overflows it."""
MAX_INT_DIGITS = 100
"""The most digits an integer may have: far beyond any count or seed (a 64-bit integer has 20), and
short enough that converting it costs nothing (Python refuses more than 4300 with a ValueError)."""


def read_bounded(path: str | Path, limit: int = MAX_DOCUMENT_BYTES) -> bytes:
    """The bytes of the regular file `path`, refused with an InputError naming it when missing, a
    folder, not a regular file (a device or FIFO, which could be endless or block forever; opened
    without blocking and never read) or larger than `limit` bytes (reading stops at `limit` + 1)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise InputError(path, "is a folder, not a file" if stat.S_ISDIR(mode) else
                         "is not a regular file (a device, FIFO or socket); give a file")
    with os.fdopen(fd, "rb") as file:
        try:
            data = file.read(limit + 1)
        except OSError as exc:
            raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise InputError(path, f"is larger than {limit / 2**20:g} MiB, more than a file edgedog reads "
                               "may hold")
    return data


class _Refused(ValueError):
    """A document the reader refuses (too deep, an alias), raised from inside the YAML event walk."""


class _Bad:
    """Stands in for a number a document may not hold, so the reader can say where it lies."""

    def __init__(self, problem: str):
        self.problem = problem


def _json_number_hooks(found: list[_Bad]) -> dict:
    """json.loads hooks that parse numbers, putting a _Bad (also appended to `found`) in place of
    an integer of too many digits, a float beyond range, NaN or Infinity."""
    def bad(problem: str) -> _Bad:
        found.append(_Bad(problem))
        return found[-1]

    def parse_int(text: str) -> int | _Bad:
        digits = len(text.lstrip("-"))
        return int(text) if digits <= MAX_INT_DIGITS else bad(f"an integer of {digits} digits")

    def parse_float(text: str) -> float | _Bad:
        value = float(text)
        return value if math.isfinite(value) else bad(f"the number {text[:24]}, beyond a float's range")

    return {"parse_int": parse_int, "parse_float": parse_float, "parse_constant": bad}


def _bad_number(value: Any) -> str | None:
    """What is wrong with `value` as a number of a document, None when nothing is."""
    if isinstance(value, _Bad):
        return value.problem
    if isinstance(value, float) and not math.isfinite(value):
        return f"the number {value}"
    if isinstance(value, int) and len(str(abs(value))) > MAX_INT_DIGITS:
        return f"an integer of {len(str(abs(value)))} digits"
    return None


def _check_numbers(value: Any, path: str | Path) -> None:
    """InputError naming the file and the place (`frames[1].transform_matrix[0][3]`) of the first
    number that is not finite or has more than MAX_INT_DIGITS digits. The walk keeps its own
    stack: the value nests at most MAX_DEPTH levels, but not recursing costs nothing."""
    stack = [(value, "")]
    while stack:
        item, where = stack.pop()
        problem = _bad_number(item)
        if problem:
            raise InputError(path, f"{where or 'the document'} is {problem}; only finite numbers of "
                                   f"at most {MAX_INT_DIGITS} digits are read")
        if isinstance(item, dict):
            stack += [(v, f"{where}.{k}" if where else str(k)) for k, v in reversed(item.items())]
        elif isinstance(item, list):
            stack += [(v, f"{where}[{i}]") for i, v in reversed(list(enumerate(item)))]


_JSON_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"')
_NOT_BRACKETS = bytes(set(range(256)) - set(b"[]{}"))


def _json_depth(text: str) -> int:
    """How deep the lists and objects of the JSON `text` nest, counted without recursion (the
    brackets outside strings, each opening one +1 and each closing one -1)."""
    import numpy as np

    brackets = _JSON_STRING.sub("", text).encode("utf-8", "replace").translate(None, _NOT_BRACKETS)
    if not brackets:
        return 0
    codes = np.frombuffer(brackets, np.uint8)
    return int(np.cumsum(np.where((codes == ord("[")) | (codes == ord("{")), 1, -1)).max())


def read_json(path: str | Path) -> Any:
    """Parse a JSON file within the bounds above (size, depth, integer digits, finite numbers);
    anything else (missing, not UTF-8, malformed, out of bounds) is one InputError naming it."""
    data = read_bounded(path)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(path, f"invalid JSON ({exc})") from None
    if _json_depth(text) > MAX_DEPTH:
        raise InputError(path, f"nests lists or objects more than {MAX_DEPTH} levels deep")
    found: list[_Bad] = []
    try:
        value = json.loads(text, **_json_number_hooks(found))
    except json.JSONDecodeError as exc:
        raise InputError(path, f"invalid JSON ({exc})") from None
    if found:  # only then walk the document to say where
        _check_numbers(value, path)
    return value


def read_yaml(path: str | Path) -> Any:
    """Parse a YAML file (safe tags only: plain data, never Python objects) within the bounds of
    read_json; aliases (`*name`) are refused, as they let a small file build a huge or endlessly
    deep value. Anything else is one InputError naming the file."""
    import yaml

    data = read_bounded(path)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(path, "is not a text file") from None
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        _check_yaml_events(yaml.parse(text, Loader=loader), yaml)
        value = yaml.load(text, Loader=loader)
    except _Refused as exc:
        raise InputError(path, str(exc)) from None
    except yaml.YAMLError as exc:
        raise InputError(path, f"invalid YAML ({' '.join(str(exc).split())})") from None
    except ValueError as exc:  # a number its constructor cannot convert
        raise InputError(path, f"invalid YAML ({exc})") from None
    _check_numbers(value, path)
    return value


_YAML_NUMBER = re.compile(r"[-+]?(0[xob])?[0-9a-fA-F_:.]+([eE][-+]?[0-9]+)?")
_YAML_MAX_CHARS = 4000
"""Longer numbers are refused before YAML converts them (Python refuses more than 4300 digits);
shorter ones are converted, then checked against MAX_INT_DIGITS with their place."""


def _check_yaml_events(events, yaml) -> None:
    """Walk the parser's events (no recursion, no value built yet) for nesting depth, aliases and
    integers of too many digits."""
    depth = 0
    for event in events:
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            if depth > MAX_DEPTH:
                raise _Refused(f"nests lists or mappings more than {MAX_DEPTH} levels deep")
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1
        elif isinstance(event, yaml.AliasEvent):
            raise _Refused(f"uses the alias *{event.anchor}; write the value out instead")
        elif isinstance(event, yaml.ScalarEvent) and not event.style and \
                len(event.value) > _YAML_MAX_CHARS and _YAML_NUMBER.fullmatch(event.value):
            raise _Refused(f"holds a number of {len(event.value)} characters, more than "
                           f"{MAX_INT_DIGITS} digits")
