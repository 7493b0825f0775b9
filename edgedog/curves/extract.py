"""The public extraction API: oriented edge points -> parametric curves, primitives in memory ->
filtered points and curves, and a run folder's primitives -> those written beside them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from edgedog.curve_files import EdgeCurves, write_edges
from edgedog.curves import (
    circles,
    completion,
    contours,
    drawing_plane,
    filtering,
    fitting,
    grouping,
    junctions,
    shading,
    slides,
    sweep,
    topology,
)
from edgedog.curves.config import ExtractConfig
from edgedog.errors import InputError
from edgedog.files import read_json
from edgedog.primitives import UNCERTAINTY, EdgePrimitives, read_ply, write_point_columns
from edgedog.scenes import Scene, load_scene

OUTPUTS = ("curves.json", "curves.obj", "curves.ply", "edge_points.ply")
"""What `extract_run` writes in the run folder."""


def scene_size(points: np.ndarray) -> float:
    """Diagonal of the bounding box of points (N, 3); the unit of the relative settings."""
    return float(np.linalg.norm(np.ptp(points, axis=0))) if len(points) else 0.0


def extract_curves(points: np.ndarray, directions: np.ndarray, config: ExtractConfig = ExtractConfig(),
                   size: float | None = None) -> tuple[EdgeCurves, list[grouping.Chain]]:
    """Fit lines and cubic Béziers to oriented edge points.

    Args:
        points: (N, 3) edge points; directions: (N, 3) their edge directions (sign ignored).
        size: the scene size the relative lengths of `config` refer to; default the diagonal of
            the points' bounding box.
    Returns:
        the curves (lines (L, 2, 3) and Béziers (B, 4, 3)), and the chains they were fitted to
        (one per curve between corners and junctions; a circle is one closed chain).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True).clip(1e-18)
    size = scene_size(points) if size is None else size
    if len(points) < config.min_chain_vertices or size <= 0:
        return EdgeCurves(), []
    c = config
    min_cos = math.cos(math.radians(c.link_angle))
    smooth_points, smooth_dirs = grouping.smooth(points, directions, c.smoothing_radius * size, min_cos,
                                                 c.smoothing_iterations)
    vertices, axes = grouping.thin(smooth_points, smooth_dirs, c.node_spacing * size, min_cos)
    pairs, lengths = grouping.candidate_links(vertices, axes, c.link_distance * size, min_cos)
    links = grouping.prune_spurs(grouping.spanning_links(pairs, lengths, len(vertices)), len(vertices),
                                 c.min_chain_vertices)
    chains = grouping.chains_from_links(vertices, links, pairs)
    chains = topology.join_chains(chains, c.join_distance * size, min_cos)
    chains = topology.drop_isolated(chains, c.min_chain_vertices, c.snap_radius * size)
    chains = [piece for chain in chains for piece in topology.split_at_corners(chain, c.corner_angle)]
    chains = topology.split_at_junctions(chains, c.snap_radius * size)
    rng = np.random.default_rng(c.seed)
    pieces = [piece for chain in chains for piece in fitting.fit_chain(
        chain, c.line_tolerance * size, c.bezier_tolerance * size, c.max_outlier_share, rng)]
    pieces = junctions.merge_collinear(pieces, c.snap_radius * size, c.line_tolerance * size)
    pieces = junctions.snap_ends(pieces, c.snap_radius * size)
    return EdgeCurves(lines=[p for p in pieces if len(p) == 2],
                      beziers=[p for p in pieces if len(p) == 4]), chains


def edge_directions(primitives: EdgePrimitives, config: ExtractConfig) -> np.ndarray:
    """(N, 3) directions: a primitive's own axis where it is elongated enough to trust, else the
    principal axis of its neighbourhood."""
    directions = primitives.directions.copy()
    round_ = primitives.elongation < config.min_elongation
    if round_.any() and len(primitives) >= 3:
        directions[round_] = grouping.principal_axes(primitives.points, config.direction_neighbours)[round_]
    return directions


def _on_chains(primitives: EdgePrimitives, config: ExtractConfig, inside: np.ndarray | None) -> np.ndarray:
    """(N,) `filtering.chain_mask` of the primitives with `config`'s chain settings, its lengths
    relative to the size of the points inside the silhouettes (`inside`; all without masks): the
    floaters the outlier filter is there for would stretch the scene's size."""
    size = scene_size(primitives.points if inside is None else primitives.points[inside])
    return filtering.chain_mask(primitives.points, edge_directions(primitives, config),
                                config.chain_radius * size, config.chain_extent * size,
                                math.cos(math.radians(config.link_angle)))


@dataclass
class RunExtraction:
    """What `extract_run` produced.

    points: the filtered primitives; directions: (N, 3) the directions used for them; counts:
    primitives left after each filter, chains, lines and Béziers, in pipeline order.
    """

    curves: EdgeCurves
    points: EdgePrimitives
    directions: np.ndarray
    counts: dict[str, int] = field(default_factory=dict)


def run_scene(run_dir: Path, maps: bool = True) -> tuple[Scene, str]:
    """The scene as a run was trained on it (its resolution, and with `maps` the edge maps it
    used, computed ones found in the edge-map cache) and the name of those maps (from log.json)."""
    from edgedog.edges.cache import attach_edge_maps

    path = run_dir / "log.json"
    log = read_json(path)
    if not (isinstance(log, dict) and all(isinstance(log.get(key), str) for key in ("scene", "detector"))):
        raise InputError(path, "expected 'scene' and 'detector' strings (from edgedog train)")
    config = log.get("config", {})
    # The config by section (run format 3) or flat (runs written before the sections).
    map_settings = config.get("maps", config) if isinstance(config, dict) else None
    downscale = map_settings.get("downscale", 1) if isinstance(map_settings, dict) else None
    if type(downscale) is not int or downscale < 1:
        raise InputError(path, f"config.maps.downscale must be a positive integer, got {downscale!r}")
    scene = load_scene(log["scene"], downscale=downscale).without_damaged()  # as training skipped them
    if maps:
        attach_edge_maps(scene, log["detector"])
    return scene, log["detector"]


def filter_primitives(primitives: EdgePrimitives, config: ExtractConfig, scene: Scene | None,
                      detector: str | None, counts: dict[str, int],
                      surface: contours.HullSurface | None = None) -> EdgePrimitives:
    """Apply the switched-on filters in order (opacity, projection, outliers, silhouette, contours),
    recording in `counts` how many primitives are left after each. A filter that does not run is
    not counted: the silhouette and contour filters on a scene without masks or without a scene
    (None), the outlier filter on 'auto' where the silhouette filter runs. The silhouette filter
    comes after the outliers: the outlier statistics are relative to the spread of all points, and
    without the points it removes they drop sparse real edges (half of 00000006's top hole
    circle). The contour filter, last, also needs the edge maps (`detector`), and carves the
    scene's visual hull unless given it (`surface`)."""
    counts["primitives"] = len(primitives)
    if config.filter_opacity:
        primitives = primitives.subset(filtering.opacity_mask(primitives.opacity, config.min_opacity))
        counts["after_opacity"] = len(primitives)
    if config.filter_projection:
        weights = None
        if config.projection_views == "drawn" and primitives.opacity_dirs is not None:
            centres = np.stack([scene.camera(i).center for i in range(len(scene))])
            weights = filtering.view_weights(primitives.points, primitives.opacity, primitives.opacity_dirs,
                                             centres)
        keep = filtering.projection_mask(primitives.points, scene, detector, config.min_edge_value, weights)
        primitives = primitives.subset(keep)
        counts["after_projection"] = len(primitives)
    # Each point's silhouette test is its own: taken now, it is the same after the outlier filter.
    inside = (filtering.silhouette_mask(primitives.points, scene, config.max_outside_pixels)
              if config.filter_silhouette and scene is not None else None)
    if config.filter_outliers == "on" or (config.filter_outliers == "auto" and inside is None):
        keep = filtering.outlier_mask(primitives.points, config.outlier_neighbours, config.outlier_std)
        if config.outlier_chains and not keep.all():
            keep |= _on_chains(primitives, config, inside)
        primitives = primitives.subset(keep)
        inside = None if inside is None else inside[keep]
        counts["after_outliers"] = len(primitives)
    if inside is not None:
        primitives = primitives.subset(inside)
        counts["after_silhouette"] = len(primitives)
    if config.filter_contours and scene is not None and detector is not None:
        surface = surface or contours.HullSurface(scene, config.contour_hull_cells)
        keep = contours.contour_mask(primitives.points, surface, detector, config.contour_max_cosine,
                                     config.contour_max_share, config.contour_probe_cells)
        if keep is not None:
            primitives = primitives.subset(keep)
            counts["after_contours"] = len(primitives)
    return primitives


def write_edge_points(path: Path, points: EdgePrimitives, directions: np.ndarray) -> None:
    """edge_points.ply: x, y, z, direction dx, dy, dz, opacity, k_0, k_1 (and uncertainty)."""
    columns = {name: points.points[:, i] for i, name in enumerate("xyz")}
    columns.update({name: directions[:, i] for i, name in enumerate(("dx", "dy", "dz"))})
    columns.update({"opacity": points.opacity, "k_0": points.k[:, 0], "k_1": points.k[:, 1]})
    if points.uncertainty is not None:
        columns[UNCERTAINTY] = points.uncertainty
    write_point_columns(path, columns)


def extract_primitives(primitives: EdgePrimitives, config: ExtractConfig = ExtractConfig(),
                       scene: Scene | None = None, detector: str | None = None) -> RunExtraction:
    """Filter primitives and fit curves to them, writing nothing.

    Args:
        primitives: e.g. `EdgePrimitives.from_arrays` of a snapshot's or a PLY's primitives.
        scene, detector: the run's scene and the name of its edge maps (loaded), needed by the
            projection and contour filters and the line completion (the silhouette filter needs
            the scene only).
    """
    counts: dict[str, int] = {}
    if scene is not None and scene.read_cache is None:
        scene = scene.with_read_cache()  # the filters read the same maps and masks several times
    # Carved on first use, and then shared by the contour filter and the line completion.
    surface = None if scene is None else contours.HullSurface(scene, config.contour_hull_cells)
    points = filter_primitives(primitives, config, scene, detector, counts, surface)
    directions = edge_directions(points, config)
    fitted, chains = extract_curves(points.points, directions, config)
    counts.update(chains=len(chains), lines=len(fitted.lines), beziers=len(fitted.beziers))
    curves = fitted
    judge_shading = (config.filter_shading and scene is not None and detector is not None
                     and surface.every_view_masked)
    judge_plane = config.filter_drawing_plane and scene is not None and detector is not None
    if judge_shading or judge_plane:
        # Both tests judge only the curves some drawing views see grazing on the hull (suspects of
        # the contour filter's test), each at its own share; the grazing is measured once.
        samples = shading.curve_samples(fitted)
        grazing = shading.curve_grazing(samples, surface, detector, config.contour_max_cosine,
                                        config.contour_probe_cells)
        keep = np.ones(len(samples), bool)
        if judge_shading:
            suspects = grazing >= config.shading_grazing
            shares = np.full(len(samples), np.nan)  # the others are kept
            shares[suspects] = shading.shading_shares(samples[suspects], scene, detector, surface.masks,
                                                      config.shading_tolerance)
            keep = ~(shares < config.shading_min_share)
            counts["shading_dropped"] = int((~keep).sum())
        if judge_plane:
            suspects = keep & (grazing >= config.drawing_plane_grazing)
            spreads = np.full(len(samples), np.nan)
            spreads[suspects] = drawing_plane.curve_spreads(samples[suspects], scene, detector)
            flat = spreads < config.drawing_plane_spread
            counts["drawing_plane_dropped"] = int(flat.sum())
            keep &= ~flat
        curves = fitted.kept(keep)
    completing = config.complete_lines or config.complete_circles or config.complete_slides
    if completing and scene is not None and detector is not None:
        # What the maps draw along the curves the shading test dropped (contours) stays explained.
        size = scene_size(points.points)
        evidence = completion.gather_evidence(fitted, surface, detector, size, config)
        lines, arcs, slid = np.empty((0, 2, 3)), np.empty((0, 4, 3)), np.empty((0, 2, 3))
        if evidence is not None and config.complete_lines:
            lines = completion.complete_lines(evidence, surface, detector, size, config)
        searching = evidence is not None and (config.complete_circles or config.complete_slides)
        maps = [sweep.view_maps(view.edge_map) for view in evidence.views] if searching else []
        if searching and config.complete_circles:
            axes = circles.found_circles(chains, config.bezier_tolerance * size, size)
            arcs = circles.complete_circles(axes, evidence, maps, size, config)
        if searching and config.complete_slides:
            # What the other completions added is found: its pixels are explained, no copy rests on it.
            found = evidence.explained_by(EdgeCurves(lines=lines, beziers=arcs).sample(size / 1000),
                                          config.completion_explained)
            slid = slides.complete_slides(curves.lines, found, maps, surface, detector, size, config)
        curves = EdgeCurves(lines=np.concatenate([curves.lines, lines, slid]),
                            beziers=np.concatenate([curves.beziers, arcs]))
        if config.complete_lines:
            counts["completed_lines"] = len(lines)
        if config.complete_circles:
            counts["completed_circles"] = len(arcs) // 4
        if config.complete_slides:
            counts["completed_slides"] = len(slid)
    return RunExtraction(curves, points, directions, counts)


def extract_run(run_dir: str | Path, config: ExtractConfig = ExtractConfig(), scene: Scene | None = None,
                detector: str | None = None, layers: set[int] | None = None,
                out_dir: str | Path | None = None) -> RunExtraction:
    """Filter a run's primitives, fit curves, and write `OUTPUTS` atomically in the run folder.

    Args:
        scene, detector: the run's scene and edge maps, when the caller has them; by default
            read from the run's log.json, and only when the projection or silhouette filter
            needs them.
        layers: extract only the primitives of these layers (default: all).
        out_dir: where the outputs go (default: the run folder).
    """
    run_dir = Path(run_dir)
    out_dir = run_dir if out_dir is None else Path(out_dir)
    primitives = EdgePrimitives.from_arrays(read_ply(run_dir / "primitives.ply"))
    if layers is not None:
        primitives = primitives.in_layers(layers)
    with_maps = (config.filter_projection or config.filter_contours or config.complete_lines
                 or config.complete_circles or config.complete_slides or config.filter_shading
                 or config.filter_drawing_plane)
    if (with_maps or config.filter_silhouette) and (scene is None or detector is None):
        scene, detector = run_scene(run_dir, maps=with_maps)
    result = extract_primitives(primitives, config, scene, detector)
    for name in OUTPUTS[:3]:
        write_edges(out_dir / name, result.curves)
    write_edge_points(out_dir / "edge_points.ply", result.points, result.directions)
    return result
