"""Curve extraction: filters, grouping and fitting on synthetic edge points with known answers."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
from plyfile import PlyData, PlyElement
from scipy.spatial import cKDTree

from edgedog.curve_files import EdgeCurves, read_edges
from edgedog.curves import filtering
from edgedog.curves.config import ExtractConfig
from edgedog.curves.extract import extract_curves, extract_primitives, extract_run
from edgedog.errors import ConfigError, InputError
from edgedog.groundtruth import ground_truth_for
from edgedog.primitives import EdgePrimitives, read_ply
from edgedog.scenes.camera import Camera, intrinsics, w2c_from_opengl_c2w
from edgedog.train.config import TrainConfig
from edgedog.train.run_folder import RunFolder, write_run
from tests.helpers.scene_builders import look_at_gl

NOISE = 0.002  # 2 mm per axis: about the noise of a well-trained run
DIRECTION_NOISE = 10.0  # degrees
# Distances from the fitted curves to the true ones: RMS within the fitting tolerance (0.004 of
# scenes of size ~1), the worst point within twice that.
RMS_ERROR, MAX_ERROR = 0.004, 0.008


def noisy(points: np.ndarray, tangents: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """Points (N, 3) and unit directions (N, 3) with position noise and tilted, sign-flipped
    directions."""
    tangents = tangents / np.linalg.norm(tangents, axis=1, keepdims=True)
    tilt = rng.normal(size=tangents.shape)
    tilt -= np.sum(tilt * tangents, axis=1, keepdims=True) * tangents
    tilt /= np.linalg.norm(tilt, axis=1, keepdims=True)
    angle = np.radians(rng.uniform(0, DIRECTION_NOISE, size=(len(points), 1)))
    directions = np.cos(angle) * tangents + np.sin(angle) * tilt
    directions *= rng.choice([-1.0, 1.0], size=(len(points), 1))
    return points + rng.normal(0.0, NOISE, size=points.shape), directions


def segment(a, b, spacing: float = 0.0025) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(a, float), np.asarray(b, float)
    t = np.linspace(0.0, 1.0, int(np.linalg.norm(b - a) / spacing))[:, None]
    return a + t * (b - a), np.repeat((b - a)[None], len(t), axis=0)


def circle(centre, radius, n=800) -> tuple[np.ndarray, np.ndarray]:
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    points = np.stack([radius * np.cos(a), radius * np.sin(a), 0 * a], axis=1) + centre
    return points, np.stack([-np.sin(a), np.cos(a), 0 * a], axis=1)


def helix(n=1500) -> tuple[np.ndarray, np.ndarray]:
    a = np.linspace(0.0, 4 * np.pi, n)
    points = np.stack([0.5 + 0.25 * np.cos(a), 0.5 + 0.25 * np.sin(a), 0.1 + 0.06 * a], axis=1)
    return points, np.stack([-0.25 * np.sin(a), 0.25 * np.cos(a), 0.06 + 0 * a], axis=1)


def extract(*curves, seed=0, **settings):
    rng = np.random.default_rng(seed)
    parts = [noisy(p, d, rng) for p, d in curves]
    points = np.concatenate([p for p, _ in parts])
    directions = np.concatenate([d for _, d in parts])
    return extract_curves(points, directions, ExtractConfig(**settings))


def assert_close(curves: EdgeCurves, truth: np.ndarray) -> None:
    """Samples of the curves lie near the dense true points (M, 3)."""
    distance = cKDTree(truth).query(curves.sample(0.001))[0]
    print(f"rms {np.sqrt(np.mean(distance**2)):.4f} max {distance.max():.4f}")
    assert np.sqrt(np.mean(distance**2)) < RMS_ERROR and distance.max() < MAX_ERROR


def coverage(curves: EdgeCurves, truth: np.ndarray, tau: float = 0.01) -> float:
    """Share of the true points (M, 3) within tau of the curves."""
    return float(np.mean(cKDTree(curves.sample(0.001)).query(truth)[0] < tau))


def end_points(curves: EdgeCurves) -> np.ndarray:
    return np.concatenate([curves.lines[:, [0, -1]], curves.beziers[:, [0, -1]]]).reshape(-1, 3)


def assert_shared(ends: np.ndarray) -> None:
    """Every end coincides exactly with at least one other end (the pieces form a closed
    network or chain without gaps)."""
    _, counts = np.unique(np.round(ends, 12), axis=0, return_counts=True)
    assert counts.min() >= 2, ends


# --- grouping and fitting ---------------------------------------------------------------------


def test_three_lines_come_back_as_three_lines():
    truth = [segment([0, 0, 0], [1, 0, 0]), segment([0, 0.3, 0.2], [0.6, 0.8, 0.2]),
             segment([0.2, 0.1, 0.8], [0.2, 0.9, 0.5])]
    curves, chains = extract(*truth)
    assert len(chains) == 3 and curves.lines.shape == (3, 2, 3) and len(curves.beziers) == 0
    dense = np.concatenate([segment(p[0], p[-1], 0.0005)[0] for p, _ in truth])
    assert_close(curves, dense)
    assert coverage(curves, dense) > 0.98


def test_circle_is_one_closed_chain_of_beziers():
    truth = circle(np.array([0.5, 0.5, 0.3]), 0.3)
    curves, chains = extract(truth)
    assert len(chains) == 1 and chains[0].closed
    assert len(curves.lines) == 0 and len(curves.beziers) >= 2
    assert_shared(end_points(curves))  # the pieces close the loop
    dense = circle(np.array([0.5, 0.5, 0.3]), 0.3, 20000)[0]
    assert_close(curves, dense)
    assert coverage(curves, dense) == 1.0


def test_helix_is_one_chain_of_beziers():
    truth = helix()
    curves, chains = extract(truth)
    assert len(chains) == 1 and not chains[0].closed
    assert len(curves.beziers) >= 3
    ends = end_points(curves)
    _, counts = np.unique(np.round(ends, 12), axis=0, return_counts=True)
    assert sorted(counts)[:3] == [1, 1, 2]  # one open chain: two free ends, the rest shared
    dense = helix(100000)[0]
    assert_close(curves, dense)
    assert coverage(curves, dense) > 0.98


def test_t_junction_is_three_lines_meeting_at_one_point():
    curves, chains = extract(segment([0, 0.5, 0], [1, 0.5, 0]), segment([0.5, 0.5, 0], [0.5, 1.0, 0]))
    assert len(chains) == 3 and curves.lines.shape == (3, 2, 3)
    ends = end_points(curves)
    junction, counts = np.unique(np.round(ends, 12), axis=0, return_counts=True)
    assert counts.max() == 3
    np.testing.assert_allclose(junction[np.argmax(counts)], [0.5, 0.5, 0.0], atol=0.003)


def test_square_is_four_lines_with_shared_corners():
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    curves, chains = extract(*[segment(corners[i], corners[(i + 1) % 4]) for i in range(4)])
    assert len(chains) == 4 and curves.lines.shape == (4, 2, 3)
    shared, counts = np.unique(np.round(end_points(curves), 12), axis=0, return_counts=True)
    assert len(shared) == 4 and np.all(counts == 2)
    assert cKDTree(corners).query(shared)[0].max() < 0.003


@pytest.mark.parametrize("seed", range(4))
def test_short_step_between_two_corners_is_kept(seed):
    # A 35 mm step often thins to fewer than min_chain_vertices vertices (seeds 0 and 2): it is
    # not noise, since both its ends meet the long lines at corners.
    truth = [segment([0, 0, 0], [0.5, 0, 0]), segment([0.5, 0, 0], [0.5, 0.035, 0]),
             segment([0.5, 0.035, 0], [1, 0.035, 0])]
    curves, _ = extract(*truth, seed=seed)
    assert curves.lines.shape == (3, 2, 3) and len(curves.beziers) == 0
    assert coverage(curves, segment([0.5, 0, 0], [0.5, 0.035, 0], 0.0005)[0], 0.005) == 1.0
    _, counts = np.unique(np.round(end_points(curves), 12), axis=0, return_counts=True)
    assert sorted(counts) == [1, 1, 2, 2]  # the step shares both its ends: one connected path


def test_isolated_short_chain_is_dropped_as_noise():
    stray = segment([0.3, 0.5, 0.2], [0.3, 0.52, 0.2])  # 20 mm, far from the line
    curves, chains = extract(segment([0, 0, 0], [1, 0, 0]), stray)
    assert len(chains) == 1 and curves.lines.shape == (1, 2, 3)


def test_extraction_is_deterministic_and_handles_too_few_points():
    a = extract(helix(), seed=3)[0]
    b = extract(helix(), seed=3)[0]
    np.testing.assert_array_equal(a.beziers, b.beziers)
    curves, chains = extract_curves(np.zeros((2, 3)), np.ones((2, 3)))
    assert curves.num_curves == 0 and chains == []


def test_config_rejects_bad_settings():
    with pytest.raises(ConfigError, match="link_angle"):
        ExtractConfig(link_angle=95)
    with pytest.raises(ConfigError, match="node_spacing"):
        ExtractConfig(node_spacing=0)


# --- filters ------------------------------------------------------------------------------------


def test_outlier_mask_drops_isolated_points():
    rng = np.random.default_rng(0)
    cloud = np.concatenate([segment([0, 0, 0], [1, 0, 0])[0] + rng.normal(0, 0.002, (400, 3)),
                            [[0.5, 0.5, 0.5], [0.2, -0.4, 0.1]]])
    keep = filtering.outlier_mask(cloud, neighbours=25, std_ratio=2.0)
    assert not keep[-2:].any() and keep[:-2].mean() > 0.97


class _TwoViewScene:
    """A stand-in for Scene: view 0 looks at the origin, view 1 looks away from it."""

    detector = "exact"
    read_cache = None  # its maps are in memory: `with_read_cache` keeps the scene as it is

    def with_read_cache(self):
        return self

    def __init__(self):
        K = intrinsics(50.0, 50.0, 49.5, 49.5)
        self.cameras = [Camera(K, w2c_from_opengl_c2w(look_at_gl([0, -3, 0], [0, 0, 0])), 100, 100),
                        Camera(K, w2c_from_opengl_c2w(look_at_gl([0, -3, 0], [0, -6, 0])), 100, 100)]
        self.maps = [np.zeros((100, 100), np.float32), np.ones((100, 100), np.float32)]
        self.maps[0][:, 49:51] = 1.0  # a vertical edge through the image centre
        self.maps[0][10, 10] = 0.3

    def __len__(self):
        return 2

    def camera(self, i):
        return self.cameras[i]

    def load_edge_map(self, i, detector):
        assert detector == self.detector
        return self.maps[i]

    def load_mask(self, i):
        return None  # no masks: the silhouette filter is skipped


def test_mean_edge_value_counts_unseen_views_as_zero():
    scene = _TwoViewScene()
    on_edge = np.array([[0.0, 0.0, 0.0]])
    pixel, inside = scene.camera(0).pixels(on_edge)
    assert inside[0] and scene.maps[0][pixel[0, 1], pixel[0, 0]] == 1.0
    assert not scene.camera(1).pixels(on_edge)[1][0]  # behind view 1, whose map is all ones
    off_edge = np.array([[0.5, 0.0, 0.5]])
    values = filtering.mean_edge_values(np.vstack([on_edge, off_edge]), scene, "exact")
    np.testing.assert_allclose(values, [0.5, 0.0])
    keep = filtering.projection_mask(np.vstack([on_edge, off_edge]), scene, "exact", 0.1)
    assert keep.tolist() == [True, False]


class _RingScene(_TwoViewScene):
    """Ten views on a ring around the origin, all looking at it; only view 0 draws an edge there
    (0.8), as a concave corner that the other views cannot see."""

    def __init__(self):
        K = intrinsics(50.0, 50.0, 49.5, 49.5)
        angles = np.linspace(0, 2 * np.pi, 10, endpoint=False)
        eyes = [[3 * np.sin(a), -3 * np.cos(a), 0.5] for a in angles]
        self.cameras = [Camera(K, w2c_from_opengl_c2w(look_at_gl(eye, [0, 0, 0])), 100, 100) for eye in eyes]
        self.maps = [np.zeros((100, 100), np.float32) for _ in angles]
        self.maps[0][45:55, 45:55] = 0.8

    def __len__(self):
        return len(self.cameras)


def _sigmoid(x):
    return 1 / (1 + np.exp(-x))


def test_view_weights_are_the_opacity_per_view_over_its_largest():
    scene = _RingScene()
    centres = np.stack([c.center for c in scene.cameras])
    points = np.array([[0.0, 0.0, 0.0], [0.1, -0.2, 0.05]])
    a, b = np.array([0.5, -1.0]), np.array([[0.0, -3.0, 0.0], [2.0, 1.0, -0.5]])
    d = centres[:, None] - points[None]
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    per_view = _sigmoid(a[None] + np.einsum("vnk,nk->vn", d, b))  # (V, N) opacity in each view
    weights = filtering.view_weights(points, per_view.max(axis=0), b, centres)
    np.testing.assert_allclose(weights, per_view / per_view.max(axis=0), rtol=1e-9)
    assert np.allclose(weights.max(axis=0), 1.0)
    # Without a view-dependent part every view counts fully.
    np.testing.assert_allclose(filtering.view_weights(points, _sigmoid(a), np.zeros_like(b), centres), 1.0)


def test_projection_filter_over_drawn_views_keeps_an_edge_few_views_see():
    scene = _RingScene()
    centres = np.stack([c.center for c in scene.cameras])
    corner = np.zeros((2, 3))  # the same point twice: an edge, and a ghost that no view draws
    dirs = np.array([centres[0] / np.linalg.norm(centres[0]) * 6.0] * 2)  # drawn towards view 0 only
    opacity = _sigmoid(np.array([0.0, 0.0]) + 6.0)
    weights = filtering.view_weights(corner, opacity, dirs, centres)
    assert weights[0].min() > 0.99 and weights[5].max() < 0.01
    # Averaged over all ten views the edge (0.8 in one) scores 0.08 and is dropped.
    assert filtering.projection_mask(corner[:1], scene, "exact", 0.1).tolist() == [False]
    assert filtering.projection_mask(corner[:1], scene, "exact", 0.1, weights[:, :1]).tolist() == [True]
    scene.maps[0][:] = 0.0  # no view draws anything there: dropped either way
    assert filtering.projection_mask(corner, scene, "exact", 0.1, weights).tolist() == [False, False]


class _MaskedScene(_TwoViewScene):
    """View 0's object mask is the 10 columns 45-54 (1 px = 0.06 world units at the origin);
    view 1's image cannot be read."""

    def load_mask(self, i):
        if i == 1:
            raise InputError("view_1.png", "cannot be decoded as an image")
        mask = np.zeros((100, 100), bool)
        mask[:, 45:55] = True
        return mask


def test_silhouette_filter_drops_points_outside_the_masks():
    # 0, 7.3 and 10.3 px from the image centre (column 49.5): 0, 3 and 6 px outside the mask
    points = np.array([[0.0, 0.0, 0.0], [7.3 * 0.06, 0.0, 0.1], [-10.3 * 0.06, 0.0, -0.1]])
    outside = filtering.pixels_outside_masks(points, _MaskedScene())
    np.testing.assert_allclose(outside, [0.0, 3.0, 6.0], atol=1e-3)
    assert filtering.silhouette_mask(points, _MaskedScene(), 4.0).tolist() == [True, True, False]
    assert filtering.silhouette_mask(points, _MaskedScene(), 2.0).tolist() == [True, False, False]
    assert filtering.silhouette_mask(points, _TwoViewScene(), 4.0) is None


def test_extract_run_counts_the_silhouette_filter_after_the_outliers(tmp_path):
    points, tangents = segment([0.0, 0.0, -0.2], [0.0, 0.0, 0.2], 0.002)
    beside = points + [10.3 * 0.06, 0.0, 0.0]  # an edge-like tube 6 px outside the mask
    write_primitives(tmp_path / "primitives.ply", np.vstack([points, beside]),
                     np.vstack([tangents, tangents]), 0.6)
    config = ExtractConfig(filter_projection=False, filter_outliers="on", filter_contours=False,
                           filter_drawing_plane=False)
    result = extract_run(tmp_path, config, _MaskedScene(), "exact")
    assert list(result.counts)[:4] == ["primitives", "after_opacity", "after_outliers", "after_silhouette"]
    kept = result.points.points
    assert len(kept) > 0.95 * len(points) and np.abs(kept[:, 0]).max() < 1e-6  # only the inside tube
    assert result.curves.num_curves == 1
    off = extract_run(tmp_path, dataclasses.replace(config, filter_silhouette=False), _MaskedScene(), "exact")
    assert "after_silhouette" not in off.counts and off.curves.num_curves == 2


def _dense_and_sparse_edges() -> tuple[np.ndarray, np.ndarray]:
    """A dense edge (200 points) at x = 0 and a sparse one (12 points 0.03 apart) at x = 0.2,
    both along z and inside `_MaskedScene`'s mask; (212, 3) points and their directions."""
    dense, tangents = segment([0.0, 0.0, -0.2], [0.0, 0.0, 0.2], 0.002)
    sparse = np.stack([np.full(12, 0.2), np.zeros(12), np.linspace(-0.165, 0.165, 12)], axis=1)
    return np.vstack([dense, sparse]), np.vstack([tangents, np.tile([0.0, 0.0, 1.0], (12, 1))])


@pytest.mark.parametrize("scene, setting, sparse_kept, outlier_count", [
    (_MaskedScene(), "auto", True, False),  # the silhouette filter runs: the outlier filter does not
    (_MaskedScene(), "on", False, True),
    (_TwoViewScene(), "auto", False, True),  # no masks: the outlier filter runs instead
    (_TwoViewScene(), "off", True, False),
    (None, "auto", False, True),  # no scene: no silhouette test
])
def test_outlier_filter_runs_where_the_silhouette_filter_does_not(tmp_path, scene, setting, sparse_kept,
                                                                   outlier_count):
    points, directions = _dense_and_sparse_edges()
    write_primitives(tmp_path / "primitives.ply", points, directions, 0.6)
    primitives = EdgePrimitives.from_arrays(read_ply(tmp_path / "primitives.ply"))
    config = ExtractConfig(filter_projection=False, filter_outliers=setting)
    result = extract_primitives(primitives, config, scene, None)
    kept_sparse = np.isclose(result.points.points[:, 0], 0.2).sum()
    assert kept_sparse == (12 if sparse_kept else 0)
    assert np.isclose(result.points.points[:, 0], 0.0).sum() == 200  # the dense edge always stays
    assert ("after_outliers" in result.counts) == outlier_count
    assert ("after_silhouette" in result.counts) == isinstance(scene, _MaskedScene)


def test_outlier_filter_on_auto_runs_when_the_silhouette_filter_is_switched_off(tmp_path):
    points, directions = _dense_and_sparse_edges()
    write_primitives(tmp_path / "primitives.ply", points, directions, 0.6)
    primitives = EdgePrimitives.from_arrays(read_ply(tmp_path / "primitives.ply"))
    config = ExtractConfig(filter_projection=False, filter_silhouette=False, filter_outliers="auto")
    result = extract_primitives(primitives, config, _MaskedScene(), None)
    assert "after_outliers" in result.counts and "after_silhouette" not in result.counts
    assert not np.isclose(result.points.points[:, 0], 0.2).any()


def test_chain_mask_keeps_a_sparse_line_not_a_scatter_nor_a_short_stub():
    rng = np.random.default_rng(0)
    line = np.stack([np.zeros(12), np.zeros(12), np.linspace(0.0, 0.33, 12)], axis=1)  # 0.03 apart
    stub = line[:3] + [0.3, 0.0, 0.0]  # three points spanning 0.06
    scatter = rng.uniform(-0.5, 0.5, (30, 3)) + [0.0, 0.8, 0.0]
    directions = np.vstack([np.tile([0.0, 0.0, 1.0], (15, 1)), rng.normal(size=(30, 3))])
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    on_chain = filtering.chain_mask(np.vstack([line, stub, scatter]), directions, radius=0.045,
                                    min_extent=0.2, min_cos=np.cos(np.radians(30)))
    assert on_chain[:12].all() and not on_chain[12:].any()
    assert filtering.chain_mask(np.zeros((0, 3)), np.zeros((0, 3)), 0.045, 0.2, 0.5).shape == (0,)


def test_outlier_chains_spare_a_sparse_edge_but_not_floaters(tmp_path):
    points, directions = _dense_and_sparse_edges()
    floaters = np.array([[0.5, 0.3, 0.1], [-0.3, -0.4, 0.0]])
    write_primitives(tmp_path / "primitives.ply", np.vstack([points, floaters]),
                     np.vstack([directions, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]), 0.6)
    primitives = EdgePrimitives.from_arrays(read_ply(tmp_path / "primitives.ply"))
    # Lengths relative to the points' size: about 0.45 without the floaters, 0.9 with them.
    config = ExtractConfig(filter_projection=False, filter_outliers="on", outlier_chains=True,
                           chain_radius=0.1, chain_extent=0.2)
    kept = extract_primitives(primitives, config, None, None).points.points
    assert np.isclose(kept[:, 0], 0.2).sum() == 12 and np.isclose(kept[:, 0], 0.0).sum() == 200
    assert len(kept) == 212  # both floaters dropped
    write_primitives(tmp_path / "edges.ply", points, directions, 0.6)  # no floaters to widen the statistics
    edges = EdgePrimitives.from_arrays(read_ply(tmp_path / "edges.ply"))
    assert np.isclose(extract_primitives(edges, config, None, None).points.points[:, 0], 0.2).sum() == 12
    plain = extract_primitives(edges, dataclasses.replace(config, outlier_chains=False), None, None)
    assert not np.isclose(plain.points.points[:, 0], 0.2).any()


def test_outlier_filter_setting_is_a_choice():
    with pytest.raises(ConfigError, match="filter_outliers must be one of auto, on, off"):
        ExtractConfig(filter_outliers=False)


# --- runs ---------------------------------------------------------------------------------------


def write_primitives(path, points, directions, opacity, uncertainty=None):
    """A primitives.ply as `edgedog train` writes it, elongated along `directions` (N, 3)."""
    n = len(points)
    x = np.array([1.0, 0.0, 0.0])
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    d *= np.where(d[:, :1] < 0, -1.0, 1.0)  # the sign is free; away from -x the formula is stable
    # Quaternion (w, x, y, z) of the shortest rotation taking the x axis to each direction.
    half = d + x
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    quats = np.concatenate([np.sum(half * x, axis=1, keepdims=True), np.cross(x, half)], axis=1) * 2.0
    names = ["x", "y", "z", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
             "opacity", "k_0", "k_1"] + (["uncertainty"] if uncertainty is not None else [])
    rows = np.empty(n, dtype=[(name, "f4") for name in names])
    for i, c in enumerate("xyz"):
        rows[c] = points[:, i]
    rows["scale_0"], rows["scale_1"], rows["scale_2"] = 0.006, 0.002, 0.002
    for i in range(4):
        rows[f"rot_{i}"] = quats[:, i]
    rows["opacity"], rows["k_0"], rows["k_1"] = opacity, 0.1, 0.2
    if uncertainty is not None:
        rows["uncertainty"] = uncertainty
    PlyData([PlyElement.describe(rows, "vertex")]).write(str(path))


def test_primitive_direction_is_the_axis_of_the_largest_scale(tmp_path):
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(50, 3))
    write_primitives(tmp_path / "primitives.ply", rng.uniform(size=(50, 3)), directions, 0.5)
    primitives = EdgePrimitives.from_arrays(read_ply(tmp_path / "primitives.ply"))
    unit = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    np.testing.assert_allclose(np.abs(np.sum(primitives.directions * unit, axis=1)), 1.0, atol=1e-5)
    np.testing.assert_allclose(primitives.elongation, 3.0, rtol=1e-5)
    assert primitives.uncertainty is None


def test_read_ply_errors_name_the_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_ply(tmp_path / "primitives.ply")
    (tmp_path / "primitives.ply").write_text("not a ply")
    with pytest.raises(InputError, match="primitives.ply: not a readable PLY"):
        read_ply(tmp_path / "primitives.ply")
    rows = np.zeros(3, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    PlyData([PlyElement.describe(rows, "vertex")]).write(str(tmp_path / "primitives.ply"))
    with pytest.raises(InputError, match="no vertex properties scale_0"):
        read_ply(tmp_path / "primitives.ply")


def test_extract_run_filters_fits_and_writes_its_outputs(tmp_path):
    rng = np.random.default_rng(1)
    points, tangents = segment([0.0, 0.0, -0.2], [0.0, 0.0, 0.2], 0.002)
    stray = rng.uniform([0.1, -0.1, -0.3], [0.3, 0.1, 0.3], size=(6, 3))
    faint = points[::10] + [-0.1, 0.0, 0.0]
    cloud = np.concatenate([points, stray, faint])
    opacity = np.concatenate([np.full(len(points) + len(stray), 0.6), np.full(len(faint), 0.1)])
    directions = np.concatenate([tangents, tangents[:6], tangents[:len(faint)]])
    write_primitives(tmp_path / "primitives.ply", cloud, directions, opacity,
                     uncertainty=np.arange(len(cloud), dtype=float))
    scene = _TwoViewScene()  # the segment lies on view 0's edge column; the stray points do not
    config = ExtractConfig(filter_outliers="off")
    result = extract_run(tmp_path, config, scene, scene.detector)
    c = result.counts
    assert c["primitives"] == len(cloud) and c["after_opacity"] == len(points) + len(stray)
    assert c["after_projection"] == len(points) and "after_outliers" not in c
    assert "after_silhouette" not in c  # the scene has no masks
    assert c["chains"] == 1 and c["lines"] == 1 and c["beziers"] == 0
    np.testing.assert_allclose(np.sort(result.curves.lines[0, :, 2]), [-0.2, 0.2], atol=0.01)
    for name in ("curves.json", "curves.obj", "curves.ply"):
        assert read_edges(tmp_path / name).num_curves == 1
    np.testing.assert_array_equal(read_edges(tmp_path / "curves.json").lines, result.curves.lines)
    ply = PlyData.read(str(tmp_path / "edge_points.ply"))["vertex"]
    assert ply.count == len(points)
    assert {"dx", "dy", "dz", "opacity", "k_0", "k_1", "uncertainty"} <= set(ply.data.dtype.names)
    np.testing.assert_array_equal(ply["uncertainty"], np.arange(len(points)))


def test_extract_run_with_nothing_left_writes_empty_files(tmp_path):
    points, tangents = segment([0.0, 0.0, -0.2], [0.0, 0.0, 0.2], 0.002)
    write_primitives(tmp_path / "primitives.ply", points, tangents, 0.1)
    result = extract_run(tmp_path, ExtractConfig(filter_projection=False, filter_silhouette=False,
                                                 filter_contours=False, complete_lines=False,
                                                 complete_circles=False, complete_slides=False,
                                                 filter_drawing_plane=False))
    assert result.counts["after_opacity"] == 0 and result.curves.num_curves == 0
    for name in ("curves.json", "curves.obj", "curves.ply", "edge_points.ply"):
        assert read_edges(tmp_path / name).is_empty


def test_the_silhouette_filter_alone_needs_no_edge_maps(builtin_scene_dir, tmp_path):
    points, tangents = segment([0.4, 0.4, 0.2], [0.6, 0.4, 0.2], 0.002)
    write_primitives(tmp_path / "primitives.ply", points, tangents, 0.6)
    # maps of an unknown detector: only the projection and contour filters, the shading and
    # drawing-plane tests and the completions would ask for them
    log = {"scene": str(builtin_scene_dir), "detector": "no-such-maps"}
    (tmp_path / "log.json").write_text(json.dumps(log))
    without_maps = ExtractConfig(filter_projection=False, filter_contours=False, complete_lines=False,
                                 complete_circles=False, complete_slides=False, filter_drawing_plane=False)
    result = extract_run(tmp_path, without_maps)
    assert "after_silhouette" in result.counts
    for needs_maps in (ExtractConfig(), ExtractConfig(filter_projection=False),
                       dataclasses.replace(without_maps, complete_lines=True),
                       dataclasses.replace(without_maps, complete_circles=True),
                       dataclasses.replace(without_maps, complete_slides=True),
                       dataclasses.replace(without_maps, filter_shading=True),
                       dataclasses.replace(without_maps, filter_drawing_plane=True)):
        with pytest.raises(ConfigError, match="no-such-maps"):
            extract_run(tmp_path, needs_maps)


@pytest.mark.shared_data
def test_cli_extract_on_ground_truth_primitives(abc_nef_scene_dir, tmp_path):
    from edgedog.scenes import load_scene

    gt = ground_truth_for(load_scene(abc_nef_scene_dir).root).load()[::2]
    rng = np.random.default_rng(0)
    neighbourhoods = gt[cKDTree(gt).query(gt, 8)[1]] - gt[:, None]
    directions = np.linalg.svd(neighbourhoods, full_matrices=False)[2][:, 0]
    write_primitives(tmp_path / "primitives.ply", gt + rng.normal(0, 0.002, gt.shape), directions, 0.8)
    (tmp_path / "log.json").write_text(json.dumps({"scene": str(abc_nef_scene_dir), "detector": "pidinet"}))
    write_run(RunFolder(tmp_path, abc_nef_scene_dir, "full", TrainConfig()))  # what makes it a run folder
    result = subprocess.run([sys.executable, "-m", "edgedog", "extract", tmp_path,
                             "--set", "filter_projection=false"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "after projection" not in result.stdout
    assert "after outliers" in result.stdout and "after silhouette" in result.stdout
    report = json.loads((tmp_path / "extract.json").read_text())
    assert 10 <= report["counts"]["chains"] <= 60
    assert report["metrics"]["curves"]["fscore_10mm"] > 90
    assert report["metrics"]["curves"]["acc_mm"] < 3


def test_cli_extract_errors_are_one_line(tmp_path):
    result = subprocess.run([sys.executable, "-m", "edgedog", "extract", tmp_path / "missing"],
                            capture_output=True, text=True)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "run folder not found" in result.stderr
    result = subprocess.run([sys.executable, "-m", "edgedog", "extract", tmp_path, "--set", "bogus=1"],
                            capture_output=True, text=True)
    assert result.returncode == 2 and "bogus" in result.stderr
    result = subprocess.run([sys.executable, "-m", "edgedog", "extract", tmp_path, "--set",
                             "extract.link_angle=bad"], capture_output=True, text=True)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "--set 'extract.link_angle=bad': extract.link_angle must be a number in (0, 90)" in result.stderr
