"""A bounds check of COLMAP's binary model files before pycolmap reads them.

pycolmap's binary reader trusts the counts a file declares: a damaged or crafted `images.bin`
or `frames.bin` whose count reads as 2**64 - 1 keeps it looping past the end of the file for
ever (C++ code, which no Python signal interrupts). This walks each file's records as COLMAP
writes them (cameras, images, points3D, rigs, frames; little-endian) and refuses, in one line
naming the file, a count that more bytes than the file holds would be needed for, an unknown
camera model or a file that ends inside a record. It reads no values beyond those.
"""

from __future__ import annotations

import struct
from pathlib import Path

from edgedog.errors import InputError

CAMERA_PARAMS = {0: 3, 1: 4, 2: 4, 3: 5, 4: 8, 5: 8, 6: 12, 7: 5, 8: 4, 9: 5, 10: 12, 11: 16, 12: 4, 13: 5,
                 14: 3, 15: 4, 16: 6, 17: 2}
"""COLMAP camera model id -> its number of parameters (pycolmap 4.x)."""
POSE = "7d"  # a rigid transform: quaternion and translation


class _Records:
    """A cursor over one binary model file that never reads or skips past its end."""

    def __init__(self, path: Path):
        self.path, self.data, self.at = path, path.read_bytes(), 0

    def take(self, layout: str) -> tuple:
        layout = "<" + layout
        size = struct.calcsize(layout)
        self._need(size)
        values = struct.unpack_from(layout, self.data, self.at)
        self.at += size
        return values

    def count(self, layout: str, record_bytes: int, what: str) -> int:
        """A declared count of records of at least `record_bytes` each, checked against the rest."""
        (number,) = self.take(layout)
        return self.bounded(number, record_bytes, what)

    def bounded(self, number: int, record_bytes: int, what: str) -> int:
        """`number` records of at least `record_bytes` each, checked against the rest of the file."""
        left = len(self.data) - self.at
        if number * record_bytes > left:
            raise InputError(self.path, f"declares {number} {what}, more than its remaining {left} bytes "
                                        "hold (a damaged binary model)")
        return number

    def skip(self, size: int) -> None:
        self._need(size)
        self.at += size

    def name(self) -> None:
        end = self.data.find(b"\0", self.at)
        if end < 0:
            raise InputError(self.path, "ends inside an image name (a damaged binary model)")
        self.at = end + 1

    def _need(self, size: int) -> None:
        if self.at + size > len(self.data):
            raise InputError(self.path, f"ends early, at byte {len(self.data)} (a damaged binary model)")


def _cameras(records: _Records) -> None:
    for _ in range(records.count("Q", 24, "cameras")):
        _, model, _, _ = records.take("iiQQ")
        if model not in CAMERA_PARAMS:
            raise InputError(records.path, f"unknown camera model id {model}")
        records.skip(8 * CAMERA_PARAMS[model])


def _images(records: _Records) -> None:
    for _ in range(records.count("Q", 73, "images")):
        records.take("I" + POSE + "I")
        records.name()
        records.skip(24 * records.count("Q", 24, "2D points"))


def _points(records: _Records) -> None:
    for _ in range(records.count("Q", 51, "3D points")):
        records.take("Q3d3Bd")
        records.skip(8 * records.count("Q", 8, "track elements"))


def _rigs(records: _Records) -> None:
    for _ in range(records.count("Q", 8, "rigs")):
        _, sensors = records.take("II")
        if sensors:
            records.take("iI")  # the reference sensor
            for _ in range(records.bounded(sensors - 1, 9, "sensors")):
                *_, has_pose = records.take("iIB")
                if has_pose:
                    records.take(POSE)


def _frames(records: _Records) -> None:
    for _ in range(records.count("Q", 68, "frames")):
        records.take("II" + POSE)
        records.skip(16 * records.count("I", 16, "data ids"))


CHECKS = {"cameras.bin": _cameras, "images.bin": _images, "points3D.bin": _points, "rigs.bin": _rigs,
          "frames.bin": _frames}


def check_binary_model(folder: Path) -> None:
    """Refuse, with an InputError naming the file, a binary model file in `folder` whose
    declared counts or records do not fit in it."""
    for name, check in CHECKS.items():
        path = folder / name
        if path.is_file():
            try:
                check(_Records(path))
            except OSError as error:
                raise InputError(path, f"cannot be read ({error.strerror or error})") from None
