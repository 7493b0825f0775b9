"""edgedog bench sfm-vs-cameras: the similarity between two camera sets, and the distance between
curve sets it aligns (synthetic: no SfM, no training, no shared data)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from edgedog.bench.sfm_cameras import (
    axis_angles,
    camera_centres,
    camera_similarity,
    curve_distances,
    markdown,
    object_size,
)
from edgedog.curve_files import EdgeCurves
from edgedog.metrics import SAMPLE_SPACING
from edgedog.scenes import Camera, Scene, View


def _similarity(scale: float, rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = scale * rotation
    T[:3, 3] = translation
    return T


def _known_cameras(count: int = 12) -> dict[str, np.ndarray]:
    """Centres on a sphere of radius 3 around the origin, as a capture rig's."""
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(count, 3))
    centres = 3.0 * directions / np.linalg.norm(directions, axis=1, keepdims=True)
    return {f"{i:06d}": centre for i, centre in enumerate(centres)}


def _curves() -> EdgeCurves:
    """Two lines and a Bézier across the unit cube."""
    return EdgeCurves(lines=[[[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [0, 1, 0.5]]],
                      beziers=[[[0, 0, 1], [0.3, 0.5, 1], [0.6, -0.5, 1], [1, 0, 1]]])


def test_a_synthetic_similarity_is_recovered_exactly_and_aligns_the_curves():
    known = _known_cameras()
    # SfM's frame: the known one seen at another scale, turned and moved; the similarity from
    # SfM's frame to the known one is the inverse of `to_sfm`.
    to_sfm = _similarity(0.37, Rotation.from_euler("zyx", [40, -25, 110], degrees=True).as_matrix(),
                         np.array([5.0, -2.0, 0.5]))
    sfm = {name: (to_sfm @ np.append(centre, 1.0))[:3] for name, centre in known.items()}
    del sfm["000003"]  # a photo SfM did not register is left out of the match
    sfm["not-in-known"] = np.array([100.0, 0.0, 0.0])  # nor does a name only SfM has count

    fit = camera_similarity(sfm, known)

    assert len(fit.names) == len(known) - 1 and "not-in-known" not in fit.names
    np.testing.assert_allclose(fit.matrix, np.linalg.inv(to_sfm), atol=1e-9)
    assert fit.residuals.max() < 1e-9

    curves = _curves()
    known_points = curves.sample(SAMPLE_SPACING)
    aligned = curves.transformed(to_sfm).transformed(fit.matrix).sample(SAMPLE_SPACING)
    size = object_size(known_points)
    result = curve_distances(aligned, known_points, size)
    for direction in ("a_to_b", "b_to_a", "symmetric"):
        assert result[direction]["p90"] < 1e-6
    # The curves left in SfM's frame are far from the known ones: the distance can fail.
    assert curve_distances(curves.transformed(to_sfm).sample(SAMPLE_SPACING), known_points,
                           size)["symmetric"]["median"] > 0.1


def test_curve_distances_measure_a_known_offset_in_units_and_as_a_share_of_the_object():
    curves = _curves()
    points = curves.sample(SAMPLE_SPACING)
    offset = _similarity(1.0, np.eye(3), np.array([0.0, 0.0, 0.02]))
    shifted = curves.transformed(offset).sample(SAMPLE_SPACING)
    size = object_size(points)

    result = curve_distances(shifted, points, size)

    # Off by 0.02 along z: the line in the z = 0 plane and the Bézier in z = 1 are 0.02 from
    # their copies; only the sloping line's samples find a nearer point of the original.
    assert result["points"] == [len(shifted), len(points)]
    assert result["a_to_b"]["p90"] == pytest.approx(0.02, abs=1e-3)
    assert result["a_to_b"]["p90_share"] == pytest.approx(result["a_to_b"]["p90"] / size)
    assert 1.0 < size < 2.0


def test_samples_left_out_of_the_count_still_answer_for_the_other_set():
    points = _curves().sample(SAMPLE_SPACING)
    stray = np.array([[5.0, 5.0, 5.0]])
    a = np.concatenate([points, stray])
    keep_a = np.arange(len(a)) < len(points)  # the stray sample is not counted
    keep_b = points[:, 0] < 0.5  # half of b is counted, measured to all of a

    result = curve_distances(a, points, object_size(points), (keep_a, keep_b))

    assert result["points"] == [len(points), int(keep_b.sum())]
    assert result["a_to_b"]["p90"] < 1e-9 and result["b_to_a"]["p90"] < 1e-9
    assert curve_distances(a, points, 1.0)["a_to_b"]["p90"] == 0.0  # 1 stray in 10 % is not at p90
    assert curve_distances(stray, points, 1.0)["a_to_b"]["median"] > 5.0


def test_the_table_names_every_direction_and_set():
    points = _curves().sample(SAMPLE_SPACING)
    size = object_size(points)
    record = {"registered": 11, "views": 12, "size": [800, 600], "preset": "quick", "object_size": size,
              "similarity": {"scale": 2.7, "matched": 11, "axis_angle_deg": {"median": 0.5, "max": 0.8},
                             "centre_residual": {"median": 0.001, "max": 0.01, "rms": 0.002}},
              "distances": {"all": curve_distances(points, points, size),
                            "on_object": curve_distances(points[:0], points, size)}}

    table = markdown(record)

    assert "SfM registered 11 of 12 photos" in table
    assert "| all | SfM -> cameras |" in table and "| on object | both |" in table
    assert "| on object | SfM -> cameras | 0 | – |" in table  # no samples: no distance


def _scene(cameras: dict[str, tuple[np.ndarray, np.ndarray]]) -> Scene:
    """A scene of 64 px views from name -> (rotation (3, 3) world to camera, centre (3,))."""
    views = []
    for name, (rotation, centre) in cameras.items():
        w2c = np.eye(4)
        w2c[:3, :3] = rotation
        w2c[:3, 3] = -rotation @ centre
        views.append(View(name, Camera(np.array([[60.0, 0, 31.5], [0, 60.0, 31.5], [0, 0, 1]]), w2c, 64, 64),
                          Path(f"{name}.png")))
    return Scene(root=Path("."), format="colmap", views=views, bounds=np.array([[-1.0] * 3, [1.0] * 3]))


def test_axis_angles_are_what_the_similarity_leaves_of_the_orientations():
    turn = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    known = {name: (Rotation.from_rotvec(np.random.default_rng(i).normal(size=3)).as_matrix(), centre)
             for i, (name, centre) in enumerate(_known_cameras(6).items())}
    # SfM's frame turned by `turn` (x_sfm = turn @ x_known): its w2c rotations are R @ turn.T.
    sfm = {name: (rotation @ turn.T, turn @ centre) for name, (rotation, centre) in known.items()}
    tilt = Rotation.from_euler("x", 2.0, degrees=True).as_matrix()
    sfm["000002"] = (tilt @ sfm["000002"][0], sfm["000002"][1])  # one camera tilted by 2 degrees
    source, target = _scene(sfm), _scene(known)

    angles = axis_angles(source, target, camera_similarity(camera_centres(source), camera_centres(target)))

    assert angles[2] == pytest.approx(2.0, abs=1e-6)
    assert np.delete(angles, 2).max() < 1e-6
