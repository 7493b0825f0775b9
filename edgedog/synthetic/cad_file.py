"""Reading a user's CAD file (STEP or BREP) into one checked solid of the CAD kernel.

Whatever is wrong with the file is one InputError naming it: not readable, empty, no closed
solid, not manifold, invalid geometry, no length unit, or too big to be a part.
"""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

import numpy as np
from build123d import Compound, Shape
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepTools import BRepTools
from OCP.collections import Sequence_TCollection_AsciiString
from OCP.IFSelect import IFSelect_RetDone
from OCP.Message import Message
from OCP.STEPControl import STEPControl_Reader
from OCP.TopoDS import TopoDS_Shape

from edgedog.errors import ConfigError, InputError
from edgedog.synthetic.brep import bounds, part_from_solid
from edgedog.synthetic.shapes import Part
from edgedog.synthetic.sharp import edge_faces

STEP_SUFFIXES, BREP_SUFFIXES = (".step", ".stp"), (".brep", ".brp")
UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
"""Length units a BREP file (which declares none) may be given in, in millimetres."""
MAX_BYTES = 512 * 2**20
"""Largest file read: ABC's biggest STEP files are tens of MB."""
MAX_FACES = 10_000
"""Most faces of a part: ABC's objects have up to a few thousand."""
MAX_SIZE_MM = 100_000.0
"""Longest side of a part (100 m): beyond it the unit is wrong or it is no part."""


@contextlib.contextmanager
def _quiet():
    """Silences the kernel's own messages (a bad STEP file prints its parse errors)."""
    messenger = Message.DefaultMessenger_s()
    printers = list(messenger.Printers())
    for printer in printers:
        messenger.RemovePrinter(printer)
    try:
        yield
    finally:
        for printer in printers:
            messenger.AddPrinter(printer)


def cad_part(path: str | Path, unit: str | None = None) -> Part:
    """The part of a STEP or BREP file (`read_cad`), normalised like an ABC object.

    Its dimensions: width, depth and height of its bounding box in ground-truth units, and
    `unit_mm`, the length of one ground-truth unit (the part's longest side) in millimetres.
    """
    path = Path(path)
    shape, mm = read_cad(path, unit)
    lo, hi = bounds(shape)
    part = part_from_solid(path.name, shape, dict(zip(("width", "depth", "height"), (hi - lo).tolist())))
    if not part.curves:
        raise InputError(path, "has no sharp edges (its faces all meet tangentially): nothing to score")
    return dataclasses.replace(part, dimensions=part.dimensions | {"unit_mm": float((hi - lo).max() * mm)})


def read_cad(path: str | Path, unit: str | None = None) -> tuple[Shape, float]:
    """The solid(s) of a STEP or BREP file, checked.

    Args:
        unit: the length unit (a key of UNITS_MM) of a file that declares none: a BREP file,
            or a STEP file without units. A STEP file that declares its unit takes none.
    Returns:
        the shape (a build123d Compound of solids), and millimetres per unit of its coordinates.
    """
    path = Path(path)
    if unit is not None and unit not in UNITS_MM:
        raise ConfigError(f"--unit {unit}: choose from {', '.join(UNITS_MM)}")
    if not path.is_file():
        raise InputError(path, "file not found")
    suffix = path.suffix.lower()
    if suffix not in STEP_SUFFIXES + BREP_SUFFIXES:
        raise InputError(path, f"not a CAD file this reads: STEP ({', '.join(STEP_SUFFIXES)}) or BREP "
                               f"({', '.join(BREP_SUFFIXES)})")
    size = path.stat().st_size
    if size == 0:
        raise InputError(path, "empty file")
    if size > MAX_BYTES:
        raise InputError(path, f"{size / 2**20:.0f} MB, over {MAX_BYTES // 2**20} MB: too big for a part")
    with _quiet():
        if suffix in STEP_SUFFIXES:
            shape, mm = _read_step(path, unit)
        else:
            shape, mm = _read_brep(path), _brep_unit(path, unit)
    check_solid(path, shape, mm)
    return Compound(shape), mm


def _read_step(path: Path, unit: str | None) -> tuple[TopoDS_Shape, float]:
    """The STEP file's shape, and millimetres per unit of its coordinates: 1 where the file
    declares its unit (the kernel converts into millimetres), else the given `unit`'s."""
    reader = STEPControl_Reader()
    if reader.ReadFile(str(path)) != IFSelect_RetDone:
        raise InputError(path, "not a readable STEP file")
    lengths = Sequence_TCollection_AsciiString()
    reader.FileUnits(lengths, Sequence_TCollection_AsciiString(), Sequence_TCollection_AsciiString())
    declared = {lengths.Value(i).ToCString() for i in range(1, lengths.Length() + 1)} - {""}
    if not declared and unit is None:
        raise InputError(path, "declares no length unit (a unit-less STEP file); say which with --unit "
                               f"{'|'.join(UNITS_MM)}")
    if declared and unit is not None:
        raise InputError(path, f"declares its length unit ({', '.join(sorted(declared))}); leave out --unit")
    reader.TransferRoots()
    shape = reader.OneShape()
    if shape.IsNull():
        raise InputError(path, "holds no shape (empty)")
    return shape, 1.0 if declared else UNITS_MM[unit]


def _read_brep(path: Path) -> TopoDS_Shape:
    shape = TopoDS_Shape()
    if not BRepTools.Read_s(shape, str(path), BRep_Builder()) or shape.IsNull():
        raise InputError(path, "not a readable BREP file")
    return shape


def _brep_unit(path: Path, unit: str | None) -> float:
    if unit is None:
        raise InputError(path, f"BREP files declare no unit; say which with --unit {'|'.join(UNITS_MM)}")
    return UNITS_MM[unit]


def check_solid(path: Path, shape: TopoDS_Shape, mm: float) -> None:
    """InputError unless `shape` is one or more valid, closed, manifold solids of a part's size."""
    whole = Shape.cast(shape)
    faces, solids = whole.faces(), whole.solids()
    if not faces:
        raise InputError(path, "holds no faces (empty)")
    if not solids:
        raise InputError(path, f"holds no solid, only {len(faces)} face(s): a scene needs a closed solid")
    if len(faces) > MAX_FACES:
        raise InputError(path, f"{len(faces)} faces, more than {MAX_FACES:,}: too big for one part")
    if sum(len(solid.faces()) for solid in solids) != len(faces):
        raise InputError(path, "holds faces outside its solids: a scene needs closed solids only")
    # A seam (a closed surface meeting itself) bounds one face from both sides: that is manifold.
    open_or_shared = sum(1 for edge, around in edge_faces(whole) if len(around) > 2
                         or (len(around) == 1 and not BRep_Tool.IsClosed_s(edge, around[0])))
    if open_or_shared:
        raise InputError(path, f"not manifold: {open_or_shared} edge(s) bound one face only or more than two")
    if not whole.is_valid:
        raise InputError(path, "the CAD kernel finds its geometry invalid (BRepCheck)")
    box = whole.bounding_box(optimal=True)
    side = float(np.max(tuple(box.max - box.min))) * mm
    if not side > 1e-6:
        raise InputError(path, "has no extent (all its points coincide)")
    if side > MAX_SIZE_MM:
        raise InputError(path, f"{side / 1000:.3g} m long, more than {MAX_SIZE_MM / 1000:.0f} m: "
                               "not a part, or not in the unit it declares")
