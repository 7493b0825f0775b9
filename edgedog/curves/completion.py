"""Line completion: straight edges that the curves miss, triangulated from the line segments the
edge maps draw where no curve projects.

An edge that only a few views can see (a concave corner behind walls) often gets no primitive:
the views where it is hidden penalise one. The views that see it still draw it. Completion looks
for what the maps draw and the curves do not explain. In each view, the drawn pixels farther than
`completion_explained` pixels from every curve's projection are thinned to one-pixel lines and cut into
straight segments. Two views' segments span two planes through their cameras; where the planes
cut at a useful angle, their line, clipped to what both segments see, is a candidate. A
candidate is refined to the line that best meets the planes of the ridges every supporting view
draws along it, and kept when, refined:

- at least `completion_views` views draw it over `completion_cover` of its length among the
  unexplained pixels (within a pixel), their directions spread by at least `completion_spread`
  degrees (settings of `ExtractConfig`): a wrong pairing of two views' segments is drawn by few
  other views, and a line beside a found curve lands on that curve's pixels, which do not count;
- it lies inside every view's mask (the object's visual hull), and most of it away from the
  curves;
- it is no occluding contour (`contours.contour_mask`, at the stricter
  `completion_contour_share`): a ruled or cylindrical face's contours are straight and drawn by
  many views.

Greedy suppression keeps the best supported of candidates that overlap. Scenes without masks
get nothing: the hull test is what keeps floaters out.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from edgedog.curve_files import EdgeCurves
from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import DRAWN_VALUE, HullSurface, contour_mask
from edgedog.scenes.camera import Camera

MIN_SEGMENT_PIXELS = 20
"""Shortest 2D segment taken from a view."""
MAX_SEGMENTS_PER_VIEW = 200
"""The longest segments of a view kept (bounds the candidates: pairs x segments^2)."""
PAIR_ANGLES = (8.0, 60.0)
"""Degrees between two views' directions for their segments to be paired: closer views
triangulate poorly, farther ones seldom see the same stretch."""
PAIR_VIEWS = 16
"""Partners of each view, the nearest in direction within `PAIR_ANGLES`."""
MIN_PLANE_ANGLE = 5.0
"""Degrees between the two segments' planes: below it their line is ill-conditioned."""
MAX_CANDIDATES = 200_000
"""The longest candidates kept before scoring (each costs samples x views lookups)."""
MAX_REFINED = 5_000
"""The best supported candidates refined (each refinement reads every supporting view)."""
SAMPLES = 12
"""Points along a candidate where the views are read."""
REFINEMENTS = 2
"""Passes of `refine` before the final score."""
RIDGE_REACH = 3
"""Pixels across a projected line searched for the map's ridge."""
NOVELTY = 0.006
"""A candidate is new where at least half of it lies farther than this (of the scene size) from
the curves."""
MIN_OVERLAP = 0.01
"""Shortest candidate (of the scene size)."""


@dataclass(frozen=True)
class ViewEvidence:
    """What completion reads of one view.

    camera: at the maps' resolution; edge_map: (H, W) float32 in [0, 1]; loose: (H, W) bool,
    within 2 px of a drawn pixel; unexplained: (H, W) bool, within 1 px of a drawn pixel that no
    curve explains; hull: (H, W) bool, the mask widened by 3 px; segments: (S, 4) x0, y0, x1, y1
    of the unexplained pixels' straight segments.
    """

    camera: Camera
    edge_map: np.ndarray
    loose: np.ndarray
    unexplained: np.ndarray
    hull: np.ndarray
    segments: np.ndarray


def _dilate(mask: np.ndarray, radius: int, shape: int = cv2.MORPH_RECT) -> np.ndarray:
    kernel = cv2.getStructuringElement(shape, (2 * radius + 1, 2 * radius + 1))
    return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool)


def view_evidence(camera: Camera, edge_map: np.ndarray, mask: np.ndarray, curve_points: np.ndarray,
                  explained_pixels: int) -> ViewEvidence:
    """One view's evidence; `curve_points` (N, 3) sample the curves densely (a pixel or less), and
    a drawn pixel within `explained_pixels` of their projection is theirs."""
    hull = _dilate(mask, 3)
    drawn = (edge_map >= DRAWN_VALUE) & hull
    explained = np.zeros(drawn.shape, bool)
    pixels, inside = camera.pixels(curve_points)
    explained[pixels[inside, 1], pixels[inside, 0]] = True
    unexplained = drawn & ~_dilate(explained, explained_pixels, cv2.MORPH_ELLIPSE)
    lines = cv2.HoughLinesP(cv2.ximgproc.thinning(unexplained.astype(np.uint8) * 255), 1, np.pi / 360, 15,
                            minLineLength=MIN_SEGMENT_PIXELS, maxLineGap=3)
    segments = np.empty((0, 4)) if lines is None else lines.reshape(-1, 4).astype(np.float64)
    lengths = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    segments = segments[np.argsort(-lengths, kind="stable")[:MAX_SEGMENTS_PER_VIEW]]
    return ViewEvidence(camera, edge_map, _dilate(drawn, 2), _dilate(unexplained, 1), hull, segments)


def segment_planes(camera: Camera, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays through each segment's two ends (S, 3) each, and the unit normal (S, 3) of the plane
    they span with the camera centre."""
    start, end = camera.ray_directions(segments[:, :2]), camera.ray_directions(segments[:, 2:])
    normal = np.cross(start, end)
    return start, end, normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-18)


def _on_plane(origin: np.ndarray, rays: np.ndarray, normals: np.ndarray, point: np.ndarray):
    """Where rays (A, 3) from `origin` meet planes (B, 3 normals) through `point`: (A, B, 3) points
    and (A, B) ray parameters (> 0 in front)."""
    facing = rays @ normals.T
    facing = np.where(np.abs(facing) < 1e-12, 1e-12, facing)
    along = ((point - origin) @ normals.T)[None, :] / facing
    return origin + along[..., None] * rays[:, None, :], along


def pair_candidates(a: ViewEvidence, b: ViewEvidence, min_length: float) -> np.ndarray:
    """(C, 2, 3) 3D segments from pairing every segment of view `a` with every one of `b`: their
    planes' line between the ends both segments see, at least `min_length` long and 60 % of the
    shorter segment's extent on it."""
    a_start, a_end, a_normal = segment_planes(a.camera, a.segments)
    b_start, b_end, b_normal = segment_planes(b.camera, b.segments)
    a_centre, b_centre = a.camera.center, b.camera.center
    p0, s0 = _on_plane(a_centre, a_start, b_normal, b_centre)  # a's ends on b's planes: (A, B, 3)
    p1, s1 = _on_plane(a_centre, a_end, b_normal, b_centre)
    q0, t0 = (np.swapaxes(x, 0, 1) for x in _on_plane(b_centre, b_start, a_normal, a_centre))
    q1, t1 = (np.swapaxes(x, 0, 1) for x in _on_plane(b_centre, b_end, a_normal, a_centre))
    axis = p1 - p0
    a_length = np.linalg.norm(axis, axis=-1)
    axis = axis / np.maximum(a_length, 1e-18)[..., None]
    u0, u1 = ((q0 - p0) * axis).sum(-1), ((q1 - p0) * axis).sum(-1)
    low, high = np.maximum(0.0, np.minimum(u0, u1)), np.minimum(a_length, np.maximum(u0, u1))
    overlap, b_length = high - low, np.abs(u1 - u0)
    good = ((np.abs(a_normal @ b_normal.T) < np.cos(np.radians(MIN_PLANE_ANGLE)))
            & (s0 > 0) & (s1 > 0) & (t0 > 0) & (t1 > 0)
            & (overlap >= min_length) & (overlap >= 0.6 * np.minimum(a_length, b_length)))
    i, j = np.nonzero(good)
    start = p0[i, j] + low[i, j, None] * axis[i, j]
    end = p0[i, j] + high[i, j, None] * axis[i, j]
    return np.stack([start, end], axis=1)


def view_pairs(cameras: list[Camera]) -> list[tuple[int, int]]:
    """Each view with its `PAIR_VIEWS` nearest partners in direction within `PAIR_ANGLES`, each
    pair once."""
    forward = np.stack([camera.forward for camera in cameras])
    angles = np.degrees(np.arccos(np.clip(forward @ forward.T, -1.0, 1.0)))
    pairs = set()
    for i, row in enumerate(angles):
        partners = np.nonzero((row >= PAIR_ANGLES[0]) & (row <= PAIR_ANGLES[1]))[0]
        for j in partners[np.argsort(row[partners], kind="stable")[:PAIR_VIEWS]]:
            pairs.add((min(i, j), max(i, j)))
    return sorted(pairs)


def _lengths(segments: np.ndarray) -> np.ndarray:
    return np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)


def _longest(segments: np.ndarray, limit: int) -> np.ndarray:
    return segments[np.argsort(-_lengths(segments), kind="stable")[:limit]]


def all_candidates(views: list[ViewEvidence], bounds: np.ndarray, min_length: float) -> np.ndarray:
    """(C, 2, 3) the longest `MAX_CANDIDATES` of every view pair's candidates (`view_pairs`,
    `pair_candidates`) inside `bounds` (2, 3), trimmed as they come so that memory stays bounded."""
    found, total = [], 0
    for i, j in view_pairs([view.camera for view in views]):
        if not (len(views[i].segments) and len(views[j].segments)):
            continue
        pair = pair_candidates(views[i], views[j], min_length)
        found.append(pair[np.all((pair > bounds[0]) & (pair < bounds[1]), axis=(1, 2))])
        total += len(found[-1])
        if total > 2 * MAX_CANDIDATES:
            found = [_longest(np.concatenate(found), MAX_CANDIDATES)]
            total = len(found[0])
    return _longest(np.concatenate(found), MAX_CANDIDATES) if found else np.empty((0, 2, 3))


def samples_along(segments: np.ndarray, count: int = SAMPLES) -> np.ndarray:
    """(C, count, 3) evenly spaced points of segments (C, 2, 3), ends included."""
    w = np.linspace(0.0, 1.0, count)[None, :, None]
    return segments[:, :1] * (1 - w) + segments[:, 1:] * w


def support(views: list[ViewEvidence], samples: np.ndarray, unexplained: bool, cover: float):
    """Which views draw each candidate (C, S, 3 samples): (C, V) bool, the whole candidate in the
    image, at least 15 px long, and `cover` of its samples on drawn pixels (unexplained ones, or
    any within 2 px); and (C,) whether a sample falls outside some view's widened mask."""
    supported = np.zeros((len(samples), len(views)), bool)
    outside = np.zeros(len(samples), bool)
    flat = samples.reshape(-1, 3)
    for k, view in enumerate(views):
        pixels, inside = view.camera.pixels(flat)
        pixels, inside = pixels.reshape(*samples.shape[:2], 2), inside.reshape(samples.shape[:2])
        x = np.clip(pixels[..., 0], 0, view.camera.width - 1)
        y = np.clip(pixels[..., 1], 0, view.camera.height - 1)
        outside |= np.any(inside & ~view.hull[y, x], axis=1)
        drawn = (view.unexplained if unexplained else view.loose)[y, x] & inside
        long_enough = np.linalg.norm(pixels[:, -1] - pixels[:, 0], axis=1) >= 15
        supported[:, k] = inside.all(axis=1) & long_enough & (drawn.mean(axis=1) >= cover)
    return supported, outside


def spread(views: list[ViewEvidence], supported: np.ndarray) -> np.ndarray:
    """(C,) largest angle in degrees between two supporting views' directions."""
    forward = np.stack([view.camera.forward for view in views])
    result = np.zeros(len(supported))
    for c in np.nonzero(supported.sum(axis=1) >= 2)[0]:
        f = forward[supported[c]]
        result[c] = np.degrees(np.arccos(np.clip((f @ f.T).min(), -1.0, 1.0)))
    return result


@dataclass(frozen=True)
class AcrossLine:
    """What a view's map holds across the projection of points along a line: values, (S, 2 R + 1)
    at whole pixels from -R to +R px across it (R = `RIDGE_REACH`, probes clipped to the image);
    uv, (S, 2) the projected points; across, (2,) the unit image direction across the line;
    inside, whether every probe fell inside the image and every point in front of the camera."""

    values: np.ndarray
    uv: np.ndarray
    across: np.ndarray
    inside: bool


def across_line(view: ViewEvidence, points: np.ndarray) -> AcrossLine:
    """`AcrossLine` of `view` for points (S, 3) along a line, the first and last its ends."""
    camera = view.camera
    uv, depth = camera.project(points)
    along = uv[-1] - uv[0]
    along /= max(np.linalg.norm(along), 1e-12)
    across = np.array([-along[1], along[0]])
    offsets = np.arange(-RIDGE_REACH, RIDGE_REACH + 1)
    probes = np.rint(uv[:, None, :] + offsets[None, :, None] * across).astype(np.int64)
    inside = bool(np.all(depth > 0) and ((probes >= 0) & (probes < [camera.width, camera.height])).all())
    probes = np.clip(probes, 0, [camera.width - 1, camera.height - 1])
    return AcrossLine(view.edge_map[probes[..., 1], probes[..., 0]], uv, across, inside)


def refine(views: list[ViewEvidence], segment: np.ndarray, supported: np.ndarray) -> np.ndarray:
    """(2, 3) the line that best meets the planes of the ridges the supporting views draw along
    `segment` (2, 3) (least squares; its ends moved onto it), or `segment` where fewer than three
    views show a ridge."""
    points = samples_along(segment[None], 40)[0]
    offsets = np.arange(-RIDGE_REACH, RIDGE_REACH + 1)
    normals, centres = [], []
    for k in np.nonzero(supported)[0]:
        camera = views[k].camera
        line = across_line(views[k], points)
        values, uv, across = line.values, line.uv, line.across
        weight = values.sum(axis=1)
        ridge = weight > 0.5
        if ridge.sum() < 5:
            continue
        shift = (values[ridge] * offsets).sum(axis=1) / weight[ridge]
        ridge_points = uv[ridge] + shift[:, None] * across
        centre = ridge_points.mean(axis=0)
        direction = np.linalg.svd(ridge_points - centre)[2][0]
        _, _, normal = segment_planes(camera, np.r_[centre - 50 * direction, centre + 50 * direction][None])
        normals.append(normal[0])
        centres.append(camera.center)
    if len(normals) < 3:
        return segment
    normals = np.array(normals)
    axis = np.linalg.svd(normals)[2][-1]
    point = np.linalg.lstsq(normals, np.einsum("ki,ki->k", normals, np.array(centres)), rcond=None)[0]
    return point + ((segment - point) @ axis)[:, None] * axis


def suppress(segments: np.ndarray, order: np.ndarray, radius: float) -> list[int]:
    """Greedy: in `order`, keep a segment unless half of its samples lie within `radius` of kept ones."""
    kept, kept_points = [], np.empty((0, 3))
    samples = samples_along(segments)
    for c in order:
        if len(kept_points) and np.mean(cKDTree(kept_points).query(samples[c])[0] < radius) >= 0.5:
            continue
        kept.append(int(c))
        kept_points = np.concatenate([kept_points, samples[c]])
    return kept


@dataclass(frozen=True)
class Evidence:
    """What the completions read of a scene: each view's `ViewEvidence` against the curves found,
    and those curves' dense samples (N, 3)."""

    views: list[ViewEvidence]
    existing: np.ndarray

    def explained_by(self, points: np.ndarray, explained_pixels: int) -> Evidence:
        """This evidence with the curves sampled densely by `points` (M, 3) (those a completion
        added) found too: the drawn pixels within `explained_pixels` of their projection are
        theirs, and they join `existing`."""
        if not len(points):
            return self
        views = []
        for view in self.views:
            explained = np.zeros(view.unexplained.shape, bool)
            pixels, inside = view.camera.pixels(points)
            explained[pixels[inside, 1], pixels[inside, 0]] = True
            unexplained = view.unexplained & ~_dilate(explained, explained_pixels + 1, cv2.MORPH_ELLIPSE)
            views.append(dataclasses.replace(view, unexplained=unexplained))
        return Evidence(views, np.concatenate([self.existing, points]))


def gather_evidence(curves: EdgeCurves, surface: HullSurface, detector: str, size: float,
                    config: ExtractConfig) -> Evidence | None:
    """Every view's evidence against `curves` (`view_evidence`, with `completion_explained`) on
    the scene of `surface`; `size` is the scene size. None on a scene without masks or without
    curves: there is nothing to complete, or no hull to keep floaters out."""
    scene = surface.scene
    if not surface.every_view_masked or curves.num_curves == 0 or size <= 0:
        return None
    existing = curves.sample(size / 1000)
    views = [view_evidence(scene.camera(i), scene.load_edge_map(i, detector), surface.masks[i], existing,
                           config.completion_explained) for i in range(len(scene))]
    return Evidence(views, existing)


def on_contours(samples: np.ndarray, surface: HullSurface, detector: str,
                config: ExtractConfig) -> np.ndarray:
    """(C,) whether most of each line's samples (C, S, 3) lie on an occluding contour
    (`contour_mask` at the stricter `completion_contour_share`: a ruled or cylindrical face's
    contours are straight and drawn by many views); all False where the test cannot run."""
    not_contour = contour_mask(samples.reshape(-1, 3), surface, detector, config.contour_max_cosine,
                               config.completion_contour_share, config.contour_probe_cells)
    if not_contour is None:
        return np.zeros(len(samples), bool)
    return not_contour.reshape(samples.shape[:2]).mean(axis=1) < 0.5


def complete_lines(evidence: Evidence, surface: HullSurface, detector: str, size: float,
                   config: ExtractConfig) -> np.ndarray:
    """(L, 2, 3) straight edges the curves of `evidence` miss (see the module's doc), with
    `config`'s `completion_*` settings, on the scene of `surface`, whose visual hull the contour
    test uses; `size` is the scene size the relative lengths refer to."""
    scene = surface.scene
    min_views, cover = config.completion_views, config.completion_cover
    views, existing = evidence.views, evidence.existing
    candidates = all_candidates(views, np.asarray(scene.bounds, dtype=np.float64), MIN_OVERLAP * size)
    supported, outside = support(views, samples_along(candidates), False, cover)
    count = supported.sum(axis=1)
    best = np.lexsort((-_lengths(candidates), -count))[:MAX_REFINED]
    best = best[(count[best] >= min_views) & ~outside[best]]
    candidates, supported = candidates[best], supported[best]
    for _ in range(REFINEMENTS):
        candidates = np.stack([refine(views, c, s) for c, s in zip(candidates, supported)]) \
            if len(candidates) else candidates
        supported, outside = support(views, samples_along(candidates), True, cover)
    distance = cKDTree(existing).query(samples_along(candidates).reshape(-1, 3))[0].reshape(-1, SAMPLES)
    count = supported.sum(axis=1)
    keep = ((count >= min_views) & ~outside & (spread(views, supported) >= config.completion_spread)
            & (np.mean(distance > NOVELTY * size, axis=1) >= 0.5))
    candidates, count = candidates[keep], count[keep]
    if len(candidates):
        keep = ~on_contours(samples_along(candidates), surface, detector, config)
        candidates, count = candidates[keep], count[keep]
    return candidates[suppress(candidates, np.lexsort((-_lengths(candidates), -count)), NOVELTY * size)]
