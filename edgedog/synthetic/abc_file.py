"""An ABC object as ABC distributes it, a mesh (.obj) and its features file (.yml), as a Part.

The mesh is drawn as it is, with its own corner normals (ABC splits them along sharp edges).
Its ground truth is the protocol's (../shared/data/README.md, `edgedog.groundtruth`): every
segment of each `sharp` feature curve sampled every 0.005 raw units. The object is normalised
by the bounding box of its mesh's vertices; ABC-NEF's stats.json pads that box by about 0.01 %.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from edgedog.errors import InputError
from edgedog.groundtruth import GT_SPACING, check_sample_count, read_obj_vertices, sharp_polylines
from edgedog.synthetic.features import Line
from edgedog.synthetic.mesh import Mesh
from edgedog.synthetic.shapes import Part


def read_obj_triangles(path: Path, vertices: np.ndarray) -> Mesh:
    """The triangles (`f` records, 1-based `v`, `v//vn` or `v/vt/vn` corners) of a Wavefront OBJ
    whose vertices are `vertices` (V, 3), with its `vn` normals, or each facet's own without them."""
    normals, faces = [], []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("vn "):
            normals.append(line.split()[1:4])
        elif line.startswith("f "):
            faces.append([corner.split("/") for corner in line.split()[1:]])
    if not faces:
        raise InputError(path, "no faces (`f` records): not a mesh")
    if any(len(face) != 3 for face in faces):
        raise InputError(path, "a face that is not a triangle: only triangle meshes are read")
    shaded = normals and all(len(corner) == 3 and corner[2] for face in faces for corner in face)
    try:
        positions = np.array([[int(corner[0]) for corner in face] for face in faces]) - 1
        corner_normals = np.array([[int(c[2]) for c in face] for face in faces]) - 1 if shaded else None
        unit = np.array(normals, dtype=np.float64) if shaded else None
    except ValueError:
        raise InputError(path, "malformed face or normal record") from None
    if positions.min() < 0 or positions.max() >= len(vertices):
        raise InputError(path, "a face refers to a vertex that is not there")
    corners = vertices[positions]  # (T, 3, 3)
    if corner_normals is None:
        facet = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        unit, corner_normals = facet, np.repeat(np.arange(len(facet))[:, None], 3, axis=1)
    if corner_normals.min() < 0 or corner_normals.max() >= len(unit):
        raise InputError(path, "a face refers to a normal that is not there")
    length = np.linalg.norm(unit, axis=1, keepdims=True)
    if not np.all(np.isfinite(unit)) or not np.all(length > 0):
        raise InputError(path, "normals of zero length, NaN or infinite")
    return Mesh(corners, (unit / length)[corner_normals])


def abc_part(obj: str | Path, features: str | Path) -> Part:
    """The ABC object of mesh `obj` and features file `features`, normalised into [0, 1]^3 by the
    mesh's bounding box; its curves are the sharp curves' segments."""
    obj, features = Path(obj), Path(features)
    vertices = read_obj_vertices(obj)
    polylines = sharp_polylines(vertices, features, obj)
    check_sample_count(polylines, features)
    lo, hi = vertices.min(0), vertices.max(0)
    if not (hi - lo).max() > 0:
        raise InputError(obj, "has no extent (all its vertices coincide)")
    scale = 1.0 / float((hi - lo).max())
    offset = 0.5 - (lo + hi) / 2 * scale
    mesh = read_obj_triangles(obj, vertices)
    mesh = Mesh(mesh.positions * scale + offset, mesh.normals)
    curves = tuple(Line(a * scale + offset, b * scale + offset)
                   for line in polylines for a, b in zip(line[:-1], line[1:]))
    dimensions = dict(zip(("width", "depth", "height"), ((hi - lo) * scale).round(6).tolist()))
    return Part(obj.name, dimensions, mesh, curves, None, spacing=GT_SPACING * scale)
