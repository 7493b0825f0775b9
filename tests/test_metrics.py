"""Tests of the ABC-NEF edge evaluation protocol (sampling, voxel averaging, scores)."""

import json

import numpy as np
import pytest
from scipy.integrate import quad

from edgedog.metrics import (
    SAMPLE_SPACING,
    THRESHOLDS,
    VOXEL_BOUNDS,
    VOXELS_PER_AXIS,
    EdgeMetrics,
    evaluate,
    sample_cubic_bezier,
    sample_line,
    sample_polyline,
    score_points,
    voxel_mean,
)


def _polyline_length(p):
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


# --- sampling --------------------------------------------------------------------------------


def test_protocol_constants():
    assert SAMPLE_SPACING == 0.005
    assert THRESHOLDS == (0.005, 0.01, 0.02)
    assert VOXELS_PER_AXIS == 256
    assert VOXEL_BOUNDS == (-1.0, 1.0)


# n = int(length // 0.005) in floating point, as EMAP computes it: the double nearest 0.005 is
# slightly above it, so a 1.0 long segment gets 199 samples, not 200.
@pytest.mark.parametrize("length, n", [(0.0049, 0), (0.005, 1), (0.0123, 2), (1.0, 199)])
def test_sample_line_count_and_endpoints(length, n):
    a = np.zeros(3)  # so that |b - a| is exactly `length`
    b = np.array([0.0, length, 0.0])
    s = sample_line(a, b)
    assert s.shape == (n, 3)
    if n >= 1:
        np.testing.assert_allclose(s[0], a, atol=1e-15)
    if n >= 2:
        np.testing.assert_allclose(s[-1], b, atol=1e-15)
        steps = np.linalg.norm(np.diff(s, axis=0), axis=1)
        np.testing.assert_allclose(steps, length / (n - 1), rtol=1e-9)


def test_sample_polyline_two_points_equals_sample_line():
    a, b = np.array([0.0, 0.0, 0.0]), np.array([0.3, 0.4, 0.1234])
    np.testing.assert_allclose(sample_polyline(np.stack([a, b])), sample_line(a, b), atol=1e-15)


def test_sample_polyline_handles_repeated_vertices():
    a, b = np.array([0.0, 0.0, 0.0]), np.array([0.5, 0.0, 0.0])
    poly = np.stack([a, a, (a + b) / 2, (a + b) / 2, b, b])
    np.testing.assert_allclose(sample_polyline(poly), sample_line(a, b), atol=1e-12)
    assert sample_polyline(np.stack([a, a, a])).shape == (0, 3)
    assert sample_polyline(a[None]).shape == (0, 3)


def test_sample_polyline_closed_square():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0]], dtype=float)
    s = sample_polyline(square)
    assert len(s) == int(4.0 // SAMPLE_SPACING) == 799  # perimeter 4, floating-point floor
    np.testing.assert_allclose(s[0], square[0], atol=1e-12)
    np.testing.assert_allclose(s[-1], square[-1], atol=1e-12)
    # Every sample lies on the square's boundary.
    on_x_edge = np.isclose(s[:, 1], 0.0) | np.isclose(s[:, 1], 1.0)
    on_y_edge = np.isclose(s[:, 0], 0.0) | np.isclose(s[:, 0], 1.0)
    assert np.all(on_x_edge | on_y_edge)
    assert np.all((s[:, :2] >= -1e-12) & (s[:, :2] <= 1 + 1e-12)) and np.all(s[:, 2] == 0)
    # n samples with both ends included: the arc-length step is 4 / (n - 1), a hair above the
    # nominal 5 mm (floor rounds n down); chords across a corner are shorter still.
    steps = np.linalg.norm(np.diff(s, axis=0), axis=1)
    step = 4.0 / (len(s) - 1)
    assert SAMPLE_SPACING <= step < SAMPLE_SPACING * 1.01
    assert steps.max() <= step + 1e-12
    assert np.count_nonzero(~np.isclose(steps, step)) <= 3  # at most one short chord per corner
    assert steps.min() > step / np.sqrt(2) - 1e-12


def test_sample_cubic_bezier_straight():
    a, b = np.array([-0.2, 0.1, 0.0]), np.array([0.5, 0.3, -0.1])
    ctrl = np.stack([a + t * (b - a) for t in (0, 1 / 3, 2 / 3, 1)])
    s = sample_cubic_bezier(ctrl)
    length = np.linalg.norm(b - a)
    assert len(s) == int(length // SAMPLE_SPACING)
    # Evenly spaced control points give a linearly parameterised segment: sample_line's points.
    np.testing.assert_allclose(s, sample_line(a, b), atol=1e-12)


def test_sample_cubic_bezier_quarter_circle_arclength():
    k = 4.0 / 3.0 * (np.sqrt(2.0) - 1.0)
    r = 0.8
    ctrl = r * np.array([[1, 0, 0], [1, k, 0], [k, 1, 0], [0, 1, 0]], dtype=float)
    t = np.linspace(0.0, 1.0, 200_001)[:, None]
    u = 1 - t
    dense = u**3 * ctrl[0] + 3 * u**2 * t * ctrl[1] + 3 * u * t**2 * ctrl[2] + t**3 * ctrl[3]
    dense_len = _polyline_length(dense)
    assert dense_len == pytest.approx(r * np.pi / 2, rel=1e-3)  # the Bézier is nearly a circle
    spacing = dense_len / 97.5  # arclen // spacing is 97 whatever the last digits
    s = sample_cubic_bezier(ctrl, spacing)
    assert len(s) == 97
    np.testing.assert_allclose(s[[0, -1]], ctrl[[0, 3]], atol=1e-15)
    # Samples are uniform in t: with 97 of them the chord sum approximates the arc length.
    assert _polyline_length(s) == pytest.approx(dense_len, rel=1e-3)
    # And with the default spacing the count follows the accurate arc length.
    assert len(sample_cubic_bezier(ctrl)) == int(dense_len // SAMPLE_SPACING)


def test_sample_cubic_bezier_count_uses_accurate_arclength():
    # A strongly curved, looping Bézier; reference length by adaptive quadrature.
    ctrl = np.array([[0.0, 0.0, 0.0], [0.6, 0.5, 0.1], [-0.6, 0.5, -0.1], [0.05, 0.0, 0.2]])

    def speed(t):
        u = 1 - t
        d = np.diff(ctrl, axis=0)
        return np.linalg.norm(3 * (u * u * d[0] + 2 * u * t * d[1] + t * t * d[2]))

    length, _ = quad(speed, 0.0, 1.0, epsabs=1e-14, epsrel=1e-13, limit=200)
    for k in (50, 137):
        # Spacings a relative 1e-9 either side of length / k: counts k and k - 1.
        assert len(sample_cubic_bezier(ctrl, length / k * (1 - 1e-9))) == k
        assert len(sample_cubic_bezier(ctrl, length / k * (1 + 1e-9))) == k - 1


def test_sample_cubic_bezier_degenerate():
    ctrl = np.tile([0.1, 0.2, 0.3], (4, 1))
    assert sample_cubic_bezier(ctrl).shape == (0, 3)


# --- voxel averaging -------------------------------------------------------------------------


def test_voxel_mean_same_cell_averaged():
    cell = 2.0 / 256
    p = np.array([[0.1 * cell, 0.2 * cell, 0.3 * cell], [0.9 * cell, 0.6 * cell, 0.5 * cell]])
    out = voxel_mean(p)
    assert out.dtype == np.float64
    np.testing.assert_allclose(out, p.mean(axis=0, keepdims=True), atol=1e-15)


def test_voxel_mean_cell_size_is_2_over_256():
    cell = 2.0 / 256
    # Just either side of a cell boundary: different cells.
    p = np.array([[cell * 0.999, 0.0, 0.0], [cell * 1.001, 0.0, 0.0]])
    assert len(voxel_mean(p)) == 2
    # Points 0.9 cells apart in the same cell (a 128-cell grid would merge more).
    q = np.array([[-1.0 + 0.05 * cell, 0, 0], [-1.0 + 0.95 * cell, 0, 0], [-1.0 + 1.5 * cell, 0, 0]])
    out = voxel_mean(q)
    assert len(out) == 2
    np.testing.assert_allclose(np.sort(out[:, 0]), [-1.0 + 0.5 * cell, -1.0 + 1.5 * cell])


def test_voxel_mean_grid_continues_beyond_the_bounds():
    # As point_cloud_utils' voxel grid: floor((p - lo) / size) with no clamp, so the upper bound
    # starts a new cell and points outside [-1, 1]^3 are kept in cells of the extended grid
    # (an edge on a face at 1 predicted 3 mm outside is not lost).
    cell = 2.0 / 256
    p = np.array([[1.0, 0.0, 0.0], [1.0 - 0.5 * cell, 0.0, 0.0]])
    assert len(voxel_mean(p)) == 2
    outside = np.array([[-1.0 - 0.5 * cell, 0, 0], [-1.0 - 0.6 * cell, 0, 0], [1.003, 0.5, 0.5], [1.5, 0, 0]])
    out = voxel_mean(outside)
    assert len(out) == 3
    np.testing.assert_allclose(out[0], [-1.0 - 0.55 * cell, 0, 0])
    assert {tuple(np.round(r, 6)) for r in out[1:]} == {(1.003, 0.5, 0.5), (1.5, 0.0, 0.0)}


def test_voxel_mean_keeps_distinct_cells_and_drops_non_finite_points():
    p = np.array(
        [
            [0.5, 0.5, 0.5],
            [-0.5, 0.25, 0.0],
            [np.nan, 0.0, 0.0],
            [0.0, np.inf, 0.0],
        ]
    )
    out = voxel_mean(p)
    assert out.shape == (2, 3)
    assert {tuple(r) for r in out} == {(0.5, 0.5, 0.5), (-0.5, 0.25, 0.0)}
    assert voxel_mean(np.empty((0, 3))).shape == (0, 3)


def test_voxel_mean_many_points_matches_loop():
    rng = np.random.default_rng(0)
    p = rng.uniform(-0.05, 0.05, size=(5000, 3))
    out = voxel_mean(p)
    cells = np.floor((p + 1.0) / (2.0 / 256)).astype(int)
    groups = {}
    for c, x in zip(map(tuple, cells), p):
        groups.setdefault(c, []).append(x)
    expected = np.array([np.mean(groups[c], axis=0) for c in sorted(groups)])
    got = out[np.lexsort(np.floor((out + 1.0) / (2.0 / 256)).astype(int).T[::-1])]
    np.testing.assert_allclose(got, expected, atol=1e-15)


# --- scores ----------------------------------------------------------------------------------


def test_score_identical_sets_is_perfect():
    rng = np.random.default_rng(1)
    gt = rng.uniform(-0.5, 0.5, size=(300, 3))
    m = score_points(gt, gt)
    assert m.accuracy_mm == 0.0 and m.completeness_mm == 0.0
    for d in (m.precision, m.recall, m.fscore):
        assert d == {5: 100.0, 10: 100.0, 20: 100.0}
    assert m.num_pred == m.num_gt == 300


def test_score_line_shifted_by_7mm():
    x = np.arange(0, 200) * 0.005 - 0.5
    gt = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    pred = gt + np.array([0.0, 0.007, 0.0])
    m = score_points(pred, gt)
    assert m.accuracy_mm == pytest.approx(7.0, abs=1e-9)
    assert m.completeness_mm == pytest.approx(7.0, abs=1e-9)
    assert m.precision[5] == m.recall[5] == m.fscore[5] == 0.0
    for mm in (10, 20):
        assert m.precision[mm] == m.recall[mm] == m.fscore[mm] == 100.0


def test_score_threshold_is_strict():
    gt = np.array([[0.0, 0.0, 0.0]])
    pred = np.array([[0.01, 0.0, 0.0]])  # exactly at the 10 mm threshold
    m = score_points(pred, gt)
    assert m.precision[10] == 0.0 and m.recall[10] == 0.0 and m.precision[20] == 100.0


def test_score_matches_brute_force():
    rng = np.random.default_rng(2)
    gt = rng.uniform(-0.3, 0.3, size=(400, 3))
    pred = np.concatenate([gt[:250] + rng.normal(scale=0.008, size=(250, 3)),
                           rng.uniform(-0.3, 0.3, size=(60, 3))])
    d = np.linalg.norm(pred[:, None, :] - gt[None, :, :], axis=2)
    d_pred, d_gt = d.min(axis=1), d.min(axis=0)
    m = score_points(pred, gt)
    assert m.accuracy_mm == pytest.approx(1000 * d_pred.mean(), rel=1e-12)
    assert m.completeness_mm == pytest.approx(1000 * d_gt.mean(), rel=1e-12)
    for tau in THRESHOLDS:
        mm = int(round(tau * 1000))
        p = 100.0 * np.count_nonzero(d_pred < tau) / len(pred)
        r = 100.0 * np.count_nonzero(d_gt < tau) / len(gt)
        assert m.precision[mm] == pytest.approx(p, abs=1e-12)
        assert m.recall[mm] == pytest.approx(r, abs=1e-12)
        assert m.fscore[mm] == pytest.approx(2 * p * r / (p + r), rel=1e-12)
        assert 0 < p < 100 or 0 < r < 100  # the case is non-trivial
    assert m.num_pred == 310 and m.num_gt == 400


def test_fscore_is_harmonic_mean_and_zero_when_nothing_matches():
    gt = np.zeros((1, 3))
    pred = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]])
    m = score_points(pred, gt)
    assert m.precision[5] == 25.0 and m.recall[5] == 100.0
    assert m.fscore[5] == pytest.approx(40.0)
    far = score_points(np.ones((2, 3)), gt)
    assert far.fscore == {5: 0.0, 10: 0.0, 20: 0.0}


def test_empty_prediction_raises():
    with pytest.raises(ValueError, match="prediction"):
        score_points(np.empty((0, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="prediction"):
        evaluate(np.array([[np.nan, 5.0, 5.0]]), np.zeros((3, 3)))  # no finite point


def test_evaluate_voxelizes_prediction_only():
    cell = 2.0 / 256
    gt = np.array([[0.1 * cell, 0.0, 0.0], [0.9 * cell, 0.0, 0.0]])  # same cell: must stay 2
    pred = gt.copy()
    m = evaluate(pred, gt)
    assert m.num_pred == 1 and m.num_gt == 2
    assert m.accuracy_mm == pytest.approx(1000 * 0.4 * cell)
    raw = evaluate(pred, gt, voxelize=False)
    assert raw.num_pred == 2 and raw.accuracy_mm == 0.0


def test_to_dict_and_table():
    x = np.arange(0, 50) * 0.005
    gt = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    m = score_points(gt + [0, 0.007, 0], gt)
    assert isinstance(m, EdgeMetrics)
    d = m.to_dict()
    expected = {"acc_mm", "comp_mm", "num_pred", "num_gt"} | {
        f"{k}_{mm}mm" for k in ("precision", "recall", "fscore") for mm in (5, 10, 20)
    }
    assert set(d) == expected
    assert d["acc_mm"] == m.accuracy_mm and d["fscore_10mm"] == 100.0
    json.dumps(d)  # JSON-ready
    text = m.table()
    for mm in (5, 10, 20):
        assert f"{mm}mm" in text
    assert "Acc" in text and "Comp" in text and "7.000" in text
