"""Detector calibration (edgedog.bench.calibrate; its record, edgedog.edges.calibration) and the map
corrections (edgedog.edges.correct): known shifts, widths and silhouette sides are recovered,
corrections undo them, records are keyed by weights, and the measured bias of the real ABC-NEF
PiDiNet maps is reproduced."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import torch

from edgedog.bench.calibrate import (
    ProjectedCurves,
    calibrate_detector,
    measure_offset,
    measure_scene_maps,
    silhouette_sides,
)
from edgedog.cli import main
from edgedog.edges.calibration import (
    DetectorCalibration,
    calibration_path,
    load_calibration,
    save_calibration,
)
from edgedog.edges.classical import CannyDetector
from edgedog.edges.correct import blur_to_profile, gaussian_kernel, shift_edge_map, warp_target
from edgedog.edges.detector import EdgeDetector
from edgedog.edges.thin import thin_edge_map
from edgedog.scenes import load_scene
from tests.helpers.paths import REPO

SIZE = 160
CENTRE, RADIUS = np.array([80.3, 79.6]), 50.0


@pytest.fixture(scope="module")
def egl():
    from edgedog.synthetic.render import GLUnavailableError, create_context

    try:
        create_context().release()
    except GLUnavailableError as error:
        pytest.skip(f"no headless OpenGL: {error}")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("EDGEDOG_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def ring_map(offset=(0.0, 0.0), radius: float = RADIUS, sigma: float = 1.2) -> np.ndarray:
    """(SIZE, SIZE) a Gaussian band of std `sigma` px along the circle of `radius` about CENTRE,
    moved by `offset` (dx, dy) px."""
    y, x = np.mgrid[:SIZE, :SIZE].astype(np.float64)
    r = np.hypot(x - CENTRE[0] - offset[0], y - CENTRE[1] - offset[1])
    return np.exp(-0.5 * ((r - radius) / sigma) ** 2).astype(np.float32)


def ring_curves(count: int = 720, flip_every: int = 2) -> ProjectedCurves:
    """Points on the circle of RADIUS about CENTRE; every `flip_every`-th tangent reversed (a
    curve's direction is arbitrary)."""
    angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
    points = CENTRE + RADIUS * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    tangents = np.stack([-np.sin(angle), np.cos(angle)], axis=1)
    tangents[::flip_every] *= -1
    return ProjectedCurves(points, tangents, np.zeros(count, np.int8))


def test_a_shifted_band_is_measured_and_the_correction_puts_it_back():
    offset = (0.7, -0.45)
    measured = measure_offset([ring_map(offset)], [ring_curves()])
    # Bilinear sampling of the pixel grid leaves ~0.02 px of error on these few hundred points.
    np.testing.assert_allclose(measured.offset_px, offset, atol=0.03)
    assert measured.correction == (-measured.offset_px[0], -measured.offset_px[1])
    # Per orientation, the offset along the bin's normal (cos a, sin a): 0 deg is x, 90 deg is y.
    for bin_ in measured.orientations:
        a = np.radians(bin_.angle_deg)
        assert bin_.offset_px == pytest.approx(offset[0] * np.cos(a) + offset[1] * np.sin(a), abs=0.08)
    corrected = shift_edge_map(ring_map(offset), *measured.correction)
    np.testing.assert_allclose(measure_offset([corrected], [ring_curves()]).offset_px, (0, 0), atol=0.05)


def test_profile_width_of_a_thinned_band_is_its_gaussian_sigma():
    wide = cv2.GaussianBlur(np.pad(np.ones((100, 1), np.float32), ((30, 30), (70, 89))), (0, 0), 3.0)
    curves = ProjectedCurves(np.stack([np.full(81, 70.0), np.linspace(40, 120, 81)], axis=1),
                             np.tile([0.0, 1.0], (81, 1)), np.zeros(81, np.int8))
    for sigma in (0.8, 1.5):
        profile = measure_offset([thin_edge_map(wide / wide.max(), sigma=sigma)], [curves]).profile
        assert profile.width_px == pytest.approx(sigma, abs=0.08)
        assert abs(profile.peak_px) < 0.05 and abs(profile.asymmetry) < 0.05


def test_a_band_drawn_outside_a_silhouette_has_a_positive_outward_offset():
    y, x = np.mgrid[:SIZE, :SIZE]
    background = np.hypot(x - CENTRE[0], y - CENTRE[1]) > RADIUS  # a disc seen against the background
    curves = silhouette_sides(ring_curves(), background)
    # Every other tangent is reversed, so half the normals point in: outward says which.
    assert set(np.unique(curves.outward)) == {-1, 1} and np.all(curves.outward != 0)
    outside = measure_offset([ring_map(radius=RADIUS + 1.0)], [curves])
    assert outside.silhouette_points == len(curves.points)
    assert outside.silhouette_offset_px == pytest.approx(1.0, abs=0.05)
    inside = measure_offset([ring_map(radius=RADIUS - 0.8)], [curves])
    assert inside.silhouette_offset_px == pytest.approx(-0.8, abs=0.05)
    # Interior creases (object on both sides) are not silhouettes.
    assert np.all(silhouette_sides(ring_curves(), np.zeros_like(background)).outward == 0)


def test_warp_target_matches_shift_edge_map_and_finite_differences():
    edge_map = ring_map((0.3, 0.2))
    shift = (0.63, -0.41)
    warped = warp_target(torch.from_numpy(edge_map), torch.tensor(shift))
    np.testing.assert_allclose(warped.numpy(), shift_edge_map(edge_map, *shift), atol=1e-4)

    target = torch.from_numpy(edge_map).double()
    weights = torch.from_numpy(ring_map((-0.5, 0.4), sigma=2.0)).double()  # any smooth loss

    def loss(s: torch.Tensor) -> torch.Tensor:
        return (warp_target(target, s) * weights).sum()

    parameter = torch.tensor(shift, dtype=torch.float64, requires_grad=True)
    loss(parameter).backward()
    step = 1e-4  # bilinear sampling is linear between pixel centres: central differences are exact
    numeric = [(loss(parameter.detach() + step * e) - loss(parameter.detach() - step * e)).item() / (2 * step)
               for e in torch.eye(2, dtype=torch.float64)]
    np.testing.assert_allclose(parameter.grad.numpy(), numeric, rtol=1e-6)


def test_blur_to_profile_widens_a_thin_line_to_the_given_sigma():
    line = torch.zeros(41, 41)
    line[:, 20] = 1.0
    line.requires_grad_(True)
    blurred = blur_to_profile(line, 1.5)
    row = blurred[20].detach().numpy()
    offsets = np.arange(41) - 20
    assert row.sum() == pytest.approx(1.0, abs=1e-5)
    assert np.sqrt((row * offsets**2).sum()) == pytest.approx(1.5, abs=0.02)
    blurred.sum().backward()
    assert line.grad is not None and torch.isfinite(line.grad).all()


def test_blur_to_profile_is_opencvs_separable_filter_with_zero_borders():
    image = np.random.default_rng(3).random((37, 52)).astype(np.float32)
    kernel = gaussian_kernel(0.8).numpy()
    expected = cv2.sepFilter2D(image, -1, kernel, kernel, borderType=cv2.BORDER_CONSTANT)
    np.testing.assert_allclose(blur_to_profile(torch.from_numpy(image), 0.8).numpy(), expected, atol=1e-6)


def synthetic_calibration(detector: EdgeDetector) -> DetectorCalibration:
    measurement = measure_offset([ring_map((0.5, -0.2))], [ring_curves()])
    return DetectorCalibration(detector.name, detector.fingerprint, measurement, {SIZE: measurement},
                               ("ring",), 1, 0, "2026-01-01T00:00:00+00:00")


def test_records_round_trip_and_are_keyed_by_fingerprint(cache):
    detector = CannyDetector()
    calibration = synthetic_calibration(detector)
    path = save_calibration(calibration)
    assert path == calibration_path(detector.name, detector.fingerprint)
    assert path.parent == cache / "calibration"
    assert load_calibration(detector) == calibration
    assert DetectorCalibration.from_dict(json.loads(path.read_text())) == calibration
    assert load_calibration(CannyDetector(low=40)) is None  # other settings, other fingerprint


def test_pidinet_records_are_keyed_by_their_weights(cache):
    from edgedog.edges.pidinet import PidinetDetector

    folder = REPO.parent / "shared" / "models" / "pidinet"
    if not folder.is_dir():
        pytest.skip(f"shared PiDiNet weights not present: {folder}")
    bsds, nyud = (PidinetDetector(folder / name) for name in ("table5_pidinet.pth", "table6_pidinet.pth"))
    assert bsds.name == nyud.name and bsds.fingerprint != nyud.fingerprint  # one architecture, two weights
    save_calibration(synthetic_calibration(bsds))
    assert load_calibration(bsds) is not None and load_calibration(nyud) is None


class ShiftedCanny(EdgeDetector):
    """Canny whose maps are moved by a known sub-pixel shift: a detector with a known bias."""

    name = "canny-shifted"

    def __init__(self, shift: tuple[float, float]):
        self.canny, self.shift = CannyDetector(), shift

    @property
    def fingerprint(self) -> str:
        return f"{self.canny.fingerprint}-shift{self.shift[0]:g},{self.shift[1]:g}"

    def detect(self, image: np.ndarray) -> np.ndarray:
        return shift_edge_map(self.canny.detect(image), *self.shift)


@pytest.mark.gl
def test_calibration_recovers_the_known_shift_of_a_detector(egl):
    settings = dict(shapes=("box", "l-bracket"), views=4, sizes=(300,))
    plain = calibrate_detector(CannyDetector(), **settings)
    shifted = calibrate_detector(ShiftedCanny((0.6, -0.4)), **settings)
    np.testing.assert_allclose(np.subtract(shifted.offset_px, plain.offset_px), (0.6, -0.4), atol=0.1)
    assert shifted.points > 2000 and 0 < shifted.overall.silhouette_points < shifted.points
    assert set(shifted.per_size) == {300} and shifted.fingerprint.endswith("shift0.6,-0.4")
    assert 0.5 < shifted.profile_width_px < 2.0  # Canny softened by a 1-px Gaussian


@pytest.mark.gl
def test_cli_calibrates_saves_the_record_and_prints_a_summary(egl, cache, tmp_path, capsys):
    out = tmp_path / "canny.json"
    assert main(["calibrate-detector", "--detector", "canny", "--shapes", "box", "--views", "3",
                 "--sizes", "200", "--json", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("canny (canny-50-150-b1-s1) on box, 3 views at 200 px")
    assert any(line.startswith("offset        dx ") for line in printed)
    assert any(line.startswith("silhouettes   peak ") for line in printed)
    record = DetectorCalibration.from_dict(json.loads(printed[-1]))
    assert record == DetectorCalibration.from_dict(json.loads(out.read_text()))
    assert load_calibration(CannyDetector()) == record


def write_scene_without_ground_truth(folder):
    """A one-view NeRF scene (ABC-NEF layout, PiDiNet maps) with no ground truth anywhere."""
    (folder / "train").mkdir(parents=True)
    (folder / "train_img").mkdir()
    cv2.imwrite(str(folder / "train_img" / "0.png"), np.zeros((32, 32, 4), np.uint8))
    cv2.imwrite(str(folder / "train" / "0.png"), np.zeros((32, 32), np.uint8))
    c2w = np.eye(4)
    c2w[2, 3] = 4.0
    frame = {"file_path": "./train/0", "transform_matrix": c2w.tolist()}
    transforms = {"camera_angle_x": 0.7, "frames": [frame]}
    (folder / "transforms_train.json").write_text(json.dumps(transforms))
    return folder


def test_cli_errors_are_one_line(tmp_path, capsys):
    scene = write_scene_without_ground_truth(tmp_path / "scene")
    assert load_scene(scene).detectors == ["pidinet"]
    assert main(["calibrate-detector", "--scene", str(scene), "--maps", "pidinet"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith(f"edgedog: error: {scene}: no ground truth")
    assert main(["calibrate-detector", "--detector", "canny", "--shapes", "sphere"]) == 2
    assert "unknown shape 'sphere'" in capsys.readouterr().err


@pytest.mark.shared_data
@pytest.mark.slow
def test_the_bias_of_the_abc_nef_pidinet_maps_is_reproduced(abc_nef_scene_dir):
    measured = measure_scene_maps(load_scene(abc_nef_scene_dir), "pidinet")
    # The published fact: the maps peak at dx, dy = -0.55, -1.0 px from the projected curves.
    np.testing.assert_allclose(measured.offset_px, (-0.55, -1.0), atol=0.15)
    assert 1.5 < measured.profile.width_px < 4.0
    # Silhouettes from the images' alpha: there the band peaks outside the object (measured +1.6
    # px; the maps were computed with the alpha dropped, which fattens the object).
    assert measured.silhouette_points > 0 and measured.silhouette_offset_px > 0.5


@pytest.mark.shared_data
def test_unknown_maps_name_is_one_line(abc_nef_scene_dir, capsys):
    assert main(["calibrate-detector", "--scene", str(abc_nef_scene_dir), "--maps", "dexined"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "no 'dexined' edge maps (available: pidinet)" in error
