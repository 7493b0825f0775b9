"""Reading and writing 3D edges in the files that users and other tools use.

Supported formats (chosen by suffix):

* ``.json``: EMAP's ``parametric_edges.json`` (``curves_ctl_pts``: cubic Béziers,
  ``lines_end_pts``: segments).
* ``.ply``: an ``edge`` element (vertex1, vertex2) is assembled into polylines; a PLY with only
  vertices is a point-cloud prediction.
* ``.obj``: ``v`` and ``l`` records (polylines); an OBJ without ``l`` records is a point cloud.

Every malformed or missing file raises :class:`~edgedog.errors.InputError`. The writers
(:func:`write_edges`) produce the same formats atomically; in OBJ and PLY every curve gets its
own vertices, so reading the file back gives one polyline per curve.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

from edgedog.bezier import bezier_points
from edgedog.errors import InputError
from edgedog.files import atomic_write, atomic_write_bytes, atomic_write_json, read_json
from edgedog.metrics import (
    MAX_SAMPLES,
    SAMPLE_SPACING,
    sample_count,
    sample_cubic_bezier,
    sample_line,
    sample_polyline,
)
from edgedog.world import check_coordinates


@dataclass
class EdgeCurves:
    """A set of predicted edges, all in the same (scene) coordinates.

    lines: (L, 2, 3) segment endpoints; beziers: (B, 4, 3) cubic control points;
    polylines: list of (M_i, 3) vertex chains; points: (P, 3) free points (point-cloud
    predictions, used as they are).
    """

    lines: np.ndarray = field(default_factory=lambda: np.empty((0, 2, 3)))
    beziers: np.ndarray = field(default_factory=lambda: np.empty((0, 4, 3)))
    polylines: list[np.ndarray] = field(default_factory=list)
    points: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))

    def __post_init__(self):
        self.lines = np.asarray(self.lines, dtype=np.float64).reshape(-1, 2, 3)
        self.beziers = np.asarray(self.beziers, dtype=np.float64).reshape(-1, 4, 3)
        self.polylines = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in self.polylines]
        self.points = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)

    @property
    def num_curves(self) -> int:
        """Number of lines, Béziers and polylines (free points not counted)."""
        return len(self.lines) + len(self.beziers) + len(self.polylines)

    @property
    def is_empty(self) -> bool:
        return self.num_curves == 0 and len(self.points) == 0

    def sample_bound(self, spacing: float = SAMPLE_SPACING) -> float:
        """An upper bound of the number of points `sample` draws from the curves (free points not
        counted; Béziers by their control polygon, never shorter than the curve), without sampling."""
        lengths = [np.linalg.norm(self.lines[:, 1] - self.lines[:, 0], axis=1),
                   np.linalg.norm(np.diff(self.beziers, axis=1), axis=2).sum(axis=1),
                   [np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in self.polylines]]
        return sum(sample_count(part, spacing) for part in lengths)

    def sample(self, spacing: float = SAMPLE_SPACING) -> np.ndarray:
        """Points (N, 3) on every curve with the evaluation's sampling rule, plus the free points."""
        parts = [sample_line(a, b, spacing) for a, b in self.lines]
        parts += [sample_cubic_bezier(c, spacing) for c in self.beziers]
        parts += [sample_polyline(p, spacing) for p in self.polylines]
        parts.append(self.points)
        return np.concatenate(parts, axis=0)

    def kept(self, keep: np.ndarray) -> EdgeCurves:
        """The curves where `keep` (num_curves,) bool holds, in the order lines, Béziers,
        polylines (that of `curve_polylines`); the free points stay."""
        lines, beziers = len(self.lines), len(self.beziers)
        return EdgeCurves(lines=self.lines[keep[:lines]], beziers=self.beziers[keep[lines:lines + beziers]],
                          polylines=[p for p, k in zip(self.polylines, keep[lines + beziers:]) if k],
                          points=self.points)

    def transformed(self, T: np.ndarray) -> EdgeCurves:
        """A copy with the homogeneous transform T (4, 4) applied to every coordinate.

        Béziers are mapped through their control points, which is exact for affine T.
        """
        T = np.asarray(T, dtype=np.float64)
        if T.shape != (4, 4):
            raise ValueError(f"expected a 4x4 transform, got shape {T.shape}")

        def apply(x: np.ndarray) -> np.ndarray:
            w = x @ T[3, :3] + T[3, 3]
            return (x @ T[:3, :3].T + T[:3, 3]) / w[..., None]

        return EdgeCurves(
            lines=apply(self.lines),
            beziers=apply(self.beziers),
            polylines=[apply(p) for p in self.polylines],
            points=apply(self.points),
        )


def read_edges(path: str | Path) -> EdgeCurves:
    """Read predicted edges from a .json (EMAP), .ply or .obj file."""
    path = Path(path)
    readers = {".json": _read_json, ".ply": _read_ply, ".obj": _read_obj}
    reader = readers.get(path.suffix.lower())
    if reader is None:
        raise InputError(path, f"unsupported edge file type {path.suffix!r} (use .json, .ply or .obj)")
    if not path.is_file():
        raise InputError(path, "no such file")
    return _within_bounds(path, reader(path))


def _within_bounds(path: Path, curves: EdgeCurves) -> EdgeCurves:
    """`curves` when their coordinates lie within MAX_COORDINATE and sampling them for the
    evaluation gives at most MAX_SAMPLES points; else an InputError naming the file."""
    check_coordinates(path, curves.lines, curves.beziers, curves.points, *curves.polylines)
    count = curves.sample_bound()
    if count > MAX_SAMPLES:
        raise InputError(path, f"its curves would be sampled into {count:.3g} points every "
                               f"{SAMPLE_SPACING} units, more than {MAX_SAMPLES:,}: far longer curves than "
                               "a scene of unit size holds")
    return curves


def _finite(path: Path, what: str, values: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(values)):
        raise InputError(path, f"{what} contains NaN or infinite coordinates")
    return values


def _read_json(path: Path) -> EdgeCurves:
    data = read_json(path)
    if not isinstance(data, dict) or not ({"curves_ctl_pts", "lines_end_pts"} & data.keys()):
        raise InputError(path, "expected an object with 'curves_ctl_pts' and/or 'lines_end_pts'")

    def parse(key: str, n_pts: int) -> np.ndarray:
        items = data.get(key) or []
        if not isinstance(items, list):
            raise InputError(path, f"'{key}' must be a list")
        out = np.empty((len(items), n_pts, 3))
        for i, item in enumerate(items):
            try:
                arr = np.asarray(item, dtype=np.float64)
            except (TypeError, ValueError):
                arr = None
            if arr is None or arr.shape not in ((3 * n_pts,), (n_pts, 3)):
                raise InputError(
                    path, f"{key}[{i}]: expected {3 * n_pts} numbers or {n_pts}x3 nested lists"
                )
            out[i] = _finite(path, f"{key}[{i}]", arr).reshape(n_pts, 3)
        return out

    return EdgeCurves(lines=parse("lines_end_pts", 2), beziers=parse("curves_ctl_pts", 4))


def _read_ply(path: Path) -> EdgeCurves:
    try:
        ply = PlyData.read(str(path))
    except Exception as e:  # plyfile raises many types (parse, struct, EOF, decode) on bad files
        raise InputError(path, f"not a readable PLY file ({e})") from None
    try:
        vertex = ply["vertex"]
        xyz = np.stack([vertex[k] for k in ("x", "y", "z")], axis=1).astype(np.float64)
    except (KeyError, ValueError):
        raise InputError(path, "needs a 'vertex' element with x, y, z properties") from None
    xyz = _finite(path, "vertex", xyz)
    if "edge" not in ply:
        return EdgeCurves(points=xyz)
    try:
        edge = ply["edge"]
        edges = np.stack([edge["vertex1"], edge["vertex2"]], axis=1).astype(np.int64)
    except (KeyError, ValueError):
        raise InputError(path, "the 'edge' element needs vertex1 and vertex2 properties") from None
    if edges.size and (edges.min() < 0 or edges.max() >= len(xyz)):
        raise InputError(path, f"edge vertex index out of range (the file has {len(xyz)} vertices)")
    return EdgeCurves(polylines=[xyz[c] for c in chain_edges(edges, len(xyz))])


def _read_obj(path: Path) -> EdgeCurves:
    vertices: list[list[float]] = []
    edges: list[tuple[int, int]] = []
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(path, "not a text OBJ file") from None
    for lineno, line in enumerate(text.splitlines(), start=1):
        tokens = line.split()
        if not tokens:
            continue
        try:
            if tokens[0] == "v":
                vertices.append([float(t) for t in tokens[1:4]])
                if len(vertices[-1]) != 3:
                    raise ValueError("a vertex needs 3 coordinates")
            elif tokens[0] == "l":
                # OBJ indices are 1-based; negative ones count back from the latest vertex.
                idx = [int(t.split("/")[0]) for t in tokens[1:]]
                idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
                if any(not 0 <= i < len(vertices) for i in idx):
                    raise ValueError(f"vertex index out of range ({len(vertices)} vertices so far)")
                edges += zip(idx[:-1], idx[1:])
        except ValueError as e:
            raise InputError(path, f"line {lineno}: {e}") from None
    xyz = _finite(path, "vertex", np.asarray(vertices, dtype=np.float64).reshape(-1, 3))
    if not edges:
        return EdgeCurves(points=xyz)
    # Chained like PLY edges, so polylines exported as many 2-vertex `l` records are not lost.
    chains = chain_edges(np.asarray(edges, dtype=np.int64), len(xyz))
    return EdgeCurves(polylines=[xyz[c] for c in chains])


_BEZIER_MIN_SEGMENTS = 16
"""Fewest segments a Bézier is written with to OBJ and PLY (enough for a half circle)."""


def curve_polylines(curves: EdgeCurves, spacing: float = SAMPLE_SPACING) -> list[np.ndarray]:
    """Every curve as a vertex chain (M_i, 3), in the order lines, Béziers, polylines.

    Lines are their two ends; Béziers are sampled uniformly in t with at least
    `_BEZIER_MIN_SEGMENTS` segments and segments no longer than about `spacing`.
    """
    chains = list(curves.lines)
    for ctrl in curves.beziers:
        polygon = float(np.sum(np.linalg.norm(np.diff(ctrl, axis=0), axis=1)))  # >= the arc length
        segments = max(_BEZIER_MIN_SEGMENTS, int(np.ceil(polygon / spacing)))
        chains.append(bezier_points(ctrl, np.linspace(0.0, 1.0, segments + 1)))
    return chains + list(curves.polylines)


def write_edges(path: str | Path, curves: EdgeCurves) -> Path:
    """Write curves to a .json (EMAP), .ply or .obj file, atomically; the suffix picks the format."""
    path = Path(path)
    writers = {".json": write_json, ".ply": write_ply, ".obj": write_obj}
    writer = writers.get(path.suffix.lower())
    if writer is None:
        raise InputError(path, f"unsupported edge file type {path.suffix!r} (use .json, .ply or .obj)")
    return writer(path, curves)


def write_json(path: str | Path, curves: EdgeCurves) -> Path:
    """EMAP's parametric_edges.json: `curves_ctl_pts` (B, 4, 3) nested, `lines_end_pts` (L, 6).

    The format has no polylines or free points; curves holding any raise ValueError.
    """
    if curves.polylines or len(curves.points):
        raise ValueError("EMAP's JSON holds only lines and cubic Béziers")
    return atomic_write_json(path, {"curves_ctl_pts": curves.beziers.tolist(),
                                    "lines_end_pts": curves.lines.reshape(-1, 6).tolist()})


def _curves_or_points(curves: EdgeCurves) -> list[np.ndarray]:
    """The vertex chains to write, or [] for a point cloud; both at once cannot be read back."""
    chains = curve_polylines(curves)
    if chains and len(curves.points):
        raise ValueError("a file holds either curves or free points, not both")
    return chains


def write_obj(path: str | Path, curves: EdgeCurves) -> Path:
    """Wavefront OBJ: one `o` group per curve with its `v` records and one `l` polyline; a point
    cloud (free points only) is `v` records alone."""
    out, first = [], 1
    for k, chain in enumerate(_curves_or_points(curves)):
        out.append(f"o curve_{k}\n")
        out += [f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in chain]
        out.append("l " + " ".join(str(first + i) for i in range(len(chain))) + "\n")
        first += len(chain)
    if first == 1:
        out += [f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in curves.points]
    return atomic_write_bytes(path, "".join(out).encode("utf-8"))


def write_ply(path: str | Path, curves: EdgeCurves) -> Path:
    """Binary PLY: float64 vertices and an `edge` element (vertex1, vertex2) joining consecutive
    vertices of each curve; a point cloud (free points only) has no `edge` element."""
    chains = _curves_or_points(curves)
    xyz = np.concatenate(chains) if chains else curves.points
    vertex = np.empty(len(xyz), dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    vertex["x"], vertex["y"], vertex["z"] = xyz.T
    elements = [PlyElement.describe(vertex, "vertex")]
    if chains:
        starts = np.cumsum([0] + [len(c) for c in chains[:-1]])
        pairs = np.concatenate([s + np.stack([np.arange(len(c) - 1), np.arange(1, len(c))], axis=1)
                                for s, c in zip(starts, chains)])
        edge = np.empty(len(pairs), dtype=[("vertex1", "i4"), ("vertex2", "i4")])
        edge["vertex1"], edge["vertex2"] = pairs.T
        elements.append(PlyElement.describe(edge, "edge"))
    return atomic_write(path, PlyData(elements).write)


def chain_edges(edges: np.ndarray, num_vertices: int) -> list[np.ndarray]:
    """Assemble edges (E, 2) of vertex indices into maximal chains (vertex index arrays).

    Chains run through vertices of degree 2 and stop at endpoints and junctions; a closed loop
    comes back as a chain whose last index repeats the first. This matters for evaluation: a
    curve stored as many short edges would get no samples at all if each edge were sampled
    separately (floor(length / 5 mm) = 0).
    """
    edges = edges[edges[:, 0] != edges[:, 1]]
    # Drop duplicate edges (either direction), keeping the first occurrence's order.
    _, first = np.unique(np.sort(edges, axis=1), axis=0, return_index=True)
    edges = edges[np.sort(first)]
    degree = np.bincount(edges.ravel(), minlength=num_vertices)
    # CSR incidence: the edges touching vertex v are incident[offset[v]:offset[v + 1]].
    incident = np.argsort(edges.ravel(), kind="stable") // 2
    offset = np.concatenate([[0], np.cumsum(degree)])
    used = np.zeros(len(edges), dtype=bool)

    def walk(start: int, e: int) -> np.ndarray:
        chain, v = [start], start
        while True:
            used[e] = True
            a, b = edges[e]
            v = b if a == v else a
            chain.append(v)
            if degree[v] != 2:
                break
            free = [f for f in incident[offset[v] : offset[v + 1]] if not used[f]]
            if not free:  # back at the start of a closed loop
                break
            e = free[0]
        return np.asarray(chain)

    chains = []
    # Open chains first, each started from an endpoint or junction, in file order.
    for e in range(len(edges)):
        a, b = edges[e]
        if not used[e] and (degree[a] != 2 or degree[b] != 2):
            chains.append(walk(a if degree[a] != 2 else b, e))
    # Whatever is left consists of closed loops through degree-2 vertices only.
    for e in range(len(edges)):
        if not used[e]:
            chains.append(walk(edges[e, 0], e))
    return chains
