"""`edgedog bench sfm-vs-cameras`: curves from photos alone against curves from known cameras.

A scene with known cameras (DTU's `cameras_sphere.npz`, say) is trained twice at the same
resolution: once on its own cameras (OUT/cameras-run) and once on a COLMAP scene that `edgedog
sfm` recovers from its photos alone (OUT/sfm-scene, trained in OUT/sfm-run). SfM's world is its
own (any scale, rotation and origin), so the SfM run's curves are carried into the known frame
by the similarity between the two camera sets: Umeyama on the camera centres, matched by image
name. The distance between the two curve sets is then the nearest-neighbour distance from each
sample of one set to the other set (samples every `SPACING` scene units), in both directions;
its median and 90th percentile are reported in scene units and as a share of the object's size.
When the known scene has masks, the same figures are also given for the samples
on the object (at most `ON_OBJECT_PX` pixels outside every view's mask; each measured to the
whole other set), as the SfM scene has no masks and its curves may run onto the background.

Finished steps in OUT are reused: the SfM scene, and each run (as `edgedog bench layers` does);
`write_comparison` measures two finished runs in that layout however they were trained.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from edgedog.bench.tables import cell
from edgedog.curve_files import EdgeCurves, read_edges
from edgedog.errors import InputError
from edgedog.files import atomic_write_bytes, atomic_write_json
from edgedog.metrics import SAMPLE_SPACING
from edgedog.scenes import Scene, load_scene
from edgedog.scenes.sfm import align_similarity
from edgedog.settings import with_values
from edgedog.train.config import TrainConfig

SFM_SCENE, SFM_RUN, CAMERAS_RUN = "sfm-scene", "sfm-run", "cameras-run"
FILES = ("sfm_vs_cameras.json", "sfm_vs_cameras.md")
"""What the bench writes into OUT beside the SfM scene and the two runs, its record first."""
ON_OBJECT_PX = 2.0
"""A curve sample is on the object when it lands at most this many pixels (at the training
resolution) outside the known scene's mask in every view that sees it."""
PERCENTILES = {"median": 50, "p90": 90}
SPACING = SAMPLE_SPACING / 5
"""Curves are sampled every 0.001 scene units: sampling adds at most half that to a distance."""


@dataclass(frozen=True)
class Similarity:
    """target = scale * rotation @ source + translation, and how well the camera centres fit it.

    names: the matched views' names; residuals: (N,) distance, in target units, between each
    matched target centre and its source centre carried by the similarity.
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    names: tuple[str, ...]
    residuals: np.ndarray

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) the similarity as a homogeneous transform."""
        T = np.eye(4)
        T[:3, :3] = self.scale * self.rotation
        T[:3, 3] = self.translation
        return T


def camera_similarity(source: dict[str, np.ndarray], target: dict[str, np.ndarray]) -> Similarity:
    """The least-squares similarity from the `source` camera centres to the `target` ones.

    Args:
        source, target: view name -> (3,) camera centre; matched by name (views only one side
            has are left out).
    Raises:
        ValueError: fewer than 3 names in common, or their centres all coincide.
    """
    names = tuple(sorted(source.keys() & target.keys()))
    src = np.array([source[name] for name in names], dtype=np.float64).reshape(-1, 3)
    dst = np.array([target[name] for name in names], dtype=np.float64).reshape(-1, 3)
    if len(names) < 3:
        raise ValueError(f"only {len(names)} views in common; the similarity needs at least 3")
    scale, rotation, translation = align_similarity(src, dst)
    moved = scale * src @ rotation.T + translation
    return Similarity(scale, rotation, translation, names, np.linalg.norm(moved - dst, axis=1))


def camera_centres(scene: Scene) -> dict[str, np.ndarray]:
    """View name -> (3,) camera centre of each view of `scene`."""
    return {view.name: view.camera.center for view in scene.views}


def axis_angles(source: Scene, target: Scene, similarity: Similarity) -> np.ndarray:
    """(N,) the angle, in degrees, between each matched view's optical axis in `target` and its
    axis in `source` turned by `similarity`: what the similarity of the centres leaves of the
    cameras' orientations (e.g. a principal point that SfM kept at the image's centre)."""
    forward = {view.name: view.camera.forward for view in source.views}
    known = {view.name: view.camera.forward for view in target.views}
    turned = np.array([similarity.rotation @ forward[name] for name in similarity.names]).reshape(-1, 3)
    axes = np.array([known[name] for name in similarity.names]).reshape(-1, 3)
    sines = np.linalg.norm(np.cross(turned, axes), axis=1)
    return np.degrees(np.arctan2(sines, np.sum(turned * axes, axis=1)))


def distance_summary(distances: np.ndarray, size: float) -> dict[str, float | None]:
    """The median and 90th percentile of `distances` (N,), and each as a share of `size`."""
    if len(distances) == 0:
        return {key: None for name in PERCENTILES for key in (name, f"{name}_share")}
    result = {}
    for name, q in PERCENTILES.items():
        value = float(np.percentile(distances, q))
        result[name] = value
        result[f"{name}_share"] = value / size if size > 0 else None
    return result


def curve_distances(a: np.ndarray, b: np.ndarray, size: float,
                    keep: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """Nearest-neighbour distances between two point sets sampled on curves.

    Args:
        a, b: (N, 3), (M, 3) curve samples in one frame; size: the object's size, for the shares.
        keep: (N,), (M,) bool: the samples of each set whose distance counts (e.g. those on the
            object); each is measured to the nearest sample of the whole other set, so that a
            counted sample is never far only because its counterpart was left out.
    Returns:
        {"points": [counted in a, counted in b], "a_to_b", "b_to_a", "symmetric" (both
        directions' distances pooled): `distance_summary` each}.
    """
    keep_a, keep_b = keep if keep is not None else (np.ones(len(a), bool), np.ones(len(b), bool))
    a_to_b = cKDTree(b).query(a[keep_a])[0] if len(b) else np.empty(0)
    b_to_a = cKDTree(a).query(b[keep_b])[0] if len(a) else np.empty(0)
    return {"points": [len(a_to_b), len(b_to_a)], "a_to_b": distance_summary(a_to_b, size),
            "b_to_a": distance_summary(b_to_a, size),
            "symmetric": distance_summary(np.concatenate([a_to_b, b_to_a]), size)}


def object_size(points: np.ndarray) -> float:
    """The diagonal of the box from the 1st to the 99th percentile of `points` (N, 3) per axis:
    the object's size, robust to a few stray curves."""
    if len(points) == 0:
        return 0.0
    lo, hi = np.percentile(points, [1, 99], axis=0)
    return float(np.linalg.norm(hi - lo))


def photo_folder(scene: Scene) -> Path:
    """The one folder that holds every view's photo (what SfM is given)."""
    folders = {view.image_path.parent for view in scene.views}
    if len(folders) != 1:
        raise InputError(scene.root, f"its photos lie in {len(folders)} folders; structure from motion "
                                     "takes one folder of photos")
    return folders.pop()


def training_downscale(known: Scene, sfm: Scene) -> int:
    """The downscale at which the known scene's images are as large as the SfM scene's (whose
    undistorted images `edgedog sfm --max-image-size` sized): the two runs train at one
    resolution."""
    known_side = max(known.views[0].camera.width, known.views[0].camera.height)
    sfm_side = max(sfm.views[0].camera.width, sfm.views[0].camera.height)
    return max(1, round(known_side / sfm_side))


def run_sfm_vs_cameras(scene_path: Path, out: Path, preset_name: str, config: TrainConfig,
                       max_image_size: int = 800, matcher: str = "exhaustive",
                       progress: bool = True) -> dict:
    """Recover the cameras of the scene's photos (or reuse OUT/sfm-scene), train (or reuse) both
    runs, align and compare their curves; write OUT/sfm_vs_cameras.json and .md.

    Args:
        config: the settings of both runs; the known-camera run's `maps.downscale` is set so that
            it trains at the SfM scene's resolution (`training_downscale`).
    Returns:
        the record written to OUT/sfm_vs_cameras.json.
    """
    from edgedog.scenes.sfm import run_sfm
    from edgedog.train.lifecycle import lock_folder

    known = load_scene(scene_path)
    sfm_path = out / SFM_SCENE
    if not (sfm_path / "sparse").is_dir():
        run_sfm(photo_folder(known), sfm_path, max_image_size=max_image_size, matcher=matcher)
    sfm = load_scene(sfm_path)
    downscale = training_downscale(known, sfm)
    with lock_folder(out):
        _train(out / CAMERAS_RUN, scene_path, preset_name, with_values(config, {"maps.downscale": downscale}),
               progress)
        _train(out / SFM_RUN, sfm_path, preset_name, config, progress)
    return write_comparison(scene_path, out, preset_name)


def write_comparison(scene_path: Path, out: Path, preset_name: str) -> dict:
    """Compare the finished runs OUT/cameras-run (on the scene at `scene_path`) and OUT/sfm-run (on
    OUT/sfm-scene), whichever way they were trained; write OUT/sfm_vs_cameras.json and .md.

    Returns:
        the record written to OUT/sfm_vs_cameras.json.
    """
    from edgedog.files import read_json

    known, sfm = load_scene(scene_path), load_scene(out / SFM_SCENE)
    downscale = training_downscale(known, sfm)
    similarity = camera_similarity(camera_centres(sfm), camera_centres(known))
    record = compare_runs(out / CAMERAS_RUN, out / SFM_RUN, similarity,
                          load_scene(scene_path, downscale=downscale))
    angles = axis_angles(sfm, known, similarity)
    record["similarity"]["axis_angle_deg"] = {"median": float(np.median(angles)), "max": float(angles.max())}
    record.update({"scene": str(known.root), "sfm_scene": str(sfm.root), "preset": preset_name,
                   "views": len(known), "registered": len(sfm), "downscale": downscale,
                   "size": [known.camera(0).width // downscale, known.camera(0).height // downscale],
                   "train_seconds": {run: read_json(out / run / "log.json")["train_seconds"]
                                     for run in (CAMERAS_RUN, SFM_RUN)}})
    atomic_write_json(out / FILES[0], record)
    atomic_write_bytes(out / FILES[1], markdown(record).encode())
    return record


def _train(run_dir: Path, scene: Path, preset_name: str, config: TrainConfig, progress: bool) -> None:
    from edgedog.train.lifecycle import REUSE, execute, plan_run

    execute(plan_run(run_dir, scene, preset_name, config, REUSE).check(), progress=progress)


def compare_runs(known_run: Path, sfm_run: Path, similarity: Similarity, known: Scene) -> dict:
    """The distances between the known-camera run's curves and the SfM run's carried by
    `similarity`, over all samples and, when `known` (at the runs' resolution) has masks, over
    the samples on the object."""
    from edgedog.curves.filtering import pixels_outside_masks

    known_points = read_edges(known_run / "curves.json").sample(SPACING)
    sfm_curves: EdgeCurves = read_edges(sfm_run / "curves.json").transformed(similarity.matrix)
    sfm_points = sfm_curves.sample(SPACING)
    size = object_size(known_points)
    sets = {"all": None}
    outside = [pixels_outside_masks(points, known) for points in (sfm_points, known_points)]
    if outside[0] is not None:
        sets["on_object"] = (outside[0] <= ON_OBJECT_PX, outside[1] <= ON_OBJECT_PX)
        size = object_size(known_points[sets["on_object"][1]])
    residuals = similarity.residuals
    return {"similarity": {"scale": similarity.scale, "rotation": similarity.rotation.tolist(),
                           "translation": similarity.translation.tolist(), "matched": len(similarity.names),
                           "centre_residual": {"median": float(np.median(residuals)),
                                               "max": float(residuals.max()),
                                               "rms": float(np.sqrt(np.mean(residuals**2)))}},
            "object_size": size, "spacing": SPACING,
            "distances": {name: curve_distances(sfm_points, known_points, size, keep)
                          for name, keep in sets.items()}}


def markdown(record: dict) -> str:
    """A line on the cameras' fit and a table of the distances per sample set and direction."""
    fit = record["similarity"]
    res = fit["centre_residual"]
    size = record["object_size"]
    lines = [f"SfM registered {record['registered']} of {record['views']} photos; both runs at "
             f"{record['size'][0]}x{record['size'][1]} ({record['preset']}). Camera centres after the "
             f"similarity (scale {fit['scale']:.4g}, {fit['matched']} matched): residual median "
             f"{res['median']:.4g}, max {res['max']:.4g} scene units; optical axes apart by "
             f"{fit['axis_angle_deg']['median']:.2f}° (median), {fit['axis_angle_deg']['max']:.2f}° (max). "
             f"Object size (1st-99th percentile box "
             f"diagonal of the known-camera curves): {size:.4g} scene units.", "",
             "| samples | direction | points | median | median / size | p90 | p90 / size |",
             "|---|---|---|---|---|---|---|"]
    directions = {"a_to_b": "SfM -> cameras", "b_to_a": "cameras -> SfM", "symmetric": "both"}
    for name, result in record["distances"].items():
        for key, label in directions.items():
            d = result[key]
            points = {"a_to_b": result["points"][0], "b_to_a": result["points"][1]}.get(
                key, sum(result["points"]))
            share = [None if d[f"{q}_share"] is None else 100 * d[f"{q}_share"] for q in PERCENTILES]
            lines.append(f"| {name.replace('_', ' ')} | {label} | {points} | {cell(d['median'], 4)} | "
                         f"{cell(share[0], 2)} % | {cell(d['p90'], 4)} | {cell(share[1], 2)} % |")
    return "\n".join(lines) + "\n"
