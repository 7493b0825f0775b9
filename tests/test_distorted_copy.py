"""edgedog bench distorted-copy: the nerfstudio copy of an ABC object with distorted cameras
loads, and once undistorted it shows the object where the original's cameras put it (reads
../shared/data; no training)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.bench.distorted_copy import DISTORTION, write_distorted_copy
from edgedog.errors import InputError
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import Camera, load_scene
from edgedog.scenes.images import as_rgb, read_raw, to_unit_float

pytestmark = pytest.mark.shared_data

HALF = 64
"""Half the side of the patch around a ground-truth point in which the shift is measured."""
VIEWS = (0, 17, 33, 45)
ECC_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-6)
"""When OpenCV's image alignment (`findTransformECC`) stops: 100 steps, or a step under 1e-6 px."""


@pytest.fixture(scope="module")
def scenes(abc_nef_scene_dir, tmp_path_factory):
    """(the original ABC-NEF scene, its distorted nerfstudio copy, loaded and so undistorted)."""
    copy = write_distorted_copy(abc_nef_scene_dir, tmp_path_factory.mktemp("distorted"))
    return load_scene(abc_nef_scene_dir), load_scene(copy)


def _gray(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)


def _patch_shifts(original: np.ndarray, original_camera: Camera, image: np.ndarray, camera: Camera,
                  points: np.ndarray) -> list[float]:
    """The shift, in pixels, between `image` (seen by the pinhole `camera`) and the `original`
    image resampled into `camera`'s pixels, in a patch around the ground-truth point (`points`,
    (N, 3)) farthest from the image's centre to the left, right, top and bottom: where a wrong
    lens model shows most. Both cameras share a pose, so the resampling is an affine map."""
    to_original = (original_camera.K @ np.linalg.inv(camera.K))[:2]
    resampled = cv2.warpAffine(original, to_original, (camera.width, camera.height),
                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
    uv, _ = camera.project(points)
    centre = np.array([camera.width, camera.height]) / 2
    shifts = []
    for axis in (0, 1):
        for sign in (-1, 1):
            far = uv[np.argmax(sign * (uv[:, axis] - centre[axis]))]
            u, v = np.clip(np.rint(far).astype(int), HALF, [camera.width - HALF, camera.height - HALF])
            window = np.s_[v - HALF:v + HALF, u - HALF:u + HALF]
            _, warp = cv2.findTransformECC(resampled[window], image[window], np.eye(2, 3, dtype=np.float32),
                                           cv2.MOTION_TRANSLATION, ECC_CRITERIA, None, 1)
            shifts.append(float(np.hypot(*warp[:, 2])))
    return shifts


def test_the_copy_loads_as_a_nerfstudio_scene_of_undistorted_pinhole_views(scenes):
    original, copy = scenes
    assert copy.format == "nerfstudio"
    assert [v.name for v in copy.views] == [v.name for v in original.views]
    assert all(view.distortion is None for view in copy.views)
    assert copy.detectors == original.detectors == ["pidinet"]
    assert ground_truth_for(copy.root) is not None  # the linked gt/, found by the folder's name
    for mine, theirs in zip(copy.views, original.views):
        np.testing.assert_allclose(mine.camera.w2c, theirs.camera.w2c, atol=1e-6)
    # Undistorting barrel distortion to images without empty borders zooms in a little.
    assert not np.allclose(copy.views[0].camera.K, original.views[0].camera.K)


def test_the_undistorted_copy_shows_a_ground_truth_point_within_half_a_pixel_of_the_original(scenes):
    original, copy = scenes
    points = ground_truth_for(copy.root).load()
    worst = 0.0
    for index in VIEWS:
        shifts = _patch_shifts(_gray(original.load_image(index)), original.camera(index),
                               _gray(copy.load_image(index)), copy.camera(index), points)
        worst = max(worst, *shifts)
    assert worst < 0.5


def test_the_check_sees_the_distortion_when_the_copy_is_read_as_pinhole(scenes):
    """The same measurement on the copy's distorted files with the original's pinhole cameras
    (what a loader that ignored camera_model would do) is off by more than the tolerance."""
    original, copy = scenes
    points = ground_truth_for(copy.root).load()
    worst = 0.0
    for index in VIEWS:
        file = copy.root / "images" / f"{original.views[index].name}.png"
        distorted = as_rgb(to_unit_float(read_raw(file)), original.background)
        shifts = _patch_shifts(_gray(original.load_image(index)), original.camera(index), _gray(distorted),
                               original.camera(index), points)
        worst = max(worst, *shifts)
    assert worst > 0.5, f"distortion {DISTORTION} moves the object by only {worst:.2f} px"


def test_a_copy_is_never_written_over_an_existing_folder(abc_nef_scene_dir, tmp_path):
    (tmp_path / abc_nef_scene_dir.name).mkdir()
    with pytest.raises(InputError, match="already exists"):
        write_distorted_copy(abc_nef_scene_dir, tmp_path)


def test_a_zero_distortion_without_maps_is_a_pinhole_copy_of_the_same_pixels(abc_nef_scene_dir, tmp_path):
    """What `bench distorted-copy --computed-maps` trains as the original."""
    copy = load_scene(write_distorted_copy(abc_nef_scene_dir, tmp_path, dict.fromkeys(DISTORTION, 0.0),
                                           maps=False))
    original = load_scene(abc_nef_scene_dir)
    assert copy.format == "nerfstudio" and copy.detectors == []
    assert copy.views[0].image_path.is_relative_to(tmp_path)  # a pinhole view: read in place
    np.testing.assert_allclose(copy.camera(0).K, original.camera(0).K, atol=1e-9)
    np.testing.assert_array_equal(read_raw(copy.views[0].image_path), read_raw(original.views[0].image_path))
