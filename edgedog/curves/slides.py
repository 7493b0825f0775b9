"""Slide completion: straight edges that few views see, found by sliding the lines the curves hold
across themselves.

A pocket's floor lies under its rim, a channel's concave corners under its walls' top edges, the
concave edge of an L section beside the far edge of its foot: on a machined part many edges that
few views see are copies of an edge that every view sees, moved along one of the directions in
which the part's edges run. The walls hide them from most views, so no primitive forms on them,
but the views that look into the pocket draw them. Each fitted line at least `MIN_LENGTH` long is
moved along each direction of the fitted lines (`line_directions`) nearly perpendicular to it, in
steps of `sweep.STEP` of the scene size up to `slide_reach` either way, and each position is
scored by what the maps draw there that no curve explains (`sweep.offset_scores`: each view
counting only where it looks across the plane the line sweeps). A peak of that score is a
candidate where:

- it lies inside every view's widened mask (the visual hull), all but `sweep.OUTSIDE_SHARE` of it;
- `slide_cover` of its points are drawn, `slide_views_cover` of them by two views or more (one
  view's line fits the plane's line at any depth along its rays; two views' agree at one), and
  the views' edge values there add up to `slide_views` views drawing all of it.

The candidate is placed where the maps themselves peak around it (`sweep.placed`: the thick
lines of the maps make the score a plateau), then moved onto the least-squares line of the
ridges the views drawing it draw along it (`completion.refine`: the found line's own error is
carried along the slide). It is a line when, there:

- `MIN_DRAWING` views draw it over `completion_cover` of its length among the pixels no curve
  explains;
- it is not seen and left undrawn (`seen_undrawn`): where the visual hull leaves a view's line
  of sight clear, a view surely sees the line if the line is on the object, and a true edge is
  drawn there; a false copy (where views looking into a pocket each draw another of its edges
  through the pocket's opening) floats in the open, and most of the views that see it draw
  nothing;
- it is no occluding contour (the line completion's test);
- most of it lies away from the curves, and from the lines added before it.

A copy of another length (a pocket's vertical corner under a block's vertical edge) is not
looked for. Scenes without masks get nothing, as for the other completions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from edgedog.curves import completion, sweep
from edgedog.curves.completion import NOVELTY, Evidence, ViewEvidence
from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import DRAWN_VALUE, HullSurface

MIN_LENGTH = 0.05
"""Shortest fitted line that is slid or gives a direction, of the scene size: a shorter one's
direction is too uncertain to carry a copy far (on 11 CAD runs, the copies of lines 0.03 to 0.04
long lay 11 to 18 mm from any edge)."""
MIN_DRAWING = 2
"""Fewest views that draw a copy over `completion_cover` of its length among the pixels no curve
explains (`completion.support`), before and after it is refined: the summed score of the search
also adds views that each draw a part (on 11 CAD runs every copy on an edge had two such views;
most of those 10 mm or more off an edge had none or one)."""
SAMPLES = 32
"""Points along a line where the views are read."""
AWAY = 2.0
"""A copy is new where most of it lies farther than this many `completion.NOVELTY` from the curves
and the lines added before it: the maps' thick lines also draw a band's far flank beside a found
edge (on ABC 00000006, copies 10 mm beside found edges, drawn by most views that see them)."""
SEARCH_STEP = 2
"""The search moves a line by this many `sweep.STEP`s at a time: the score's plateaus are wider
(`sweep.PLACE_STEPS`), and the copy is then placed at single steps."""
SAME_DIRECTION = 5.0
"""Degrees: fitted lines this close in direction share one (`line_directions`)."""
MAX_DIRECTIONS = 6
"""The directions of most total length that lines are slid along."""
MIN_SLIDE_ANGLE = 80.0
"""Degrees: a line is slid along the directions at least this far from its own."""
CLEAR_SHARE = 0.8
"""A view sees a line where the hull leaves its line of sight clear from this share of the line's
points."""
RIDGE_SAMPLES = 24
"""Points along a line where `ridge_drawn` reads the maps."""
RIDGE_NEAR = 1
"""... and within this of the projection the ridge must be."""
RIDGE_SHARE = 0.8
"""The map's value near the projection is a ridge where it is this share of the largest within
`completion.RIDGE_REACH` px."""
DRAWN_COVER = 0.5
"""A view draws a line where this share of its points lies on a ridge (`ridge_drawn`)."""
MIN_UNDRAWN = 2
"""A line is seen and left undrawn where at least this many views see it and do not draw it, and
they outnumber those that see it and draw it."""


@dataclass(frozen=True)
class SlidLine:
    """A line segment, ends (2, 3), to be moved along `slide` (3,), a unit vector perpendicular
    to it."""

    ends: np.ndarray
    slide: np.ndarray
    closed = False

    def points(self, count: int = SAMPLES, offsets: np.ndarray | None = None) -> np.ndarray:
        """(count, 3) evenly spaced points, ends included, or (T, count, 3) those of the line
        moved by each of `offsets` (T,)."""
        w = np.linspace(0.0, 1.0, count)[:, None]
        line = self.ends[0] * (1 - w) + self.ends[1] * w
        return line if offsets is None else line[None] + np.asarray(offsets)[:, None, None] * self.slide

    def swept(self, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T, SAMPLES, 3) the line moved by each of `offsets` (T,), and the unit normal (1, 1, 3)
        of the plane it sweeps."""
        normal = np.cross(self.ends[1] - self.ends[0], self.slide)
        return self.points(SAMPLES, offsets), (normal / np.linalg.norm(normal))[None, None]

    def moved(self, offset: float) -> np.ndarray:
        """(2, 3) the ends moved by `offset` along the slide."""
        return self.ends + offset * self.slide

    def within(self, offsets: np.ndarray, box: np.ndarray) -> np.ndarray:
        """The `offsets` (T,) by which the line moved stays in `box` (2, 3), both ends."""
        moved = self.ends[None] + offsets[:, None, None] * self.slide  # (T, 2, 3)
        return offsets[np.all((moved >= box[0]) & (moved <= box[1]), axis=(1, 2))]


def _unit_directions(lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(L, 3) unit directions and (L,) lengths of lines (L, 2, 3)."""
    along = lines[:, 1] - lines[:, 0]
    lengths = np.linalg.norm(along, axis=1)
    return along / np.maximum(lengths, 1e-18)[:, None], lengths


def line_directions(lines: np.ndarray, min_length: float) -> np.ndarray:
    """(K, 3) the directions the lines (L, 2, 3) at least `min_length` long run in: each line, the
    longest first, joins the first direction within SAME_DIRECTION of its own (sign ignored) or
    starts one; the MAX_DIRECTIONS of most total length, that first."""
    units, lengths = _unit_directions(lines)
    same = np.cos(np.radians(SAME_DIRECTION))
    directions: list[np.ndarray] = []
    totals: list[float] = []
    for k in np.argsort(-lengths, kind="stable"):
        if lengths[k] < min_length:
            break
        match = next((i for i, d in enumerate(directions) if abs(d @ units[k]) >= same), None)
        if match is None:
            directions.append(units[k])
            totals.append(float(lengths[k]))
        else:
            totals[match] += float(lengths[k])
    order = np.argsort(-np.asarray(totals), kind="stable")[:MAX_DIRECTIONS]
    return np.asarray(directions).reshape(-1, 3)[order]


def slides(lines: np.ndarray, size: float) -> list[SlidLine]:
    """Each line (L, 2, 3) at least MIN_LENGTH of `size` long, with each of the lines' directions
    at least MIN_SLIDE_ANGLE from its own (made perpendicular to it)."""
    lines = np.asarray(lines, dtype=np.float64).reshape(-1, 2, 3)
    min_length = MIN_LENGTH * size
    directions = line_directions(lines, min_length)
    units, lengths = _unit_directions(lines)
    across = np.cos(np.radians(MIN_SLIDE_ANGLE))
    found = []
    for line, unit, length in zip(lines, units, lengths):
        if length < min_length:
            continue
        for direction in directions:
            if abs(direction @ unit) <= across:
                slide = direction - (direction @ unit) * unit
                found.append(SlidLine(line, slide / np.linalg.norm(slide)))
    return found


def ridge_drawn(views: list[ViewEvidence], segment: np.ndarray) -> np.ndarray:
    """(V,) whether each view draws a segment (2, 3) on the ridge of its map: on `DRAWN_COVER` of
    `RIDGE_SAMPLES` points along it, the map's largest value within `RIDGE_NEAR` px across its
    projection is at least `DRAWN_VALUE` and `RIDGE_SHARE` of the largest within
    `completion.RIDGE_REACH` px. A line beside a drawn edge (a few pixels off it, on the flank of
    its band) is not drawn. False where the segment leaves the image or projects shorter than
    15 px."""
    points = completion.samples_along(segment[None], RIDGE_SAMPLES)[0]
    reach = completion.RIDGE_REACH
    drawn = np.zeros(len(views), bool)
    for k, view in enumerate(views):
        line = completion.across_line(view, points)
        if not (line.inside and np.linalg.norm(line.uv[-1] - line.uv[0]) >= 15):
            continue
        centre = line.values[:, reach - RIDGE_NEAR:reach + RIDGE_NEAR + 1].max(axis=1)
        on_ridge = (centre >= DRAWN_VALUE) & (centre >= RIDGE_SHARE * line.values.max(axis=1))
        drawn[k] = on_ridge.mean() >= DRAWN_COVER
    return drawn


def seen_undrawn(segment: np.ndarray, evidence: Evidence, surface: HullSurface) -> bool:
    """Whether a segment (2, 3) is seen and left undrawn: MIN_UNDRAWN views or more whose image
    holds it (15 px or longer) and whose line of sight the hull leaves clear (`CLEAR_SHARE`) do
    not draw it on a ridge of their maps (`ridge_drawn`), and they outnumber those that do."""
    samples = completion.samples_along(segment[None])
    centres = np.stack([view.camera.center for view in evidence.views])
    clear = surface.unblocked(samples[0], centres).mean(axis=0) >= CLEAR_SHARE
    shown, _ = completion.support(evidence.views, samples, False, 0.0)
    seen = clear & shown[0]
    drawn = ridge_drawn(evidence.views, segment)
    undrawn = int((seen & ~drawn).sum())
    return undrawn >= MIN_UNDRAWN and undrawn > int((seen & drawn).sum())


def complete_slides(lines: np.ndarray, evidence: Evidence, maps: list[sweep.ViewMaps], surface: HullSurface,
                    detector: str, size: float, config: ExtractConfig) -> np.ndarray:
    """(L, 2, 3) the lines the curves of `evidence` miss that are copies of `lines` (L, 2, 3)
    moved across themselves (see the module's doc), with `config`'s `slide_*` settings, and the
    lines joining a copy's ends to its line's (a pocket's corners, between its rim and its
    floor) where they pass the same tests; `maps` are the views' `sweep.view_maps`, `surface` the
    scene's hull, `detector` its edge maps' name (for the contour test), `size` the scene size
    the relative lengths refer to."""
    step = sweep.STEP * size
    reach = round(config.slide_reach / sweep.STEP)
    steps = np.arange(-reach, reach + 1) * step
    box = surface.box
    existing = cKDTree(evidence.existing) if len(evidence.existing) else None
    added: list[np.ndarray] = []
    earlier: cKDTree | None = None  # the points of the lines added

    def drawn(segment: np.ndarray) -> np.ndarray:
        """(V,) the views that draw `segment` among the unexplained pixels."""
        return completion.support(evidence.views, completion.samples_along(segment[None]), True,
                                  config.completion_cover)[0][0]

    def add(segment: np.ndarray) -> bool:
        """Add `segment` (2, 3) where it is drawn, new, and neither seen undrawn nor a contour."""
        nonlocal earlier
        points = completion.samples_along(segment[None])[0]
        if not (drawn(segment).sum() >= MIN_DRAWING and sweep.away(points, existing, AWAY * NOVELTY * size)
                and sweep.away(points, earlier, AWAY * NOVELTY * size)):
            return False
        if seen_undrawn(segment, evidence, surface):
            return False
        if completion.on_contours(points[None], surface, detector, config)[0]:
            return False
        added.append(segment)
        earlier = cKDTree(completion.samples_along(np.asarray(added)).reshape(-1, 3))
        return True

    for line in slides(lines, size):
        offsets = line.within(steps[::SEARCH_STEP], box)
        if len(offsets) < 3:
            continue
        scores = sweep.offset_scores(line, evidence, offsets, maps)
        value = np.where(scores.outside, 0.0, scores.value)
        strong = ((scores.cover >= config.slide_cover) & (scores.cover_two >= config.slide_views_cover)
                  & (scores.value >= config.slide_views * SAMPLES))
        for index in sweep.peaks(value):
            if not strong[index]:
                continue
            found = line.moved(sweep.placed(line, evidence, offsets[index], step, maps))
            drawing = drawn(found)
            if drawing.sum() < MIN_DRAWING:
                continue
            found = completion.refine(evidence.views, found, drawing)
            if add(found):
                for end in range(2):
                    add(np.stack([line.ends[end], found[end]]))
    return np.asarray(added).reshape(-1, 2, 3)
