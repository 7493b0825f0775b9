"""Structure from motion for photos without poses: `run_sfm(photos, out)` writes a COLMAP scene
folder (undistorted PINHOLE cameras) that `edgedog.scenes.load_scene` reads.

Also `align_similarity`, the Umeyama similarity between two point sets, to compare recovered
cameras with known ones.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from edgedog.errors import InputError, OutputError
from edgedog.files import create_folder
from edgedog.scenes.colmap import COLMAP_SUFFIXES, colmap_log_level

MATCHERS = ("exhaustive", "sequential")
MIN_REGISTERED = 3
PARTIAL = ".{}.partial-"
"""The name of the temporary folder beside the output (formatted with its name), before a random tail."""
TO_TRY = ("try more photos with more overlap (every part of the object in 3 or more photos taken a "
          "step apart), sharp photos of a textured object in even light, a larger --max-image-size, "
          "or --matcher sequential for video frames")
"""What a failed registration suggests."""


def align_similarity(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity dst ~ s R src + t (Umeyama 1991).

    Args:
        src, dst: (N, 3) corresponding points, N >= 3 and not all collinear.
    Returns:
        s: scale; R: (3, 3) rotation (det +1); t: (3,) translation.
    """
    src = np.asarray(src, dtype=np.float64).reshape(-1, 3)
    dst = np.asarray(dst, dtype=np.float64).reshape(-1, 3)
    if len(src) != len(dst) or len(src) < 3:
        raise ValueError(f"need at least 3 corresponding points, got {len(src)} and {len(dst)}")
    mu_src, mu_dst = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_src, dst - mu_dst
    var_src = (a**2).sum() / len(src)
    if var_src <= 0:
        raise ValueError("the source points all coincide")
    U, D, Vt = np.linalg.svd(b.T @ a / len(src))
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1.0
    R = U @ S @ Vt
    s = float(np.trace(np.diag(D) @ S) / var_src)
    t = mu_dst - s * R @ mu_src
    return s, R, t


def _say(message: str) -> None:
    print(f"sfm: {message}", flush=True)


def partial_folders(out: Path) -> list[Path]:
    """The temporary folders `run_sfm` left beside `out` when its process was killed (a normal end
    or an error removes its own); for a caller that killed it, while no other writes `out`."""
    out = Path(out).expanduser().resolve()
    return sorted(out.parent.glob(f"{PARTIAL.format(out.name)}*"))


def photo_names(folder: Path) -> list[str]:
    """Names of the image files directly in `folder`, sorted; InputErrors for unusable folders."""
    if not folder.exists():
        raise InputError(folder, "photo folder not found")
    if not folder.is_dir():
        raise InputError(folder, "is a file, not a folder of photos")
    names = sorted(p.name for p in folder.iterdir()
                   if p.is_file() and p.suffix.lower() in COLMAP_SUFFIXES)
    if not names:
        raise InputError(folder, f"no images found ({', '.join(COLMAP_SUFFIXES)})")
    if len(names) < MIN_REGISTERED:
        raise InputError(folder, f"only {len(names)} image(s); structure from motion needs at "
                                 f"least {MIN_REGISTERED} overlapping photos")
    return names


def _sizes(folder: Path, names: list[str]) -> set[tuple[int, int]]:
    """The distinct (width, height) of the photos (decodes each once)."""
    sizes = set()
    for name in names:
        image = cv2.imread(str(folder / name), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise InputError(folder / name, "cannot be decoded as an image")
        sizes.add((image.shape[1], image.shape[0]))
    return sizes


def _check_out(out: Path) -> None:
    if out.is_dir() and not any(out.iterdir()):
        return  # an empty folder is replaced
    if out.exists() or out.is_symlink():
        raise InputError(out, "already exists; choose a new output folder or remove this one")


REGISTRATION_LINES = 20
"""Lines the mapping prints at most (about) on the photos it registers: one per photo for up to
2 * REGISTRATION_LINES photos, then one every `len(photos) // REGISTRATION_LINES`."""


def registration_reporter(photos: int) -> Callable[[], None]:
    """The mapping's callback for each photo registered: says how many are, every
    max(1, photos // REGISTRATION_LINES) photos, so that a progress bar moves on a few photos
    and the output stays short on many."""
    every, registered = max(1, photos // REGISTRATION_LINES), [0]

    def next_image() -> None:
        registered[0] += 1
        if registered[0] % every == 0:
            _say(f"  {registered[0]} images registered")

    return next_image


def run_sfm(photos: Path, out: Path, max_image_size: int = 1600,
            matcher: str = "exhaustive") -> Path:
    """Recover cameras for a folder of photos and write a COLMAP scene folder.

    SIFT features (one shared camera when all photos have the same size, COLMAP's default
    SIMPLE_RADIAL model), `matcher` matching, incremental mapping, then undistortion of the
    largest model to PINHOLE cameras. `out` receives `images/` and `sparse/` (cameras, images,
    points3D); it is written in a temporary folder beside it and renamed into place when complete.

    Args:
        photos: folder of overlapping photos (.jpg, .png, ...), not searched recursively.
        out: the scene folder to create (must not exist, or be empty).
        max_image_size: longest side for feature extraction and for the undistorted images.
        matcher: "exhaustive" (every pair; up to a few hundred photos) or "sequential" (video).
    Returns:
        `out`, resolved.
    Raises:
        InputError: no or too few photos, `out` exists, or fewer than 3 photos registered.
    """
    import pycolmap

    if matcher not in MATCHERS:
        raise ValueError(f"matcher must be one of {', '.join(MATCHERS)}, got {matcher!r}")
    photos = Path(photos).expanduser().resolve()
    out = Path(out).expanduser().resolve()
    names = photo_names(photos)
    _check_out(out)
    sizes = _sizes(photos, names)
    create_folder(out.parent, named=out)
    try:
        temporary = Path(tempfile.mkdtemp(prefix=PARTIAL.format(out.name), dir=out.parent))
    except OSError as exc:
        raise OutputError(out, f"cannot create the folder ({exc.strerror or exc})") from None
    started = time.perf_counter()
    try:
        database = temporary / "database.db"
        models = temporary / "models"
        models.mkdir()
        shared = len(sizes) == 1
        _say(f"extracting SIFT features from {len(names)} photos in {photos} "
             f"({'one shared camera' if shared else f'{len(sizes)} image sizes'})")
        extraction = pycolmap.FeatureExtractionOptions()
        extraction.max_image_size = int(max_image_size)
        with colmap_log_level(2):
            pycolmap.extract_features(
                database, photos, image_names=names,
                camera_mode=pycolmap.CameraMode.SINGLE if shared else pycolmap.CameraMode.AUTO,
                extraction_options=extraction, device=pycolmap.Device.cpu)
            _say(f"matching ({matcher})")
            match = pycolmap.match_exhaustive if matcher == "exhaustive" else pycolmap.match_sequential
            match(database, device=pycolmap.Device.cpu)
            with pycolmap.Database.open(database) as db:
                read = {image.name for image in db.read_all_images()}
                _, geometries = db.read_two_view_geometries()
        unread = [name for name in names if name not in read]
        if unread:
            raise InputError(photos / unread[0], "COLMAP could not read this image")
        pairs = sum(len(geometry.inlier_matches) > 0 for geometry in geometries)
        _say(f"{pairs} image pairs with geometrically verified matches; incremental mapping")
        options = pycolmap.IncrementalPipelineOptions()
        options.random_seed = 0
        with colmap_log_level(3):  # a failed mapping is reported below as one line
            reconstructions = pycolmap.incremental_mapping(database, photos, models, options=options,
                                                           next_image_callback=registration_reporter(len(names)))
        if not reconstructions:
            raise InputError(photos, f"structure from motion registered 0 of {len(names)} photos "
                                     f"(no model: too little overlap or texture); {TO_TRY}")
        key, best = max(reconstructions.items(), key=lambda item: item[1].num_reg_images())
        if best.num_reg_images() < MIN_REGISTERED:
            raise InputError(photos, f"structure from motion registered only "
                                     f"{best.num_reg_images()} of {len(names)} photos "
                                     f"(needs {MIN_REGISTERED}; too little overlap or texture); {TO_TRY}")
        _say(f"largest of {len(reconstructions)} model(s): {best.num_reg_images()} of "
             f"{len(names)} photos, {best.num_points3D()} points, mean reprojection error "
             f"{best.compute_mean_reprojection_error():.2f} px; undistorting")
        model_dir = models / str(key)
        if not (model_dir / "cameras.bin").is_file():
            model_dir = temporary / "best"
            model_dir.mkdir()
            best.write(model_dir)
        scene_dir = temporary / "scene"
        undistort = pycolmap.UndistortCameraOptions()
        undistort.max_image_size = int(max_image_size)
        with colmap_log_level(2):
            pycolmap.undistort_images(scene_dir, model_dir, photos, output_type="COLMAP",
                                      undistort_options=undistort)
        for extra in scene_dir.iterdir():  # keep images/ and sparse/ (drop stereo/, scripts)
            if extra.name not in ("images", "sparse"):
                shutil.rmtree(extra) if extra.is_dir() else extra.unlink()
        from edgedog.scenes.colmap import load_colmap

        load_colmap(scene_dir)  # what we hand over must load
        _check_out(out)
        if out.is_dir():
            out.rmdir()
        scene_dir.rename(out)
    finally:
        shutil.rmtree(temporary, ignore_errors=True)
    _say(f"wrote {out} in {time.perf_counter() - started:.0f} s")
    return out
