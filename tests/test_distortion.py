"""Distorted cameras load as the pinhole cameras of their undistorted images: for every camera
model nerfstudio and COLMAP scenes name, a dot drawn where a 3D point projects through the
distorted model lands, once the scene is loaded (undistorted by OpenCV into the cache), within
0.5 px of that point's projection through the loaded pinhole camera."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgedog.errors import InputError
from edgedog.scenes import load_scene
from edgedog.scenes.undistort import scene_cache

W, H, F = 200, 150, 150.0
CX, CY = 99.5, 74.5  # OpenCV's (and edgedog's) principal point: pixel centres at integers
K = np.array([[F, 0.0, CX], [0.0, F * 1.02, CY], [0.0, 0.0, 1.0]])
# Points in the camera frame (OpenCV: +Z forward), on a grid reaching near the image's corners.
POINTS = np.array([[x, y, 1.0] for x in np.linspace(-0.55, 0.55, 5) for y in np.linspace(-0.4, 0.4, 4)])
SIGMA = 1.2  # px, the dots' Gaussian radius


def dots_image(pixels: np.ndarray, with_mask: bool = False) -> np.ndarray:
    """(H, W, 3) uint8 image, grey Gaussian dots at `pixels` (N, 2) on black."""
    ys, xs = np.mgrid[0:H, 0:W]
    image = np.zeros((H, W))
    for x, y in pixels[np.all(np.abs(pixels - [W / 2, H / 2]) < 2 * W, axis=1)]:  # far ones draw nothing
        image += np.exp(-((xs - x) ** 2 + (ys - y) ** 2) / (2 * SIGMA**2))
    grey = np.round(255 * np.clip(image, 0, 1)).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=2)


def dot_centres(image: np.ndarray, expected: np.ndarray, radius: int = 5) -> np.ndarray:
    """(N, 2) the intensity centroid of the dot near each of `expected` (N, 2) pixels."""
    found = []
    for x, y in expected:
        x0, y0 = int(round(x)) - radius, int(round(y)) - radius
        window = image[y0 : y0 + 2 * radius + 1, x0 : x0 + 2 * radius + 1].astype(np.float64)
        window = np.where(window > 0.05 * window.max(), window, 0.0)
        ys, xs = np.mgrid[y0 : y0 + window.shape[0], x0 : x0 + window.shape[1]]
        found.append([(window * xs).sum() / window.sum(), (window * ys).sum() / window.sum()])
    return np.array(found)


def assert_dots_on_the_pinhole_projections(root: Path, distorted_pixels: np.ndarray) -> None:
    """Load the scene at `root` and check its one view: undistorted, the dots drawn at
    `distorted_pixels` lie on the pinhole projections of POINTS (those well inside the image)."""
    scene = load_scene(root)
    view = scene.views[0]
    assert view.distortion is None and view.image_path.is_relative_to(scene_cache(scene.root))
    camera = scene.camera(0)
    assert (camera.width, camera.height) == (W, H)
    uv, depth = camera.project(POINTS)  # the camera is at the origin, looking down +Z
    inside = (depth > 0) & np.all((uv > 8) & (uv < [W - 9, H - 9]), axis=1)
    assert inside.sum() >= 10, "too few points left to check"
    image = cv2.imread(str(view.image_path), cv2.IMREAD_GRAYSCALE)
    found = dot_centres(image, uv[inside])
    error = np.linalg.norm(found - uv[inside], axis=1)
    assert error.max() < 0.5, error
    # A pinhole reading of the distorted image would be off by pixels: the test can fail.
    assert np.linalg.norm(distorted_pixels[inside] - uv[inside], axis=1).max() > 2.0


# --- nerfstudio ---------------------------------------------------------------------------------


NERFSTUDIO_CASES = {
    "OPENCV": {"k1": -0.25, "k2": 0.06, "k3": -0.004, "p1": 0.002, "p2": -0.0015},
    "OPENCV_FISHEYE": {"k1": 0.08, "k2": -0.03, "k3": 0.01, "k4": -0.002},
    "PINHOLE": {"k1": 0.12},  # nerfstudio applies the coefficients of every perspective model
}


def write_nerfstudio(root: Path, model: str, coefficients: dict, image: np.ndarray, **extra) -> Path:
    """A one-frame nerfstudio scene: the camera at the origin looking down OpenCV's +Z."""
    (root / "images").mkdir(parents=True)
    cv2.imwrite(str(root / "images" / "frame_00001.png"), image)
    c2w_opengl = np.diag([1.0, -1.0, -1.0, 1.0])
    meta = {"camera_model": model, "fl_x": K[0, 0], "fl_y": K[1, 1], "cx": CX + 0.5, "cy": CY + 0.5,
            "w": W, "h": H, **coefficients,
            "frames": [{"file_path": "images/frame_00001.png", "transform_matrix": c2w_opengl.tolist()}],
            **extra}
    (root / "transforms.json").write_text(json.dumps(meta))
    return root


def opencv_projection(model: str, coefficients: dict) -> np.ndarray:
    """(N, 2) POINTS projected by OpenCV's own model for a nerfstudio camera."""
    if model == "OPENCV_FISHEYE":
        d = np.array([coefficients.get(k, 0.0) for k in ("k1", "k2", "k3", "k4")])
        uv, _ = cv2.fisheye.projectPoints(POINTS[None], np.zeros(3), np.zeros(3), K, d)
    else:
        d = np.array([coefficients.get(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")])
        uv, _ = cv2.projectPoints(POINTS, np.zeros(3), np.zeros(3), K, d)
    return uv.reshape(-1, 2)


@pytest.mark.parametrize("model", list(NERFSTUDIO_CASES))
def test_nerfstudio_cameras_are_undistorted(tmp_path, model):
    coefficients = NERFSTUDIO_CASES[model]
    distorted = opencv_projection(model, coefficients)
    root = write_nerfstudio(tmp_path / "scene", model, coefficients, dots_image(distorted))
    assert_dots_on_the_pinhole_projections(root, distorted)


# --- COLMAP -------------------------------------------------------------------------------------


COLMAP_CASES = {
    "SIMPLE_RADIAL": [F, CX + 0.5, CY + 0.5, -0.2],
    "RADIAL": [F, CX + 0.5, CY + 0.5, -0.2, 0.05],
    "OPENCV": [F, F * 1.02, CX + 0.5, CY + 0.5, -0.25, 0.06, 0.002, -0.0015],
    "FULL_OPENCV": [F, F * 1.02, CX + 0.5, CY + 0.5, -0.25, 0.06, 0.002, -0.0015, 0.01, 0.02, -0.01, 0.005],
    "OPENCV_FISHEYE": [F, F * 1.02, CX + 0.5, CY + 0.5, 0.08, -0.03, 0.01, -0.002],
}


def write_colmap(root: Path, model: str, params: list[float]) -> np.ndarray:
    """A one-image COLMAP project at `root` whose dots are POINTS projected by COLMAP's own
    model; returns those (N, 2) pixels in edgedog's convention."""
    pycolmap = pytest.importorskip("pycolmap")
    camera = pycolmap.Camera.create_from_model_name(1, model, F, W, H)
    camera.params = np.asarray(params, dtype=np.float64)
    # COLMAP puts the top-left pixel's centre at (0.5, 0.5).
    distorted = np.asarray(camera.img_from_cam(POINTS), dtype=np.float64) - 0.5
    rec = pycolmap.Reconstruction()
    rec.add_camera_with_trivial_rig(camera)
    rec.add_image_with_trivial_frame(pycolmap.Image(name="a.png", camera_id=1, image_id=1),
                                     pycolmap.Rigid3d(pycolmap.Rotation3d(np.eye(3)), np.zeros(3)))
    (root / "images").mkdir(parents=True)
    cv2.imwrite(str(root / "images" / "a.png"), dots_image(distorted))
    (root / "sparse" / "0").mkdir(parents=True)
    rec.write_text(str(root / "sparse" / "0"))
    return distorted


@pytest.mark.parametrize("model", list(COLMAP_CASES))
def test_colmap_cameras_are_undistorted(tmp_path, model):
    distorted = write_colmap(tmp_path / "scene", model, COLMAP_CASES[model])
    assert_dots_on_the_pinhole_projections(tmp_path / "scene", distorted)


# --- images, masks and maps stay aligned; undistorted once --------------------------------------


def test_masks_and_maps_are_undistorted_with_the_image(tmp_path):
    coefficients = NERFSTUDIO_CASES["OPENCV"]
    distorted = opencv_projection("OPENCV", coefficients)
    image = dots_image(distorted)
    root = write_nerfstudio(tmp_path / "scene", "OPENCV", coefficients, image)
    meta = json.loads((root / "transforms.json").read_text())
    meta["frames"][0]["mask_path"] = "masks/frame_00001.png"
    (root / "transforms.json").write_text(json.dumps(meta))
    (root / "masks").mkdir()
    cv2.imwrite(str(root / "masks" / "frame_00001.png"), image[..., 0])
    (root / "edge_mine").mkdir()
    cv2.imwrite(str(root / "edge_mine" / "frame_00001.png"), image[..., 0])

    scene = load_scene(root)
    assert scene.detectors == ["mine"]
    undistorted = scene.load_image(0)[..., 0]
    np.testing.assert_allclose(scene.load_coverage(0), undistorted, atol=1 / 255)
    np.testing.assert_allclose(scene.load_edge_map(0, "mine"), undistorted, atol=1 / 255)
    # Loaded again: the cached files are reused, not written again.
    view = scene.views[0]
    stamps = [path.stat().st_mtime_ns for path in (view.image_path, view.mask_path, view.edge_paths["mine"])]
    again = load_scene(root).views[0]
    assert (again.image_path, again.mask_path, again.edge_paths) == (view.image_path, view.mask_path,
                                                                      view.edge_paths)
    np.testing.assert_array_equal(again.camera.K, view.camera.K)
    assert stamps == [path.stat().st_mtime_ns for path in (again.image_path, again.mask_path,
                                                           again.edge_paths["mine"])]


def test_a_distortion_no_pinhole_can_undistort_is_one_line(tmp_path):
    write_colmap(tmp_path / "scene", "OPENCV", [F, F, CX + 0.5, CY + 0.5, 1e300, 0.0, 0.0, 0.0])
    with pytest.raises(InputError) as info:
        load_scene(tmp_path / "scene")
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{tmp_path / 'scene' / 'images' / 'a.png'}: cannot be "
                                                      "undistorted (opencv distortion (1e+300"), message
