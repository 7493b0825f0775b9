"""Where a command may write: the one output policy of every command that writes a file a user names.

- Never inside a scene folder: it holds a user's images, cameras and maps (a scene's edge maps
  computed by edgedog go to the cache, `edgedog.files.default_cache`).
- Never over a file the command did not make: an existing file is refused with one line, or
  replaced with `--force` where the command has it (replacing is then what the user asked for).
  A command's own default output (export's RUN/curves_world.obj) is replaced as before.
- Inside a run folder, never over the run's own files, whatever --force says, and only while
  holding the run's lock (`RunLock`, taken by `edgedog.train.lifecycle.lock_folder`): no command
  writes into a run that another process trains, resumes or extracts.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from edgedog.errors import InputError, OutputError
from edgedog.files import read_json
from edgedog.train.run_folder import LOCK_FILE, check_outside_scenes


def _is_run(folder: Path) -> bool:
    """A run of ours, or a layered run's top folder (`holds_run`)."""
    from edgedog.train.lifecycle import holds_run  # loads the scene readers (cv2): only when asked

    return holds_run(folder)


def enclosing_run(path: str | Path) -> Path | None:
    """The run folder (a run, or a layered run's top folder) that the file `path` lies in, None
    when it lies in none."""
    folder = Path(os.path.realpath(path)).parent  # a symlink loop stays as it is (Path.resolve raises)
    for folder in (folder, *folder.parents):
        if _is_run(folder):
            return folder
    return None


def check_new_file(path: str | Path, force: bool | None = False, default: Path | None = None) -> Path | None:
    """Check that a command may write the file `path`; return the run folder it lies in (whose
    lock the writer must hold), or None.

    Args:
        force: the command's --force was given (None: the command has no --force).
        default: the command's own default output: `path` naming it is replaced without --force.
    Raises:
        OutputError: `path` lies in a scene folder, is a run's own file, or exists and may not be
        replaced.
    """
    path = Path(path)
    check_outside_scenes(path)
    run = enclosing_run(path)
    own = default is not None and os.path.realpath(path) == os.path.realpath(default)
    exists = path.exists() or path.is_symlink()
    if exists and path.is_dir():
        raise OutputError(path, "is a folder; give a file name")
    if exists and run is not None and not own:
        raise OutputError(path, f"is a file of the run in {run}; edgedog replaces a run's files only by "
                                "training or extracting it: choose another name")
    if exists and not (own or force):
        how = "pass --force to replace it, or choose" if force is not None else "choose"
        raise OutputError(path, f"already exists; {how} another name")
    return run


@contextlib.contextmanager
def output_file(path: str | Path, force: bool | None = False, default: Path | None = None) -> Iterator[Path]:
    """Within it, the file `path` may be written (`check_new_file`, checked again under the lock
    of the run folder it lies in, held throughout)."""
    from edgedog.train.lifecycle import lock_folder

    run = check_new_file(path, force, default)
    if run is None:
        yield Path(path)
        return
    with lock_folder(run):
        check_new_file(path, force, default)  # the run's writer may have made it meanwhile
        yield Path(path)


def check_output_folder(path: str | Path, own_files: tuple[str, ...]) -> None:
    """A folder a command fills with runs and tables (a batch's, a benchmark's) may be new, empty,
    or one this command filled before: runs of ours, and `own_files` when the first of them (the
    command's record, e.g. batch.json) is there. Anything else in it is a user's: OutputError
    before anything is written, as for a folder inside a scene or a training run."""
    path = Path(path)
    check_outside_scenes(path)
    if not path.exists():
        return
    if not path.is_dir():
        raise OutputError(path, "is a file, not a folder; choose a new or empty folder")
    if _is_run(path):
        raise OutputError(path, "is a training run; give this command a folder of its own")
    ours = set(own_files) if _is_record(path / own_files[0]) else set()
    for entry in sorted(path.iterdir()):
        if entry.name == LOCK_FILE or entry.name in ours or (entry.is_dir() and _holds_a_run(entry)):
            continue
        raise OutputError(path, f"holds {entry.name}, which this command did not write; choose a new or "
                                "empty folder")


def _holds_a_run(folder: Path) -> bool:
    """A run of ours, or a run folder whose first writer stopped before writing its config.json
    (nothing in it but its lock)."""
    return _is_run(folder) or all(entry.name == LOCK_FILE for entry in folder.iterdir())


def _is_record(file: Path) -> bool:
    """Whether `file` is a command's JSON record (an object), not a user's file of that name."""
    try:
        return isinstance(read_json(file), dict)
    except InputError:
        return False
