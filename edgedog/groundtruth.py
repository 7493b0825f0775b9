"""Ground-truth 3D edge points of ABC objects, by the protocol published results use, and the
providers that find them beside a scene (`ground_truth_for`).

Two sources: the CAD model (mesh .obj + feature curves .yml + bbox stats .json), resampled
here, or a pre-sampled point .ply (EMAP's `sampled_pts/<id>_0.005.ply`). Points are in the
ground-truth frame: the object normalised into [0, 1]^3, where 1 unit = 1000 "mm".

The curves themselves, with an identity (`GroundTruthCurve`: id, type, dihedral sign), come from
the features file (`abc_curves`): through the mesh where there is one, which also gives each
curve's dihedral sign, and otherwise from the file's own line and circle parameters.
"""

from __future__ import annotations

import abc
import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from plyfile import PlyData

from edgedog.errors import InputError
from edgedog.files import read_json, read_yaml
from edgedog.metrics import MAX_SAMPLES, sample_count, sample_line

GT_SPACING = 0.005
"""Resampling step along each feature curve, in raw CAD units (the protocol's value)."""
CURVE_TYPES = {"Line": "line", "Circle": "circle", "Ellipse": "ellipse", "BSpline": "bspline"}
"""ABC's curve types -> the names reports use; any other type is "other"."""


@dataclass(frozen=True)
class GroundTruthSource:
    """Where a scene's ground truth comes from; `load()` builds the points once.

    Attributes:
        scan_id: the ABC object id, e.g. "00000006".
        sampled_ply: a pre-sampled point cloud, used when present.
        obj, features, stats: the CAD files, used otherwise; beside a sampled_ply, those found
            (the features and stats without the mesh in EMAP's copy) give the curves' identity.
    """

    scan_id: str
    sampled_ply: Path | None = None
    obj: Path | None = None
    features: Path | None = None
    stats: Path | None = None

    @property
    def description(self) -> str:
        if self.sampled_ply is not None:
            return f"sampled points {self.sampled_ply.name}"
        return f"CAD curves {self.features.name}"

    def load(self) -> np.ndarray:
        """(N, 3) float64 ground-truth edge points in the ground-truth frame."""
        return _load_cached(self)


@functools.lru_cache(maxsize=8)
def _load_cached(source: GroundTruthSource) -> np.ndarray:
    if source.sampled_ply is not None:
        points = read_points_ply(source.sampled_ply)
    else:
        points = abc_points_from_cad(source.obj, source.features, source.stats, source.scan_id)
    points.flags.writeable = False  # shared by every caller of the cache
    return points


def read_points_ply(path: Path) -> np.ndarray:
    """(N, 3) float64 vertex positions of a point-cloud PLY."""
    try:
        vertex = PlyData.read(str(path))["vertex"]
        points = np.stack([vertex["x"], vertex["y"], vertex["z"]], axis=1).astype(np.float64)
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except Exception as exc:  # plyfile raises several types for malformed files
        raise InputError(path, f"not a readable point-cloud PLY ({exc})") from None
    if not np.all(np.isfinite(points)):
        raise InputError(path, "points contain NaN or Inf")
    return points


def read_obj_vertices(path: Path) -> np.ndarray:
    """(V, 3) float64 vertices (`v` records) of a Wavefront OBJ, in file order (0-based)."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except UnicodeDecodeError:
        raise InputError(path, "not a text OBJ file") from None
    rows = [line.split()[1:4] for line in lines if line.startswith("v ")]
    try:
        vertices = np.array(rows, dtype=np.float64)
    except ValueError:
        raise InputError(path, "malformed vertex record") from None
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(path, "no vertices with three coordinates")
    if not np.all(np.isfinite(vertices)):
        raise InputError(path, "vertices contain NaN or Inf")
    return vertices


def normalisation(stats_path: Path, scan_id: str) -> tuple[float, np.ndarray]:
    """Scale s and offset o with gt = raw * s + o, from the object's bbox statistics.

    The renders put the object in [0, 1]^3: s = 1 / max(range), o = 0.5 - center * s.
    """
    stats = read_json(stats_path)
    if scan_id not in stats or "bbox" not in stats[scan_id]:
        raise InputError(stats_path, f"no bbox for object {scan_id}")
    try:
        bbox = np.asarray(stats[scan_id]["bbox"], dtype=np.float64).reshape(9)
    except (TypeError, ValueError):
        raise InputError(stats_path, f"bbox of object {scan_id} is not 9 numbers") from None
    lo, hi, ranges = bbox[0:3], bbox[3:6], bbox[6:9]
    if not (np.all(np.isfinite(bbox)) and ranges.max() > 0):
        raise InputError(stats_path, f"bbox of object {scan_id} is not finite with a positive range")
    scale = 1.0 / ranges.max()
    return scale, 0.5 - (lo + hi) / 2 * scale


def resample_polyline(vertices: np.ndarray, spacing: float = GT_SPACING) -> np.ndarray:
    """The protocol's curve resampling, segment by segment.

    Each segment gets floor(|b - a| / spacing) points with both ends included (segments
    shorter than `spacing` contribute nothing), exactly as predicted lines are sampled.

    Args:
        vertices: (M, 3) curve vertices in order.
    Returns:
        (N, 3) samples.
    """
    pieces = [sample_line(a, b, spacing) for a, b in zip(vertices[:-1], vertices[1:])]
    return np.concatenate(pieces) if pieces else np.zeros((0, 3))


def abc_points_from_cad(obj: Path, features: Path, stats: Path, scan_id: str) -> np.ndarray:
    """Sample the sharp feature curves of an ABC object into ground-truth points.

    Returns:
        (N, 3) float64 points in the ground-truth frame.
    """
    polylines = sharp_polylines(read_obj_vertices(obj), features, obj)
    check_sample_count(polylines, features)
    samples = [resample_polyline(p) for p in polylines]
    scale, offset = normalisation(stats, scan_id)
    return np.concatenate(samples) * scale + offset


def check_sample_count(polylines: list[np.ndarray], features: Path) -> None:
    """InputError when the (M, 3) polylines of `features` would be sampled into more than
    MAX_SAMPLES points: no ABC object's curves are that long."""
    count = sum(sample_count(np.linalg.norm(np.diff(p, axis=0), axis=1)) for p in polylines)
    if count > MAX_SAMPLES:
        raise InputError(features, f"its sharp curves would be sampled into {count:.3g} points, more than "
                                   f"{MAX_SAMPLES:,}: not an ABC object's curves")


def sharp_polylines(vertices: np.ndarray, features: Path, obj: Path) -> list[np.ndarray]:
    """The sharp curves of an ABC features file, each as its (M, 3) polyline through `vertices`
    (V, 3), the vertices of the mesh file `obj` it indexes."""
    curves = _sharp_curves(_feature_curves(features), features)
    polylines = [vertices[_indices(curve, number, len(vertices), features, obj)] for number, curve in curves]
    if not polylines:
        raise InputError(features, "no sharp feature curves")
    return polylines


@functools.lru_cache(maxsize=4)
def _features_document(features: Path) -> dict:
    """An ABC features file, parsed once per process (seconds for a large file); callers must
    not change it."""
    document = read_yaml(features)  # bounded: a deeply nested file crashed the C parser
    if not isinstance(document, dict) or "curves" not in document:
        raise InputError(features, "not an ABC features file (no 'curves')")
    if not isinstance(document["curves"], list):
        raise InputError(features, "'curves' is not a list")
    return document


def _feature_curves(features: Path) -> list:
    """The `curves` list of an ABC features file."""
    return _features_document(features)["curves"]


def _sharp_curves(curves: list, features: Path) -> list[tuple[int, dict]]:
    """(number in the file, record) of each sharp curve of an ABC features file's `curves`."""
    try:
        return [(number, curve) for number, curve in enumerate(curves) if curve.get("sharp", False)]
    except AttributeError:
        raise InputError(features, "a curve is not a mapping") from None


def _indices(curve: dict, number: int, vertex_count: int, features: Path, obj: Path) -> np.ndarray:
    """(M,) vertex indices of one curve record, checked against a mesh of `vertex_count` vertices."""
    try:
        indices = np.asarray(curve["vert_indices"], dtype=np.int64).reshape(-1)
    except (KeyError, TypeError, ValueError):
        raise InputError(features, f"curve {number} has no list of integer vert_indices") from None
    if indices.size and (indices.min() < 0 or indices.max() >= vertex_count):
        raise InputError(features, f"curve {number} indexes vertices outside {obj.name}")
    return indices


@dataclass(frozen=True)
class GroundTruthCurve:
    """One ground-truth curve and its identity, in the ground-truth frame.

    Attributes:
        id: its number: the curve's index in the features file (ABC) or in the scene's curves
            file (a generated scene).
        type: line, circle, ellipse, bspline or other.
        dihedral: convex or concave (the sign of the dihedral angle at the edge: the material's
            wedge under or over 180 degrees), or unknown.
        polyline: (M, 3) vertices along it, no farther apart than the protocol's spacing where
            the curve is not straight.
        wedge: where the dihedral is unknown but the two faces along the curve are, (2, 3) unit
            directions into each face across the curve at its middle (perpendicular to it):
            the material fills the wedge between them (convex) or the rest (concave).
    """

    id: int
    type: str
    dihedral: str
    polyline: np.ndarray
    wedge: np.ndarray | None = None

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.polyline, axis=0), axis=1).sum())


@functools.lru_cache(maxsize=4)
def abc_curves(source: GroundTruthSource) -> list[GroundTruthCurve] | None:
    """The sharp curves of an ABC object with their identity, or None when `source` has no
    features file. With the mesh (`source.obj`): the polylines through its vertices and each
    curve's dihedral sign from the two triangles along it (`mesh_dihedral`). Without it: lines
    and circles from the file's own parameters (`analytic_polyline`; other types are left
    out), dihedral unknown, with the wedge of the faces along it (`face_wedges`). Built once
    per source: callers must not change the list."""
    if source.features is None or source.stats is None:
        return None
    curves = _sharp_curves(_feature_curves(source.features), source.features)
    scale, offset = normalisation(source.stats, source.scan_id)
    if source.obj is not None:
        vertices, faces = read_obj_vertices(source.obj), read_obj_faces(source.obj)
        corners = [_indices(curve, number, len(vertices), source.features, source.obj)
                   for number, curve in curves]
        dihedrals = mesh_dihedrals(vertices, faces, corners)
        polylines = [vertices[indices] for indices in corners]
        wedges = [None] * len(curves)
    else:
        polylines = [analytic_polyline(curve) for _, curve in curves]
        dihedrals = ["unknown"] * len(curves)
        wedges = face_wedges(_features_document(source.features), curves, polylines)
    return [GroundTruthCurve(number, CURVE_TYPES.get(curve.get("type"), "other"), dihedral,
                             line * scale + offset, wedge)
            for (number, curve), line, dihedral, wedge in zip(curves, polylines, dihedrals, wedges)
            if line is not None]


def face_wedges(document: dict, curves: list[tuple[int, dict]],
                polylines: list[np.ndarray | None]) -> list[np.ndarray | None]:
    """For each sharp curve (raw (M, 3) `polylines`, None where unknown), (2, 3) unit directions
    into the two surfaces of the features file that hold two or more of its vertices, at its
    middle, or None. A plane's normal is its `z_axis`, a cylinder's the radial direction from
    its axis; the direction into a face is normal x tangent, turned towards the face's vertices
    nearest the curve across its middle (of those that any line or circle of the file places)."""
    placed: dict[int, np.ndarray] = {}
    for curve in document["curves"]:
        line = analytic_polyline(curve) if isinstance(curve, dict) else None
        if line is not None:
            placed.update(zip(np.asarray(curve["vert_indices"]).reshape(-1).tolist(), line))
    surfaces = [s for s in document.get("surfaces") or [] if isinstance(s, dict)]
    members = [set(np.asarray(s.get("vert_indices", []), dtype=np.int64).reshape(-1).tolist())
               for s in surfaces]
    result: list[np.ndarray | None] = []
    for (_, curve), line in zip(curves, polylines):
        own = set(np.asarray(curve.get("vert_indices", []), dtype=np.int64).reshape(-1).tolist())
        faces = [k for k, m in enumerate(members) if len(own & m) >= 2]
        if line is None or len(faces) != 2:
            result.append(None)
            continue
        middle = len(line) // 2
        point, tangent = line[middle], line[min(middle + 1, len(line) - 1)] - line[max(middle - 1, 0)]
        tangent = tangent / np.linalg.norm(tangent)
        reach = 0.25 * float(np.linalg.norm(line[-1] - line[0]))
        directions = [_into_face(surfaces[k], members[k] - own, placed, point, tangent, reach) for k in faces]
        result.append(None if any(d is None for d in directions) else np.stack(directions))
    return result


def _into_face(surface: dict, vertices: set[int], placed: dict[int, np.ndarray], point: np.ndarray,
               tangent: np.ndarray, reach: float) -> np.ndarray | None:
    """(3,) unit direction into `surface` across a curve at `point` (3,) with unit `tangent`,
    judged by the face's vertices within `reach` of the plane across the curve there (all of
    them where none is), or None (an unknown surface type, no placed vertex of the face)."""
    try:
        axis = np.asarray(surface["z_axis"], dtype=np.float64).reshape(3)
        if surface.get("type") == "Cylinder":
            radial = point - np.asarray(surface["location"], dtype=np.float64).reshape(3)
            axis = radial - axis * (radial @ axis)
        elif surface.get("type") != "Plane":
            return None
    except (KeyError, TypeError, ValueError):
        return None
    across = np.cross(axis, tangent)
    norm = np.linalg.norm(across)
    known = np.array([placed[v] for v in vertices if v in placed]).reshape(-1, 3)
    offsets = known - point
    along = np.abs(offsets @ tangent)
    offsets -= np.outer(offsets @ tangent, tangent)  # across the curve only
    apart = np.linalg.norm(offsets, axis=1) > 1e-9
    if not norm > 1e-12 or not apart.any():
        return None
    # The vertices in a slab across the curve's middle: beside a curved edge, those nearest it
    # along the face's other edges can lie on the far side of its chord.
    slab = apart & (along <= reach) if (apart & (along <= reach)).any() else apart
    nearest = offsets[slab][np.argsort(np.linalg.norm(offsets[slab], axis=1))[:8]]
    return across / norm * (1.0 if np.sum(np.sign(nearest @ across)) >= 0 else -1.0)


def analytic_polyline(curve: dict) -> np.ndarray | None:
    """(M, 3) raw vertices of an ABC line or circle record from its own parameters, None for
    another type or a malformed record. Lines: location + t direction at the vertices'
    parameters. Circles: vertices at equal angles from the first parameter to the last (the
    intermediate parameters of ABC's files are not angles); this reproduces EMAP's sampled
    points of 00004926 exactly."""
    try:
        t = np.asarray(curve["vert_parameters"], dtype=np.float64).reshape(-1)
        location = np.asarray(curve["location"], dtype=np.float64).reshape(3)
        if curve["type"] == "Line":
            line = location + t[:, None] * np.asarray(curve["direction"], dtype=np.float64).reshape(3)
        elif curve["type"] == "Circle":
            angles = np.linspace(t[0], t[-1], len(t))[:, None]
            axes = (np.asarray(curve[key], dtype=np.float64).reshape(3) for key in ("x_axis", "y_axis"))
            radius = float(curve["radius"])
            line = location + radius * (np.cos(angles) * next(axes) + np.sin(angles) * next(axes))
        else:
            return None
    except (KeyError, TypeError, ValueError, IndexError):
        return None
    return line if len(line) >= 2 and np.all(np.isfinite(line)) else None


def read_obj_faces(path: Path) -> np.ndarray:
    """(T, 3) int64 0-based vertex indices of the triangles (`f` records) of a Wavefront OBJ;
    polygons with more corners are fanned into triangles."""
    triangles = []
    try:
        for line in path.read_text(encoding="utf-8").splitlines():
            if line.startswith("f "):
                corners = [int(corner.split("/")[0]) - 1 for corner in line.split()[1:]]
                triangles += [(corners[0], corners[k], corners[k + 1]) for k in range(1, len(corners) - 1)]
    except UnicodeDecodeError:
        raise InputError(path, "not a text OBJ file") from None
    except ValueError:
        raise InputError(path, "malformed face record") from None
    return np.array(triangles, dtype=np.int64).reshape(-1, 3)


def mesh_dihedrals(vertices: np.ndarray, faces: np.ndarray, curves: list[np.ndarray]) -> list[str]:
    """The dihedral sign along each curve through mesh vertices: "convex" where, across the mesh
    edges it follows, one triangle runs against the other's outward normal (counter-clockwise
    corners seen from outside), "concave" where it runs along it; the majority of the curve's
    segments decides, "unknown" where no segment has exactly two triangles.

    Args:
        vertices: (V, 3) mesh vertices; faces: (T, 3) their triangles; curves: (M_i,) each
            curve's vertices in order.
    """
    count = len(vertices)
    pairs = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    keys = pairs[:, 0] * count + pairs[:, 1]
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    return [_dihedral(vertices, faces, indices, order, sorted_keys) for indices in curves]


def _dihedral(vertices: np.ndarray, faces: np.ndarray, indices: np.ndarray, order: np.ndarray,
              sorted_keys: np.ndarray) -> str:
    """One curve's sign (`mesh_dihedrals`); `sorted_keys` (3T,) are the triangles' edges as
    lower * V + upper vertex index, sorted by `order` (3T,) (edge k of triangle k // 3)."""
    count = len(vertices)
    votes = 0
    for a, b in zip(indices[:-1], indices[1:]):
        key = min(a, b) * count + max(a, b)
        lo, hi = np.searchsorted(sorted_keys, [key, key + 1])
        if hi - lo != 2:
            continue
        first, second = faces[order[lo:hi] // 3]
        tangent = vertices[b] - vertices[a]
        third = vertices[[c for c in first if c not in (a, b)][0]] - vertices[a]
        inward = third - tangent * (third @ tangent) / max(tangent @ tangent, 1e-300)
        p = vertices[second]
        normal = np.cross(p[1] - p[0], p[2] - p[0])
        votes += int(np.sign(inward @ normal))
    return "unknown" if votes == 0 else ("convex" if votes < 0 else "concave")


class GroundTruthProvider(abc.ABC):
    """Finds a scene's ground truth in one dataset layout, from the scene's folder and name alone
    (scene loaders never look: commands ask `ground_truth_for` where they score).

    Attributes:
        layout: where it looks, for people (help texts, reports).
    """

    layout: str

    @abc.abstractmethod
    def find(self, scene_root: Path, scan_id: str) -> GroundTruthSource | None:
        """The ground truth of object `scan_id` for the scene in `scene_root`, or None when this
        layout has none. Raises InputError naming a file that is there but unreadable."""


@dataclass(frozen=True)
class AbcFolderProvider(GroundTruthProvider):
    """ABC ground truth in `groundtruth` folders at fixed places around the scene: in each, a
    pre-sampled `<id>_0.005.ply` wins over the CAD files (`<id>*.obj`, `<id>*features*.yml` and
    a `stats.json` / `*_stats.json` that holds the id), searched at any depth.

    Attributes:
        folders: scene folder -> the folders to search, in order.
    """

    layout: str
    folders: Callable[[Path], list[Path]]

    def find(self, scene_root: Path, scan_id: str) -> GroundTruthSource | None:
        for folder in (f for f in self.folders(scene_root) if f.is_dir()):
            plys = sorted(folder.glob(f"**/{scan_id}_{GT_SPACING}.ply"))
            features = sorted(folder.glob(f"**/{scan_id}*features*.yml"))
            objs = sorted(folder.glob(f"**/{scan_id}*.obj"))
            stats = sorted(folder.glob("**/stats.json")) + sorted(folder.glob("**/*_stats.json"))
            stats = [s for s in stats if _mentions(s, scan_id)] if features and (objs or plys) else []
            if plys:
                return GroundTruthSource(scan_id, sampled_ply=plys[0], obj=next(iter(objs), None),
                                         features=features[0] if stats else None,
                                         stats=next(iter(stats), None))
            if stats and objs:
                return GroundTruthSource(scan_id, obj=objs[0], features=features[0], stats=stats[0])
        return None


@dataclass(frozen=True)
class OwnSampledProvider(GroundTruthProvider):
    """The single `*_0.005.ply` in the scene's own `gt/`, whatever its id: a generated scene keeps
    its ground truth when its folder is renamed."""

    layout: str = f"the one *_{GT_SPACING}.ply in <scene>/gt"

    def find(self, scene_root: Path, scan_id: str) -> GroundTruthSource | None:
        own = sorted((scene_root / "gt").glob(f"*_{GT_SPACING}.ply"))
        if len(own) != 1:
            return None
        return GroundTruthSource(own[0].name.removesuffix(f"_{GT_SPACING}.ply"), sampled_ply=own[0])


PROVIDERS: tuple[GroundTruthProvider, ...] = (
    AbcFolderProvider("ABC-NEF: <scene>/gt or <scene>/groundtruth",
                      lambda root: [root / "gt", root / "groundtruth"]),
    # The EMAP layout keeps data/<id>/ beside groundtruth/.
    AbcFolderProvider("EMAP: groundtruth/ one or two levels above the scene",
                      lambda root: [parent / "groundtruth" for parent in list(root.parents)[:2]]),
    OwnSampledProvider(),
)
"""Asked in this order; the first that finds ground truth wins."""


def ground_truth_for(scene_root: Path, scan_id: str | None = None) -> GroundTruthSource | None:
    """The ground truth of the scene in `scene_root` (object `scan_id`, by default the folder's
    name) that the first of `PROVIDERS` finds, or None. Nothing is loaded (see
    `GroundTruthSource.load`). Raises InputError naming a ground-truth file that cannot be read."""
    scan_id = scene_root.name if scan_id is None else scan_id
    return next((source for provider in PROVIDERS
                 if (source := provider.find(scene_root, scan_id)) is not None), None)


def _mentions(stats: Path, scan_id: str) -> bool:
    """Whether a bbox statistics file holds object `scan_id`."""
    try:
        return f'"{scan_id}"' in stats.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(stats, f"not a readable bbox statistics file ({type(error).__name__})") from None
