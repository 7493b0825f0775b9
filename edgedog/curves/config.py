"""Typed settings of curve extraction (`edgedog extract RUN --set key=value`).

Lengths of the grouping and fitting stages are fractions of the scene size: the diagonal of
the bounding box of the filtered points (about 1.4 for an ABC object, where 1 unit = 1000 mm).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

from edgedog.errors import ConfigError
from edgedog.settings import check_setting

OutlierFilter = Literal["auto", "on", "off"]
"""When the statistical outlier filter runs: 'on', 'off', or 'auto' (where the silhouette filter
does not)."""


@dataclass(frozen=True)
class ExtractConfig:
    """Every setting of `extract`. Each filter can be switched off on its own.

    The grouping and fitting defaults were chosen on a noisy ABC run (primitives ~9 mm from the
    edges); cleaner runs can use a smaller `node_spacing` and tolerances.
    """

    # --- filters (EdgeGaussians' post-processing, and a silhouette test)
    filter_opacity: bool = True
    min_opacity: float = 0.2
    """Keep primitives whose (activated) opacity is above this."""
    filter_projection: bool = True
    min_edge_value: float = 0.1
    """Keep points whose edge-map value, averaged over ALL views, is above this (a view that does
    not see the point counts as 0)."""
    filter_silhouette: bool = True
    max_outside_pixels: float = 4.0
    """Keep points that land at most this many pixels (of the run's views) outside the object's
    mask in every view; skipped on scenes without masks. Edge maps also draw the occluding
    contours of curved surfaces, which move with the view and are not edges of the object;
    training places primitives for them around the object, outside it in some views."""
    filter_outliers: OutlierFilter = "on"
    """Statistical outliers: drop points whose mean distance to their `outlier_neighbours` nearest
    points exceeds the mean of that value over all points by `outlier_std` standard deviations.
    'auto' runs it only where the silhouette filter does not (a scene without masks, or
    `filter_silhouette` off). The statistics are relative to the points' own density: an edge
    that training holds with few primitives is taken for outliers (on the ABC renders, where the
    silhouette filter removes the floaters, 'auto' gains up to 3.7 F10), while multi-view ghosts
    inside the object's silhouette, which no mask removes, are what it is there for (the built-in
    part: 'auto' loses 2.8 to 5.2 F10). docs/notes/2026-11-25-outlier-filter.md."""
    outlier_neighbours: int = 8
    """EdgeGaussians use 25 neighbours; an edge held by fewer primitives than that reaches across
    to other edges and is dropped whole, so 8 (docs/BENCHMARKS.md)."""
    outlier_std: float = 2.0

    # --- directions
    min_elongation: float = 1.5
    """A primitive's own axis (largest scale) is its direction when largest / middle scale is at
    least this; rounder primitives get the principal axis of their neighbourhood instead."""
    direction_neighbours: int = 32
    """Neighbourhood size of those principal axes."""

    # --- grouping (fractions of the scene size)
    smoothing_radius: float = 0.015
    """Points move across their direction onto the centre of the agreeing points this close
    (directions are re-estimated from the same neighbours)."""
    smoothing_iterations: int = 1
    """More iterations thin the point tube further but merge nearby parallel edges."""
    node_spacing: float = 0.006
    """Spacing of the chain vertices the points are thinned to."""
    link_distance: float = 0.06
    """Longest link between two vertices of a chain (each vertex links only among its 8
    nearest). 0.03 before: 0.06 bridges the sparse stretches of faint curved edges; on 21 ABC
    runs F10 +0.37 on average, at worst -1.2 (docs/BENCHMARKS.md)."""
    join_distance: float = 0.045
    """Longest gap bridged between two chain ends that face each other (a curve broken where
    points are missing; the two ends of a circle)."""
    link_angle: float = 30.0
    """Degrees: linked vertices' directions, and the vector between them, agree within this."""
    corner_angle: float = 60.0
    """Degrees: a chain is split where it turns more than this over a few vertices."""
    min_chain_vertices: int = 4
    """Shorter chains are dropped as noise unless an end meets a longer chain's end (within
    `snap_radius`: a short edge between corners), and shorter side branches are pruned."""

    # --- fitting (fractions of the scene size)
    line_tolerance: float = 0.004
    """A chain is a line when RANSAC finds one holding all but `max_outlier_share` of its vertices
    within this distance; also the collinearity tolerance of merges."""
    max_outlier_share: float = 0.05
    bezier_tolerance: float = 0.002
    """A cubic Bézier is kept when its RMS distance to the chain is below this; else it is split.
    At 0.004 (7 mm on an ABC object) one Bézier cut up to 7.7 mm inside a rounded part;
    0.002 raised F5 on all four ABC runs measured (docs/BENCHMARKS.md) for 3 to 8 more curves."""
    snap_radius: float = 0.01
    """Curve ends this close, or whose extensions meet within it, are snapped to one junction
    point; a chain end this close to another chain's interior splits it there (a T)."""
    seed: int = 0
    """Seed of RANSAC."""

    def __post_init__(self):
        for name in ("outlier_neighbours", "direction_neighbours", "min_chain_vertices"):
            if getattr(self, name) < 2:
                raise ConfigError(f"{name} must be at least 2, got {getattr(self, name)}")
        if self.smoothing_iterations < 0:
            raise ConfigError(f"smoothing_iterations must be >= 0, got {self.smoothing_iterations}")
        for name in ("smoothing_radius", "node_spacing", "link_distance", "join_distance", "line_tolerance",
                     "bezier_tolerance", "snap_radius"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be positive, got {getattr(self, name)}")
        for name in ("link_angle", "corner_angle"):
            if not 0 < getattr(self, name) < 90:
                raise ConfigError(f"{name} must be in (0, 90) degrees, got {getattr(self, name)}")
        check_setting("filter_outliers", OutlierFilter, self.filter_outliers)
        if not self.max_outside_pixels >= 0:
            raise ConfigError(f"max_outside_pixels must be >= 0, got {self.max_outside_pixels}")
        if not 0 <= self.max_outlier_share < 1:
            raise ConfigError(f"max_outlier_share must be in [0, 1), got {self.max_outlier_share}")


def to_dict(config: ExtractConfig) -> dict:
    return dataclasses.asdict(config)
