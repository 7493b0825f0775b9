"""Typed settings of curve extraction: `ExtractConfig`, one section of settings as
`edgedog.settings` defines them (each field's allowed values in its type, checked when one is
made), and `with_overrides`, which reads `edgedog extract RUN --set extract.FIELD=VALUE` (or the
bare FIELD) as `edgedog train --set` reads a run's settings.

Lengths of the grouping and fitting stages are fractions of the scene size: the diagonal of
the bounding box of the filtered points (about 1.4 for an ABC object, where 1 unit = 1000 mm).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Annotated, Literal

from edgedog.hull import MAX_HULL_CELLS
from edgedog.settings import Range, Settings, to_dict
from edgedog.settings import with_overrides as settings_with_overrides

ProjectionViews = Literal["all", "drawn"]
"""Which views the projection filter averages the edge value over: 'all' equally (EdgeGaussians),
or 'drawn': each view by the primitive's opacity there relative to its largest (a view-dependent
opacity's primitive counts the views it is drawn in; without one, the same as 'all')."""

OutlierFilter = Literal["auto", "on", "off"]
"""When the statistical outlier filter runs: 'on', 'off', or 'auto' (where the silhouette filter
does not)."""

MAX_NEIGHBOURS = 256
"""Neighbour counts size (N, k) arrays of KD-tree queries: EdgeGaussians' outlier filter takes 25,
the principal axes 32."""
MAX_SMOOTHING_ITERATIONS = 50
"""Each smoothing iteration is a pass of ball queries over every point; a few already merge
nearby parallel edges."""

Share = Annotated[float, Range(0, 1)]
SceneLength = Annotated[float, Range(0, 1, open_low=True)]
"""A length as a fraction of the scene size: no two points are further apart than 1, and a radius
that large makes every point every other's neighbour."""
Angle = Annotated[float, Range(0, 90, open_low=True, open_high=True)]
"""Degrees between two directions (undirected: at most 90)."""
Neighbours = Annotated[int, Range(2, MAX_NEIGHBOURS)]


@dataclass(frozen=True)
class ExtractConfig(Settings):
    """Every setting of `extract`. Each filter can be switched off on its own.

    The grouping and fitting defaults were chosen on a noisy ABC run (primitives ~9 mm from the
    edges); cleaner runs can use a smaller `node_spacing` and tolerances.
    """

    # --- filters (EdgeGaussians' post-processing, and a silhouette test)
    filter_opacity: bool = True
    min_opacity: Share = 0.2
    """Keep primitives whose (activated) opacity is above this."""
    filter_projection: bool = True
    min_edge_value: Share = 0.1
    """Keep points whose edge-map value, averaged over ALL views, is above this (a view that does
    not see the point counts as 0)."""
    projection_views: ProjectionViews = "all"
    """'drawn': average over the views that draw the primitive instead (`ProjectionViews`), as
    training's projection cull counts views, so that an edge only a few views see (its
    view-dependent opacity low in the others) is not dropped for the views that cannot see it.
    'all' stays the default: on today's runs primitives seldom form on such edges and the CAD
    benchmark does not move (F10 90.37 -> 90.38; docs/notes/2026-11-27-few-view-probes.md)."""
    filter_silhouette: bool = True
    max_outside_pixels: Annotated[float, Range(0)] = 3.0
    """Keep points that land at most this many pixels (of the run's views) outside the object's
    mask in every view; skipped on scenes without masks. Edge maps also draw the occluding
    contours of curved surfaces, which move with the view and are not edges of the object;
    training places primitives for them around the object, outside it in some views. 3 (was 4):
    it also drops the corners where a fillet's silhouette rays meet outside the part (the 42 CAD
    designs: docs/RESULTS.md, "The silhouette filter's limit")."""
    filter_outliers: OutlierFilter = "on"
    """Statistical outliers: drop points whose mean distance to their `outlier_neighbours` nearest
    points exceeds the mean of that value over all points by `outlier_std` standard deviations.
    'auto' runs it only where the silhouette filter does not (a scene without masks, or
    `filter_silhouette` off). The statistics are relative to the points' own density: an edge
    that training holds with few primitives is taken for outliers (on the ABC renders, where the
    silhouette filter removes the floaters, 'auto' gains up to 3.7 F10), while multi-view ghosts
    inside the object's silhouette, which no mask removes, are what it is there for (the built-in
    part: 'auto' loses 2.8 to 5.2 F10). docs/notes/2026-11-25-outlier-filter.md."""
    outlier_neighbours: Neighbours = 8
    """EdgeGaussians use 25 neighbours; an edge held by fewer primitives than that reaches across
    to other edges and is dropped whole, so 8 (docs/BENCHMARKS.md)."""
    outlier_std: Annotated[float, Range(0)] = 2.0
    outlier_chains: bool = True
    """Spare the outliers on a chain (`filtering.chain_mask`): points linked within
    `chain_radius`, their directions and offsets agreeing within `link_angle`, spanning at least
    `chain_extent`: edges that training holds with few primitives. On the CAD benchmark's 42
    `quick` runs F10 +0.3 (docs/RESULTS.md, "Sparing the outliers on chains"); False: every
    outlier goes, as in the paper."""
    chain_radius: SceneLength = 0.02
    """Longest link of `outlier_chains`' chains (a fraction of the scene size, measured before the
    outlier filter over the points inside the silhouettes)."""
    chain_extent: SceneLength = 0.06
    """Shortest chain that `outlier_chains` spares (the diagonal of its bounding box)."""
    filter_contours: bool = True
    """Drop the points on the occluding contours of curved faces: those that most views drawing
    them see at grazing incidence on the object's visual hull (`edgedog.curves.contours`);
    skipped on scenes without masks. On the 42 CAD designs at `quick` F10 87.7 -> 89.0 (better on
    11, worse on 6 by at most 0.3; Acc 11.5 -> 7.4 mm); on the shared ABC objects within 0.4
    (docs/notes/2026-11-27-contour-filter.md)."""
    contour_max_cosine: Share = 0.25
    """A view sees a point at grazing incidence where |cos| between the direction to its camera
    and the hull's normals is below this (0.25: within 14.5 degrees of the surface)."""
    contour_max_share: Share = 0.5
    """Keep a point when at most this share of the views drawing it see it at grazing incidence.
    Stricter shares remove more contours and, on the shared ABC objects, some true edges: 0.3
    with `contour_probe_cells` 1.5 gains 2.3 F10 on the CAD designs, loses up to 0.9 on 00004926."""
    contour_hull_cells: Annotated[int, Range(16, MAX_HULL_CELLS)] = 128
    """Cells per side of the visual hull's grid over the object's box. 192 (5.6 mm cells on the
    CAD designs) moves the 42 CAD designs' F10 by +0.10 ± 0.18 and costs 00000006 1.1 over three
    seeds (docs/notes/2026-12-02-hull-vote-today.md)."""
    contour_probe_cells: Annotated[float, Range(0, 8)] = 1.0
    """A view grazes a point only where it grazes the hull's normals this many cells around it
    too (0: the point's own normal): at an edge the hull creases, and no view grazes both faces."""

    filter_shading: bool = False
    """Drop the fitted curves that some of the views drawing them see at grazing incidence on
    the visual hull (`shading_grazing`, below the contour filter's own limit) and whose two
    sides' grey values change between those views (`edgedog.curves.shading`): occluding contours
    of curved faces that the contour filter leaves. Needs renders or photos of a matte object
    under a fixed light; skipped on scenes without masks. Off: on the 42 CAD designs at `quick`
    F10 +0.73 ± 0.43 (22 better, 6 worse, the cup -10.8), on ABC 00000006 -1.05 ± 0.43 over
    three seeds (arcs beside its chamfer go; docs/notes/2026-12-02-shading-on-the-suite.md)."""
    shading_grazing: Share = 0.2
    """Only curves whose points this share of the drawing views see at grazing incidence (on
    average; the contour filter's test, `contour_max_cosine`, `contour_probe_cells`) are judged
    by their shading: an outline whose far side is the part itself also changes its grey values
    between views, but no view grazes it."""
    shading_min_share: Share = 0.4
    """Keep a curve when on each of its sides at least this share of the views that draw it show
    the same grey value (within `shading_tolerance`)."""
    shading_tolerance: Share = 0.02
    """Largest difference of a side's grey value (0 to 1) from its median over the views that
    still counts as the same face."""
    filter_drawing_plane: bool = True
    """Drop the fitted curves that the views drawing them all look at from near one plane through
    them (`edgedog.curves.drawing_plane`): a view draws the contour of a curved face where it looks
    along the surface, so a contour's drawing views lie near its tangent plane, while an edge's
    come from all around. Only the contour filter's suspects are judged (`drawing_plane_grazing`);
    skipped on scenes without masks. On the 42 CAD designs at `quick` F10 +0.36 (7 better, the
    loft +11.4, the stepped shaft +2.3, the cup +0.5; none worse); the shared objects' six runs
    unchanged (docs/RESULTS.md). False: the curves as fitted."""
    drawing_plane_spread: Annotated[float, Range(0, 1)] = 0.08
    """Drop a suspect curve whose drawing directions spread off their best plane by less than
    this (the smallest eigenvalue of their mean outer product, median over the curve; 1/3 for
    views from all around)."""
    drawing_plane_grazing: Share = 0.35
    """Only curves whose points this share of the drawing views see at grazing incidence on the
    visual hull (on average; the contour filter's test) are judged. 0.1 also drops chamfer edges
    (CAD designs 10 and 34: F10 -1.15 and -0.36); 0.35, chosen on the same 19 designs, none."""

    # --- completion
    complete_lines: bool = True
    """Add the straight edges the curves miss, triangulated from the line segments the edge maps
    draw where no curve projects and refined on the views that draw them
    (`edgedog.curves.completion`): edges few views see, on which no primitive formed. Skipped on
    scenes without masks. On the CAD benchmark's 42 `quick` runs F10 +0.2, concave recall 54.5 ->
    57.8 % (docs/RESULTS.md, "Completing straight edges from the maps"); False: the curves are
    the primitives' only, as in the paper."""
    completion_views: Annotated[int, Range(2, 1000)] = 5
    """A completed line is drawn, among the pixels no curve explains, by at least this many views."""
    completion_explained: Annotated[int, Range(1, 32)] = 4
    """Pixels (of the edge maps): a drawn pixel this close to a curve's projection is that curve's,
    and no completed line may rest on it."""
    completion_cover: Annotated[float, Range(0, 1, open_low=True)] = 0.75
    """A view draws a line where this share of its points lands on drawn pixels."""
    completion_spread: Annotated[float, Range(0, 180)] = 20.0
    """Degrees between the directions of the two farthest views that draw a completed line."""
    completion_contour_share: Share = 0.3
    """A completed line is an occluding contour, and dropped, where more than this share of the
    views drawing it see it at grazing incidence (the contour filter's test, stricter: a ruled
    face's contours are straight)."""
    complete_circles: bool = True
    """Add the circles the curves miss on the axis of a circle they hold, of its radius (a blind
    hole's floor, a counterbore's step, a boss's foot: edges few views see), found where the edge
    maps draw them and no curve explains it (`edgedog.curves.circles`). Skipped on scenes without
    masks. On the 42 CAD designs' `quick` runs F10 +0.35, Comp -0.7 mm, 8 better, one worse, the
    shared objects unchanged (docs/RESULTS.md, "Completing circles along their axes"). False: no
    circle is added."""
    circle_reach: SceneLength = 0.3
    """How far along its axis, either way, a circle is moved in search of another."""
    circle_cover: Share = 0.8
    """An added circle has this share of its points drawn by the views."""
    circle_views_cover: Share = 0.6
    """... and this share drawn by two views or more (one view's ellipse fits a circle at any
    depth along its line of sight). Both chosen on 23 CAD designs' `quick` runs, where the true
    circles found scored 0.81-1.0 and 0.61-0.91, and no circle off the edges both over 0.77 and
    0.48."""

    complete_slides: bool = True
    """Add the straight edges the curves miss that are copies of a fitted line moved across
    itself along a direction the part's lines run in (a pocket's floor under its rim, a channel's
    concave corners under its walls' top edges), found where the edge maps draw them and no curve
    explains it, with the lines joining a copy's ends to its line's (`edgedog.curves.slides`).
    Skipped on scenes without masks. On the 42 CAD designs' `quick` runs F10 +0.16, concave
    recall at 10 mm 67.4 -> 70.4 %, Comp -0.5 mm, the shared objects unchanged (docs/RESULTS.md,
    "Sliding lines across themselves"). False: no line is slid."""
    slide_reach: SceneLength = 0.3
    """How far, either way, a line is moved in search of a copy."""
    slide_cover: Share = 0.8
    """An added line has this share of its points drawn by the views."""
    slide_views_cover: Share = 0.6
    """... and this share drawn by two views or more."""
    slide_views: Annotated[float, Range(0, 1000)] = 2.0
    """... and the views' edge values summed at each of its points, averaged along it, at least
    this: as much as this many views drawing all of it at full strength."""

    # --- directions
    min_elongation: Annotated[float, Range(1)] = 1.5
    """A primitive's own axis (largest scale) is its direction when largest / middle scale is at
    least this; rounder primitives get the principal axis of their neighbourhood instead."""
    direction_neighbours: Neighbours = 32
    """Neighbourhood size of those principal axes."""

    # --- grouping (fractions of the scene size)
    smoothing_radius: SceneLength = 0.015
    """Points move across their direction onto the centre of the agreeing points this close
    (directions are re-estimated from the same neighbours)."""
    smoothing_iterations: Annotated[int, Range(0, MAX_SMOOTHING_ITERATIONS)] = 1
    """More iterations thin the point tube further but merge nearby parallel edges."""
    node_spacing: SceneLength = 0.006
    """Spacing of the chain vertices the points are thinned to."""
    link_distance: SceneLength = 0.06
    """Longest link between two vertices of a chain (each vertex links only among its 8
    nearest). 0.03 before: 0.06 bridges the sparse stretches of faint curved edges; on 21 ABC
    runs F10 +0.37 on average, at worst -1.2 (docs/BENCHMARKS.md)."""
    join_distance: SceneLength = 0.045
    """Longest gap bridged between two chain ends that face each other (a curve broken where
    points are missing; the two ends of a circle)."""
    link_angle: Angle = 30.0
    """Degrees: linked vertices' directions, and the vector between them, agree within this."""
    corner_angle: Angle = 60.0
    """Degrees: a chain is split where it turns more than this over a few vertices."""
    min_chain_vertices: Annotated[int, Range(2)] = 4
    """Shorter chains are dropped as noise unless an end meets a longer chain's end (within
    `snap_radius`: a short edge between corners), and shorter side branches are pruned."""

    # --- fitting (fractions of the scene size)
    line_tolerance: SceneLength = 0.004
    """A chain is a line when RANSAC finds one holding all but `max_outlier_share` of its vertices
    within this distance; also the collinearity tolerance of merges."""
    max_outlier_share: Annotated[float, Range(0, 1, open_high=True)] = 0.05
    bezier_tolerance: SceneLength = 0.002
    """A cubic Bézier is kept when its RMS distance to the chain is below this; else it is split.
    At 0.004 (7 mm on an ABC object) one Bézier cut up to 7.7 mm inside a rounded part;
    0.002 raised F5 on all four ABC runs measured (docs/BENCHMARKS.md) for 3 to 8 more curves."""
    snap_radius: SceneLength = 0.01
    """Curve ends this close, or whose extensions meet within it, are snapped to one junction
    point; a chain end this close to another chain's interior splits it there (a T)."""
    seed: Annotated[int, Range(0)] = 0
    """Seed of RANSAC."""


@dataclass(frozen=True)
class ExtractSettings(Settings):
    """What `edgedog extract --set` names: the section `extract` (`extract.min_opacity`; the bare
    `min_opacity` names it too)."""

    extract: ExtractConfig = field(default_factory=ExtractConfig)


def with_overrides(config: ExtractConfig, assignments: Iterable[str]) -> ExtractConfig:
    """`config` with the `--set KEY=VALUE` strings applied (KEY `extract.FIELD` or FIELD), each
    value read by its setting's type; a bad one raises ConfigError naming it and its range."""
    return settings_with_overrides(ExtractSettings(config), assignments).extract


__all__ = ["MAX_NEIGHBOURS", "MAX_SMOOTHING_ITERATIONS", "ExtractConfig", "ExtractSettings", "OutlierFilter",
           "to_dict", "with_overrides"]
