"""Writing a built-in part as a scene folder in the ABC-NEF layout.

    <scene>/train_img/<i>.png       RGBA renders (transparent background)
    <scene>/train/<i>.png           8-bit edge maps of the named detector, white on black
    <scene>/val_img/, val/          VAL_VIEWS held-out views, never degraded
    <scene>/transforms_{train,val}.json
                                    `camera_angle_x`, `edge_detector`, frames with `file_path`
                                    (the edge map), OpenGL camera-to-world `transform_matrix` and
                                    `camera_intrinsics`; with pose noise also the
                                    `true_transform_matrix` the image was rendered with
    <scene>/gt/<scene>_0.005.ply    ground-truth points (what `ground_truth_for` finds)
    <scene>/gt/<scene>_curves.json  the exact curves they were sampled from
    <scene>/edgedog_scene.json      how the scene was made: shape, seed, dimensions, options

The folder is built under a hidden temporary name beside the target and renamed when complete,
so a reader (or a crash) never sees half a scene.
"""

from __future__ import annotations

import json
import shutil
import uuid
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from edgedog.curve_files import EdgeCurves, write_ply
from edgedog.edges.registry import make_detector
from edgedog.errors import InputError
from edgedog.files import create_folder
from edgedog.groundtruth import GT_SPACING
from edgedog.scenes.camera import OPENGL_TO_OPENCV, Camera
from edgedog.scenes.images import as_rgb, to_u8, to_unit_float
from edgedog.synthetic import degrade
from edgedog.synthetic.cameras import orbit_cameras
from edgedog.synthetic.exact import EXACT, exact_edge_map
from edgedog.synthetic.render import Render, Renderer
from edgedog.synthetic.shapes import Part

VAL_VIEWS = 4
VAL_PHASE = 1.0  # radians: the held-out spiral is turned away from the training one
MANIFEST = "edgedog_scene.json"
EdgeMapper = Callable[[Camera, Render, np.ndarray], np.ndarray]


def edge_mapper(detector: str, part: Part, weights: str | Path | None = None) -> tuple[str, EdgeMapper]:
    """The detector's name and a function (camera, render, rgba) -> (H, W) float32 edge map.

    `detector` is a name `make_detector` accepts ("auto": PiDiNet, with the shipped BSDS weights
    unless others are given) or EXACT: the part's visible feature curves.
    """
    if detector == EXACT:
        return EXACT, lambda camera, render, rgba: exact_edge_map(part.curves, camera, render)
    model = make_detector(detector, weights)
    # Detectors see the render composited on black, as a scene loaded with default options shows it.
    return model.name, lambda camera, render, rgba: model.detect(as_rgb(to_unit_float(rgba), (0.0, 0.0, 0.0)))


def write_scene(folder: str | Path, part: Part, views: int = 50, size: int = 800, seed: int = 0,
                detector: str = "auto", weights: str | Path | None = None,
                degradations: degrade.Degradations = degrade.Degradations(), progress: bool = False,
                lighting: str = "two-lights") -> Path:
    """Render `part` from `views` orbit cameras at `size` x `size` pixels into a new scene folder.

    Args:
        folder: the scene folder to create (it must not exist); its name is the scene's id.
        seed: the seed of the degradations' random draws.
        detector: edge maps by this detector (see `edge_mapper`).
        degradations: what to spoil in the training views.
        lighting: the images' look (`edgedog.synthetic.render.LIGHTINGS`).
    Returns:
        `folder`.
    """
    folder = Path(folder)
    if folder.exists():
        raise InputError(folder, "already exists; choose another folder or remove it")
    name, edge_map = edge_mapper(detector, part, weights)
    train = orbit_cameras(views, size)
    kept = degrade.kept_views(views, degradations.keep_views, degrade.stream(seed, "views"))
    splits = {"train": ({int(i): train[i] for i in kept}, degradations),
              "val": (dict(enumerate(orbit_cameras(VAL_VIEWS, size, VAL_PHASE))), degrade.Degradations())}
    create_folder(folder.parent, named=folder)
    partial = folder.with_name(f".{folder.name}.{uuid.uuid4().hex[:8]}.partial")
    create_folder(partial, exist_ok=False, named=folder)  # not mkdtemp: the usual permissions, not 0700
    try:
        with Renderer(part.mesh, size, size, lighting) as renderer:
            for split, (cameras, spoil) in splits.items():
                frames = _write_views(partial, split, cameras, renderer, edge_map, spoil, seed,
                                      progress and split == "train")
                transforms = {"camera_angle_x": 2 * np.arctan(size / (2 * train[0].K[0, 0])),
                              "edge_detector": name, "frames": frames}
                (partial / f"transforms_{split}.json").write_text(json.dumps(transforms, indent=1))
        _write_ground_truth(partial / "gt", folder.name, part)
        manifest = {"shape": part.name, "dimensions": part.dimensions, "seed": seed, "views": views,
                    "size": size, "edge_detector": name, "lighting": lighting,
                    "degradations": degradations.to_json()}
        (partial / MANIFEST).write_text(json.dumps(manifest, indent=1))
        partial.rename(folder)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    return folder


def _write_views(root: Path, split: str, cameras: dict[int, Camera], renderer: Renderer,
                 edge_map: EdgeMapper, spoil: degrade.Degradations, seed: int, progress: bool) -> list[dict]:
    """Render, detect, spoil and write one split's views; returns their transforms frames."""
    (root / split).mkdir()
    (root / f"{split}_img").mkdir()
    noise, poses, drops = (degrade.stream(seed, name) for name in ("image_noise", "poses", "drops"))
    dropped = degrade.dropped_views(len(cameras), spoil.drop_fraction, drops)
    frames = []
    for (number, camera), drop in tqdm(list(zip(cameras.items(), dropped)), desc=f"{split} views",
                                       unit="view", disable=not progress):
        render = renderer.render(camera)
        rgba = render.rgba
        if spoil.image_noise:
            rgba = degrade.add_image_noise(rgba, spoil.image_noise, noise)
        edges = edge_map(camera, render, rgba)
        if drop:
            edges = degrade.drop_segments(edges, drops)
        cv2.imwrite(str(root / f"{split}_img" / f"{number}.png"), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
        cv2.imwrite(str(root / split / f"{number}.png"), to_u8(edges))
        frame = {"file_path": f"./{split}/{number}", "camera_intrinsics": camera.K.tolist()}
        c2w = written = camera.c2w()
        if spoil.rotation_deg or spoil.translation_mm:
            written = degrade.perturb_pose(c2w, spoil.rotation_deg, spoil.translation_mm, poses)
            frame["true_transform_matrix"] = (c2w @ OPENGL_TO_OPENCV).tolist()
        frames.append({**frame, "transform_matrix": (written @ OPENGL_TO_OPENCV).tolist()})
    return frames


def _write_ground_truth(folder: Path, scene_id: str, part: Part) -> None:
    folder.mkdir()
    write_ply(folder / f"{scene_id}_{GT_SPACING}.ply", EdgeCurves(points=part.ground_truth()))
    curves = [curve.to_json() for curve in part.curves]
    (folder / f"{scene_id}_curves.json").write_text(
        json.dumps({"frame": "ground truth: [0, 1]^3, 1 unit = 1000 mm", "curves": curves}, indent=1))
