"""Edge maps computed once per scene, detector and resolution, and reused.

Maps go to `<scene>/edgedog_edges/<detector>/<fingerprint>_<W>x<H>/<view>.png` (8-bit), or under
the user cache when the scene folder is read-only. Each map is written atomically and a
`manifest.json` is written last: an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import time
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from edgedog.edges.detector import EdgeDetector
from edgedog.files import atomic_write, atomic_write_json, default_cache, read_json
from edgedog.scenes import Scene
from edgedog.scenes.images import to_u8

CACHE_FOLDER = "edgedog_edges"


def cache_root(scene: Scene) -> Path:
    """`<scene>/edgedog_edges` when writable, else a folder of the user cache for this scene.

    A folder without any write permission bit counts as read-only even for root (who may write
    anywhere): shared datasets are read in place and never written into.
    """
    if os.access(scene.root, os.W_OK) and scene.root.stat().st_mode & 0o222:
        return scene.root / CACHE_FOLDER
    digest = hashlib.sha1(str(scene.root).encode()).hexdigest()[:12]
    return default_cache() / "edges" / f"{scene.root.name}-{digest}"


def maps_folder(scene: Scene, detector: EdgeDetector) -> Path:
    camera = scene.camera(0)
    safe_name = detector.name.replace(":", "-")
    return cache_root(scene) / safe_name / f"{detector.fingerprint}_{camera.width}x{camera.height}"


def _write_png(path: Path, edge_map: np.ndarray) -> None:
    ok, data = cv2.imencode(".png", to_u8(edge_map))
    if not ok:
        raise RuntimeError(f"PNG encoding failed for {path}")
    atomic_write(path, lambda f: f.write(data.tobytes()))


@dataclasses.dataclass
class EdgeMapRun:
    """What `ensure_edge_maps` did.

    Attributes:
        detector: the detector name the maps are attached under.
        folder: where the maps are (None when the scene's own maps were used).
        computed: how many maps were computed now (the rest were cached or provided).
        seconds: time spent detecting.
        megapixels: image area processed by the detector.
    """

    detector: str
    folder: Path | None
    computed: int
    seconds: float
    megapixels: float

    @property
    def seconds_per_megapixel(self) -> float | None:
        return self.seconds / self.megapixels if self.megapixels else None


def ensure_edge_maps(scene: Scene, detector: EdgeDetector, recompute: bool = False,
                     progress: bool = True) -> EdgeMapRun:
    """Make `detector.name` maps available for every view of `scene`, computing missing ones.

    A scene that ships maps under that name (ABC-NEF, EMAP) keeps them unless `recompute`.
    The scene's views are updated in place to point at the maps.
    """
    if detector.name in scene.detectors and not recompute:
        return EdgeMapRun(detector.name, None, 0, 0.0, 0.0)
    folder = maps_folder(scene, detector)
    manifest = folder / "manifest.json"
    complete = manifest.is_file() and read_json(manifest).get("views") == len(scene) and not recompute
    paths, computed, seconds, pixels = [], 0, 0.0, 0
    views = tqdm(range(len(scene)), desc=f"edges ({detector.name})", unit="view",
                 disable=not progress or complete)
    for index in views:
        path = folder / f"{scene.views[index].name}.png"
        if recompute or not (complete or path.is_file()):
            image = scene.load_image(index)
            start = time.perf_counter()
            edge_map = detector.detect(image)
            seconds += time.perf_counter() - start
            pixels += image.shape[0] * image.shape[1]
            _write_png(path, edge_map)
            computed += 1
        paths.append(path)
    camera = scene.camera(0)
    atomic_write_json(manifest, {"detector": detector.name, "fingerprint": detector.fingerprint,
                                 "width": camera.width, "height": camera.height, "views": len(scene)})
    scene.views = [dataclasses.replace(view, edge_paths={**view.edge_paths, detector.name: path})
                   for view, path in zip(scene.views, paths)]
    return EdgeMapRun(detector.name, folder, computed, seconds, pixels / 1e6)


def attach_edge_maps(scene: Scene, name: str, progress: bool = False) -> None:
    """Make the maps called `name` loadable from `scene`: its own maps of that name, else those
    of the detector of that name (found in the cache, or computed now)."""
    from edgedog.edges.registry import make_detector

    if name not in scene.detectors:
        ensure_edge_maps(scene, make_detector(name), progress=progress)
