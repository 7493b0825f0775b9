"""A run folder: what makes a folder one of ours, its config.json, and its one-writer lock.

`edgedog train`, the demo, the benchmarks and the studio all write and read config.json here,
so any of them can resume, extract or inspect a run another one made. A folder is ours when its
config.json says so (`"format": "edgedog-run"`, or the keys of the files written before the
format was named); nothing is ever written into a non-empty folder that is not ours. Every
writer holds the folder's lock while it writes (`RunLock`).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from edgedog.curves.config import ExtractConfig
from edgedog.errors import ConfigError, InputError, OutputError
from edgedog.files import atomic_write_json, create_folder, read_json, remove_stale_temporaries
from edgedog.train.config import DEFAULT_PRESET, PRESETS_RENAMED, TrainConfig, from_dict, to_dict

if TYPE_CHECKING:
    from edgedog.scenes import Scene

RUN_CONFIG = "config.json"
LOG = "log.json"
"""Written by the trainer at its end (and by the speed bench at each evaluation)."""
LOCK_FILE = ".edgedog.lock"
RUN_FORMAT = "edgedog-run"
RUN_VERSION = 3
"""Version 3 writes the config by section (`{"maps": {...}, "init": {...}, ...}`) and names the
presets anew; version 2 added the format marker and the scene fingerprint. Versions 1 and 2
(flat configs, 'paper' for today's 'full') are still read, migrated by `from_dict` and
`PRESETS_RENAMED`."""


@dataclass(frozen=True)
class RunFolder:
    """path: the run folder; scene: the scene folder; preset: the preset the config started
    from (DEFAULT_PRESET when a file does not say); config: the full resolved config;
    scene_fingerprint: `edgedog.scenes.fingerprint.scene_fingerprint` of the scene trained on
    (None in runs written before it was recorded); maps_fingerprint: `maps_fingerprint` of its
    shipped edge maps and masks (None in runs written before it was recorded)."""

    path: Path
    scene: Path
    preset: str
    config: TrainConfig
    scene_fingerprint: str | None = None
    maps_fingerprint: str | None = None

    @property
    def curves_folder(self) -> Path:
        """Where the curves of the whole model are: the run folder."""
        return self.path

    @property
    def report_file(self) -> Path:
        """The extraction's report (extract.json, with scores when the scene has ground truth)."""
        from edgedog.curves.report import REPORT

        return self.path / REPORT

    def extraction_scene(self, config: ExtractConfig) -> Scene:
        """The scene as the run trained on it (`edgedog.curves.extract.run_scene`: from log.json),
        with the maps it was fitted to when the projection filter of `config` needs them."""
        from edgedog.curves.extract import run_scene

        return run_scene(self.path, maps=config.filter_projection)[0]

    def extract(self, scene: Scene, config: ExtractConfig = ExtractConfig()) -> dict:
        """Extract the curves of the trained run into its folder with the maps it was fitted to;
        returns the report (also written to `report_file`)."""
        from edgedog.curves.report import extract_with_report

        return extract_with_report(self.path, scene, read_json(self.path / LOG)["detector"], config)[1]

    def selection_folder(self, name: str | None = None) -> Path:
        """Where the curves of the whole model are (`own_curves`): a run of one layer has no
        selections of layers."""
        return own_curves(self.path, name)

    def layers(self) -> tuple[RunFolder, ...]:
        """The run folder of each layer, bottom first: a run folder is a stack of one layer
        (`edgedog.train.layered.LayeredRun` is one of several)."""
        return (self,)

    def write(self) -> None:
        """Write config.json (`write_run`)."""
        write_run(self)


def own_curves(path: Path, selection: str | None) -> Path:
    """The curves folder of a run of one layer, or of a folder of curves that records no run:
    `path` itself; InputError naming it when a layered run's `selection` is asked for."""
    if selection:
        raise InputError(path, "--layers needs a layered run (edgedog train --layers)")
    return path


def _run_config_data(path: Path) -> dict | None:
    """config.json of `path` as a dict when it is one of our run files, else None."""
    file = Path(path) / RUN_CONFIG
    if not file.is_file():
        return None
    try:
        data = read_json(file)
    except InputError:
        return None
    if not isinstance(data, dict):
        return None
    if data.get("format") == RUN_FORMAT or {"scene", "config"} <= data.keys():
        return data
    return None


def is_run_folder(path: Path) -> bool:
    """Whether `path` holds one of our runs (its config.json is ours)."""
    return _run_config_data(path) is not None


def read_run(path: Path) -> RunFolder:
    """The run in `path`; a missing or malformed config.json is one InputError naming it."""
    file = Path(path) / RUN_CONFIG
    data = read_json(file)
    if not isinstance(data, dict) or not {"scene", "config"} <= data.keys():
        raise InputError(file, "expected 'scene' and 'config' keys (written by edgedog train)")
    version = data.get("version", 1)
    if not isinstance(version, int) or version > RUN_VERSION:
        raise InputError(file, f"run format version {version!r} is newer than this edgedog reads "
                               f"({RUN_VERSION}); update edgedog")
    scene, fingerprint, maps = data["scene"], data.get("scene_fingerprint"), data.get("maps_fingerprint")
    preset = data.get("preset", DEFAULT_PRESET)
    if not (isinstance(scene, str) and isinstance(preset, str) and isinstance(fingerprint, str | None)
            and isinstance(maps, str | None)):
        raise InputError(file, "'scene', 'preset', 'scene_fingerprint' and 'maps_fingerprint' must be "
                               "strings")
    if version < 3:
        preset = PRESETS_RENAMED.get(preset, preset)
    if not isinstance(data["config"], dict):
        raise InputError(file, "'config' must be an object of settings")
    try:
        config = from_dict(data["config"])
    except ConfigError as exc:
        raise InputError(file, f"config: {exc}") from None
    return RunFolder(Path(path), Path(scene), preset, config, fingerprint, maps)


def write_run(run: RunFolder) -> None:
    """Write config.json atomically, creating the run folder if needed."""
    atomic_write_json(run.path / RUN_CONFIG, {
        "format": RUN_FORMAT, "version": RUN_VERSION, "scene": str(run.scene),
        "scene_fingerprint": run.scene_fingerprint, "maps_fingerprint": run.maps_fingerprint,
        "preset": run.preset, "config": to_dict(run.config)})


def enclosing_scene(path: str | Path) -> Path | None:
    """The scene folder that `path` is or lies in (a folder above it holds a scene's cameras), None
    when it lies in none."""
    from edgedog.scenes import FORMATS

    path = Path(os.path.realpath(path))  # a symlink loop stays as it is (Path.resolve raises)
    for folder in (path, *path.parents):
        if folder.is_dir() and any(test(folder) for _, test, _ in FORMATS):
            return folder
    return None


def check_outside_scenes(path: str | Path) -> None:
    """OutputError when the file or folder `path` is or lies inside a scene folder: a scene holds a
    user's images, cameras and maps, and edgedog writes none of its outputs there."""
    scene = enclosing_scene(path)
    if scene is not None:
        raise OutputError(path, f"lies inside the scene folder {scene}; edgedog never writes into a scene "
                                "folder: choose a path outside it")


def check_new_run_folder(path: Path) -> None:
    """A new run may go into `path` only when it does not exist or is an empty folder outside any
    scene folder: never into another run (that is `--resume`'s job) nor into a folder of someone
    else's files."""
    path = Path(path)
    check_outside_scenes(path)
    if not path.exists():
        if path.is_symlink():
            raise InputError(path, "is a broken symbolic link; choose another folder")
        return
    if not path.is_dir():
        raise InputError(path, "is a file, not a folder; choose a new or empty folder")
    if is_run_folder(path):
        raise InputError(path, "already holds a run; pass --resume to continue it, or choose another folder")
    try:
        entries = [entry.name for entry in os.scandir(path) if entry.name != LOCK_FILE]
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if entries:
        holder = lock_holder(path)
        if holder not in (None, str(os.getpid())):  # a writer has just made it, its run not yet recorded
            raise InputError(path, f"is in use by another edgedog process (pid {holder}); wait for it "
                                   "to finish or choose another folder")
        raise InputError(path, "is not empty and is not an edgedog run folder; choose a new or empty folder")


def lock_holder(path: Path) -> str | None:
    """The pid in `path`'s lock file while another process holds that lock ("unknown" when it
    wrote none), else None; takes no lock and creates nothing."""
    try:
        fd = os.open(path / LOCK_FILE, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)  # released when fd closes
    except OSError as exc:
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
            return os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
        return None
    finally:
        os.close(fd)
    return None


def config_digest(config: TrainConfig) -> str:
    """Eight hex digits naming a configuration: a default run folder named with them never meets a
    run that another version's defaults made (a reused folder must hold the very same run)."""
    return hashlib.sha256(json.dumps(to_dict(config), sort_keys=True).encode()).hexdigest()[:8]


def differ(recorded: str | None, current: str | None) -> bool:
    """Whether two fingerprints tell two contents apart (None: a run written before it was recorded)."""
    return None not in (recorded, current) and recorded != current


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except OSError:
        return False


class RunLock:
    """An exclusive lock on a folder we write (a run, a benchmark's output): one writer at a time.

    An advisory `flock` on `<folder>/.edgedog.lock`, which holds the owner's process id for the
    message a second writer gets. The kernel drops the lock when its process ends, however it
    ends (kill -9 too), so a killed run never leaves its folder locked.
    """

    def __init__(self, path: Path, fd: int):
        self.path, self._fd = path, fd

    @classmethod
    def acquire(cls, path: str | Path) -> RunLock:
        """Lock `path` (created if missing); InputError naming it when another writer holds it."""
        path = Path(path)
        create_folder(path)
        try:
            fd = os.open(path / LOCK_FILE, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        except OSError as exc:
            raise InputError(path, f"cannot be used as an output folder ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            owner = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise InputError(path, f"is in use by another edgedog process (pid {owner}); wait for it "
                                       "to finish or choose another folder") from None
            raise InputError(path, f"cannot be locked ({exc.strerror})") from None
        if not _same_file(fd, path / LOCK_FILE):  # its holder discarded it while we waited
            os.close(fd)
            raise InputError(path, "was just given up by another edgedog process; run the command again")
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        remove_stale_temporaries(path)  # a writer killed mid-write (kill -9) left its temporary file
        return cls(path, fd)

    def release(self) -> None:
        """Unlock (closing the file drops the lock); a second call does nothing."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def discard(self, remove_folder: bool = False) -> None:
        """Remove the lock file, and the folder too when `remove_folder` and nothing else is in it,
        then unlock: what a writer refused before writing anything leaves behind is nothing. A
        writer that opened the lock file meanwhile finds it gone once locked (`acquire`)."""
        (self.path / LOCK_FILE).unlink(missing_ok=True)
        if remove_folder:
            with contextlib.suppress(OSError):  # not empty: someone else's files came meanwhile
                self.path.rmdir()
        self.release()

    def __enter__(self) -> RunLock:
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()
