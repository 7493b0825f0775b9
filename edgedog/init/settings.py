"""The settings of the initialisation, shared by `edgedog init` and training's `init` section.

They live here, below training, so that `edgedog.init`'s functions and `edgedog init` take
their defaults from the same place as `edgedog train`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

from edgedog.settings import Range, Settings

MAX_PRIMITIVES = 2_000_000
"""Ten times the paper's budget (strategy.max_primitives); each primitive costs about 0.3 KB with
its Adam moments and gradients, and every step renders all of them."""
MAX_LOGIT = 20.0
"""Raw values that go through a sigmoid or exp: sigmoid(20) is 1 in float32, and exp overflows
past 88."""

MAX_MATCH_NEIGHBOURS = 100
"""Views each view's SIFT features are matched with: 100 is past any overlap worth matching
(EMAP's and DTU's captures are 50-64 views in all)."""

Count = Annotated[int, Range(1, MAX_PRIMITIVES)]
"""A number of primitives."""
Logit = Annotated[float, Range(-MAX_LOGIT, MAX_LOGIT)]
"""A raw value before its activation."""

InitMethod = Literal["auto", "triangulate", "sfm-points", "uniform", "edge-vote"]
"""'uniform': EdgeGaussians' cube; 'triangulate': SIFT matches triangulated with the known
cameras; 'sfm-points': a COLMAP scene's own points; 'edge-vote': the cells of the cube where the
views' edge maps agree (`edgedog.init.edge_vote`); 'auto': the first of sfm-points, triangulate,
uniform that gives enough points (see `edgedog.init.initialize`)."""


@dataclass(frozen=True)
class InitSettings(Settings):
    """Where the initial primitives come from and how they start."""

    method: InitMethod = "auto"
    """How the initial points are found (see `InitMethod`)."""
    count: Count = 10000
    """Points of the uniform cube (EdgeGaussians start from 2500; with w = exp(-Up) the rims that
    are also depth jumps need the denser start: docs/BENCHMARKS.md); the most that 'edge-vote'
    keeps."""
    side: Annotated[float | None, Range(0, open_low=True)] = 1.1
    """Edge of the uniform cube (EdgeGaussians: 1.1 around the object for ABC); None: the scene
    bounds' largest extent."""
    edge_threshold: Annotated[float, Range(0, 1, open_low=True)] = 0.3
    """Triangulated and SfM points are kept where the edge map is >= this in 2+ views (looser
    than maps.edge_threshold: a point need only land near an edge)."""
    match_neighbours: Annotated[int, Range(0, MAX_MATCH_NEIGHBOURS)] = 10
    """Triangulation matches each view with this many others, the nearest camera centres among
    the views facing its way (optical axes within 90 degrees), instead of every pair: matching
    grows with views x neighbours, not views squared. 0, or at least the other views: every
    pair, facing away or not (COLMAP's exhaustive matching)."""
    vote_surprise: Annotated[float, Range(0, 50)] = 1.5
    """'edge-vote' keeps a cell when its views' votes have a p-value under 10^-this by chance,
    over all views or within a cone of `vote_cone` neighbouring views."""
    vote_cone: Annotated[int, Range(2, MAX_MATCH_NEIGHBOURS)] = 6
    """Views in each cone of 'edge-vote': about the fewest views that see an edge it must find
    (the floor of a deep pocket is seen by 4 to 6 of 50 views around it)."""
    vote_sight: Annotated[float, Range(0, MAX_LOGIT)] = 0.0
    """With `model.view_opacity`, each 'edge-vote' point's view-dependent opacity b starts at
    this times the mean direction toward the views that voted for it, so that an edge hidden
    from most views starts drawn only toward those that see it (held until b trains, from
    `schedule.view_opacity_from_epoch`; capped at `model.view_opacity_cap`). 0: b starts at 0."""
    vote_spacing: Annotated[float, Range(0, 0.1)] = 0.0
    """'edge-vote' thins the agreeing cells to about one per this share of the cube's side of edge
    (0.009: 10 mm on ABC's 1.1 cube), so that the count follows the length of edge the maps draw
    (`count` stays the ceiling). 0: every agreeing cell, a random `count` of them when more."""
    opacity: Annotated[float, Range(0, 1, open_low=True, open_high=True)] = 0.08
    """Initial opacity of every primitive."""
    k: tuple[Logit, Logit] = (0.0, 0.0)
    """Raw DoG shape k at initialisation (the paper's 0)."""

