"""Ground truth from a B-rep: its sharp edges, as exact curves.

An edge is sharp where the two faces that meet there are not tangent: at some of CHECKS points
along it their outward normals differ by more than SHARP_ANGLE (the dihedral angle departs from
180 degrees by that much). Fillets and other tangent seams are not sharp, nor is the seam where
a closed surface meets itself (a cylinder's), as ABC's `sharp` flag has it. Convex and concave
edges count alike; each curve records which it is (`dihedral_sign`).
"""

from __future__ import annotations

import numpy as np
from build123d import Shape
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve, BRepAdaptor_Curve2d
from OCP.BRepGProp import BRepGProp_Face
from OCP.collections import IndexedDataMap_TopoDS_Shape_List_TopoDS_Shape_TopTools_ShapeMapHasher as EdgeFaces
from OCP.GCPnts import GCPnts_AbscissaPoint, GCPnts_UniformAbscissa
from OCP.GeomAbs import GeomAbs_Circle, GeomAbs_Line
from OCP.gp import gp_Pnt, gp_Vec
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_REVERSED
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Edge, TopoDS_Face

from edgedog.synthetic.features import Arc, Curve, Line, Traced

SHARP_ANGLE = 20.0
"""Degrees: faces whose normals turn by more than this across an edge make it sharp."""
CHECKS = 5
"""Points along each edge (equal parameter steps, ends left out) where the normals are compared."""
TRACE_STEP = 0.0002
"""World units (0.2 mm on a normalised part) between the kernel's points on a traced curve."""


def edge_faces(shape: Shape) -> list[tuple[TopoDS_Edge, list[TopoDS_Face]]]:
    """Every edge of `shape` (degenerate ones, such as a cone's apex, left out) with the distinct
    faces that meet there: two on a manifold solid, one on a seam."""
    table = EdgeFaces()
    TopExp.MapShapesAndAncestors_s(shape.wrapped, TopAbs_EDGE, TopAbs_FACE, table)
    result = []
    for index in range(1, table.Extent() + 1):
        edge = TopoDS.Edge(table.FindKey(index))
        if BRep_Tool.Degenerated_s(edge):
            continue
        faces: list[TopoDS_Face] = []
        for face in table.FindFromIndex(index):
            if not any(face.IsSame(other) for other in faces):
                faces.append(TopoDS.Face(face))
        result.append((edge, faces))
    return result


def turn_angle(edge: TopoDS_Edge, first: TopoDS_Face, second: TopoDS_Face) -> float:
    """Largest angle (degrees) between the two faces' outward normals at CHECKS points of `edge`."""
    curve = BRepAdaptor_Curve(edge)
    steps = curve.FirstParameter() + (np.arange(CHECKS) + 0.5) / CHECKS * (curve.LastParameter() -
                                                                           curve.FirstParameter())
    normals = []
    for face in (first, second):
        on_face, surface = BRepAdaptor_Curve2d(edge, face), BRepGProp_Face(face)
        row = []
        for t in steps:
            uv, point, normal = on_face.Value(float(t)), gp_Pnt(), gp_Vec()
            surface.Normal(uv.X(), uv.Y(), point, normal)
            row.append((normal.X(), normal.Y(), normal.Z()))
        normals.append(np.array(row))
    a, b = normals
    lengths = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
    usable = lengths > 1e-12  # singular points (a cone's tip) have no normal
    if not usable.any():
        return 0.0
    cos = np.einsum("ij,ij->i", a[usable], b[usable]) / lengths[usable]
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max())


def _normal_and_inward(edge: TopoDS_Edge, face: TopoDS_Face, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(3,) outward normal of `face` at parameter `t` of `edge`, and (3,) the direction into the
    face across the edge: the kernel orients each face's boundary with the face on its left seen
    from outside, so it is normal x (the edge's tangent as the face runs it)."""
    explorer, reversed_here = TopExp_Explorer(face, TopAbs_EDGE), False
    while explorer.More():
        if explorer.Current().IsSame(edge):
            reversed_here = explorer.Current().Orientation() == TopAbs_REVERSED
            break
        explorer.Next()
    point, tangent = gp_Pnt(), gp_Vec()
    BRepAdaptor_Curve(edge).D1(t, point, tangent)
    uv, normal = BRepAdaptor_Curve2d(edge, face).Value(t), gp_Vec()
    BRepGProp_Face(face).Normal(uv.X(), uv.Y(), point, normal)
    outward = _xyz(normal)
    return outward, np.cross(outward, -_xyz(tangent) if reversed_here else _xyz(tangent))


def dihedral_sign(edge: TopoDS_Edge, first: TopoDS_Face, second: TopoDS_Face) -> str:
    """"convex" where the first face, followed across `edge`, runs against the second face's
    outward normal (the material's wedge is under 180 degrees), "concave" otherwise; taken at
    CHECKS points along the edge, the sum of the signs decides."""
    curve = BRepAdaptor_Curve(edge)
    first_t, last_t = curve.FirstParameter(), curve.LastParameter()
    total = 0.0
    for t in first_t + (np.arange(CHECKS) + 0.5) / CHECKS * (last_t - first_t):
        _, inward = _normal_and_inward(edge, first, float(t))
        outward, _ = _normal_and_inward(edge, second, float(t))
        total += np.sign(float(inward @ outward))
    return "convex" if total < 0 else "concave"


def as_curve(edge: TopoDS_Edge, dihedral: str = "unknown") -> Curve:
    """The edge's exact curve: a Line, an Arc, or for any other type the kernel's points on it,
    with the sign of its dihedral angle (a `features.DIHEDRALS` name)."""
    curve = BRepAdaptor_Curve(edge)
    first, last = curve.FirstParameter(), curve.LastParameter()
    kind = curve.GetType()
    if kind == GeomAbs_Line:
        return Line(_xyz(curve.Value(first)), _xyz(curve.Value(last)), dihedral)
    if kind == GeomAbs_Circle:
        circle = curve.Circle()
        axes, radius = circle.Position(), circle.Radius()
        return Arc(_xyz(axes.Location()), radius * _xyz(axes.XDirection()), radius * _xyz(axes.YDirection()),
                   first, last, dihedral)
    length = GCPnts_AbscissaPoint.Length_s(curve)
    spacing = GCPnts_UniformAbscissa(curve, max(2, int(np.ceil(length / TRACE_STEP)) + 1), first, last)
    points = np.array([_xyz(curve.Value(spacing.Parameter(i))) for i in range(1, spacing.NbPoints() + 1)])
    return Traced(kind.name.removeprefix("GeomAbs_").lower().replace("curve", ""), points, dihedral)


def sharp_curves(shape: Shape) -> list[Curve]:
    """The curves of the sharp edges of `shape`, in the kernel's order of its edges, each with
    its dihedral sign."""
    return [as_curve(edge, dihedral_sign(edge, *faces)) for edge, faces in edge_faces(shape)
            if len(faces) == 2 and turn_angle(edge, *faces) > SHARP_ANGLE]


def _xyz(point) -> np.ndarray:
    return np.array([point.X(), point.Y(), point.Z()])
