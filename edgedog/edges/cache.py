"""Edge maps computed once per scene content, detector and resolution, and reused.

Maps go to the user cache ($EDGEDOG_CACHE, else ~/.cache/edgedog), never into the scene folder
(it is the user's, or a shared dataset's):
`edges/<scene>-<path digest>/<detector>/<fingerprint>_<W>x<H>_<content>/<view>.png` (8-bit).
`<content>` digests the images and cameras (`scene_fingerprint`) and the background RGBA images
are composited on, so maps of images that changed since are never reused. Each map is written
atomically, so every map in a folder is whole and belongs to its content: an interrupted run
resumes where it stopped. `manifest.json`, written last, records what the folder holds (for
people; the cache does not read it).
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from edgedog.edges.detector import EdgeDetector
from edgedog.errors import InputError
from edgedog.files import atomic_write, atomic_write_json
from edgedog.scenes import Scene
from edgedog.scenes.fingerprint import scene_fingerprint
from edgedog.scenes.images import Background, to_u8
from edgedog.scenes.undistort import scene_cache


def cache_root(scene: Scene) -> Path:
    """The user cache's folder for `scene`'s maps: one per scene folder (named after it and a
    digest of its path), whatever its permissions; its undistorted files live there too."""
    return scene_cache(scene.root)


def content_key(fingerprint: str, background: Background) -> str:
    """16 hex digits over what maps are computed from: a scene's images and cameras (its
    `scene_fingerprint`) and the background its RGBA images are composited on."""
    return hashlib.sha256(f"{fingerprint} {background}".encode()).hexdigest()[:16]


def maps_folder(scene: Scene, detector: EdgeDetector, fingerprint: str | None = None) -> Path:
    """Where `detector`'s maps of `scene` at its loaded resolution are kept (`fingerprint`: the
    scene's, computed when not given)."""
    camera = scene.camera(0)
    safe_name = detector.name.replace(":", "-")
    content = content_key(fingerprint or scene_fingerprint(scene), scene.background)
    return cache_root(scene) / safe_name / f"{detector.fingerprint}_{camera.width}x{camera.height}_{content}"


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
    fingerprint = scene_fingerprint(scene)
    folder = maps_folder(scene, detector, fingerprint)
    paths = [folder / f"{view.name}.png" for view in scene.views]
    missing = [i for i, path in enumerate(paths) if recompute or not path.is_file()]
    for image in (scene.views[i].image_path for i in missing):
        if image in scene.damaged:  # refused before any map is written
            raise InputError(image, scene.damaged[image])
    computed, seconds, pixels = 0, 0.0, 0
    for index in tqdm(missing, desc=f"edges ({detector.name})", unit="view",
                      disable=not progress or not missing):
        image = scene.load_image(index)
        start = time.perf_counter()
        edge_map = detector.detect(image)
        seconds += time.perf_counter() - start
        pixels += image.shape[0] * image.shape[1]
        _write_png(paths[index], edge_map)
        computed += 1
    manifest = folder / "manifest.json"
    if computed or not manifest.is_file():
        camera = scene.camera(0)
        atomic_write_json(manifest, {"detector": detector.name, "fingerprint": detector.fingerprint,
                                     "scene": fingerprint, "background": scene.background,
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
