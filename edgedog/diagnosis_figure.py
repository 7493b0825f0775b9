"""A picture of the per-curve diagnosis (`edgedog eval --per-curve --figure FILE.png`).

The views that show the most of the missed ground-truth curves and of the predicted curves on
no edge, each with its image and, drawn over it, every ground-truth curve by outcome (found or
missed, hidden stretches dotted) and those predicted curves; a missed curve is labelled with its
id, and the legend names each missed curve's cause. It shows at a glance what a table of causes says.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from edgedog.curve_files import EdgeCurves, curve_polylines
from edgedog.diagnosis import CurveSource, Diagnosis, examined_views, render_mesh, visible_points
from edgedog.files import atomic_write_bytes
from edgedog.metrics import SAMPLE_SPACING, sample_polyline

FOUND, MISSED, FALSE = "#2ca02c", "#d62728", "#ff7f0e"
MAX_LISTED = 14
"""Missed curves named in a panel's legend; more are counted."""
PANEL_INCHES = 5.0


def choose_views(seen: np.ndarray, count: int) -> list[int]:
    """Up to `count` views, greedily: each the row of `seen` (V, N) bool that sees the most points
    not seen by the views already chosen; view 0 when none sees any."""
    chosen: list[int] = []
    covered = np.zeros(seen.shape[1], bool)
    for _ in range(min(count, len(seen))):
        gain = (seen & ~covered).sum(axis=1)
        gain[chosen] = -1
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        chosen.append(best)
        covered |= seen[best]
    return chosen or [0]


def _cause(text: str) -> str:
    """A cause's first clause: 'no primitive formed (within ...)' -> 'no primitive formed'."""
    return text.split(" (")[0].split(":")[0]


def _densified(polyline: np.ndarray) -> np.ndarray:
    """(S, 3) samples every SAMPLE_SPACING along a polyline (M, 3), its vertices where shorter."""
    samples = sample_polyline(polyline, SAMPLE_SPACING)
    return samples if len(samples) >= 2 else polyline


def _backdrop(scene, view: int) -> np.ndarray:
    """(H, W) grey picture of a view: the part's shading lifted and compressed, the background
    (where the view has a mask) near white, so that coloured curves read over both."""
    grey = 0.3 + 0.45 * scene.load_image(view).mean(axis=2)
    mask = scene.load_mask(view)
    return grey if mask is None else np.where(mask, grey, 0.95)


def _frame(camera, points: np.ndarray, margin: float = 0.08) -> tuple[np.ndarray, np.ndarray]:
    """Top-left and bottom-right pixel corners of a square around the projections of `points`
    (N, 3) in front of `camera`, `margin` of its side wider; the whole image when none is."""
    uv, depth = camera.project(points)
    uv = uv[depth > 0]
    if not len(uv):
        return np.zeros(2), np.array([camera.width, camera.height], float)
    low, high = uv.min(axis=0), uv.max(axis=0)
    half = (1 + 2 * margin) * float(np.max(high - low)) / 2 + 1
    return (low + high) / 2 - half, (low + high) / 2 + half


def _visibility(scene, mesh, gt_to_world: np.ndarray, views: np.ndarray,
                point_sets: list[np.ndarray]) -> list[np.ndarray]:
    """For each set of world points (N_k, 3), (len(views), N_k) bool: whether each view sees each
    point (on the part's mesh rendered from it; without a mesh, whether it frames the point)."""
    renderers: dict = {}
    seen: list[list[np.ndarray]] = [[] for _ in point_sets]
    try:
        for view in views:
            camera = scene.camera(int(view))
            render = None if mesh is None else render_mesh(renderers, mesh, gt_to_world, camera)
            for k, points in enumerate(point_sets):
                seen[k].append(visible_points(points, camera, render))
    finally:
        for renderer in renderers.values():
            renderer.release()
    return [np.stack(rows) for rows in seen]


def _draw_panel(axes, scene, view: int, curves: list[np.ndarray], visible: list[np.ndarray], missed: set[int],
                labels: list[str], false_lines: list[np.ndarray], every: np.ndarray) -> None:
    """One view: its picture, the ground-truth curves (world, each with its (S,) visibility) by
    outcome, the false curves, and the missed curves it sees named with their causes (`labels`)."""
    camera = scene.camera(view)
    axes.imshow(_backdrop(scene, view), cmap="gray", vmin=0, vmax=1)
    for i, (points, seen) in enumerate(zip(curves, visible)):
        uv, depth = camera.project(points)
        if (depth <= 0).any():
            continue
        colour, width = (MISSED, 2.2) if i in missed else (FOUND, 1.0)
        axes.plot(uv[:, 0], uv[:, 1], color=colour, lw=0.8, ls=":", alpha=0.7)
        axes.plot(*np.where(seen[:, None], uv, np.nan).T, color=colour, lw=width)
        if i in missed and seen.any():
            x, y = uv[seen][seen.sum() // 2]
            axes.annotate(labels[i].split()[0], (x, y), color=MISSED, fontsize=8, weight="bold",
                          xytext=(3, 3), textcoords="offset points")
    for points in false_lines:
        uv, depth = camera.project(points)
        if (depth > 0).all():
            axes.plot(uv[:, 0], uv[:, 1], color=FALSE, lw=1.4, ls="--")
    (left, top), (right, bottom) = _frame(camera, every)
    axes.set_xlim(left, right)
    axes.set_ylim(bottom, top)
    axes.set_xticks([])
    axes.set_yticks([])
    in_view = [labels[i] for i in sorted(missed) if visible[i].any()]
    listed = in_view[:MAX_LISTED]
    if len(in_view) > MAX_LISTED:
        listed.append(f"... {len(in_view) - MAX_LISTED} more")
    axes.set_title(f"view {view}: {len(in_view)} missed curve(s) seen", fontsize=9)
    if listed:
        axes.text(0.01, 0.01, "\n".join(listed), transform=axes.transAxes, fontsize=6.5, va="bottom",
                  color="white", bbox={"facecolor": "black", "alpha": 0.55, "lw": 0})


def draw_missed_edges(diagnosis: Diagnosis, source: CurveSource, prediction: EdgeCurves, scene,
                      out: Path, views: int = 2, title: str = "") -> list[int]:
    """Write the picture (PNG, atomically) and return the views shown.

    Args:
        diagnosis: `edgedog.diagnosis.diagnose`'s report of `prediction`.
        source: the ground-truth curves it diagnosed (ground-truth frame) and the part's mesh.
        prediction: the predicted curves, ground-truth frame.
        scene: the views diagnosed (cameras, images; world frame = inverse of its world_to_gt).
        views: how many views to show; chosen by `choose_views`, among the views the diagnosis
            examines, over the samples of the missed curves and of the predicted curves on no
            edge that each view sees.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    gt_to_world = np.linalg.inv(scene.world_to_gt)
    densified = EdgeCurves(polylines=[_densified(c.polyline) for c in source.curves])
    curves = densified.transformed(gt_to_world).polylines
    reports = {r.id: r for r in diagnosis.curves}
    missed = {i for i, c in enumerate(source.curves) if reports[c.id].missed}
    labels = [f"{c.id} {reports[c.id].kind}: {_cause(reports[c.id].cause)}" for c in source.curves]
    false_indices = {f.index for f in diagnosis.false_curves}
    false_lines = EdgeCurves(polylines=[chain for index, chain in enumerate(curve_polylines(prediction))
                                        if index in false_indices]).transformed(gt_to_world).polylines
    every = np.concatenate(curves) if curves else np.zeros((0, 3))
    owner = np.repeat(np.arange(len(curves)), [len(c) for c in curves])
    examined = examined_views(len(scene))
    seen, seen_false = _visibility(scene, source.mesh, gt_to_world, examined,
                                   [every, np.concatenate(false_lines) if false_lines else np.zeros((0, 3))])
    rows = choose_views(np.concatenate([seen[:, np.isin(owner, sorted(missed))], seen_false], axis=1), views)

    figure = Figure(figsize=(PANEL_INCHES * len(rows), PANEL_INCHES + 1.0))
    FigureCanvasAgg(figure)
    for panel, row in enumerate(rows):
        visible = [seen[row, owner == i] for i in range(len(curves))]
        _draw_panel(figure.add_subplot(1, len(rows), panel + 1), scene, int(examined[row]), curves, visible,
                    missed, labels, false_lines, every)
    heading = [title] if title else []
    heading += [f"{len(missed)} of {len(curves)} ground-truth curves missed, "
                f"{diagnosis.false_count} predicted on no edge",
                "ground truth found: green, missed: red (dotted where hidden)",
                "predicted curves on no edge: orange"]
    figure.suptitle("\n".join(heading), fontsize=8)
    figure.tight_layout()
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    atomic_write_bytes(out, buffer.getvalue())
    return [int(examined[row]) for row in rows]
