"""Structure-from-motion points with the scene's KNOWN cameras.

SIFT features are extracted and matched with pycolmap, then triangulated with the scene's own
intrinsics and poses (no pose estimation, no bundle adjustment), and optionally kept only where
they project onto pseudo edges in several views.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from edgedog.errors import InputError, OutputError
from edgedog.init.points import InitialPoints, nearest_neighbour_scales
from edgedog.init.settings import InitSettings
from edgedog.scenes.camera import Camera
from edgedog.scenes.colmap import COLMAP_SUFFIXES, colmap_log_level
from edgedog.scenes.images import read_raw
from edgedog.scenes.scene import Scene

# Scale clip range of the triangulated points, as fractions of the bounds' largest extent.
SCALE_RANGE = (0.0005, 0.02)
MAX_SIFT_SIZE = 1600
"""Longest image side SIFT sees by default: COLMAP's own default is 3200, and a point finer
than 1/1600 of the view is finer than the edges trained from it."""


def edge_support(scene: Scene, points: np.ndarray, views: list[int], detector: str,
                 threshold: float) -> np.ndarray:
    """(N,) number of `views` in which each point projects onto a pseudo edge.

    A point counts for a view when it lies in front of the camera, its rounded projection falls
    inside the image, and the edge map there is >= `threshold`. Occlusion is not checked.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    counts = np.zeros(len(points), dtype=np.int64)
    for index in views:
        camera = scene.camera(index)
        edges = scene.load_edge_map(index, detector)
        pixels, inside = camera.pixels(points)
        hit = np.zeros(len(points), dtype=bool)
        hit[inside] = edges[pixels[inside, 1], pixels[inside, 0]] >= threshold
        counts += hit
    return counts


def scene_scale_range(scene: Scene) -> tuple[float, float]:
    """(lo, hi) clip range of nearest-neighbour scales for a scene, from its bounds' size."""
    size = float(np.max(scene.bounds[1] - scene.bounds[0]))
    return SCALE_RANGE[0] * size, SCALE_RANGE[1] * size


def _needs_conversion(path: Path, camera: Camera) -> bool:
    """True when COLMAP cannot read `path` as it is (alpha, 16 bit, unusual format)."""
    if path.suffix.lower() not in COLMAP_SUFFIXES:
        return True
    image = read_raw(path, (camera.width, camera.height))  # also checks the size
    return image.dtype != np.uint8 or (image.ndim == 3 and image.shape[2] not in (1, 3))


def _prepare_images(scene: Scene, views: list[int], image_dir: Path) -> dict[str, Camera]:
    """Put the views' images into one folder COLMAP can read -> {file name: its camera}.

    Plain 8-bit images are symlinked (camera at the file's resolution); RGBA, 16-bit or other
    files are written as PNG copies composited as `scene.load_image` does (loaded resolution).
    """
    image_dir.mkdir(parents=True, exist_ok=True)
    names: dict[str, Camera] = {}
    for index in views:
        view = scene.views[index]
        # The view's index only: COLMAP's match list splits at spaces, and rig names at '/'.
        stem = f"{index:05d}"
        if _needs_conversion(view.image_path, view.camera):
            name = f"{stem}.png"
            rgb = np.clip(np.rint(scene.load_image(index) * 255.0), 0, 255).astype(np.uint8)
            # Uncompressed: the copy lives only as long as the triangulation reads it.
            if not cv2.imwrite(str(image_dir / name), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                               [cv2.IMWRITE_PNG_COMPRESSION, 0]):
                raise OSError(f"could not write {image_dir / name}")
            names[name] = scene.camera(index)
        else:
            name = f"{stem}{view.image_path.suffix.lower()}"
            os.symlink(view.image_path.resolve(), image_dir / name)
            names[name] = view.camera
    return names


def _colmap_camera(camera_id: int, camera: Camera):
    """Our pinhole camera as a COLMAP PINHOLE camera (first pixel centre at (0.5, 0.5))."""
    import pycolmap

    K = camera.K
    colmap_camera = pycolmap.Camera.create_from_model_name(
        int(camera_id), "PINHOLE", float(K[0, 0]), int(camera.width), int(camera.height))
    colmap_camera.params = [K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5]
    colmap_camera.has_prior_focal_length = True
    return colmap_camera


def _known_reconstruction(database_path: Path, cameras: dict[str, Camera], image_dir: Path):
    """A pycolmap.Reconstruction with the database's ids and names but our cameras and poses.

    Also rewrites the database's cameras to the same PINHOLE models and parameters.
    """
    import pycolmap

    reconstruction = pycolmap.Reconstruction()
    with pycolmap.Database.open(database_path) as database:
        images = database.read_all_images()
        found = {image.name for image in images}
        for name in cameras:
            if name not in found:
                raise InputError((image_dir / name).resolve(), "COLMAP could not read this image")
        for image in images:
            camera = cameras[image.name]
            colmap_camera = _colmap_camera(image.camera_id, camera)
            database.update_camera(colmap_camera)
            reconstruction.add_camera_with_trivial_rig(colmap_camera)
            pose = pycolmap.Rigid3d(pycolmap.Rotation3d(camera.R.copy()), camera.t.copy())
            reconstruction.add_image_with_trivial_frame(
                pycolmap.Image(name=image.name, camera_id=image.camera_id, image_id=image.image_id),
                pose)
    return reconstruction


def checked_views(scene: Scene, views: list[int] | None) -> list[int]:
    """`views` (default all) as ints; ValueError for an index outside the scene."""
    views = list(range(len(scene))) if views is None else [int(v) for v in views]
    if any(not 0 <= v < len(scene) for v in views):
        raise ValueError(f"view indices must be in [0, {len(scene)}), got {views}")
    return views


def nearest_view_pairs(cameras: list[Camera], neighbours: int) -> list[tuple[int, int]]:
    """The view pairs worth matching: each view with its `neighbours` nearest camera centres
    among the views facing its way (optical axes within 90 degrees), both ways merged.

    Args:
        cameras: the views' cameras.
        neighbours: views paired with each view (>= 1).
    Returns:
        Sorted pairs (i, j), i < j, of indices into `cameras`: at most len(cameras) x neighbours.
    """
    centres = np.stack([c.center for c in cameras])
    axes = np.stack([c.forward for c in cameras])
    pairs = set()
    for i in range(len(cameras)):  # a row at a time: memory linear in the views
        distance = np.linalg.norm(centres - centres[i], axis=1)
        distance[axes @ axes[i] <= 0] = np.inf  # facing away: they see other sides of the scene
        distance[i] = np.inf
        for j in np.argsort(distance, kind="stable")[:neighbours]:
            if np.isfinite(distance[j]):
                pairs.add((min(i, int(j)), max(i, int(j))))
    return sorted(pairs)


def _write_pairs(path: Path, names: list[str], pairs: list[tuple[int, int]]) -> None:
    """COLMAP's match list: one pair of image names per line."""
    path.write_text("".join(f"{names[i]} {names[j]}\n" for i, j in pairs), encoding="utf-8")


def sift_size(scene: Scene, views: list[int], max_image_size: int | None) -> int:
    """The longest image side SIFT sees: `max_image_size`, or for None the views' resolution as
    loaded (the training resolution: features finer than its pixels fit nothing), at most
    MAX_SIFT_SIZE."""
    if max_image_size is not None:
        return int(max_image_size)
    return min(MAX_SIFT_SIZE, max(max(scene.camera(v).width, scene.camera(v).height) for v in views))


def _extract_features(scene: Scene, views: list[int], workdir: Path,
                      max_image_size: int) -> dict[str, Camera]:
    """SIFT features of `views` into workdir/database.db (the folder's COLMAP files replaced)
    -> {image name: its camera} in the order of `views`."""
    import pycolmap

    for stale in ("images", "sparse", "database.db", "pairs.txt"):
        target = workdir / stale
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        elif target.exists() or target.is_symlink():
            target.unlink()
    cameras = _prepare_images(scene, views, workdir / "images")
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.max_image_size = int(max_image_size)
    try:
        with colmap_log_level(2):
            pycolmap.extract_features(workdir / "database.db", workdir / "images", image_names=list(cameras),
                                      camera_mode=pycolmap.CameraMode.PER_IMAGE,
                                      extraction_options=extraction, device=pycolmap.Device.cpu)
    except RuntimeError as error:  # e.g. a full disk: "No registered database factory succeeded."
        first_line = (str(error).splitlines() or ["RuntimeError"])[0]
        raise OutputError(workdir / "database.db", f"cannot write COLMAP's feature database "
                                                   f"({first_line})") from None
    return cameras


def keypoints_per_view(scene: Scene, views: list[int], workdir: Path,
                       max_image_size: int | None = None) -> float:
    """Mean number of SIFT keypoints of `views`, found as triangulation finds them (in
    `workdir`, whose COLMAP files are replaced)."""
    import pycolmap

    workdir = Path(workdir)
    _extract_features(scene, views, workdir, sift_size(scene, views, max_image_size))
    with pycolmap.Database.open(workdir / "database.db") as database:
        return database.num_keypoints() / max(1, database.num_images())


def triangulate_known_poses(scene: Scene, workdir: Path, detector: str | None = None,
                            max_image_size: int | None = None, min_edge_views: int = 2,
                            edge_threshold: float = InitSettings.edge_threshold,
                            views: list[int] | None = None,
                            match_neighbours: int = InitSettings.match_neighbours) -> InitialPoints:
    """Triangulate SIFT matches with the scene's cameras; optionally keep only edge points.

    Args:
        scene: the posed views.
        workdir: folder for COLMAP's database, image links, match list and model (replaced if
            present).
        detector: pseudo-edge maps to filter on; None (or maps the scene lacks) keeps every
            triangulated point.
        max_image_size: images are downsized to this longest side for SIFT; None: the scene's
            resolution as loaded (the training resolution, features finer than its pixels fit
            nothing), at most MAX_SIFT_SIZE.
        min_edge_views: a point is kept when it projects onto an edge in this many views.
        edge_threshold: edge-map value that counts as an edge.
        views: indices of the views to use (default all).
        match_neighbours: views each view is matched with (`nearest_view_pairs`); 0, or as many
            as there are other views: every pair (COLMAP's exhaustive matching).
    Returns:
        InitialPoints with method "triangulated"; it may hold few or no points (textureless
        renders): `report` says how many were triangulated and kept.
    """
    import pycolmap

    views = checked_views(scene, views)
    if len(views) < 2:
        raise ValueError(f"triangulation needs at least 2 views, got {len(views)}")
    started = time.perf_counter()
    workdir = Path(workdir)
    max_image_size = sift_size(scene, views, max_image_size)
    image_dir, database_path, model_dir = workdir / "images", workdir / "database.db", workdir / "sparse"
    cameras = _extract_features(scene, views, workdir, max_image_size)
    every_pair = not 0 < match_neighbours < len(views) - 1
    if not every_pair:
        pairs = nearest_view_pairs([scene.camera(v) for v in views], match_neighbours)
        _write_pairs(workdir / "pairs.txt", list(cameras), pairs)
    with colmap_log_level(2):  # COLMAP's progress and warnings are summarised in `report`
        reconstruction = _known_reconstruction(database_path, cameras, image_dir)
        if every_pair:
            pycolmap.match_exhaustive(database_path, device=pycolmap.Device.cpu)
        else:
            pycolmap.match_image_pairs(database_path,
                                       pairing_options=pycolmap.ImportedPairingOptions(
                                           match_list_path=str(workdir / "pairs.txt")),
                                       device=pycolmap.Device.cpu)
        model_dir.mkdir(parents=True, exist_ok=True)
        reconstruction = pycolmap.triangulate_points(reconstruction, database_path, image_dir,
                                                     model_dir, refine_intrinsics=False)
    points3d = list(reconstruction.points3D.values())
    positions = np.array([p.xyz for p in points3d], dtype=np.float64).reshape(-1, 3)
    track = np.array([p.track.length() for p in points3d], dtype=np.int64)

    report: dict[str, Any] = {
        "views": len(views),
        "max_image_size": int(max_image_size),
        "matched_pairs": len(views) * (len(views) - 1) // 2 if every_pair else len(pairs),
        "triangulated": int(len(positions)),
        "mean_track_length": float(track.mean()) if len(track) else 0.0,
        "mean_reprojection_error_px": float(reconstruction.compute_mean_reprojection_error())
        if len(track) else 0.0,
    }
    report["seconds"] = round(time.perf_counter() - started, 2)
    return keep_on_edges(scene, positions, "triangulated", report, views, detector, edge_threshold,
                         min_edge_views)


def keep_on_edges(scene: Scene, positions: np.ndarray, method: str, report: dict[str, Any],
                  views: list[int], detector: str | None, edge_threshold: float,
                  min_edge_views: int) -> InitialPoints:
    """Points (N, 3) that land on `detector`'s edges in >= min_edge_views views, with scales from
    their neighbours' distances; `report` gains the filter used and the count kept."""
    if detector is not None and detector in scene.detectors:
        support = edge_support(scene, positions, views, detector, edge_threshold)
        positions = positions[support >= min_edge_views]
        report["edge_filter"] = {"detector": detector, "threshold": float(edge_threshold),
                                 "min_views": int(min_edge_views)}
    elif detector is not None:
        report["edge_filter"] = f"skipped: the scene has no '{detector}' edge maps"
    else:
        report["edge_filter"] = "none"
    lo, hi = scene_scale_range(scene)
    scales = nearest_neighbour_scales(positions, k=3, lo=lo, hi=hi) if len(positions) else np.zeros(0)
    report.update({"kept": int(len(positions)), "scale_clip": [lo, hi]})
    return InitialPoints(positions, scales, method, report)
