"""Initial points: the uniform cube, nearest-neighbour scales, the edge filter, triangulation
with known cameras on real photos (DTU scan 37) and the fallback on feature-poor renders (ABC)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from edgedog.builtin.scene import ground_truth_points, write_box_scene
from edgedog.errors import ConfigError, InputError
from edgedog.init import (
    DEFAULTS,
    PROBE_VIEWS,
    InitialPoints,
    InitSettings,
    initialize,
    keypoints_needed,
    nearest_neighbour_scales,
    spread_views,
    uniform_init,
)
from edgedog.init.triangulate import edge_support, nearest_view_pairs
from edgedog.scenes import load_scene
from edgedog.scenes.camera import Camera
from edgedog.scenes.common import look_at_point
from edgedog.synthetic.cameras import orbit_cameras
from edgedog.train.config import TrainConfig
from tests.helpers.paths import shared_path as shared

DTU_VIEWS = list(range(10, 20))  # neighbouring views of the second row of the DTU rig


# --- uniform cube ------------------------------------------------------------------------------

def test_uniform_init_counts_cube_and_scales():
    center = np.array([0.5, -1.0, 2.0])
    points = uniform_init(center, side=1.1, count=2500, scale_range=(0.004, 0.005), seed=3)
    assert points.method == "uniform"
    assert points.positions.shape == (2500, 3) and points.positions.dtype == np.float64
    assert points.scales.shape == (2500,) and points.scales.dtype == np.float64
    assert np.all(np.abs(points.positions - center) <= 0.55)
    # Uniform: the cube is filled to its faces, not just near the centre.
    assert np.all(np.abs(points.positions - center).max(axis=0) > 0.5)
    assert np.allclose(points.positions.mean(axis=0), center, atol=0.03)
    assert np.all((points.scales >= 0.004) & (points.scales <= 0.005))
    assert points.report["points"] == 2500 and points.report["side"] == 1.1


def test_uniform_init_seed_reproducible():
    a = uniform_init(np.zeros(3), side=1.1, count=2500, seed=7)
    b = uniform_init(np.zeros(3), side=1.1, count=2500, seed=7)
    c = uniform_init(np.zeros(3), side=1.1, count=2500, seed=8)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.scales, b.scales)
    assert not np.array_equal(a.positions, c.positions)
    assert len(a) == 2500 and a.report["scale_range"] == [0.004, 0.005]


def test_uniform_init_rejects_bad_arguments():
    with pytest.raises(ValueError):
        uniform_init(np.zeros(3), side=0, count=10)
    with pytest.raises(ValueError):
        uniform_init(np.zeros(3), side=1.1, count=10, scale_range=(0.5, 0.1))


def test_initial_points_checks_shapes_and_method():
    with pytest.raises(ValueError):
        InitialPoints(np.zeros((3, 3)), np.zeros(2), "uniform")
    with pytest.raises(ValueError):
        InitialPoints(np.zeros((3, 3)), np.zeros(3), "random")


# --- nearest-neighbour scales ------------------------------------------------------------------

def test_nearest_neighbour_scales_on_a_grid_equal_the_spacing():
    spacing = 0.25
    axis = np.arange(6) * spacing
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    scales = nearest_neighbour_scales(grid + 10.0, k=3, lo=0.0, hi=1.0)
    assert scales.shape == (len(grid),)
    # Every grid point has at least 3 neighbours at exactly one spacing.
    assert np.allclose(scales, spacing)


def test_nearest_neighbour_scales_clip_and_degenerate_clouds():
    points = np.array([[0.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0], [3.0, 0, 0]])
    assert np.allclose(nearest_neighbour_scales(points, k=1), [0.0, 0.0, 1.0, 2.0])
    assert np.allclose(nearest_neighbour_scales(points, k=1, lo=0.1, hi=1.5), [0.1, 0.1, 1.0, 1.5])
    assert np.allclose(nearest_neighbour_scales(points[:2] + [[0, 0, 0], [0, 2, 0]], k=5), [2.0, 2.0])
    assert nearest_neighbour_scales(np.zeros((0, 3))).shape == (0,)
    assert np.allclose(nearest_neighbour_scales(np.zeros((1, 3)), lo=0.01), [0.01])


# --- synthetic box: edge filter, RGBA renders, fallback ----------------------------------------

@pytest.fixture(scope="module")
def box_scene(tmp_path_factory):
    return load_scene(write_box_scene(tmp_path_factory.mktemp("box") / "box", views=12, size=300))


def test_edge_support_counts_views_where_points_fall_on_edges(box_scene):
    views = list(range(len(box_scene)))
    on_edges = ground_truth_points()[::10]
    support = edge_support(box_scene, on_edges, views, "exact", 0.3)
    # A box edge is visible (one of its faces faces the camera) in about half of the views.
    assert np.median(support) >= 3
    lo, hi = box_scene.bounds
    off_object = np.array([[lo[0], lo[1], lo[2]], [hi[0], hi[1], hi[2]], [lo[0], hi[1], lo[2]]])
    assert np.all(edge_support(box_scene, off_object, views, "exact", 0.3) == 0)


def test_auto_falls_back_to_uniform_on_featureless_renders(box_scene, tmp_path):
    # Flat-shaded RGBA renders (composited for COLMAP) give SIFT nothing to triangulate.
    # The cube of the scene's bounds (side None), so that every point lies in them.
    result = initialize(box_scene, InitSettings(side=None), workdir=tmp_path / "colmap", detector="exact",
                        min_points=50, seed=1)
    assert result.method == "uniform"
    assert result.report["requested"] == "auto"
    # The keypoints of a few views show it before every view is matched.
    attempt = result.report["attempts"][0]
    assert attempt["method"] == "triangulated" and attempt["skipped"]
    assert attempt["probed_views"] == PROBE_VIEWS
    assert attempt["keypoints_per_view"] < keypoints_needed(50, len(box_scene))
    assert "SIFT keypoints each" in result.report["reason"]
    assert "too few image features" in result.report["reason"]
    lo, hi = box_scene.bounds
    assert np.all((result.positions >= lo) & (result.positions <= hi))
    assert len(list((tmp_path / "colmap" / "probe" / "images").glob("*.png"))) == PROBE_VIEWS
    with pytest.raises(InputError, match="triangulation found no points"):
        initialize(box_scene, InitSettings(method="triangulate"), workdir=tmp_path / "colmap",
                   views=[0, 1, 2, 3])


def test_initialize_uniform_and_unknown_method(box_scene):
    result = initialize(box_scene, InitSettings(method="uniform", count=100), seed=2)
    assert result.method == "uniform" and len(result) == 100
    assert result.report["reason"] == "requested"
    with pytest.raises(ConfigError, match="method must be one of auto, triangulate, sfm-points, uniform"):
        InitSettings(method="random")
    with pytest.raises(InputError, match="no SfM points"):
        initialize(box_scene, InitSettings(method="sfm-points"))


def test_edgedog_init_starts_as_training_does():
    """One place for the defaults: `edgedog init`, `initialize` and training's init section."""
    assert DEFAULTS == TrainConfig().init == InitSettings()
    assert (DEFAULTS.count, DEFAULTS.side, DEFAULTS.edge_threshold) == (10000, 1.1, 0.3)


# --- which views are matched -------------------------------------------------------------------

def test_view_pairs_are_each_views_nearest_cameras_facing_its_way():
    cameras = orbit_cameras(40, 64)
    pairs = nearest_view_pairs(cameras, 6)
    centres = np.stack([c.center for c in cameras])
    partners = {i: set() for i in range(40)}
    for i, j in pairs:
        assert i < j
        partners[i].add(j)
        partners[j].add(i)
    for i in range(40):
        distance = np.linalg.norm(centres - centres[i], axis=1)
        distance[i] = np.inf
        nearest = set(np.argsort(distance)[:6].tolist())
        assert nearest <= partners[i]  # its own 6, plus the views that chose it
    assert len(pairs) <= 40 * 6 and len(pairs) < 40 * 39 // 2
    # Every pair faces the same way: on an orbit, the nearest centres are the nearest directions.
    assert all(cameras[i].forward @ cameras[j].forward > 0 for i, j in pairs)
    # As many neighbours as other views: every pair facing each other.
    assert nearest_view_pairs(cameras[:5], 10) == [(i, j) for i in range(5) for j in range(i + 1, 5)
                                                   if cameras[i].forward @ cameras[j].forward > 0]


def test_the_probe_views_spread_over_the_scene_and_the_keypoints_needed(box_scene):
    assert spread_views(list(range(50)), 5) == [0, 12, 24, 37, 49]
    assert spread_views([3, 9], 5) == [3, 9]
    assert spread_views([3, 9], 1) == [3] and spread_views([3, 9], 0) == []
    with pytest.raises(ValueError, match="view indices"):  # checked before the probe reads them
        initialize(box_scene, views=[0, 1, len(box_scene)])
    # 500 points from 50 views: at most k * 50 / 2 points, and `auto` asks that 4 times over.
    assert keypoints_needed(500, 50) == 80
    assert keypoints_needed(500, 10) == 400


def test_view_names_with_spaces_reach_colmaps_match_list(box_scene, tmp_path):
    # COLMAP splits the match list's lines at spaces: the names it gets are the views' indices.
    scene = dataclasses.replace(box_scene, views=[dataclasses.replace(v, name=f"my view {i}")
                                                  for i, v in enumerate(box_scene.views)])
    with pytest.raises(InputError, match="triangulation found no points"):
        initialize(scene, InitSettings(method="triangulate", match_neighbours=1), workdir=tmp_path,
                   views=[0, 1, 2, 3, 4])
    lines = (tmp_path / "pairs.txt").read_text().splitlines()
    images = {path.name for path in (tmp_path / "images").iterdir()}
    assert 2 <= len(lines) <= 5
    assert all(len(line.split(" ")) == 2 and set(line.split(" ")) <= images for line in lines)


def test_view_pairs_skip_cameras_facing_away_however_near():
    K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    ahead, behind, far_ahead = np.eye(4), np.diag([-1.0, 1.0, -1.0, 1.0]), np.eye(4)
    far_ahead[0, 3] = -5.0  # centre 5 units to the side, facing the same way
    cameras = [Camera(K, w2c, 640, 480) for w2c in (ahead, behind, far_ahead)]
    # The camera at the same place facing the other way is the nearest but is never paired.
    assert nearest_view_pairs(cameras, 1) == [(0, 2)]


# --- DTU scan 37: real photos, given cameras ---------------------------------------------------

@pytest.fixture(scope="module")
def dtu_triangulated(tmp_path_factory):
    scene = load_scene(shared("dtu_scan37"), downscale=2)
    workdir = tmp_path_factory.mktemp("dtu_colmap")
    result = initialize(scene, workdir=workdir, min_points=200, views=DTU_VIEWS)
    return scene, result


@pytest.mark.slow
def test_dtu_triangulation_with_known_cameras(dtu_triangulated):
    scene, result = dtu_triangulated
    assert result.method == "triangulated", result.report
    # Measured: 2396 points triangulated from 10 views at 800 px, all kept (no edge maps).
    assert len(result) >= 500
    assert result.report["triangulated"] == result.report["kept"] == len(result)
    assert result.report["edge_filter"] == "none"
    assert "skipped" not in result.report["attempts"][-1]  # the probe found keypoints enough
    assert result.report["matched_pairs"] == 45  # 10 views: each with its 10 nearest is every pair
    assert result.report["max_image_size"] == 800  # SIFT at the loaded (training) resolution
    assert result.report["mean_reprojection_error_px"] < 2.0
    assert "triangulation kept" in result.report["reason"]
    assert np.all(np.isfinite(result.scales)) and np.all(result.scales > 0)
    lo, hi = scene.bounds
    inside = np.all((result.positions >= lo) & (result.positions <= hi), axis=1)
    assert inside.mean() >= 0.95  # measured 0.999


@pytest.mark.slow
def test_dtu_triangulated_points_project_inside_the_object_masks(dtu_triangulated):
    scene, result = dtu_triangulated
    fractions = []
    for index in range(0, len(scene), 4):  # used views and views the points never saw
        camera, mask = scene.camera(index), scene.load_mask(index)
        uv, depth = camera.project(result.positions)
        pixels = np.rint(uv).astype(int)
        inside = (depth > 0) & (pixels[:, 0] >= 0) & (pixels[:, 0] < camera.width) \
            & (pixels[:, 1] >= 0) & (pixels[:, 1] < camera.height)
        if inside.sum() >= 50:
            fractions.append(mask[pixels[inside, 1], pixels[inside, 0]].mean())
    fractions = np.array(fractions)
    # Measured: 0.975 to 0.994 of the points inside the mask in every one of the 49 views.
    assert len(fractions) >= 10
    assert np.mean(fractions >= 0.9) >= 0.8
    assert np.median(fractions) >= 0.95


# --- ABC 00000006: grey CAD renders with few features ------------------------------------------

def test_abc_auto_skips_triangulation_on_renders_with_too_few_keypoints(tmp_path):
    scene = load_scene(shared("abc_nef/00000006"))
    min_points = 500
    result = initialize(scene, InitSettings(count=2500, side=None), workdir=tmp_path / "colmap",
                        detector="pidinet", min_points=min_points, views=list(range(0, 50, 5)))
    report = result.report
    attempt = report["attempts"][-1]
    # Measured: the renders give 10 to 37 SIFT keypoints per view (18.6 on average over five),
    # where 10 views need 400 for 500 points: the cube is used without matching every view.
    assert result.method == "uniform" and len(result) == 2500
    assert attempt["method"] == "triangulated" and attempt["skipped"]
    assert 0 < attempt["keypoints_per_view"] < keypoints_needed(min_points, 10) == 400
    assert f"that {min_points} triangulated points need" in report["reason"]
    # Forced, the triangulation runs on every view and finds nothing.
    with pytest.raises(InputError, match="triangulation found no points"):
        initialize(scene, InitSettings(method="triangulate"), workdir=tmp_path / "forced",
                   detector="pidinet", views=list(range(0, 50, 5)))
    lo, hi = scene.bounds
    assert np.all((result.positions >= lo - 1e-9) & (result.positions <= hi + 1e-9))


def test_uniform_cube_centres_on_the_point_an_orbit_looks_at(box_scene):
    # EMAP's metadata box is [-1, 1]^3 around an object in [0, 1]^3: centring the cube on it
    # would start most primitives off the object.
    loose = dataclasses.replace(box_scene, bounds=np.array([[-1.0] * 3, [1.0] * 3]))
    np.testing.assert_allclose(look_at_point(loose.cameras), [0.5, 0.5, 0.5], atol=1e-6)
    result = initialize(loose, InitSettings(method="uniform", count=2000, side=1.1), seed=3)
    np.testing.assert_allclose(result.positions.mean(0), [0.5, 0.5, 0.5], atol=0.03)
    assert np.all(np.abs(result.positions - 0.5) <= 0.55)


def test_forward_facing_views_have_no_look_at_point():
    K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    cameras = []
    for x in np.linspace(-1, 1, 5):  # a sideways sweep with parallel optical axes
        w2c = np.eye(4)
        w2c[0, 3] = -x
        cameras.append(Camera(K, w2c, 640, 480))
    assert look_at_point(cameras) is None
