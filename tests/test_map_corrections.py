"""Map corrections in training: fixed shifts, the shift fitted with the primitives, the profile
loss, and their bookkeeping in checkpoints and logs."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from edgedog.renderer.rasterize import rasterize

from edgedog.edges.correct import blur_to_profile, shift_edge_map
from edgedog.errors import ConfigError
from edgedog.train.config import with_settings
from edgedog.train.losses import projection_loss
from edgedog.train.targets import LearnedShift, prepare_maps
from edgedog.train.trainer import Trainer
from tests.helpers.tiny_runs import every_fifth_view
from tests.helpers.tiny_runs import tiny_config as shared_tiny_config


def tiny_config(**changes):
    """The shared tiny run over four epochs; a learned shift starts at epoch 1."""
    return shared_tiny_config(**{"epochs": 4, "map_shift_from_epoch": 1, **changes})


@pytest.fixture
def box(builtin_scene_dir):
    return every_fifth_view(builtin_scene_dir)


def vertical_line(width: int = 40, x: float = 20.0) -> np.ndarray:
    columns = np.arange(width, dtype=np.float32)
    return np.tile(np.exp(-0.5 * (columns - x) ** 2), (30, 1)).astype(np.float32)


def test_prepared_maps_are_floored_then_shifted_and_masked():
    line = vertical_line()
    config = tiny_config(map_floor=0.5)
    (target,), (mask,), _ = prepare_maps([line], config, (1.4, 0.0))
    assert np.argmax(target[10]) in (21, 22) and target[10, 20] < line[10, 20]
    # The mask keeps the line's three edge pixels (19-21) and moves them by the nearest whole pixel.
    assert np.flatnonzero(mask[10]).tolist() == [20, 21, 22]


def test_contrast_normalised_targets_lift_a_faint_edge_to_a_strong_ones_height_and_keep_the_masks():
    edge_map = np.full((20, 40), 0.1, np.float32)  # shading everywhere
    edge_map[:, 10], edge_map[:, 30] = 0.6, 1.0  # a faint edge and a strong one
    plain = tiny_config()
    (as_drawn,), (plain_mask,), _ = prepare_maps([edge_map], plain, (0.0, 0.0))
    np.testing.assert_array_equal(as_drawn, edge_map)  # 0: the maps as they are
    (target,), (mask,), _ = prepare_maps([edge_map], with_settings(plain, {"maps.contrast": 0.5}), (0.0, 0.0))
    assert target[5, 10] == pytest.approx(1.0) and target[5, 30] == pytest.approx(1.0)
    assert target[5, 9] == pytest.approx(0.1 / 0.6)  # beside the faint edge: its peak divides
    assert target[5, 20] == pytest.approx(0.1 / 0.5)  # far from both: lifted by at most 1 / contrast
    assert target[5, 28] == pytest.approx(0.1)  # beside the strong edge: unchanged
    np.testing.assert_array_equal(mask, plain_mask)


def test_a_faint_thin_line_keeps_its_edge_pixels_when_shifted_by_a_fraction_of_a_pixel():
    columns = np.arange(40, dtype=np.float32)
    line = np.tile(0.65 * np.exp(-2.0 * (columns - 20) ** 2), (30, 1)).astype(np.float32)  # sigma 0.5 px
    config = tiny_config()
    (target,), (mask,), _ = prepare_maps([line], config, (0.45, 0.0))
    assert (line >= config.maps.edge_threshold).sum() == 30
    assert (target >= config.maps.edge_threshold).sum() == 0  # interpolation dims the line below 0.5
    np.testing.assert_array_equal(mask, line >= config.maps.edge_threshold)  # the nearest pixel is itself
    (thin,), _, _ = prepare_maps([line], with_settings(config, {"maps.edge_profile": "thin"}), (0.0, 0.0))
    assert np.argmax(thin[10]) == 20


def test_the_learned_shift_finds_a_known_offset():
    line = torch.from_numpy(vertical_line(x=20.0))
    render = torch.from_numpy(shift_edge_map(vertical_line(x=20.0), -0.8, 0.0))  # where the truth is
    learned = LearnedShift(tiny_config(lr_map_shift=0.02, map_shift_from_epoch=0), torch.device("cpu"))
    for _ in range(300):
        loss = (learned.target(line, epoch=0) - render).abs().mean()
        loss.backward()
        learned.step()
        learned.zero_grad()
    dx, dy = learned.value()
    assert dx == pytest.approx(-0.8, abs=0.1) and dy == pytest.approx(0.0, abs=0.1)


def test_learned_shift_trains_resumes_exactly_and_is_logged(box, tmp_path):
    config = tiny_config(map_correction="learned")
    whole = Trainer(box, config, tmp_path / "whole", progress=False)
    whole.run()
    assert whole.learned_shift.value() != [0.0, 0.0]
    part = Trainer(box, config, tmp_path / "part", progress=False)
    while part.epoch < 2:
        part.step()
    resumed = Trainer(box, config, tmp_path / "part", progress=False)
    resumed.run()
    assert resumed.learned_shift.value() == whole.learned_shift.value()
    torch.testing.assert_close(resumed.model.means, whole.model.means, rtol=0, atol=0)
    log = json.loads((tmp_path / "whole" / "log.json").read_text())
    assert log["map_shift_px"] == [round(v, 4) for v in whole.learned_shift.value()]


def test_fixed_shifts_are_scaled_to_the_training_resolution(box, tmp_path):
    shifted = Trainer(box, tiny_config(map_correction="shift", map_shift=(2.0, -1.0), epochs=1,
                                       silhouette_correction="none"), tmp_path / "shift", progress=False)
    # The box's own maps are stored at 400 px and trained at 100 px: the shift is divided by 4.
    assert shifted.map_shift == (0.5, -0.25)
    original = box.load_edge_map(0, shifted.detector)
    np.testing.assert_allclose(shifted.targets[0].numpy(), shift_edge_map(original, 0.5, -0.25), atol=1e-6)


def test_the_profile_loss_compares_the_blurred_render_with_the_map(box, tmp_path):
    box.views = box.views[:1]  # one view: the first step renders it
    config = tiny_config(edge_profile="profile", profile_sigma=1.5, pixel_uncertainty=False, epochs=1)
    trainer = Trainer(box, config, tmp_path / "p", progress=False)
    with torch.no_grad():
        render = rasterize(trainer.model.primitives(), trainer.cameras[0], trainer.raster).image[..., 0]
    blurred = projection_loss(blur_to_profile(render, 1.5), trainer.targets[0], None).item()
    sharp = projection_loss(render, trainer.targets[0], None).item()
    assert abs(blurred - sharp) > 0.01 * sharp  # the blur matters here, so the check below can tell
    trainer.step()
    assert trainer.last_loss == pytest.approx(blurred, rel=1e-5)


def test_calibrated_needs_a_record(box, tmp_path, monkeypatch):
    monkeypatch.setenv("EDGEDOG_CACHE", str(tmp_path / "cache"))
    with pytest.raises(ConfigError, match="calibrate-detector --detector canny"):
        Trainer(box, tiny_config(map_correction="calibrated", detector="canny"), tmp_path / "c",
                progress=False)
