"""Initial Gaussian positions and scales: triangulated SfM points on pseudo edges, the scene's
own SfM points, or EdgeGaussians' uniform cube, chosen automatically.

`initialize(scene)` is the entry point; `InitialPoints.report` records what was done and why.
"""

from __future__ import annotations

import tempfile
import typing
from pathlib import Path
from typing import Any

import numpy as np

from edgedog.errors import InputError
from edgedog.init.points import InitialPoints, nearest_neighbour_scales
from edgedog.init.settings import InitMethod, InitSettings
from edgedog.init.triangulate import checked_views, keep_on_edges, keypoints_per_view, triangulate_known_poses
from edgedog.init.uniform import uniform_init
from edgedog.scenes.common import look_at_point
from edgedog.scenes.scene import Scene

INIT_METHODS = typing.get_args(InitMethod)
DEFAULTS = InitSettings()
"""The defaults of `edgedog init` and of training's `init` section."""


def scene_cube(scene: Scene, side: float | None = DEFAULTS.side) -> tuple[np.ndarray, float]:
    """(3,) centre and edge of the cube the scene's object lies in: centred on the point an
    object-centric capture looks at, else on the scene's bounds (metadata boxes such as EMAP's
    [-1, 1]^3 are often loose and off-centre); `side` None: the bounds' largest extent."""
    lo, hi = np.asarray(scene.bounds, dtype=np.float64)
    side = float(np.max(hi - lo)) if side is None else float(side)
    center = look_at_point(scene.cameras)
    return ((lo + hi) / 2 if center is None else center), side


def uniform_for_scene(scene: Scene, count: int = DEFAULTS.count, side: float | None = DEFAULTS.side,
                      seed: int = 0) -> InitialPoints:
    """EdgeGaussians' uniform cube over `scene_cube`."""
    center, side = scene_cube(scene, side)
    # EdgeGaussians' scales (0.004 to 0.005) are for a 1.1-wide cube: keep their ratio to it.
    scale_range = (0.004 * side / 1.1, 0.005 * side / 1.1)
    return uniform_init(center, side=side, count=count, scale_range=scale_range, seed=seed)


def edge_vote_for_scene(scene: Scene, settings: InitSettings, detector: str | None,
                        seed: int = 0) -> InitialPoints:
    """The cells of `scene_cube` where the views' `detector` maps agree (`edge_vote_points`),
    carved by the views' masks where the scene has them."""
    # Imported here: scipy.stats takes half a second, which every command would pay at start-up.
    from edgedog.init.edge_vote import VoteSettings, edge_vote_points

    center, side = scene_cube(scene, settings.side)
    maps = [scene.load_edge_map(i, detector) for i in range(len(scene))]
    masks = [scene.load_mask(i) for i in range(len(scene))]
    vote = VoteSettings(cone=settings.vote_cone, surprise=settings.vote_surprise,
                        edge_threshold=settings.edge_threshold)
    # Scales as the uniform cube's at its densest, down to a tenth of that for close neighbours.
    scale_range = (0.0004 * side / 1.1, 0.005 * side / 1.1)
    return edge_vote_points(scene.cameras, maps, masks, center, side, settings.count, scale_range, vote, seed,
                            spacing=settings.vote_spacing * side)


def sfm_points_on_edges(scene: Scene, detector: str | None = None, min_edge_views: int = 2,
                        edge_threshold: float = DEFAULTS.edge_threshold,
                        views: list[int] | None = None) -> InitialPoints:
    """The scene's own SfM points (COLMAP scenes), kept on pseudo edges like triangulated ones."""
    if scene.sfm_points is None:
        raise InputError(scene.root, "the scene has no SfM points (only COLMAP scenes carry them)")
    positions = np.asarray(scene.sfm_points, dtype=np.float64).reshape(-1, 3)
    views = list(range(len(scene))) if views is None else list(views)
    return keep_on_edges(scene, positions, "sfm-points", {"sfm_points": int(len(positions))}, views,
                         detector, edge_threshold, min_edge_views)


PROBE_VIEWS = 5
"""Views whose SIFT keypoints `auto` counts before it triangulates."""
KEYPOINT_MARGIN = 4.0
"""A triangulated point needs a keypoint in two views, so V views of k keypoints give at most
k V / 2 points; `auto` skips triangulation when that bound is under this many times the points
it needs, i.e. when even a quarter of it would not do. Real photos keep about a tenth (DTU scan
37 at 800 px: 9,655 points of a bound of 90,000), so what is skipped would have failed;
ABC renders hold about 19 keypoints per view where 50 views need 80."""


def spread_views(views: list[int], count: int) -> list[int]:
    """Up to `count` of `views`, evenly spread over the list (its ends included)."""
    if len(views) <= count:
        return list(views)
    if count <= 1:
        return list(views[:count])
    return [views[round(i * (len(views) - 1) / (count - 1))] for i in range(count)]


def keypoints_needed(min_points: int, views: int) -> float:
    """Keypoints per view below which `views` views cannot give `min_points` triangulated points
    (with KEYPOINT_MARGIN to spare)."""
    return KEYPOINT_MARGIN * 2 * min_points / max(1, views)


def before_uniform(attempts: list[dict[str, Any]]) -> str:
    """The start of a fallback's reason naming the SfM points when they were tried first."""
    return "the scene's SfM points and " if any(a["method"] == "sfm-points" for a in attempts) else ""


def initialize(scene: Scene, settings: InitSettings = DEFAULTS, workdir: Path | None = None,
               detector: str | None = None, min_points: int = 500, seed: int = 0, *,
               views: list[int] | None = None, max_image_size: int | None = None) -> InitialPoints:
    """Initial points for a scene.

    Args:
        scene: the posed views.
        settings: the method, the uniform cube (count, side) and the edge threshold of the
            points kept. Methods: "uniform"; "triangulate" (SIFT matches triangulated with the
            known cameras); "sfm-points" (a COLMAP scene's own points); or "auto": the scene's
            SfM points when it has at least `min_points` of them on edges, else triangulation
            when that keeps at least `min_points`, else uniform (renders with few features).
            Before triangulating, "auto" counts the SIFT keypoints of PROBE_VIEWS views and goes
            straight to uniform when they are too few for `min_points` (`keypoints_needed`).
        workdir: where COLMAP's database and model go; a temporary folder (removed) if None.
        detector: pseudo-edge maps that points must project onto (None: keep all points).
        min_points: fewest points "auto" accepts before falling back.
        seed: seed of the uniform sampling.
        views: view indices used for triangulation and edge filtering (default all).
        max_image_size: longest image side for SIFT (None: the scene's as loaded, at most 1600).
    Returns:
        InitialPoints whose `report` holds "requested", the chosen "method", a "reason" and,
        for "auto", every "attempts" made with its counts.
    """
    method, threshold = settings.method, settings.edge_threshold

    def uniform(reason: str, attempts: list[dict[str, Any]]) -> InitialPoints:
        result = uniform_for_scene(scene, settings.count, settings.side, seed)
        result.report.update({"requested": method, "reason": reason, "attempts": attempts})
        return result

    def finish(result: InitialPoints, reason: str, attempts: list[dict[str, Any]]) -> InitialPoints:
        result.report.update({"requested": method, "reason": reason, "attempts": attempts})
        return result

    if method == "uniform":
        return uniform("requested", [])
    if method == "edge-vote":
        result = edge_vote_for_scene(scene, settings, detector, seed)
        if len(result) == 0:
            raise InputError(scene.root, "the views' edge maps agree on no point (empty maps, or cameras "
                                         "that do not see one object); use the uniform initialisation")
        return finish(result, "requested", [])
    if method == "sfm-points":
        result = sfm_points_on_edges(scene, detector, edge_threshold=threshold, views=views)
        return finish(result, "requested", [])

    attempts: list[dict[str, Any]] = []
    if method == "auto" and scene.sfm_points is not None:
        result = sfm_points_on_edges(scene, detector, edge_threshold=threshold, views=views)
        attempts.append({"method": "sfm-points", "points": len(result)})
        if len(result) >= min_points:
            return finish(result, f"the scene's SfM points give {len(result)} points "
                                  f"(>= {min_points})", attempts)

    count = len(scene) if views is None else len(views)
    if count < 2:  # nothing to match
        if method == "triangulate":
            raise InputError(scene.root, f"triangulation needs at least 2 views; the scene has {count}")
        return uniform(f"triangulation needs at least 2 views, and the scene has {count}", attempts)
    all_views = checked_views(scene, views)
    with tempfile.TemporaryDirectory(prefix="edgedog-init-") as temporary:
        folder = Path(workdir) if workdir is not None else Path(temporary)
        folder.mkdir(parents=True, exist_ok=True)
        if method == "auto":
            probe = spread_views(all_views, PROBE_VIEWS)
            density = keypoints_per_view(scene, probe, folder / "probe", max_image_size)
            needed = keypoints_needed(min_points, count)
            if density < needed:
                attempts.append({"method": "triangulated", "skipped": True,
                                 "keypoints_per_view": round(density, 1), "probed_views": len(probe)})
                return uniform(f"{before_uniform(attempts)}the views hold {density:.0f} SIFT keypoints each "
                               f"(mean of {len(probe)}), fewer than the {needed:.0f} that "
                               f"{min_points} triangulated points need: too few image features", attempts)
        result = triangulate_known_poses(scene, folder, detector=detector, edge_threshold=threshold,
                                         max_image_size=max_image_size, views=all_views,
                                         match_neighbours=settings.match_neighbours)
    attempts.append({"method": "triangulated", "points": len(result),
                     "triangulated": result.report["triangulated"]})
    if method == "triangulate":
        if len(result) == 0:
            raise InputError(scene.root, "triangulation found no points (too few image features "
                                         "or matches); use the uniform initialisation")
        return finish(result, "requested", attempts)
    if len(result) >= min_points:
        return finish(result, f"triangulation kept {len(result)} points (>= {min_points})", attempts)
    filtered = isinstance(result.report.get("edge_filter"), dict)
    detail = (f" of {result.report['triangulated']} triangulated on '{detector}' edges"
              if filtered else "")
    return uniform(f"{before_uniform(attempts)}triangulation kept {len(result)} points{detail}, fewer than "
                   f"{min_points}: too few image features or matches", attempts)


__all__ = [
    "DEFAULTS",
    "edge_vote_for_scene",
    "INIT_METHODS",
    "KEYPOINT_MARGIN",
    "PROBE_VIEWS",
    "InitSettings",
    "InitialPoints",
    "initialize",
    "keypoints_needed",
    "keypoints_per_view",
    "nearest_neighbour_scales",
    "sfm_points_on_edges",
    "spread_views",
    "triangulate_known_poses",
    "uniform_for_scene",
    "uniform_init",
]
