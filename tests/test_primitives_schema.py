"""The primitives' one schema: primitives.ply round trips (layer column included, files of the
previous writer byte for byte), raw <-> activated conversions, and extraction from memory."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import Primitives, activate

from edgedog.curves.config import ExtractConfig
from edgedog.curves.extract import extract_primitives, extract_run
from edgedog.primitives import (
    RAW,
    SCHEMA,
    VIEW_OPACITY,
    EdgePrimitives,
    PrimitiveArrays,
    read_ply,
    write_ply,
    write_point_columns,
)
from edgedog.train.model import GROUPS


def random_raw(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """One float32 array per raw parameter, as `EdgeModel.to_numpy` gives."""
    rng = np.random.default_rng(seed)
    raw = {"means": rng.normal(size=(n, 3)), "log_scales": rng.normal(-3.0, 1.0, (n, 3)),
           "quats": rng.normal(size=(n, 4)), "opacity_logits": rng.normal(0.0, 3.0, n),
           "k_raw": rng.normal(size=(n, 2))}
    return {name: values.astype(np.float32) for name, values in raw.items()}


def layered(n: int = 30, seed: int = 0) -> PrimitiveArrays:
    """Activated primitives of two layers (a third of them in layer 0)."""
    return PrimitiveArrays.from_raw(random_raw(n, seed), np.repeat([0, 1], [n // 3, n - n // 3]))


def assert_same(a: PrimitiveArrays, b: PrimitiveArrays) -> None:
    for field in dataclasses.fields(PrimitiveArrays):
        x, y = getattr(a, field.name), getattr(b, field.name)
        assert (x is None) == (y is None), field.name
        if x is not None:
            assert x.dtype == y.dtype and np.array_equal(x, y), field.name


def test_the_schema_names_the_trained_tensors_and_the_rasterizers_parameters():
    assert GROUPS == (*RAW, VIEW_OPACITY.raw)
    raster_fields = [f.name for f in dataclasses.fields(Primitives)]
    assert raster_fields == [*RAW, "colors"]
    arrays = [f.name for f in dataclasses.fields(PrimitiveArrays)]
    assert arrays[:len(SCHEMA)] == [p.activated for p in SCHEMA]


def test_ply_round_trip_keeps_every_value_and_the_layers(tmp_path):
    primitives = dataclasses.replace(layered(), uncertainty=np.linspace(0, 1, 30, dtype=np.float32))
    write_ply(tmp_path / "a.ply", primitives)
    back = read_ply(tmp_path / "a.ply")
    assert_same(back, primitives)
    assert back.layers.dtype == np.int64 and back.layers.tolist() == [0] * 10 + [1] * 20
    write_ply(tmp_path / "b.ply", back)
    assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()
    single = read_ply(write_ply(tmp_path / "c.ply", dataclasses.replace(primitives, layers=None)))
    assert single.layers is None and np.array_equal(single.means, primitives.means)


@pytest.mark.parametrize("layers", [None, np.repeat([0, 1, 2], 10)])
def test_files_of_the_previous_writer_read_back_and_rewrite_byte_for_byte(tmp_path, layers):
    raw = random_raw(30, seed=1)
    # The previous writer's columns, spelled out: activated values, k raw, a float32 layer last.
    scales, opacity = np.exp(raw["log_scales"]), 1 / (1 + np.exp(-raw["opacity_logits"]))
    columns = {"x": raw["means"][:, 0], "y": raw["means"][:, 1], "z": raw["means"][:, 2]}
    columns.update({f"scale_{i}": scales[:, i] for i in range(3)})
    columns.update({f"rot_{i}": raw["quats"][:, i] for i in range(4)})
    columns["opacity"] = opacity
    columns.update({f"k_{i}": raw["k_raw"][:, i] for i in range(2)})
    if layers is not None:
        columns["layer"] = layers
    old = write_point_columns(tmp_path / "old.ply", columns)
    read = read_ply(old)
    assert_same(read, PrimitiveArrays(raw["means"], scales, raw["quats"], opacity, raw["k_raw"], layers))
    assert write_ply(tmp_path / "new.ply", read).read_bytes() == old.read_bytes()


def test_activation_and_its_inverse(tmp_path):
    raw = random_raw(200, seed=2)
    arrays = PrimitiveArrays.from_raw(raw)
    for name, values in arrays.raw().items():
        # float32 logits of opacities near 1 keep about 3 decimals (1 - y has few bits left)
        np.testing.assert_allclose(values, raw[name], rtol=1e-4, atol=1e-3, err_msg=name)
    again = PrimitiveArrays.from_raw(arrays.raw())
    for p in SCHEMA:
        np.testing.assert_allclose(getattr(again, p.activated), getattr(arrays, p.activated), rtol=1e-6)
    # Saturated opacities come back as finite logits.
    assert np.isfinite(PrimitiveArrays.from_raw({**raw, "opacity_logits": np.full(200, 40.0)}).raw()
                       ["opacity_logits"]).all()


def test_activated_arrays_are_what_the_rasterizer_computes():
    raw = random_raw(50, seed=3)
    arrays = PrimitiveArrays.from_raw(raw)
    tensors = {name: torch.from_numpy(values) for name, values in raw.items()}
    mine = activate(Primitives(**tensors, colors=torch.ones(50, 1)), RasterConfig())
    np.testing.assert_allclose(arrays.scales, mine.scales.numpy(), rtol=1e-6)
    np.testing.assert_allclose(arrays.opacity, mine.opacity.numpy(), rtol=1e-6)


def test_edge_points_follow_the_largest_scale():
    n = 20
    rng = np.random.default_rng(4)
    scales = np.tile([0.002, 0.009, 0.003], (n, 1))  # the y axis is the longest
    angle = rng.uniform(0, np.pi, n)  # rotations about z: the y axis turns to (-sin, cos, 0)
    quats = np.stack([np.cos(angle / 2), 0 * angle, 0 * angle, np.sin(angle / 2)], axis=1)
    arrays = PrimitiveArrays(rng.normal(size=(n, 3)), scales, quats, np.full(n, 0.5), np.zeros((n, 2)))
    points = EdgePrimitives.from_arrays(arrays)
    np.testing.assert_allclose(points.directions, np.stack([-np.sin(angle), np.cos(angle), 0 * angle], 1),
                               atol=1e-12)
    np.testing.assert_allclose(points.elongation, 3.0)


def segment_arrays(seed: int = 5) -> PrimitiveArrays:
    """Float32 primitives along a 40 cm segment on the x axis, elongated along it, with a few
    faint ones off it and two layers."""
    rng = np.random.default_rng(seed)
    n = 400
    means = np.stack([np.linspace(-0.2, 0.2, n), np.zeros(n), np.zeros(n)], 1) + rng.normal(0, 0.001, (n, 3))
    opacity = np.where(np.arange(n) % 17 == 0, 0.05, 0.7)
    layers = (np.arange(n) >= n // 2).astype(np.int64)
    return PrimitiveArrays(means.astype(np.float32), np.tile(np.float32([0.006, 0.002, 0.002]), (n, 1)),
                           np.tile(np.float32([1, 0, 0, 0]), (n, 1)), opacity.astype(np.float32),
                           np.zeros((n, 2), np.float32), layers)


def test_extraction_from_memory_equals_extraction_from_the_ply(tmp_path):
    arrays = segment_arrays()
    write_ply(tmp_path / "primitives.ply", arrays)
    # nothing here needs a scene
    config = ExtractConfig(filter_projection=False, filter_silhouette=False, filter_contours=False,
                           complete_lines=False, complete_circles=False, complete_slides=False,
                           filter_drawing_plane=False)
    from_file = extract_run(tmp_path, config)
    in_memory = extract_primitives(EdgePrimitives.from_arrays(arrays), config)
    assert from_file.curves.num_curves >= 1 and from_file.counts["after_opacity"] < len(arrays)
    assert in_memory.counts == from_file.counts
    assert np.array_equal(in_memory.points.points, from_file.points.points)
    assert np.array_equal(in_memory.directions, from_file.directions)
    assert [c.tolist() for c in in_memory.curves.lines] == [c.tolist() for c in from_file.curves.lines]
    assert [c.tolist() for c in in_memory.curves.beziers] == [c.tolist() for c in from_file.curves.beziers]
    upper = extract_primitives(EdgePrimitives.from_arrays(arrays).in_layers({1}), config)
    assert upper.counts["primitives"] == len(arrays) // 2
    assert upper.counts == extract_run(tmp_path, config, layers={1}, out_dir=tmp_path / "L1").counts
