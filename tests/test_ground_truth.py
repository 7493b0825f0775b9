"""Ground truth on the real ABC objects pins every camera convention, and scores itself."""

from __future__ import annotations

import numpy as np
import pytest

from edgedog.errors import InputError
from edgedog.groundtruth import (
    GT_SPACING,
    abc_points_from_cad,
    ground_truth_for,
    read_obj_vertices,
    read_points_ply,
    sharp_polylines,
)
from edgedog.metrics import score_points
from edgedog.scenes import load_scene


def gt_in_world(scene) -> np.ndarray:
    gt_to_world = np.linalg.inv(scene.world_to_gt)  # may hold a scale: not a rigid inverse
    points = ground_truth_for(scene.root).load()
    return points @ gt_to_world[:3, :3].T + gt_to_world[:3, 3]


def edge_value_ratio(scene, detector: str, points: np.ndarray, index: int) -> float:
    """Mean edge-map value at the projected points over the map's mean value."""
    camera, edges = scene.camera(index), scene.load_edge_map(index, detector)
    uv, depth = camera.project(points)
    pixel = np.round(uv).astype(int)
    inside = (depth > 0) & (pixel >= 0).all(1) & (pixel[:, 0] < camera.width) & (pixel[:, 1] < camera.height)
    assert inside.mean() > 0.99  # the whole object is in view
    return edges[pixel[inside, 1], pixel[inside, 0]].mean() / edges.mean()


@pytest.mark.parametrize("fixture", ["abc_nef_scene_dir", "abc_emap_scene_dir"])
def test_projected_ground_truth_lands_on_the_edge_maps_of_every_view(fixture, request):
    scene = load_scene(request.getfixturevalue(fixture))
    points = gt_in_world(scene)
    for detector in scene.detectors:
        ratios = [edge_value_ratio(scene, detector, points, i) for i in range(len(scene))]
        # Measured 20-60x on these objects; a wrong axis flip or transpose gives ~1-3x.
        assert min(ratios) > 10, (detector, np.round(ratios, 1))


def test_a_wrong_convention_would_be_caught(abc_nef_scene_dir):
    scene = load_scene(abc_nef_scene_dir)
    points = gt_in_world(scene)
    # Y-up instead of Z-up, a classic convention slip: the statistic must collapse.
    swapped = points[:, [0, 2, 1]]
    for i in (0, 17, 33):
        true_ratio = edge_value_ratio(scene, "pidinet", points, i)
        assert edge_value_ratio(scene, "pidinet", swapped, i) < 0.3 * true_ratio


def test_cad_ground_truth_follows_the_protocol(abc_nef_scene_dir):
    source = ground_truth_for(abc_nef_scene_dir)
    assert source.features is not None
    points = source.load()
    # Normalised into [0, 1]^3 with the longest side exactly 1.
    assert points.min() >= -1e-9 and points.max() <= 1 + 1e-9
    assert np.isclose((points.max(0) - points.min(0)).max(), 1.0, atol=2 * GT_SPACING)
    # n = floor(|segment| / spacing) samples per segment, ends included: consecutive samples
    # of a segment lie between one and two raw spacings apart (scaled into the gt frame).
    scaled_spacing = GT_SPACING / 5.500814750931611  # 1 / max bbox range in stats.json
    steps = np.linalg.norm(points[1:] - points[:-1], axis=1)
    assert scaled_spacing * 0.999 <= np.median(steps) <= 2 * scaled_spacing
    again = abc_points_from_cad(source.obj, source.features, source.stats, source.scan_id)
    np.testing.assert_array_equal(points, again)


def test_sampled_ply_ground_truth(abc_emap_scene_dir):
    source = ground_truth_for(abc_emap_scene_dir)
    assert source.sampled_ply is not None and source.sampled_ply.name == "00004926_0.005.ply"
    points = source.load()
    assert points.shape == (63840, 3)
    np.testing.assert_array_equal(points, read_points_ply(source.sampled_ply))


@pytest.mark.parametrize("fixture", ["abc_nef_scene_dir", "abc_emap_scene_dir"])
def test_ground_truth_scores_perfectly_against_itself(fixture, request):
    gt = ground_truth_for(request.getfixturevalue(fixture)).load()
    metrics = score_points(gt, gt)
    assert metrics.accuracy_mm == 0 and metrics.completeness_mm == 0
    assert all(v == 100 for d in (metrics.precision, metrics.recall, metrics.fscore) for v in d.values())


@pytest.mark.parametrize("fixture", ["abc_nef_scene_dir", "abc_emap_scene_dir"])
def test_a_copy_shifted_by_7mm_scores_what_geometry_says(fixture, request):
    gt = ground_truth_for(request.getfixturevalue(fixture)).load()
    shift = 0.007 * np.array([2.0, -1.0, 2.0]) / 3.0  # |shift| = 7 mm
    moved = gt + shift
    metrics = score_points(moved, gt)
    # Every moved point has its own original 7 mm away, so no distance exceeds 7 mm ...
    assert 0 < metrics.accuracy_mm <= 7.0 + 1e-9 and 0 < metrics.completeness_mm <= 7.0 + 1e-9
    for tau in (10, 20):
        assert metrics.precision[tau] == metrics.recall[tau] == metrics.fscore[tau] == 100.0
    # ... and at 5 mm the share within reach is what brute force over all pairs gives.
    sample = moved[:: max(1, len(moved) // 3000)]
    d = np.sqrt(((sample[:, None, :] - gt[None, :, :]) ** 2).sum(-1)).min(1) if len(gt) < 20000 \
        else np.array([np.linalg.norm(gt - p, axis=1).min() for p in sample])
    assert d.max() <= 0.007 + 1e-12
    brute_share = 100 * np.mean(d < 0.005)
    tree_share = 100 * np.mean(score_points(sample, gt).precision[5] / 100)
    assert brute_share == pytest.approx(tree_share, abs=1e-9)
    assert metrics.precision[5] < 100  # the shift is visible at the tightest threshold


def test_dtu_cameras_agree_on_the_object(dtu_scene_dir):
    scene = load_scene(dtu_scene_dir, downscale=4)
    A, b = np.zeros((3, 3)), np.zeros(3)
    masks = []
    for i in range(len(scene)):
        camera, mask = scene.camera(i), scene.load_mask(i)
        assert mask is not None and mask.shape == (camera.height, camera.width)
        masks.append(mask)
        ys, xs = np.nonzero(mask)
        ray = camera.R.T @ np.linalg.solve(camera.K, [xs.mean(), ys.mean(), 1.0])
        ray /= np.linalg.norm(ray)
        P = np.eye(3) - np.outer(ray, ray)
        A, b = A + P, b + P @ camera.center
    # The rays through the mask centres meet near one point (inside the unit sphere) ...
    center = np.linalg.solve(A, b)
    assert np.linalg.norm(center) < 0.5
    # ... and that point, like the sphere's centre, projects inside every mask.
    for point in (center, np.zeros(3)):
        for i, mask in enumerate(masks):
            uv, depth = scene.camera(i).project(point[None])
            x, y = np.round(uv[0]).astype(int)
            assert depth[0] > 0 and mask[y, x], (i, point)


def test_a_features_file_nested_too_deep_is_one_line(tmp_path):
    """200,000 nested lists crashed the C YAML parser (a segmentation fault): now one line."""
    obj = tmp_path / "part.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\n")
    features = tmp_path / "part_features.yml"
    features.write_text("curves: " + "[" * 200_000 + "]" * 200_000)
    with pytest.raises(InputError, match="part_features.yml: nests lists or mappings more than 64 levels"):
        sharp_polylines(read_obj_vertices(obj), features, obj)
