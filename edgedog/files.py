"""File I/O shared by every module: JSON reads with one-line errors, atomic writes.

Atomic writes mean a reader (or a crash) never sees a half-written file."""

from __future__ import annotations

import functools
import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

from edgedog.errors import InputError, OutputError


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


def read_json(path: Path) -> Any:
    """Parse a JSON file; a missing or malformed file is an InputError naming it."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"invalid JSON ({exc})") from None
