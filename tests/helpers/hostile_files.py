"""Crafted files of the hostile-case table (tests/test_hostile_cases.py): each function writes one
kind of bad file the way ../shared/reports/hostile-cases.md made it (a crafted checkpoint, a PNG
whose header lies, a PLY claiming 10**11 rows, a file that is a FIFO or /dev/zero ...)."""

from __future__ import annotations

import json
import os
import pickle
import re
import struct
import zipfile
import zlib
from pathlib import Path

import cv2
import numpy as np

SPECIAL = ("/dev/zero", "/dev/urandom", "/etc/passwd")
"""Contents that replace a file by a symlink to that path (a device or another's file)."""


def place(path: Path, content) -> Path:
    """`path` made to hold `content`: bytes or str; "FIFO", "DIR" (a folder), "MISSING" (removed),
    "SPARSE" (a 65 MiB file of zeros, past the readers' 64 MiB cap) or one of SPECIAL (a symlink)."""
    if path.is_symlink() or path.is_file():
        path.unlink()
    if content == "MISSING":
        return path
    if content == "FIFO":
        os.mkfifo(path)
    elif content == "DIR":
        path.mkdir()
    elif content == "SPARSE":
        with open(path, "wb") as sparse:
            sparse.truncate(65 * 2**20)
    elif content in SPECIAL:
        path.symlink_to(content)
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


class CodeInPickle:
    """Unpickling this runs os.system: a crafted pickle's payload (it never may run)."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def checkpoint(path: Path, kind: str) -> None:
    """Replace the run's checkpoint at `path` by the report's crafted checkpoint `kind`."""
    import torch

    real = path.read_bytes()
    marker = path.parent.parent / "PWNED"
    if kind == "rce_raw":
        path.write_bytes(pickle.dumps({"model": CodeInPickle(marker)}))
    elif kind == "rce_zip":
        torch.save({"format": "edgedog-checkpoint", "model": CodeInPickle(marker)}, path)
    elif kind == "zip_trav":
        with zipfile.ZipFile(path, "w") as archive:
            archive.writestr("../../../../TRAV_written", b"x")
            archive.writestr("archive/data.pkl", pickle.dumps({}))
    elif kind == "trunc":
        path.write_bytes(real[: len(real) // 2])
    elif kind == "hugestorage":
        storage_claiming(path, 2**31 - 1)
    elif kind in ("empty", "random"):
        path.write_bytes(b"" if kind == "empty" else np.random.default_rng(0).bytes(4096))
    else:
        state = torch.load(path, weights_only=True)
        edit_state(state, kind)
        torch.save(state, path)


def storage_claiming(path: Path, count: int) -> None:
    """A checkpoint whose one tensor's storage header claims `count` elements (8 GiB of floats at
    2**31 - 1) while its record holds 16 bytes."""
    import torch

    torch.save({"format": "edgedog-checkpoint", "model": {"means": torch.zeros(4)}}, path)
    with zipfile.ZipFile(path) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    pickled = next(name for name in entries if name.endswith("data.pkl"))
    # the storage's persistent id ends ('storage', FloatStorage, '0', 'cpu', 4): its 4, BININT1
    entries[pickled], found = re.subn(rb"(?s)(cpuq.)K\x04t",
        lambda match: match[1] + b"J" + struct.pack("<i", count)
                                      + b"t", entries[pickled])
    assert found == 1
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in entries.items():
            archive.writestr(name, data)


def edit_state(state: dict, kind: str) -> None:
    """A checkpoint's state changed as the report's `kind` changed it."""
    import torch

    model = state["model"]
    if kind == "hugetensor":  # a 10**12-element view of one float: 4 bytes on disk
        model["means"] = torch.zeros(1).expand(1_000_000, 1_000_000)
    elif kind == "nanmeans":
        model["means"] = torch.full_like(model["means"], float("nan"))
    elif kind == "shape":
        model["log_scales"] = torch.zeros(model["log_scales"].shape[0] + 7, 3)
    elif kind == "optbad":
        state["optimizers"] = {"means": "not a state"}
    elif kind == "genbad":
        state["generator"] = torch.zeros(3, dtype=torch.uint8)
    elif kind == "histbad":
        state["history"] = [{"epoch": "x"}, 5, None]
    else:  # stepneg, stepstr, stephuge
        state["step_index"] = {"stepneg": -5, "stepstr": "12", "stephuge": 10**9}[kind]


def edited_json(path: Path, edit) -> None:
    """`path`'s JSON changed in place by `edit(data)` (NaN and 1e308 written as given)."""
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))


def png_declaring(path: Path, width: int, height: int) -> None:
    """`path` replaced by a small PNG whose header says width x height (a decompression bomb's)."""
    data = bytearray(path.read_bytes())
    ihdr = struct.pack(">II", width, height) + bytes(data[24:29])
    data[16:29] = ihdr
    data[29:33] = struct.pack(">I", zlib.crc32(b"IHDR" + bytes(ihdr)))
    path.write_bytes(bytes(data))


def zero_png(path: Path, side: int) -> bytes:
    """A side x side all-black PNG (121 MP at 11000 px in about 470 KB)."""
    ok, encoded = cv2.imencode(".png", np.zeros((side, side), np.uint8))
    assert ok
    path.write_bytes(encoded.tobytes())
    return encoded.tobytes()


def ply_header(vertices, *, binary: bool = False, edges=None, props: str = "xyz") -> str:
    """A PLY header of `vertices` rows (any text) with float properties `props`, and edges."""
    form = "binary_little_endian" if binary else "ascii"
    lines = ["ply", f"format {form} 1.0", f"element vertex {vertices}",
             *(f"property float {name}" for name in props)]
    if edges is not None:
        lines += [f"element edge {edges}", "property int vertex1", "property int vertex2"]
    return "\n".join([*lines, "end_header"]) + "\n"


def obj_of_lines(count: int, length: float) -> str:
    """`count` parallel lines of `length` units as OBJ text."""
    vertices = "".join(f"v 0 {i * 0.01:.3f} 0\nv {length} {i * 0.01:.3f} 0\n" for i in range(count))
    return vertices + "".join(f"l {2 * i + 1} {2 * i + 2}\n" for i in range(count))


def colmap_as_binary(root: Path) -> Path:
    """The COLMAP project `root` (tests/helpers/scene_builders.make_colmap) with its text model
    rewritten as COLMAP's binary files; returns the model's folder."""
    import pycolmap

    model = root / "sparse" / "0"
    reconstruction = pycolmap.Reconstruction(str(model))
    for path in model.iterdir():
        path.unlink()
    reconstruction.write_binary(str(model))
    return model
