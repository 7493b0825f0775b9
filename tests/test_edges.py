"""Weight-free detectors, detector names, and the per-scene edge-map cache."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from edgedog.edges.cache import ensure_edge_maps, maps_folder
from edgedog.edges.classical import CannyDetector, SobelDetector
from edgedog.edges.registry import make_detector
from edgedog.errors import ConfigError
from edgedog.scenes import load_scene


def step_image(size=64, column=32) -> np.ndarray:
    image = np.zeros((size, size, 3), np.float32)
    image[:, column:] = 0.8
    return image


@pytest.mark.parametrize("detector", [SobelDetector(), CannyDetector()])
def test_weight_free_detectors_find_a_step_edge(detector):
    edges = detector.detect(step_image())
    assert edges.shape == (64, 64) and edges.dtype == np.float32
    assert 0 <= edges.min() and edges.max() <= 1
    profile = edges[32]
    assert abs(int(np.argmax(profile)) - 31.5) <= 1.5  # the step lies between columns 31 and 32
    assert profile.max() > 0.5 and profile[:20].max() == 0 and profile[44:].max() < 1e-3


def test_flat_image_has_no_edges():
    flat = np.full((32, 48, 3), 0.5, np.float32)
    assert SobelDetector().detect(flat).max() == 0
    assert CannyDetector().detect(flat).max() == 0


def test_detector_names():
    assert make_detector("canny").name == "canny"
    assert make_detector("sobel").fingerprint.startswith("sobel")
    with pytest.raises(ConfigError, match="unknown detector 'foo'"):
        make_detector("foo")
    with pytest.raises(ConfigError):
        make_detector("pidinet:side9")


def test_auto_without_configured_weights_is_pidinet(monkeypatch):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    assert make_detector("auto").name == "pidinet"  # its weights ship with edgedog


@pytest.fixture
def box_scene(builtin_scene_dir, tmp_path):
    folder = tmp_path / "box"
    shutil.copytree(builtin_scene_dir, folder)
    return folder


def test_maps_are_computed_once_attached_and_reused(box_scene):
    scene = load_scene(box_scene)
    run = ensure_edge_maps(scene, CannyDetector(), progress=False)
    assert run.computed == len(scene) and run.seconds > 0 and run.megapixels == pytest.approx(50 * 0.16)
    assert "canny" in scene.detectors
    edges = scene.load_edge_map(3, "canny")
    assert edges.shape == (400, 400) and edges.max() > 0.5
    # A new process (a fresh scene object) finds the cache and computes nothing.
    again = load_scene(box_scene)
    rerun = ensure_edge_maps(again, CannyDetector(), progress=False)
    assert rerun.computed == 0 and rerun.folder == run.folder
    np.testing.assert_array_equal(again.load_edge_map(3, "canny"), edges)


def test_an_interrupted_run_resumes(box_scene):
    scene = load_scene(box_scene)
    run = ensure_edge_maps(scene, SobelDetector(), progress=False)
    (run.folder / "manifest.json").unlink()
    (run.folder / f"{scene.views[7].name}.png").unlink()
    rerun = ensure_edge_maps(load_scene(box_scene), SobelDetector(), progress=False)
    assert rerun.computed == 1 and (run.folder / "manifest.json").is_file()


def test_each_resolution_has_its_own_maps(box_scene):
    full, half = load_scene(box_scene), load_scene(box_scene, downscale=2)
    assert maps_folder(full, CannyDetector()) != maps_folder(half, CannyDetector())
    ensure_edge_maps(half, CannyDetector(), progress=False)
    assert half.load_edge_map(0, "canny").shape == (200, 200)


def test_provided_maps_are_used_unless_recomputed(box_scene):
    scene = load_scene(box_scene)
    exact = CannyDetector()
    exact.name = "exact"  # the built-in scene ships 'exact' maps
    assert ensure_edge_maps(scene, exact, progress=False).folder is None
    provided = scene.load_edge_map(0, "exact")
    run = ensure_edge_maps(scene, exact, recompute=True, progress=False)
    assert run.computed == len(scene)
    assert not np.array_equal(scene.load_edge_map(0, "exact"), provided)


def test_maps_are_cached_in_the_user_cache_never_in_the_scene(box_scene, tmp_path, monkeypatch):
    monkeypatch.setenv("EDGEDOG_CACHE", str(tmp_path / "cache"))
    before = sorted(box_scene.rglob("*"))
    scene = load_scene(box_scene)
    run = ensure_edge_maps(scene, CannyDetector(), progress=False)
    assert run.computed == len(scene) and (tmp_path / "cache") in run.folder.parents
    assert sorted(box_scene.rglob("*")) == before


def test_thinning_moves_an_asymmetric_band_to_its_ridge():
    from edgedog.edges.thin import ridge_mask, thin_edge_map

    x = np.arange(64, dtype=np.float32)
    # A vertical edge at x = 20 drawn as a band that extends 1 px inwards and 5 px outwards, like a
    # detector's silhouette response: its centre of mass is 2 px off the ridge.
    across = np.where(x < 20, np.exp(-((x - 20) / 1.0) ** 2), np.exp(-((x - 20) / 5.0) ** 2))
    band = np.tile(across, (48, 1)).astype(np.float32)
    assert abs((band[0] * x).sum() / band[0].sum() - 20) > 1.5
    ridge = ridge_mask(band)
    assert np.array_equal(np.nonzero(ridge[10])[0], [20])
    thin = thin_edge_map(band, sigma=0.7)
    row = thin[24]
    assert row.argmax() == 20 and abs(row[20] - 1.0) < 0.02
    assert abs((row * x).sum() / row.sum() - 20) < 0.05  # symmetric profile around the ridge
    assert row[17] < 1e-3 and row[23] < 1e-3  # narrow: nothing left of the 5 px outer band
    assert not thin_edge_map(np.zeros((16, 16), np.float32)).any()
