"""`edgedog bench distorted-copy`: a scene rewritten in nerfstudio's format with distorted cameras
trains as well as the original.

`write_distorted_copy` writes a pinhole scene (ABC-NEF's NeRF files, say) as nerfstudio's
`transforms.json` (`fl_x fl_y cx cy w h`, `camera_model` OPENCV with `k1 k2 p1 p2`) whose images,
masks and edge maps are the originals seen through that lens distortion (resampled with OpenCV).
Loading the copy undistorts it again (`edgedog.scenes.undistort`), into pinhole views of other
intrinsics; so a copy that trains to the original's score, within the seeds' spread, shows the
nerfstudio loader and the undistortion losing nothing. The copy links the original's ground
truth (`gt/`, `groundtruth/`) and keeps its folder name, by which the ground truth is found.

`run_distorted_copy` trains the original and the copy for each seed (OUT/original-seed<N>,
OUT/copy-seed<N>; finished runs reused) and writes OUT/distorted_copy.json and .md.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np

from edgedog.batch.table import mean_and_spread
from edgedog.bench.tables import cell, spread_cell
from edgedog.errors import InputError
from edgedog.files import atomic_write, atomic_write_bytes, atomic_write_json
from edgedog.scenes import Scene, load_scene
from edgedog.scenes.camera import OPENGL_TO_OPENCV
from edgedog.scenes.images import read_raw
from edgedog.settings import with_values
from edgedog.train.config import TrainConfig

DISTORTION = {"k1": -0.3, "k2": 0.1, "p1": 0.002, "p2": -0.0015}
"""The copy's synthetic OPENCV lens: barrel distortion of about 11 px at the middle of an edge of
an 800 px ABC view (f = 1111 px), with some decentering."""
LINKED = ("gt", "groundtruth")
"""The original's ground-truth folders the copy links to."""
FILES = ("distorted_copy.json", "distorted_copy.md")
"""What the bench writes into OUT beside the copy and the runs, its record first."""
METRICS = (("fscore_5mm", "F5", 1), ("fscore_10mm", "F10", 1), ("fscore_20mm", "F20", 1),
           ("acc_mm", "Acc (mm)", 2), ("comp_mm", "Comp (mm)", 2))


def distortion_maps(K: np.ndarray, coefficients: np.ndarray, width: int,
                    height: int) -> tuple[np.ndarray, np.ndarray]:
    """The (H, W) float32 x and y maps for `cv2.remap` that distort a pinhole image: where in the
    undistorted image (intrinsics `K`, pixel centres at integers) each pixel of the image through
    OpenCV's lens `coefficients` (k1, k2, p1, p2) lies."""
    xs, ys = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    pixels = np.stack([xs.ravel(), ys.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    undistorted = cv2.undistortPoints(pixels, K, coefficients, R=None, P=K, criteria=criteria)
    undistorted = undistorted.reshape(height, width, 2)
    return undistorted[..., 0].astype(np.float32), undistorted[..., 1].astype(np.float32)


def _write_image(path: Path, image: np.ndarray) -> None:
    """An RGB(A) or grey array (as `read_raw` gives it) written as PNG."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR if image.shape[2] == 3 else cv2.COLOR_RGBA2BGRA)
    ok, data = cv2.imencode(".png", image)
    if not ok:
        raise RuntimeError(f"encoding failed for {path}")
    atomic_write(path, lambda file: file.write(data.tobytes()))


def write_distorted_copy(scene_path: Path, folder: Path, distortion: dict[str, float] = DISTORTION,
                         maps: bool = True) -> Path:
    """Write the nerfstudio copy of the pinhole scene `scene_path` into `folder`/<its name>.

    Every view's image (`images/`), mask (`masks/`) and, with `maps`, edge maps
    (`edge_<detector>/`) are resampled through `distortion` (nerfstudio's OPENCV k1 k2 p1 p2),
    bilinearly, zero outside the original; a zero distortion gives a pinhole copy of the same
    pixels. Returns the copy's folder.

    Raises:
        InputError: the copy's folder exists, or the scene's views differ in intrinsics (the copy
            has one camera).
    """
    scene = load_scene(scene_path)
    copy = Path(folder) / scene.root.name
    if copy.exists():
        raise InputError(copy, "already exists; choose a new folder for the copy")
    first = scene.views[0].camera
    if any(not np.allclose(view.camera.K, first.K) or (view.camera.width, view.camera.height)
           != (first.width, first.height) for view in scene.views):
        raise InputError(scene.root, "its views differ in intrinsics; the distorted copy has one camera")
    coefficients = np.array([distortion[k] for k in ("k1", "k2", "p1", "p2")], dtype=np.float64)
    warp = distortion_maps(first.K, coefficients, first.width, first.height)
    frames = [_copy_view(scene, index, copy, warp, maps) for index in range(len(scene))]
    K = first.K
    # nerfstudio puts the top-left pixel's centre at (0.5, 0.5); edgedog at (0, 0).
    meta = {"camera_model": "OPENCV", "fl_x": K[0, 0], "fl_y": K[1, 1], "cx": K[0, 2] + 0.5,
            "cy": K[1, 2] + 0.5, "w": first.width, "h": first.height, **distortion, "frames": frames}
    atomic_write(copy / "transforms.json", lambda file: file.write(json.dumps(meta, indent=1).encode()))
    for name in LINKED:
        if (scene.root / name).is_dir():
            os.symlink(scene.root / name, copy / name, target_is_directory=True)
    return copy


def _copy_view(scene: Scene, index: int, copy: Path, warp: tuple[np.ndarray, np.ndarray], maps: bool) -> dict:
    """Write view `index`'s distorted files (`warp`: `distortion_maps`; its edge maps only with
    `maps`) into `copy`; return its nerfstudio frame."""
    view = scene.views[index]
    size = (view.camera.width, view.camera.height)

    def distorted(source: Path, target: Path) -> str:
        _write_image(target, cv2.remap(read_raw(source, size), *warp, cv2.INTER_LINEAR,
                                       borderMode=cv2.BORDER_CONSTANT, borderValue=0))
        return target.relative_to(copy).as_posix()

    frame = {"file_path": distorted(view.image_path, copy / "images" / f"{view.name}.png"),
             "transform_matrix": (view.camera.c2w() @ OPENGL_TO_OPENCV).tolist()}
    if view.mask_path is not None:
        frame["mask_path"] = distorted(view.mask_path, copy / "masks" / f"{view.name}.png")
    for detector, path in (view.edge_paths.items() if maps else ()):
        distorted(path, copy / f"edge_{detector}" / f"{view.name}.png")
    return frame


def run_distorted_copy(scene_path: Path, out: Path, preset_name: str, config: TrainConfig,
                       seeds: tuple[int, ...], copy_seeds: tuple[int, ...], computed_maps: bool = False,
                       progress: bool = True) -> dict:
    """Write the copy into OUT/copy (or reuse it), train the original for `seeds` and the copy for
    `copy_seeds` (finished runs reused), and write OUT/distorted_copy.json and .md.

    With `computed_maps` neither scene keeps the original's edge maps, and the detector computes
    them from each scene's (undistorted) images, as from a user's capture: the copy is written
    without maps, and the original is replaced by its pinhole copy without maps (OUT/pinhole).
    The scene's own maps, distorted and undistorted, are resampled twice, which blurs them.

    Returns:
        the record: per run its scores (the extraction report's curve metrics) and training
        seconds; per scene the mean and sample standard deviation over its seeds.
    """
    from edgedog.train.lifecycle import REUSE, execute, lock_folder, plan_run

    original = load_scene(scene_path).root
    copy = out / "copy" / original.name
    if not (copy / "transforms.json").is_file():
        write_distorted_copy(original, out / "copy", maps=not computed_maps)
    if computed_maps:
        pinhole = out / "pinhole" / original.name
        if not (pinhole / "transforms.json").is_file():
            write_distorted_copy(original, out / "pinhole", dict.fromkeys(DISTORTION, 0.0), maps=False)
        original = pinhole
    runs = []
    with lock_folder(out):
        for kind, scene, kind_seeds in (("original", original, seeds), ("copy", copy, copy_seeds)):
            for seed in kind_seeds:
                plan = plan_run(out / f"{kind}-seed{seed}", scene, preset_name,
                                with_values(config, {"run.seed": seed}), REUSE).check()
                result = execute(plan, progress=progress)
                metrics = result.report.get("metrics", {}).get("curves")
                if metrics is None:
                    raise InputError(scene, "has no ground truth to score the curves against")
                runs.append({"scene": kind, "seed": seed, "detector": result.log["detector"],
                             "train_seconds": result.log["train_seconds"],
                             **{key: metrics[key] for key, _, _ in METRICS}})
    record = {"scene": str(original), "copy": str(copy), "preset": preset_name, "distortion": DISTORTION,
              "computed_maps": computed_maps,
              "runs": runs, "summary": {kind: _summary([r for r in runs if r["scene"] == kind])
                                        for kind in ("original", "copy")}}
    atomic_write_json(out / FILES[0], record)
    atomic_write_bytes(out / FILES[1], markdown(record).encode())
    return record


def _summary(runs: list[dict]) -> dict:
    """Per metric: mean and sample standard deviation over `runs` (None for one run)."""
    result = {"seeds": [r["seed"] for r in runs]}
    for key, _, _ in METRICS:
        mean, spread = mean_and_spread([r[key] for r in runs])
        result[key] = {"mean": mean, "std": spread}
    return result


def markdown(record: dict) -> str:
    """One row per run, then the mean ± spread of each scene."""
    lens = ", ".join(f"{k} {v:g}" for k, v in record["distortion"].items())
    header = " | ".join(label for _, label, _ in METRICS)
    maps = "maps computed from each scene's images" if record["computed_maps"] else "the scene's own maps"
    lines = [f"The copy: nerfstudio OPENCV with {lens} ({record['preset']}; {maps}).", "",
             f"| scene | seed | {header} | training s |", "|---" * (len(METRICS) + 3) + "|"]
    for run in record["runs"]:
        scores = " | ".join(cell(run[key], digits) for key, _, digits in METRICS)
        lines.append(f"| {run['scene']} | {run['seed']} | {scores} | {run['train_seconds']:.0f} |")
    for kind, summary in record["summary"].items():
        scores = " | ".join(spread_cell(summary[key]["mean"], summary[key]["std"], digits)
                            for key, _, digits in METRICS)
        lines.append(f"| {kind}, mean | {len(summary['seeds'])} seeds | {scores} | |")
    return "\n".join(lines) + "\n"
