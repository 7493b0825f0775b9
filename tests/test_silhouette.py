"""The silhouette correction: outlines from anti-aliased masks, the offset of a map's outline
band, pulling it onto the outline, and its use in training."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from edgedog.edges.silhouette import Outline, OutlinePull, distances_read, measure_silhouette_profile
from edgedog.errors import InputError
from edgedog.train.targets import corrects_silhouettes, prepare_maps, scene_outlines
from edgedog.train.trainer import Trainer
from tests.helpers.tiny_runs import every_fifth_view, tiny_config

SIZE, CENTRE, RADIUS = 96, (47.3, 48.6), 30.0


def disc_coverage(radius: float = RADIUS, samples: int = 8) -> np.ndarray:
    """(SIZE, SIZE) exact-ish anti-aliased coverage of a disc, by supersampling each pixel."""
    offsets = (np.arange(samples) + 0.5) / samples - 0.5
    ys, xs = np.mgrid[0:SIZE, 0:SIZE].astype(np.float64)
    covered = np.zeros((SIZE, SIZE))
    for dy in offsets:
        for dx in offsets:
            covered += np.hypot(xs + dx - CENTRE[0], ys + dy - CENTRE[1]) <= radius
    return (covered / samples**2).astype(np.float32)


def true_distance() -> np.ndarray:
    ys, xs = np.mgrid[0:SIZE, 0:SIZE].astype(np.float64)
    return np.hypot(xs - CENTRE[0], ys - CENTRE[1]) - RADIUS


def ring_map(at_distance: float, sigma: float = 0.8) -> np.ndarray:
    """A map whose band follows the disc's outline at a signed distance (> 0 outside)."""
    return np.exp(-0.5 * ((true_distance() - at_distance) / sigma) ** 2).astype(np.float32)


def test_outline_distance_and_normals_of_an_antialiased_disc():
    outline = Outline.from_coverage(disc_coverage())
    truth = true_distance()
    near = np.abs(truth) < 3
    assert np.abs(outline.distance[near] - truth[near]).max() < 0.2
    assert abs(np.mean(outline.distance[near] - truth[near])) < 0.05
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    radial = np.stack([xs - CENTRE[0], ys - CENTRE[1]], axis=-1)
    radial /= np.linalg.norm(radial, axis=-1, keepdims=True)
    assert np.min(np.sum(outline.normal[near] * radial[near], axis=-1)) > 0.97


@pytest.mark.parametrize("reach", [1.0, 3.0, 12.0])
def test_an_outline_made_within_reach_equals_the_whole_views_where_it_is_read(reach):
    # The disc in a corner of a larger view: the distance transforms then run on its box only.
    coverage = np.zeros((230, 310), np.float32)
    coverage[5:5 + SIZE, 190:190 + SIZE] = disc_coverage()
    whole, boxed = Outline.from_coverage(coverage), Outline.from_coverage(coverage, distances_read(reach))
    read = np.abs(whole.distance) <= distances_read(reach)
    assert read.sum() > 1000
    assert np.array_equal(boxed.distance[read], whole.distance[read])  # to the bit
    assert np.array_equal(boxed.normal[read], whole.normal[read])
    assert np.all(np.abs(boxed.distance[~read]) > distances_read(reach))
    edge_map = np.random.default_rng(0).random(coverage.shape).astype(np.float32)
    pulls = [OutlinePull.towards(outline, 1.3, reach) for outline in (whole, boxed)]
    assert np.array_equal(pulls[0].apply(edge_map), pulls[1].apply(edge_map))
    mask = edge_map > 0.9
    assert np.array_equal(pulls[0].apply(mask, nearest=True), pulls[1].apply(mask, nearest=True))
    profiles = [measure_silhouette_profile([edge_map], [outline]) for outline in (whole, boxed)]
    assert profiles[0].to_dict() == profiles[1].to_dict()
    with pytest.raises(ValueError, match="made within"):  # a pull reaching past what was made
        OutlinePull.towards(boxed, 1.3, reach * 4)
    # Faint noise over the whole view (a JPEG mask): the box stays the object's, and exact.
    noisy = np.where(coverage > 0, coverage, np.float32(0.01))
    noisy_whole = Outline.from_coverage(noisy)
    read = np.abs(noisy_whole.distance) <= distances_read(reach)
    noisy_boxed = Outline.from_coverage(noisy, distances_read(reach))
    assert np.array_equal(noisy_boxed.distance[read], noisy_whole.distance[read])
    assert np.all(noisy_boxed.distance[:, :150] == distances_read(reach) + 1)  # off the box: not made


@pytest.mark.parametrize("drawn_at", [-0.6, 0.0, 1.2])
def test_measured_offset_is_where_the_band_is_drawn_and_the_pull_removes_it(drawn_at):
    outline = Outline.from_coverage(disc_coverage())
    band = ring_map(drawn_at)
    measured = measure_silhouette_profile([band], [outline])
    assert measured.offset_px == pytest.approx(drawn_at, abs=0.1)
    pulled = OutlinePull.towards(outline, measured.offset_px, reach_px=3.0).apply(band)
    assert abs(measure_silhouette_profile([pulled], [outline]).offset_px) < 0.12


def test_pull_leaves_edges_deep_inside_alone():
    outline = Outline.from_coverage(disc_coverage())
    inner = ring_map(-12.0)  # an edge 12 px inside the outline: beyond twice the reach
    pulled = OutlinePull.towards(outline, 1.2, reach_px=3.0).apply(inner)
    np.testing.assert_allclose(pulled, inner, atol=1e-5)


def straight_alpha_disc(alpha_dropped: bool) -> np.ndarray:
    """Grey map of a white disc on black as a detector sees it: straight-alpha PNGs keep the
    object's colour under partial alpha, so dropping the alpha grows the object by its rim."""
    coverage = disc_coverage()
    grey = (coverage > 0).astype(np.float32) if alpha_dropped else coverage
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3)
    magnitude = np.hypot(gx, gy)
    return magnitude / magnitude.max()


def test_dropping_a_straight_alpha_draws_the_outline_outside():
    outline = Outline.from_coverage(disc_coverage())
    dropped = measure_silhouette_profile([straight_alpha_disc(True)], [outline]).offset_px
    composited = measure_silhouette_profile([straight_alpha_disc(False)], [outline]).offset_px
    assert dropped > 0.3
    assert abs(composited) < 0.15


def test_empty_or_full_masks_have_no_profile():
    for coverage in (np.zeros((20, 20), np.float32), np.ones((20, 20), np.float32)):
        with pytest.raises(ValueError, match="outline"):
            measure_silhouette_profile([np.zeros((20, 20), np.float32)], [Outline.from_coverage(coverage)])


def test_prepare_maps_without_outlines_leaves_the_maps_and_reports_nothing():
    band = ring_map(1.0)
    (target,), _, report = prepare_maps([band], tiny_config(silhouette_correction="measured"), (0.0, 0.0))
    np.testing.assert_array_equal(target, band)
    assert report is None


def test_prepare_maps_pulls_the_band_onto_the_outline_and_reports_it():
    outline = Outline.from_coverage(disc_coverage())
    config = tiny_config(silhouette_correction="measured")
    (target,), (mask,), report = prepare_maps([ring_map(1.2)], config, (0.0, 0.0), [outline])
    assert report["offset_px"] == pytest.approx(1.2, abs=0.1) and abs(report["residual_px"]) < 0.12
    # Edge pixels now straddle the outline (to within the half pixel of nearest sampling).
    assert np.abs(outline.distance[mask]).max() < 1.5 and abs(np.mean(outline.distance[mask])) < 0.2


def test_a_thin_line_keeps_its_edge_pixels_when_pulled_by_a_fraction_of_a_pixel():
    outline = Outline.from_coverage(disc_coverage())
    line = 0.65 * ring_map(0.5, sigma=0.5)  # a faint line half a pixel outside, as at 200 px
    config = tiny_config(silhouette_correction="measured")
    (target,), (mask,), report = prepare_maps([line], config, (0.0, 0.0), [outline])
    before = line >= config.maps.edge_threshold
    assert report["offset_px"] == pytest.approx(0.5, abs=0.1) and before.sum() > 100
    assert (target >= config.maps.edge_threshold).sum() < 0.2 * before.sum()  # interpolation dims the line
    np.testing.assert_array_equal(mask, before)  # under half a pixel: the nearest pixel is itself


def test_scene_without_masks_is_refused_and_auto_leaves_it_alone(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    assert corrects_silhouettes(tiny_config(), scene)  # 'auto' on RGBA renders
    assert not corrects_silhouettes(tiny_config(silhouette_correction="none"), scene)
    scene.views = [dataclass_without_alpha(view, tmp_path) for view in scene.views[:2]]
    assert not corrects_silhouettes(tiny_config(), scene)
    assert corrects_silhouettes(tiny_config(silhouette_correction="measured"), scene)
    with pytest.raises(InputError, match="needs object masks"):
        scene_outlines(scene, 3.0)


def dataclass_without_alpha(view, folder):
    """The view with its image rewritten as RGB (no alpha, no mask file)."""
    import dataclasses

    image = cv2.imread(str(view.image_path), cv2.IMREAD_UNCHANGED)
    path = folder / f"{view.name}.png"
    cv2.imwrite(str(path), image[..., :3])
    return dataclasses.replace(view, image_path=path, mask_path=None, alpha=False)


def test_training_with_the_correction_logs_the_measured_offset(builtin_scene_dir, tmp_path):
    scene = every_fifth_view(builtin_scene_dir)
    trainer = Trainer(scene, tiny_config(silhouette_correction="measured"), tmp_path / "run", progress=False)
    trainer.run()
    report = json.loads((tmp_path / "run" / "log.json").read_text())["silhouette_correction"]
    assert np.isfinite(report["offset_px"]) and abs(report["offset_px"]) < 2.0
    assert abs(report["residual_px"]) < abs(report["offset_px"]) + 0.05
    assert report["views_without_mask"] == []
