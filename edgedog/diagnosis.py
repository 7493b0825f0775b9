"""Per-curve diagnosis of a prediction (`edgedog eval --per-curve`): for every ground-truth curve
its identity (id, type, kind), length and recall at 5/10/20 mm, and for a missed one where it was
lost; for every predicted curve that lies on no ground-truth edge, why.

Kinds. A curve's dihedral sign (convex or concave: the material's wedge at the edge under or over
180 degrees) comes with the ground truth: the B-rep of a generated scene (its curves file, or the
part rebuilt from the scene's manifest for scenes written before curves carried it), or an ABC
object's mesh. An ABC object without a mesh (EMAP's copy) has its curves' faces in the features
file but not which side is material: the maps decide (`_dihedrals_from_maps`). A convex (or
unknown) curve is an "outline" where, in most of the views that see it, the pixels beside its
projection on one side are background (the scene's masks, else the rendered depth); without a
mesh, the views whose maps draw it stand for those that see it. A concave curve is never an
outline.

Where a missed curve (recall at 10 mm under MISSED_RECALL) was lost, the first of: occluded (seen
by fewer than MIN_VIEWS views: needs the part's mesh, rendered offscreen), not drawn (mean edge
value along its projection in the views that see it under MIN_DRAWN), no primitive formed (under
half of its points have a primitive centre of primitives.ply within NEAR; with whether the last
Fisher pruning, the only one a run's checkpoint records, removed primitives on it), dropped at
extraction (under half have a point of edge_points.ply within NEAR: the filter that removed most
of the primitives near it, re-applied), or dropped at curve fitting (edge points near it, no
curve; "or by the shading test" where the run's extraction dropped curves by their shading,
`extract.filter_shading`, which acts on the fitted curves).

A predicted curve is false where under half of its samples lie within NEAR of the ground truth:
an outlier (off the part's surface), the contour of a curved face (on a curved surface), or on a
flat face (texture or shading); without a mesh, outside the silhouettes or "not told apart".

Sizes are bounded: PROBES points per curve and at most MAX_VIEWS views are examined, at most
MAX_FALSE false curves are reported (the longest).
"""

from __future__ import annotations

import dataclasses
import json
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from edgedog.curve_files import EdgeCurves, curve_polylines
from edgedog.curves.contours import DRAWN_VALUE, window_max
from edgedog.errors import InputError
from edgedog.groundtruth import (
    GT_SPACING,
    GroundTruthCurve,
    GroundTruthSource,
    abc_curves,
    normalisation,
    read_obj_vertices,
    read_points_ply,
)
from edgedog.metrics import SAMPLE_SPACING, THRESHOLDS, sample_polyline, voxel_mean

MISSED_RECALL = 50.0
"""A curve whose recall at 10 mm is under this (%) is missed."""
NEAR = 0.01
"""Ground-truth units (10 mm): a primitive, edge point or predicted sample this close is on it."""
MIN_VIEWS = 2
"""Fewest views that must see a curve for it to be triangulated."""
MIN_DRAWN = 0.1
"""Mean edge value along a curve's projection under which it is not drawn in the maps."""
PROBES = 32
"""Points per curve examined in each view."""
MAX_VIEWS = 100
"""Most views examined (evenly spread over the scene's)."""
MAX_FALSE = 200
"""Most false predicted curves reported, the longest first."""
BESIDE_PX = 3
"""Pixels from a curve's projection, across it, where the background is looked for."""
ASSIGN_STEP = 0.001
"""Spacing (1 mm) of the points a ground-truth point is matched to its curve by."""
ASSIGN_DISTANCE = 0.002
"""Ground-truth points farther than this (2 mm) from every curve are unidentified."""
SURFACE_STEP = 0.004
"""Spacing of the points sampled on the mesh's surface to place false curves (4 mm)."""
MAX_SURFACE_POINTS = 400_000
WEDGE_MARGIN = 0.05
"""Difference of mean edge values between the two sides of a curve's faces that signs it."""
CURVED_DEG = 2.0
"""Triangles whose corner normals differ by more than this tessellate a curved face."""


@dataclass
class CurveReport:
    """One ground-truth curve's identity, scores and, when missed, where it was lost.

    Recall and covers are in %, lengths and distances in mm; `views_seeing` is None without a
    mesh (visibility unknown), `drawn` the mean edge value along its visible projection;
    `primitive_mm` the median distance from its points to the nearest primitive centre and
    `primitive_cover` the share of its points with one within NEAR (`edge_point_*` likewise for
    the extracted edge points).
    """

    id: int
    type: str
    kind: str
    dihedral: str
    length_mm: float
    gt_points: int
    recall: dict[int, float]
    views_seeing: int | None = None
    views_drawn: int | None = None
    views_outline: int | None = None
    drawn: float | None = None
    primitive_mm: float | None = None
    primitive_cover: float | None = None
    edge_point_mm: float | None = None
    edge_point_cover: float | None = None
    pruned_near: int | None = None
    missed: bool = False
    cause: str = ""


@dataclass
class FalseCurve:
    """A predicted curve on no ground-truth edge: its length (mm), share of samples near the
    ground truth (%), and why."""

    index: int
    length_mm: float
    near_gt: float
    cause: str


@dataclass
class Diagnosis:
    """The per-curve report: curves, false predicted curves, recall by kind and type, notes."""

    curves: list[CurveReport]
    false_curves: list[FalseCurve]
    false_count: int
    by_kind: dict[str, dict[str, float]]
    by_type: dict[str, dict[str, float]]
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"curves": [asdict(c) for c in self.curves],
                "false_curves": [asdict(c) for c in self.false_curves], "false_curve_count": self.false_count,
                "recall_by_kind": self.by_kind, "recall_by_type": self.by_type, "notes": self.notes,
                "rules": {"missed_recall_10mm": MISSED_RECALL, "near_mm": NEAR * 1000, "min_views": MIN_VIEWS,
                          "min_drawn": MIN_DRAWN, "views_examined_max": MAX_VIEWS}}

    def table(self) -> str:
        """The readable report: one row per ground-truth curve, the aggregates, the false curves."""
        def number(value, fmt):
            return "-" if value is None else format(value, fmt)
        rows = [f"{'id':>4} {'type':<8} {'kind':<8} {'len mm':>7} {'R5':>6} {'R10':>6} {'R20':>6} "
                f"{'seen':>5} {'drew':>5} {'drawn':>5} {'prim':>6}  cause"]
        for c in self.curves:
            rows.append(f"{c.id:>4} {c.type:<8} {c.kind:<8} {c.length_mm:7.0f} {c.recall[5]:6.1f} "
                        f"{c.recall[10]:6.1f} {c.recall[20]:6.1f} {number(c.views_seeing, 'd'):>5} "
                        f"{number(c.views_drawn, 'd'):>5} {number(c.drawn, '.2f'):>5} "
                        f"{number(c.primitive_mm, '.1f'):>6}  {c.cause}")
        for title, groups in (("kind", self.by_kind), ("type", self.by_type)):
            rows.append(f"recall by {title}: " + "; ".join(
                f"{name} ({g['curves']:.0f} curves) R5 {g['recall_5mm']:.1f} R10 {g['recall_10mm']:.1f} "
                f"R20 {g['recall_20mm']:.1f}" for name, g in groups.items()))
        shown = min(len(self.false_curves), 20)
        rows.append(f"predicted curves on no ground-truth edge: {self.false_count}"
                    + (f" (the {shown} longest below)" if self.false_count > shown else ""))
        rows += [f"  curve {f.index}: {f.length_mm:.0f} mm, {f.near_gt:.0f}% near GT: {f.cause}"
                 for f in self.false_curves[:20]]
        legend = ("columns: seen = views that see it (on the rendered mesh; - without one), drew = views "
                  f"whose map draws it (mean edge value >= {DRAWN_VALUE}), drawn = mean edge value along it "
                  "in the views that see it, prim = median distance (mm) to the nearest primitive centre")
        return "\n".join(rows + [legend] + [f"note: {n}" for n in self.notes])


# --- the ground-truth curves ------------------------------------------------------------------

@dataclass
class CurveSource:
    """A scene's ground-truth curves with identity and, where known, the part's mesh.

    Attributes:
        curves: in the ground-truth frame.
        mesh: (T, 3, 3) triangle corners and (T, 3, 3) corner normals in the ground-truth frame,
            as an `edgedog.synthetic.mesh.Mesh`, or None.
        notes: how they were found.
    """

    curves: list[GroundTruthCurve]
    mesh: object | None
    notes: list[str]


def ground_truth_curves(source: GroundTruthSource, scene_root: Path) -> CurveSource:
    """The curves of a scene's ground truth: an ABC object's features file (with its mesh where
    there is one), or a generated scene's curves file. InputError when there is neither."""
    curves = abc_curves(source)
    if curves is not None:
        mesh = None
        if source.obj is not None:
            from edgedog.synthetic.abc_file import read_obj_triangles
            from edgedog.synthetic.mesh import Mesh

            scale, offset = normalisation(source.stats, source.scan_id)
            raw = read_obj_triangles(source.obj, read_obj_vertices(source.obj))
            mesh = Mesh(raw.positions * scale + offset, raw.normals)
        note = ("curves and dihedral signs from the mesh" if mesh is not None else
                "no mesh: curves from the features file's line and circle parameters; visibility unknown "
                "(every view the curve projects into counts)")
        return CurveSource(curves, mesh, [f"{source.features.name}: {note}"])
    if source.sampled_ply is None:
        raise InputError(source.features or scene_root, "no curve information for a per-curve diagnosis")
    stem = source.sampled_ply.name.removesuffix(f"_{GT_SPACING}.ply")
    path = source.sampled_ply.with_name(f"{stem}_curves.json")
    return _generated_curves(path, scene_root)


def _generated_curves(path: Path, scene_root: Path) -> CurveSource:
    """A generated scene's curves file; the part rebuilt from the scene's manifest (a built-in
    shape or a family design) gives the mesh, and the dihedral signs a file written before
    curves carried them lacks."""
    from edgedog.synthetic.features import curve_from_json

    if not path.is_file():
        raise InputError(path.parent, f"ground truth without curve information: no {path.name} beside the "
                                      "points (a per-curve diagnosis needs the curves: a generated scene's "
                                      "curves file or an ABC features file)")
    try:
        records = json.loads(path.read_text(encoding="utf-8"))["curves"]
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError):
        raise InputError(path, "not a curves file (a JSON object with 'curves')") from None
    curves = [curve_from_json(record, path) for record in records]
    notes = [f"{path.name}: {len(curves)} curves"]
    part = _rebuilt_part(scene_root)
    mesh = None
    if part is not None and len(part.curves) == len(curves) and all(
            np.allclose(a.at(np.r_[0.0, 0.5, 1.0]), b.at(np.r_[0.0, 0.5, 1.0]), atol=1e-6)
            for a, b in zip(part.curves, curves)):
        mesh = part.mesh
        if all(c.dihedral == "unknown" for c in curves):
            curves = list(part.curves)
            notes.append("dihedral signs from the part rebuilt from the scene's manifest")
        notes.append("mesh from the part rebuilt from the scene's manifest")
    elif part is not None:
        notes.append("the part rebuilt from the scene's manifest does not match its curves: no mesh")
    else:
        notes.append("no part to rebuild from the scene's manifest: no mesh, visibility unknown")
    return CurveSource([GroundTruthCurve(i, c.type, c.dihedral, _polyline(c)) for i, c in enumerate(curves)],
                       mesh, notes)


def _polyline(curve) -> np.ndarray:
    """(M, 3) points along a synthetic curve: its ends for a line, every ASSIGN_STEP otherwise."""
    if curve.type == "line":
        return np.stack([curve.a, curve.b])
    return curve.at(np.linspace(0.0, 1.0, max(2, int(np.ceil(curve.length / ASSIGN_STEP)) + 1)))


def _rebuilt_part(scene_root: Path):
    """The Part a generated scene was made of, rebuilt from its manifest (a built-in shape or a
    family design, by name and seed), or None."""
    from edgedog.builtin.writer import MANIFEST

    try:
        manifest = json.loads((scene_root / MANIFEST).read_text(encoding="utf-8"))
        name, seed = str(manifest["shape"]), int(manifest["seed"])
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError):
        return None
    from edgedog.synthetic.family import DESIGNS, family_part
    from edgedog.synthetic.shapes import SHAPES, make_part

    if name in SHAPES:
        return make_part(name, seed)
    index = next((i for i, recipe in enumerate(DESIGNS) if recipe.name == name), None)
    return None if index is None else family_part(index, seed)


def assign_points(gt_points: np.ndarray, curves: list[GroundTruthCurve]) -> np.ndarray:
    """(N,) index into `curves` of the curve each ground-truth point (N, 3) lies on, -1 for
    points farther than ASSIGN_DISTANCE from every curve."""
    dense = [sample_polyline(c.polyline, ASSIGN_STEP) if c.length > ASSIGN_STEP else c.polyline
             for c in curves]
    owner = np.concatenate([np.full(len(d), i) for i, d in enumerate(dense)])
    distance, nearest = cKDTree(np.concatenate(dense)).query(gt_points)
    return np.where(distance <= ASSIGN_DISTANCE, owner[nearest], -1)


# --- what the views show ------------------------------------------------------------------------

@dataclass
class ViewEvidence:
    """Per curve (C,): views that see it (None without a mesh), views that draw it, views where it
    is an outline, its mean edge value over the views that see it, and for a curve with a
    `wedge`, its mean edge value in the views looking into the wedge and in the others (NaN
    where no view does)."""

    seeing: np.ndarray | None
    drawn_views: np.ndarray
    outline_views: np.ndarray
    drawn: np.ndarray
    into_wedge: np.ndarray
    outside_wedge: np.ndarray


def probes(curve: GroundTruthCurve) -> tuple[np.ndarray, np.ndarray]:
    """(PROBES, 3) points evenly along a curve (ends left out) and (PROBES, 3) unit tangents."""
    lengths = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(curve.polyline, axis=0), axis=1))]
    s = (np.arange(PROBES) + 0.5) / PROBES * lengths[-1]
    points = np.stack([np.interp(s, lengths, curve.polyline[:, k]) for k in range(3)], axis=1)
    segment = np.clip(np.searchsorted(lengths, s, side="right") - 1, 0, len(curve.polyline) - 2)
    tangent = curve.polyline[segment + 1] - curve.polyline[segment]
    return points, tangent / np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)


def view_evidence(curves: list[GroundTruthCurve], mesh, scene, detector: str | None) -> ViewEvidence:
    """What the scene's views show of each curve (ground-truth frame, mapped into the world).

    A view sees a curve where it sees most of its probe points (`edgedog.synthetic.exact.visible`
    on the mesh rendered offscreen; without a mesh every view it projects into); the edge value
    is the largest of the 3x3 pixels at each point (the maps' sub-pixel bias); an outline in a
    view where, beside most of its visible points, one side is background."""
    gt_to_world = np.linalg.inv(scene.world_to_gt)
    wedge_sums = np.zeros((len(curves), 2, 2))  # [curve, into / outside, sum / views]
    points, tangents = zip(*(probes(c) for c in curves))
    middles = (np.stack([p[PROBES // 2] for p in points]), np.stack([t[PROBES // 2] for t in tangents]))
    points = np.concatenate(points) @ gt_to_world[:3, :3].T + gt_to_world[:3, 3]
    tangents = np.concatenate(tangents) @ gt_to_world[:3, :3].T
    owner = np.repeat(np.arange(len(curves)), PROBES)
    count = len(curves)
    seeing, drawn_views, outline_views = np.zeros(count, int), np.zeros(count, int), np.zeros(count, int)
    drawn_sum = np.zeros(count)
    views = examined_views(len(scene))
    renderers: dict = {}
    try:
        for i in views:
            camera = scene.camera(int(i))
            render = render_mesh(renderers, mesh, gt_to_world, camera) if mesh is not None else None
            seen = visible_points(points, camera, render)
            edge = window_max(scene.load_edge_map(int(i), detector)) if detector is not None else None
            background = _background(scene, int(i), render)
            pixels, _ = camera.pixels(points)
            seen_count = np.bincount(owner, seen, count)
            in_view = seen_count >= 0.5 * PROBES
            seeing += in_view
            counted = in_view  # without a mesh, the views that draw it stand for those that see it
            if edge is not None:
                value = np.bincount(owner, np.where(seen, edge[pixels[:, 1], pixels[:, 0]], 0.0), count)
                value = value / np.maximum(seen_count, 1)
                drawn_sum += np.where(in_view, value, 0.0)
                drawn_views += in_view & (value >= DRAWN_VALUE)
                counted = in_view if render is not None else in_view & (value >= DRAWN_VALUE)
                into = _looks_into_wedge(curves, *middles, scene.world_to_gt @ np.r_[camera.center, 1.0])
                for side, chosen in ((0, into & in_view), (1, ~into & in_view)):
                    wedge_sums[:, side] += np.stack([np.where(chosen, value, 0.0), chosen], axis=1)
            if background is not None:
                beside = _beside_background(points, tangents, camera, background) & seen
                outline_views += counted & (np.bincount(owner, beside, count) >= 0.5 * seen_count)
    finally:
        for renderer in renderers.values():
            renderer.release()
    with np.errstate(invalid="ignore", divide="ignore"):
        wedge_means = wedge_sums[..., 0] / wedge_sums[..., 1]
    return ViewEvidence(seeing if mesh is not None else None, drawn_views, outline_views,
                        drawn_sum / np.maximum(seeing, 1), wedge_means[:, 0], wedge_means[:, 1])


def examined_views(count: int) -> np.ndarray:
    """The views examined of a scene of `count`: every one, or MAX_VIEWS spread evenly."""
    return np.unique(np.linspace(0, count - 1, min(count, MAX_VIEWS)).round().astype(int))


def _looks_into_wedge(curves: list[GroundTruthCurve], middles: np.ndarray, tangents: np.ndarray,
                      centre: np.ndarray) -> np.ndarray:
    """(C,) whether a camera at `centre` (4,) homogeneous, ground-truth frame, looks at each
    curve's middle (C, 3), unit tangents there (C, 3), from inside its `wedge` (across the curve,
    between the two directions into its faces); False for curves without one."""
    result = np.zeros(len(curves), bool)
    for i, (curve, middle, tangent) in enumerate(zip(curves, middles, tangents)):
        if curve.wedge is None:
            continue
        view = centre[:3] / centre[3] - middle
        view -= tangent * (view @ tangent)
        (a, b), *_ = np.linalg.lstsq(curve.wedge.T, view, rcond=None)
        result[i] = a > 0 and b > 0
    return result


def render_mesh(renderers: dict, mesh, gt_to_world: np.ndarray, camera):
    """The mesh (ground-truth frame) rendered by `camera`, one renderer per image size."""
    from edgedog.synthetic.mesh import Mesh
    from edgedog.synthetic.render import Renderer

    size = (camera.width, camera.height)
    if size not in renderers:
        rotation = gt_to_world[:3, :3]
        normals = mesh.normals @ np.linalg.inv(rotation)  # inverse transpose, row vectors
        world = Mesh(mesh.positions @ rotation.T + gt_to_world[:3, 3],
                     normals / np.linalg.norm(normals, axis=-1, keepdims=True))
        renderers[size] = Renderer(world, *size)
    return renderers[size].render(camera)


def visible_points(points: np.ndarray, camera, render) -> np.ndarray:
    """(N,) whether `camera` sees each point: on the rendered mesh, or in the image without one."""
    if render is None:
        return camera.pixels(points)[1]
    from edgedog.synthetic.exact import visible

    return visible(points, camera, render)


def _background(scene, index: int, render) -> np.ndarray | None:
    """(H, W) bool background of a view: its mask's complement, else where the render is empty."""
    try:
        mask = scene.load_mask(index)
    except InputError:
        mask = None
    if mask is not None:
        return ~mask
    return None if render is None else render.depth <= 0


def _beside_background(points: np.ndarray, tangents: np.ndarray, camera,
                       background: np.ndarray) -> np.ndarray:
    """(N,) whether either pixel BESIDE_PX across the projected curve from each point is
    background (or outside the image)."""
    uv, _ = camera.project(points)
    ahead, _ = camera.project(points + tangents * 1e-3)
    direction = ahead - uv
    across = np.stack([-direction[:, 1], direction[:, 0]], axis=1)
    across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-12)
    result = np.zeros(len(points), bool)
    height, width = background.shape
    for sign in (-1, 1):
        pixel = np.round(uv + sign * BESIDE_PX * across).astype(np.int64)
        inside = (pixel[:, 0] >= 0) & (pixel[:, 0] < width) & (pixel[:, 1] >= 0) & (pixel[:, 1] < height)
        x, y = np.clip(pixel[:, 0], 0, width - 1), np.clip(pixel[:, 1], 0, height - 1)
        result |= ~inside | background[y, x]
    return result


# --- the run's stages ---------------------------------------------------------------------------

@dataclass
class RunStages:
    """A run folder's intermediate results in the ground-truth frame: primitive centres (P, 3)
    with the primitives themselves (for re-applying the filters), edge points (E, 3) or None,
    the extraction settings, the number of Fisher prunings logged and (M, 3) the centres the
    last one removed (the run's checkpoint keeps those only; None without a checkpoint)."""

    centres: np.ndarray
    primitives: object
    edge_points: np.ndarray | None
    extract_config: dict
    prunings: int
    pruned: np.ndarray | None


def run_stages(run: Path, world_to_gt: np.ndarray) -> RunStages | None:
    """The stages of `run` (a folder written by `edgedog train`), None without primitives.ply."""
    from edgedog.primitives import EdgePrimitives, read_ply

    if not (run / "primitives.ply").is_file():
        return None
    primitives = EdgePrimitives.from_arrays(read_ply(run / "primitives.ply"))

    def to_gt(points: np.ndarray) -> np.ndarray:
        return points @ world_to_gt[:3, :3].T + world_to_gt[:3, 3]
    edge_file = run / "edge_points.ply"
    edge_points = to_gt(read_points_ply(edge_file)) if edge_file.is_file() else None
    config, prunings = {}, 0
    try:
        config = json.loads((run / "extract.json").read_text(encoding="utf-8")).get("config", {})
        events = json.loads((run / "log.json").read_text(encoding="utf-8")).get("events", [])
        prunings = sum(1 for e in events if isinstance(e, dict) and e.get("event") == "fisher_prune")
    except (OSError, UnicodeDecodeError, ValueError, AttributeError):
        pass
    return RunStages(to_gt(primitives.points), primitives, edge_points, config, prunings,
                     _last_pruned(run, to_gt))


def _last_pruned(run: Path, to_gt) -> np.ndarray | None:
    """(M, 3) ground-truth-frame centres removed by the run's last Fisher pruning, from its
    checkpoint; None without a readable one."""
    from edgedog.train.checkpoint import read_checkpoint

    try:
        positions = read_checkpoint(run / "checkpoint.pt")["pruned_positions"]
    except InputError:
        return None
    return to_gt(np.asarray(positions, dtype=np.float64).reshape(-1, 3))


def filter_losses(indices: np.ndarray, stages: RunStages, scene, detector: str | None) -> np.ndarray:
    """(N,) the extraction filter that removed each primitive `indices` (N,) of the run, re-applied
    in the extraction's order: "kept" for those in edge_points.ply, "opacity", "projection",
    "silhouette", "contours", and "outliers" for the rest (that filter depends on every point;
    a point it removed that also fails a later test is named by that test)."""
    from edgedog.curves import contours, filtering
    from edgedog.curves.config import ExtractConfig

    config = stages.extract_config
    chosen = stages.primitives.subset(indices)
    kept = (cKDTree(stages.edge_points).query(stages.centres[indices])[0] < 1e-6
            if stages.edge_points is not None and len(stages.edge_points) else np.zeros(len(indices), bool))
    loss = np.where(kept, "kept", "outliers").astype(object)
    left = ~kept
    default = ExtractConfig()

    def setting(name: str):
        return config.get(name, getattr(default, name))
    # An extract.json without the key was written before the contour filter existed: it did not run.
    contours_on = bool(config.get("filter_contours", False))
    opacity, edge_value = float(setting("min_opacity")), float(setting("min_edge_value"))
    outside = float(setting("max_outside_pixels"))
    tests = [("opacity", setting("filter_opacity"),
              lambda points, rows: filtering.opacity_mask(chosen.opacity[rows], opacity))]
    if scene is not None:
        tests.append(("projection", setting("filter_projection") and detector is not None,
                      lambda points, rows: filtering.projection_mask(points, scene, detector, edge_value)))
        tests.append(("silhouette", setting("filter_silhouette"),
                      lambda points, rows: filtering.silhouette_mask(points, scene, outside)))
        tests.append(("contours", contours_on and detector is not None,
                      lambda points, rows: contours.contour_mask(
                          points, contours.HullSurface(scene, int(setting("contour_hull_cells"))), detector,
                          float(setting("contour_max_cosine")), float(setting("contour_max_share")),
                          float(setting("contour_probe_cells")))))
    for name, active, test in tests:
        rows = np.flatnonzero(left)
        if not (active and len(rows)):
            continue
        keep = test(chosen.points[rows], rows)
        if keep is None:  # a scene without masks
            continue
        loss[rows[~keep]] = name
        left[rows[~keep]] = False
    return loss


# --- the whole diagnosis ------------------------------------------------------------------------

def diagnose(prediction: EdgeCurves, gt_points: np.ndarray, source: CurveSource, scene, detector: str | None,
             run: Path | None, voxelize: bool = True) -> Diagnosis:
    """Diagnose every ground-truth curve and every false predicted curve.

    Args:
        prediction: the predicted curves in the ground-truth frame.
        gt_points: (N, 3) the ground-truth points the evaluation scores against.
        scene: the scene (its cameras, edge maps of `detector` and masks); run: the run folder
            the prediction came from, or None (no stages).
    """
    curves, notes = source.curves, list(source.notes)
    samples = prediction.sample(SAMPLE_SPACING)
    predicted = voxel_mean(samples) if voxelize else samples
    distance, _ = cKDTree(predicted).query(gt_points)
    owner = assign_points(gt_points, curves)
    if (owner < 0).any():
        notes.append(f"{int((owner < 0).sum())} ground-truth points lie on no identified curve (in no row)")
    evidence = view_evidence(curves, source.mesh, scene, detector)
    notes.append(f"views: {min(len(scene), MAX_VIEWS)} of {len(scene)}; maps: {detector or 'none'}")
    curves = _dihedrals_from_maps(curves, evidence, notes)
    stages = run_stages(run, scene.world_to_gt) if run is not None else None
    if run is None:
        notes.append("no run folder: the stages after the maps are not examined")
    elif stages is None:
        notes.append(f"{run} has no primitives.ply: the stages after the maps are not examined")
    primitive_tree = cKDTree(stages.centres) if stages is not None and len(stages.centres) else None
    pruned_tree = (cKDTree(stages.pruned) if stages is not None and stages.pruned is not None
                   and len(stages.pruned) else None)
    edge_tree = (cKDTree(stages.edge_points) if stages is not None and stages.edge_points is not None
                 and len(stages.edge_points) else None)
    reports = []
    for i, curve in enumerate(curves):
        own = gt_points[owner == i]
        d = distance[owner == i]
        recall = {int(round(t * 1000)): 100.0 * float(np.mean(d < t)) if len(d) else 0.0 for t in THRESHOLDS}
        report = CurveReport(curve.id, curve.type, _kind(curve.dihedral, evidence, i), curve.dihedral,
                             round(curve.length * 1000, 1), len(own), recall,
                             None if evidence.seeing is None else int(evidence.seeing[i]),
                             int(evidence.drawn_views[i]), int(evidence.outline_views[i]),
                             round(float(evidence.drawn[i]), 3) if detector is not None else None)
        if primitive_tree is not None and len(own):
            report.primitive_mm, report.primitive_cover = _closeness(primitive_tree, own)
        if edge_tree is not None and len(own):
            report.edge_point_mm, report.edge_point_cover = _closeness(edge_tree, own)
        if pruned_tree is not None and len(own):
            report.pruned_near = int(len(set().union(*pruned_tree.query_ball_point(own, NEAR))))
        report.missed = recall[10] < MISSED_RECALL
        report.cause = _cause(report, stages) if report.missed else ""
        reports.append(report)
    if stages is not None:
        _name_filters(reports, gt_points, owner, stages, primitive_tree, scene, detector)
    false_curves, false_count = _false_curves(prediction, gt_points, source.mesh, scene)
    return Diagnosis(reports, false_curves, false_count, _aggregate(reports, distance, owner, "kind"),
                     _aggregate(reports, distance, owner, "type"), notes)


def _dihedrals_from_maps(curves: list[GroundTruthCurve], evidence: ViewEvidence,
                        notes: list[str]) -> list[GroundTruthCurve]:
    """Curves of unknown dihedral whose faces are known (`wedge`), signed by the maps: a concave
    edge can be seen only from inside the wedge of air between its faces, a convex one only from
    outside the wedge of material, so the side whose views draw it more (by WEDGE_MARGIN) says
    which."""
    signed = []
    result = []
    for i, curve in enumerate(curves):
        into, outside = evidence.into_wedge[i], evidence.outside_wedge[i]
        known = curve.dihedral != "unknown" or curve.wedge is None
        if not known and abs(np.nan_to_num(into - outside)) > WEDGE_MARGIN:
            curve = dataclasses.replace(curve, dihedral="concave" if into > outside else "convex")
            signed.append(curve.id)
        result.append(curve)
    if signed:
        notes.append(f"dihedral signs of {len(signed)} curves from the maps (mean edge value in the views "
                     "looking into the wedge between their faces against the others)")
    return result


def _closeness(tree: cKDTree, points: np.ndarray) -> tuple[float, float]:
    """Median distance (mm) from `points` (N, 3) to the nearest point of `tree`, and the share (%)
    of them with one within NEAR."""
    distance = tree.query(points)[0]
    return round(1000 * float(np.median(distance)), 1), round(100 * float(np.mean(distance < NEAR)), 1)


def _kind(dihedral: str, evidence: ViewEvidence, i: int) -> str:
    """outline, convex, concave or unknown (see the module's docstring)."""
    if dihedral == "concave":
        return "concave"
    views = evidence.seeing[i] if evidence.seeing is not None else evidence.drawn_views[i]
    return "outline" if views and evidence.outline_views[i] > 0.5 * views else dihedral


def _cause(report: CurveReport, stages: RunStages | None) -> str:
    """Where a missed curve was lost: the first stage that fails (module docstring)."""
    if report.views_seeing is not None and report.views_seeing < MIN_VIEWS:
        return f"occluded: seen by {report.views_seeing} view(s)"
    if report.drawn is not None and report.drawn < MIN_DRAWN:
        return f"not drawn in the maps (mean edge value {report.drawn:.2f})"
    if stages is None:
        return "drawn; the run's stages are not available"
    if not report.primitive_cover or report.primitive_cover < MISSED_RECALL:
        logged = f"{stages.prunings} Fisher prunings logged"
        if not stages.prunings:
            pruned = "never reached (no Fisher pruning logged)"
        elif stages.pruned is None:
            pruned = f"pruned by Fisher or never reached: not recorded ({logged})"
        elif report.pruned_near:
            pruned = (f"pruned by Fisher: {report.pruned_near} of the last pruning's {len(stages.pruned)} "
                      f"primitives lay on it ({logged}, only the last recorded)")
        else:
            pruned = (f"none of the last Fisher pruning's {len(stages.pruned)} primitives lay on it: never "
                      f"reached or pruned earlier ({logged}, only the last recorded)")
        return (f"no primitive formed (within 10 mm of {report.primitive_cover or 0:.0f}% of it, median "
                f"{report.primitive_mm} mm); {pruned}")
    if not report.edge_point_cover or report.edge_point_cover < MISSED_RECALL:
        return "extraction"  # the filter is named once all curves' primitives are re-filtered
    shading = " or by the shading test" if stages.extract_config.get("filter_shading") else ""
    return (f"dropped at curve fitting{shading} (edge points within 10 mm of {report.edge_point_cover:.0f}% "
            "of it)")


def _name_filters(reports: list[CurveReport], gt_points: np.ndarray, owner: np.ndarray, stages: RunStages,
                  primitive_tree, scene, detector: str | None) -> None:
    """Names, in the cause of each curve lost at extraction, the filter that removed most of
    the primitives within NEAR of it (the filters run once over all those curves' primitives)."""
    lost = [i for i, report in enumerate(reports) if report.cause == "extraction"]
    if not lost:
        return
    near = {i: np.unique(np.concatenate(primitive_tree.query_ball_point(gt_points[owner == i], NEAR)
                                        ).astype(np.int64)) for i in lost}
    union = np.unique(np.concatenate(list(near.values())))
    losses = dict(zip(union.tolist(), filter_losses(union, stages, scene, detector)))
    for i in lost:
        counts = Counter(losses[j] for j in near[i].tolist())
        counts.pop("kept", None)
        name, number = counts.most_common(1)[0] if counts else ("outliers", 0)
        reports[i].cause = (f"dropped at extraction: {sum(counts.values())} of the {len(near[i])} primitives "
                            f"near it removed, {number} by the {name} filter")


def _aggregate(reports: list[CurveReport], distance: np.ndarray, owner: np.ndarray, key: str) -> dict:
    """Recall (%) over the ground-truth points of the curves of each kind (or type)."""
    groups: dict[str, list[int]] = {}
    for i, report in enumerate(reports):
        groups.setdefault(getattr(report, key), []).append(i)
    result = {}
    for name, members in sorted(groups.items()):
        d = distance[np.isin(owner, members)]
        recall = {f"recall_{int(round(t * 1000))}mm": 100.0 * float(np.mean(d < t)) if len(d) else 0.0
                  for t in THRESHOLDS}
        result[name] = {"curves": len(members), "gt_points": len(d), **recall}
    return result


def _false_curves(prediction: EdgeCurves, gt_points: np.ndarray, mesh, scene) -> tuple[list[FalseCurve], int]:
    """The predicted curves with under half their samples within NEAR of the ground truth, the
    longest MAX_FALSE of them with their cause, and how many there are."""
    tree = cKDTree(gt_points)
    found = []
    for index, chain in enumerate(curve_polylines(prediction)):
        samples = sample_polyline(chain, SAMPLE_SPACING)
        if len(samples) == 0:
            continue
        near = 100.0 * float(np.mean(tree.query(samples)[0] < NEAR))
        if near < 50.0:
            length = float(np.linalg.norm(np.diff(chain, axis=0), axis=1).sum())
            found.append((length, index, near, samples))
    found.sort(key=lambda item: -item[0])
    shown = found[:MAX_FALSE]
    samples = [item[3] for item in shown]
    if not shown:
        causes = []
    elif mesh is not None:
        causes = _surface_causes(samples, _surface(mesh))
    else:
        causes = _silhouette_causes(samples, scene)
    result = [FalseCurve(index, round(length * 1000, 1), round(near, 1), cause)
              for (length, index, near, _), cause in zip(shown, causes)]
    return result, len(found)


def _surface(mesh) -> tuple[cKDTree, np.ndarray]:
    """Points on the mesh's triangles about SURFACE_STEP apart (at most MAX_SURFACE_POINTS), in a
    tree, and (P,) whether each lies on a curved face (corner normals that differ)."""
    corners = mesh.positions
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    step = max(SURFACE_STEP, float(np.sqrt(area.sum() / MAX_SURFACE_POINTS)))
    count = np.minimum(np.ceil(area / step**2).astype(int), MAX_SURFACE_POINTS) + 1
    triangle = np.repeat(np.arange(len(corners)), count)
    rng = np.random.default_rng(0)
    u, v = rng.random(len(triangle)), rng.random(len(triangle))
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    c = corners[triangle]
    points = c[:, 0] + u[:, None] * (c[:, 1] - c[:, 0]) + v[:, None] * (c[:, 2] - c[:, 0])
    n = mesh.normals
    cos = np.minimum(np.einsum("ij,ij->i", n[:, 0], n[:, 1]), np.einsum("ij,ij->i", n[:, 0], n[:, 2]))
    curved = cos < np.cos(np.radians(CURVED_DEG))
    return cKDTree(points), curved[triangle]


def _surface_causes(samples: list[np.ndarray], surface: tuple[cKDTree, np.ndarray]) -> list[str]:
    """Why each false curve's samples (S_i, 3), ground-truth frame, lie on no edge, from the
    part's surface (`_surface`)."""
    tree, curved = surface
    causes = []
    for points in samples:
        distance, nearest = tree.query(points)
        if np.median(distance) > NEAR:
            causes.append(f"outlier ({1000 * float(np.median(distance)):.0f} mm off the surface)")
        elif np.mean(curved[nearest]) >= 0.5:
            causes.append("contour of a curved face")
        else:
            causes.append("on a flat face: texture or shading")
    return causes


def _silhouette_causes(samples: list[np.ndarray], scene) -> list[str]:
    """Without the part's mesh: an outlier where most of a false curve's samples (S_i, 3) land
    outside the object's masks, otherwise not told apart (the masks are read once for all)."""
    from edgedog.curves.filtering import pixels_outside_masks

    gt_to_world = np.linalg.inv(scene.world_to_gt)
    every = np.concatenate(samples)
    outside = pixels_outside_masks(every @ gt_to_world[:3, :3].T + gt_to_world[:3, 3], scene)
    if outside is None:
        return ["contour, texture or outlier: not told apart without the part's mesh or masks"] * len(samples)
    ends = np.cumsum([len(points) for points in samples])[:-1]
    return ["outlier (outside the object's silhouettes)" if np.median(part) > BESIDE_PX
            else "contour, texture or outlier: not told apart without the part's mesh"
            for part in np.split(outside, ends)]
