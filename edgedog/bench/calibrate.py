"""Where a detector draws its edges, relative to the true ones: the measurement behind
`edgedog calibrate-detector`.

It measures a detector's bias on built-in parts rendered with exact ground truth
(`calibrate_detector`) or a dataset's own maps against its ground truth (`measure_scene_maps`);
the record it makes, and the sign convention of its offsets, are `edgedog.edges.calibration`'s.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone

import numpy as np
from scipy.spatial import cKDTree
from tqdm import tqdm

from edgedog.curve_files import EdgeCurves
from edgedog.edges.calibration import (
    PROFILE_OFFSETS,
    DetectorCalibration,
    EdgeProfile,
    OffsetMeasurement,
    OrientationOffset,
    parabola_vertex,
)
from edgedog.edges.detector import EdgeDetector
from edgedog.errors import ConfigError, InputError
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import Scene
from edgedog.scenes.camera import Camera
from edgedog.synthetic.cameras import orbit_cameras
from edgedog.synthetic.shapes import Part, make_part

SEARCH_RADIUS = 3.0  # px: the 2D offset is searched in [-3, 3]^2
COARSE_STEP, FINE_STEP = 0.25, 0.05  # px: grid steps of the 2D search, then a parabolic fit
COARSE_POINTS = 30_000  # enough to find the right coarse cell
ORIENTATION_BINS = 8
MAX_POINTS = 200_000
"""Points the measurement keeps (a random subset beyond this): enough for 0.01-px precision."""
SILHOUETTE_PROBES = (1.5, 3.0)
"""px from a curve point, on both sides, where the render is probed for background."""
DEFAULT_SHAPES = ("box", "l-bracket", "plate-holes", "stepped-block", "chamfered-block", "boss")


# --- the measurement ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ProjectedCurves:
    """Visible ground-truth curve points of one view, in its pixels.

    Attributes:
        points: (N, 2) float64 pixel coordinates (x right, y down, pixel centres at integers).
        tangents: (N, 2) float64 unit curve directions in the image.
        outward: (N,) int8: +1 where `normals` points out of the object (a silhouette point),
            -1 where it points into it, 0 for interior creases and where it is unknown.
    """

    points: np.ndarray
    tangents: np.ndarray
    outward: np.ndarray

    @property
    def normals(self) -> np.ndarray:
        """(N, 2) unit normals: the tangents turned by +90 degrees, (-ty, tx)."""
        return np.stack([-self.tangents[:, 1], self.tangents[:, 0]], axis=1)


class _Sampler:
    """Bilinear samples of many edge maps, each point reading its own map (0 outside it).

    The maps are stored flat, each padded with zeros, so that a sample needs no bounds test.

    Args:
        edge_maps: the (H_i, W_i) maps.
    """

    PAD = 8  # px of zeros around each map; coordinates beyond them are clamped into them

    def __init__(self, edge_maps: Sequence[np.ndarray]):
        padded = [np.pad(np.asarray(m, np.float32), self.PAD) for m in edge_maps]
        sizes = np.array([m.size for m in padded])
        self.flat = np.concatenate([m.ravel() for m in padded])
        self.base = np.cumsum(sizes) - sizes
        self.width = np.array([m.shape[1] for m in padded])
        self.height = np.array([m.shape[0] for m in padded])

    def __call__(self, xy: np.ndarray, views: np.ndarray) -> np.ndarray:
        """(..., N, 2) pixel coordinates in the maps `views` (N,) -> (..., N) values."""
        xy = xy + self.PAD
        corner = np.floor(xy)
        fx, fy = (xy - corner)[..., 0], (xy - corner)[..., 1]
        width = self.width[views]
        x0 = np.clip(corner[..., 0], 0, width - 2).astype(np.int64)
        y0 = np.clip(corner[..., 1], 0, self.height[views] - 2).astype(np.int64)
        index = self.base[views] + y0 * width + x0
        top = self.flat[index] + fx * (self.flat[index + 1] - self.flat[index])
        below = index + width
        bottom = self.flat[below] + fx * (self.flat[below + 1] - self.flat[below])
        return top + fy * (bottom - top)


def _grid_peak(scores: np.ndarray) -> tuple[int, int, float, float]:
    """(rows, cols) scores -> argmax (row, col) and its parabolic refinement along each axis
    (fractions of a step; 0 on the grid's border)."""
    row, col = np.unravel_index(np.argmax(scores), scores.shape)
    frac_row = parabola_vertex(*scores[row - 1:row + 2, col]) if 0 < row < scores.shape[0] - 1 else 0.0
    frac_col = parabola_vertex(*scores[row, col - 1:col + 2]) if 0 < col < scores.shape[1] - 1 else 0.0
    return int(row), int(col), frac_row, frac_col


def _best_shift(sample: _Sampler, points: np.ndarray, views: np.ndarray) -> tuple[float, float]:
    """The (dx, dy) in [-SEARCH_RADIUS, SEARCH_RADIUS]^2 maximising the mean map value at
    (N, 2) `points` + (dx, dy) in maps `views` (N,): a COARSE_STEP grid (on a subset of
    COARSE_POINTS points), then a FINE_STEP grid around its best, then a parabolic fit."""
    centre = np.zeros(2)
    subset = slice(None, None, max(1, len(points) // COARSE_POINTS))
    for step, radius, chosen in ((COARSE_STEP, SEARCH_RADIUS, subset), (FINE_STEP, COARSE_STEP, slice(None))):
        grid = np.arange(-round(radius / step), round(radius / step) + 1) * step
        scores = np.array([[sample(points[chosen] + centre + (dx, dy), views[chosen]).mean() for dx in grid]
                           for dy in grid])
        row, col, frac_row, frac_col = _grid_peak(scores)
        centre = centre + (grid[col], grid[row])
    dx, dy = centre + step * np.array([frac_col, frac_row])
    return float(dx), float(dy)


def _profile_values(sample: _Sampler, points: np.ndarray, views: np.ndarray,
                    normals: np.ndarray) -> np.ndarray:
    """(49,) the mean across-edge profile of (N, 2) points of maps `views` (N,) along their
    (N, 2) unit normals, at PROFILE_OFFSETS."""
    along = points[None] + PROFILE_OFFSETS[:, None, None] * normals[None]  # (49, N, 2)
    return sample(along, views).mean(axis=1)


def _orientation_profiles(sample: _Sampler, points: np.ndarray, views: np.ndarray, normals: np.ndarray,
                          bins: int) -> tuple[tuple[OrientationOffset, ...], EdgeProfile]:
    """Per bin of the normal's direction (modulo 180 degrees), the offset along the bin's centre
    direction, the normals flipped onto it (empty bins are left out); and the band's own
    profile: the bins' profiles moved to peak at 0 and averaged, weighted by their points (so
    that offsets differing between orientations do not widen it)."""
    width = np.pi / bins
    angle = np.mod(np.arctan2(normals[:, 1], normals[:, 0]), np.pi)
    index = np.floor((angle + width / 2) / width).astype(np.int64) % bins
    offsets, centred = [], []
    for k in range(bins):
        chosen = index == k
        if not chosen.any():
            continue
        axis = np.array([np.cos(k * width), np.sin(k * width)])
        flipped = normals[chosen] * np.sign(normals[chosen] @ axis)[:, None]
        values = _profile_values(sample, points[chosen], views[chosen], flipped)
        peak = EdgeProfile.from_values(values).peak_px
        offsets.append(OrientationOffset(float(np.degrees(k * width)), peak, int(chosen.sum())))
        centred.append(np.interp(PROFILE_OFFSETS + peak, PROFILE_OFFSETS, values))
    band = np.average(centred, axis=0, weights=[o.points for o in offsets])
    return tuple(offsets), EdgeProfile.from_values(band)


def measure_offset(edge_maps: Sequence[np.ndarray], projections: Sequence[ProjectedCurves],
                   bins: int = ORIENTATION_BINS, max_points: int = MAX_POINTS,
                   seed: int = 0) -> OffsetMeasurement:
    """Measure where the maps draw the curves: the 2D offset, per orientation, on silhouettes.

    Args:
        edge_maps: the (H, W) float maps, one per view.
        projections: each map's visible ground-truth points (same order).
        bins: orientation bins over 180 degrees.
        max_points: beyond this many points, a random subset (drawn from `seed`) is measured.
    Returns:
        The measurement; offsets follow the module's sign convention (the map relative to the
        truth).
    """
    if len(edge_maps) != len(projections):
        raise ValueError(f"{len(edge_maps)} maps but {len(projections)} projections")
    points = np.concatenate([p.points for p in projections]).reshape(-1, 2)
    if len(points) == 0:
        raise ConfigError("no visible ground-truth points to measure the edge maps against")
    normals = np.concatenate([p.normals for p in projections])
    outward = np.concatenate([p.outward for p in projections])
    views = np.concatenate([np.full(len(p.points), i) for i, p in enumerate(projections)])
    if len(points) > max_points:
        keep = np.sort(np.random.default_rng(seed).choice(len(points), max_points, replace=False))
        points, normals, outward, views = points[keep], normals[keep], outward[keep], views[keep]
    sample = _Sampler(edge_maps)
    offset = _best_shift(sample, points, views)
    orientations, profile = _orientation_profiles(sample, points, views, normals, bins)
    on_silhouette = outward != 0
    silhouette = None
    if on_silhouette.any():
        outward_normals = normals[on_silhouette] * outward[on_silhouette, None]
        silhouette = EdgeProfile.from_values(
            _profile_values(sample, points[on_silhouette], views[on_silhouette], outward_normals))
    return OffsetMeasurement(offset, orientations, profile, silhouette, len(points), int(on_silhouette.sum()))


# --- ground-truth curves in the images ---------------------------------------------------------

def curve_tangents(points: np.ndarray, neighbours: int = 4) -> np.ndarray:
    """Unit tangents of points sampled densely along curves, in any order.

    Each tangent is the main axis of the point and its `neighbours` nearest points within three
    sample spacings (the median nearest-neighbour distance). Where fewer than two neighbours are
    that close, or where they do not lie on a line (corners, junctions), the tangent is NaN.

    Args:
        points: (N, 3) curve samples.
    Returns:
        (N, 3) unit tangents (sign arbitrary), NaN where undefined.
    """
    distance, index = cKDTree(points).query(points, k=neighbours + 1)
    near = distance <= 3 * np.median(distance[:, 1])  # (N, k + 1), the point itself included
    count = near.sum(axis=1)
    mean = (points[index] * near[..., None]).sum(axis=1) / count[:, None]
    centred = (points[index] - mean[:, None]) * near[..., None]
    eigenvalues, eigenvectors = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred))
    tangents = eigenvectors[:, :, -1].copy()
    straight = eigenvalues[:, 1] <= 0.05 * eigenvalues[:, 2]
    tangents[(count < 3) | ~straight] = np.nan
    return tangents


def project_curves(camera: Camera, points: np.ndarray, tangents: np.ndarray) -> ProjectedCurves:
    """The curve points `camera` sees inside its image, with their image tangents.

    Args:
        points: (N, 3) world curve points (already known to be visible, or not tested).
        tangents: (N, 3) their unit 3D tangents; points with NaN tangents are dropped.
    Returns:
        The points in front of the camera and within the image, `outward` all 0.
    """
    known = np.isfinite(tangents).all(axis=1)
    points, tangents = points[known], tangents[known]
    uv, depth = camera.project(points)
    # A step of 1e-4 of the depth: far below a pixel, far above float64 round-off.
    step = (1e-4 * np.abs(depth))[:, None]
    direction = camera.project(points + step * tangents)[0] - camera.project(points - step * tangents)[0]
    length = np.linalg.norm(direction, axis=1)
    inside = (depth > 0) & (length > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= camera.width - 1) \
        & (uv[:, 1] >= 0) & (uv[:, 1] <= camera.height - 1)
    tangents_2d = direction[inside] / length[inside, None]
    return ProjectedCurves(uv[inside], tangents_2d, np.zeros(int(inside.sum()), np.int8))


def silhouette_sides(projected: ProjectedCurves, background: np.ndarray) -> ProjectedCurves:
    """Mark silhouette points: background on one side of the curve, the object on the other.

    Args:
        projected: curve points of one view.
        background: (H, W) bool, True where the render shows no object.
    Returns:
        `projected` with `outward` +1 where background lies along +normal at every probe
        distance (SILHOUETTE_PROBES) and the object along -normal, -1 the other way round, 0
        elsewhere. Outside the image counts as background.
    """
    height, width = background.shape

    def is_background(side: float) -> np.ndarray:  # (probes, N)
        probes = np.array(SILHOUETTE_PROBES)[:, None, None] * side * projected.normals[None]
        x, y = np.moveaxis(np.rint(projected.points[None] + probes).astype(np.int64), -1, 0)
        inside = (x >= 0) & (x < width) & (y >= 0) & (y < height)
        return ~inside | background[np.clip(y, 0, height - 1), np.clip(x, 0, width - 1)]

    plus, minus = is_background(1.0), is_background(-1.0)
    outward = np.where(plus.all(0) & ~minus.any(0), 1, np.where(minus.all(0) & ~plus.any(0), -1, 0))
    return dataclasses.replace(projected, outward=outward.astype(np.int8))


def _render_and_detect(detector: EdgeDetector, part: Part, cameras: list[Camera],
                       progress: tqdm) -> tuple[list[np.ndarray], list[ProjectedCurves]]:
    """The detector's maps of `part` seen by `cameras` and each view's visible curve points,
    silhouettes marked from the render's background."""
    from edgedog.scenes.images import as_rgb, to_unit_float
    from edgedog.synthetic.exact import visible
    from edgedog.synthetic.render import Renderer  # imports moderngl

    points = part.ground_truth()
    tangents = curve_tangents(points)
    maps, projections = [], []
    with Renderer(part.mesh, cameras[0].width, cameras[0].height) as renderer:
        for camera in cameras:
            render = renderer.render(camera)
            shown = visible(points, camera, render)
            projected = project_curves(camera, points[shown], tangents[shown])
            projections.append(silhouette_sides(projected, render.depth <= 0))
            # As a scene loaded with default options shows the render: composited on black.
            maps.append(detector.detect(as_rgb(to_unit_float(render.rgba), (0.0, 0.0, 0.0))))
            progress.update()
    return maps, projections


def calibrate_detector(detector: EdgeDetector, shapes: Sequence[str] = DEFAULT_SHAPES, views: int = 8,
                       sizes: Sequence[int] = (400, 800), seed: int = 0, bins: int = ORIENTATION_BINS,
                       progress: bool = False) -> DetectorCalibration:
    """Measure `detector`'s bias on built-in parts rendered through EGL with exact ground truth.

    Args:
        shapes: `make_part` names, each drawn with `seed`.
        views: orbit cameras per part and size (ABC-NEF's orbit, scaled to the size).
        sizes: square image sizes in pixels; the bias is measured per size and over all.
        bins: orientation bins over 180 degrees.
    Raises:
        ConfigError for an unknown shape or an empty setting; GLUnavailableError without EGL.
    """
    if views < 1 or not sizes or not shapes:
        raise ConfigError("calibration needs at least one view, one size and one shape")
    parts = [make_part(name, seed) for name in shapes]
    per_size, all_maps, all_projections = {}, [], []
    with tqdm(total=len(sizes) * len(parts) * views, desc=f"calibrate {detector.name}", unit="view",
              disable=not progress) as bar:
        for size in sizes:
            maps, projections = [], []
            cameras = orbit_cameras(views, size)
            for part in parts:
                part_maps, part_projections = _render_and_detect(detector, part, cameras, bar)
                maps += part_maps
                projections += part_projections
            per_size[int(size)] = measure_offset(maps, projections, bins, seed=seed)
            all_maps += maps
            all_projections += projections
    overall = measure_offset(all_maps, all_projections, bins, seed=seed)
    date = datetime.now(timezone.utc).isoformat(timespec="seconds")
    return DetectorCalibration(detector.name, detector.fingerprint, overall, per_size, tuple(shapes), views,
                               seed, date)


# --- a dataset's own maps ----------------------------------------------------------------------

def measure_scene_maps(scene: Scene, maps_name: str, bins: int = ORIENTATION_BINS,
                       progress: bool = False) -> OffsetMeasurement:
    """The same measurement on a scene's own edge maps against its ground truth.

    Every ground-truth point is projected into every view: real scenes have no depth renders,
    so occlusion is not tested. Most hidden points land where the map shows no edge, but those
    near visible edges pull the result. On ABC-NEF 00000006, whose CAD mesh gives the exact
    visibility, all points put its PiDiNet maps at dx, dy = -0.49, -1.03 px and the visible
    ones at -0.46, -0.83 (a Sobel map of its images: -0.03, -0.39 and 0.02, -0.15). Silhouette
    points are told apart with the scene's object masks (mask files or the images' alpha) when
    it has them; otherwise `silhouette` is None.

    Raises:
        InputError when the scene has no ground truth or no maps named `maps_name`.
    """
    ground_truth = ground_truth_for(scene.root)
    if ground_truth is None:
        raise InputError(scene.root, "no ground truth beside the scene: nothing to measure its maps against")
    if maps_name not in scene.detectors:
        available = ", ".join(scene.detectors) or "none"
        raise InputError(scene.root, f"no '{maps_name}' edge maps (available: {available})")
    gt_to_world = np.linalg.inv(scene.world_to_gt)  # may hold a scale: not a rigid inverse
    points = EdgeCurves(points=ground_truth.load()).transformed(gt_to_world).points
    tangents = curve_tangents(points)
    maps, projections = [], []
    for index in tqdm(range(len(scene)), desc=f"maps ({maps_name})", unit="view", disable=not progress):
        maps.append(scene.load_edge_map(index, maps_name))
        projected = project_curves(scene.camera(index), points, tangents)
        mask = scene.load_mask(index)
        projections.append(projected if mask is None else silhouette_sides(projected, ~mask))
    return measure_offset(maps, projections, bins)
