"""Tests of our PiDiNet: exact PDC-to-conv conversion, the shipped BSDS weights (their hash, the
provided ABC-NEF PiDiNet maps reproduced with them, the default of 'auto'), the other official
checkpoints, and one-line errors for bad weight files."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import torch.nn.functional as F

from edgedog.edges import pidinet
from edgedog.edges.pidinet import (
    SHIPPED_SHA256,
    SHIPPED_WEIGHTS,
    WEIGHTS_MISSING,
    PidinetDetector,
    convert_pdc,
    load_pidinet,
    pidinet_weights,
    shipped_weights,
)
from edgedog.edges.registry import make_detector, require_detector
from edgedog.errors import InputError
from tests.helpers.paths import REPO, shared_path

URL = "https://github.com/hellozhuo/pidinet"


def _weights(name: str) -> Path:
    return shared_path(f"../models/pidinet/{name}")


@pytest.fixture(scope="module")
def bsds() -> PidinetDetector:
    """The shipped BSDS weights: these tests need no ../shared."""
    return PidinetDetector(shipped_weights())


# --- the PDC conversion, against an explicit pixel-difference reference ----------------------


def _shift(x: torch.Tensor, dy: int, dx: int) -> torch.Tensor:
    """(N, C, H, W) -> x[..., y + dy, x + dx] with zeros outside, as a zero-padded conv sees it."""
    padded = F.pad(x, (2, 2, 2, 2))
    h, w = x.shape[-2:]
    return padded[..., 2 + dy : 2 + dy + h, 2 + dx : 2 + dx + w]


def _weighted_differences(x, weight, pairs, groups):
    """sum_k w_k * (x[p + a_k] - x[p + b_k]): for each 3x3 kernel position k (raster order)
    `pairs[k]` = (a_k, b_k) offsets (dy, dx), b_k None for no subtraction; the products are 1x1
    convs, so channel mixing and groups behave as in the network."""
    out = 0
    for k, (a, b) in pairs.items():
        w = weight[:, :, k // 3, k % 3][:, :, None, None]
        difference = _shift(x, *a) if b is None else _shift(x, *a) - _shift(x, *b)
        out = out + F.conv2d(difference, w, groups=groups)
    return out


_OFFSETS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]  # raster order


def _reference_pdc(kind, x, weight, groups):
    """The paper's pixel-difference convolutions, written out pair by pair."""
    if kind == "cv":  # no differences: a plain 3x3 conv
        return _weighted_differences(x, weight, {k: (o, None) for k, o in enumerate(_OFFSETS)}, groups)
    if kind == "cd":  # each neighbour minus the centre
        return _weighted_differences(x, weight, {k: (o, (0, 0)) for k, o in enumerate(_OFFSETS)}, groups)
    if kind == "ad":  # each ring pixel minus the next one clockwise; the centre weight is unused
        ring = [(-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1)]
        pairs = {_OFFSETS.index(p): (p, ring[(i + 1) % 8]) for i, p in enumerate(ring)}
        return _weighted_differences(x, weight, pairs, groups)
    if kind == "rd":  # direction k (raster order, no centre): pixel at distance 2 minus distance 1,
        # weighted by W.flat[k + 1] as in the official code (W.flat[0] is unused)
        directions = [o for o in _OFFSETS if o != (0, 0)]
        pairs = {k + 1: ((2 * dy, 2 * dx), (dy, dx)) for k, (dy, dx) in enumerate(directions)}
        return _weighted_differences(x, weight, pairs, groups)
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", ["cd", "ad", "rd", "cv"])
@pytest.mark.parametrize("in_ch, out_ch, groups", [(3, 5, 1), (6, 6, 6)])  # init_block, depthwise
def test_converted_pdc_equals_pixel_differences(kind, in_ch, out_ch, groups):
    gen = torch.Generator().manual_seed(7)
    x = torch.randn(2, in_ch, 13, 11, generator=gen)
    weight = torch.randn(out_ch, in_ch // groups, 3, 3, generator=gen)
    kernel = convert_pdc(kind, weight)
    assert kernel.shape[-1] == (5 if kind == "rd" else 3)
    plain = F.conv2d(x, kernel, padding=kernel.shape[-1] // 2, groups=groups)
    torch.testing.assert_close(plain, _reference_pdc(kind, x, weight, groups), rtol=0, atol=1e-5)


def test_convert_pdc_leaves_the_trained_kernel_alone():
    weight = torch.randn(4, 1, 3, 3)
    before = weight.clone()
    for kind in ("cd", "ad", "rd", "cv"):
        convert_pdc(kind, weight)
    assert torch.equal(weight, before)


def test_network_runs_only_plain_convolutions():
    model = load_pidinet(SHIPPED_WEIGHTS)
    assert not model.training
    leaf_types = {type(m) for m in model.modules() if not list(m.children())}
    assert leaf_types == {torch.nn.Conv2d}
    # carv4: cd, ad, rd, cv repeating from init_block; rd became 5x5 with padding 2.
    assert model.init_block.kernel_size == (3, 3)
    assert model.block1_2.conv1.kernel_size == (5, 5) and model.block1_2.conv1.padding == (2, 2)
    assert model.block4_3.conv1.kernel_size == (5, 5)
    assert model.block4_4.conv1.kernel_size == (3, 3)


# --- the shipped BSDS weights ----------------------------------------------------------------


def test_the_shipped_weights_are_the_official_bsds_file_with_its_licence():
    import hashlib
    import importlib.resources

    import tomllib

    resource = importlib.resources.files("edgedog.edges") / "weights"
    assert Path(str(resource / "table5_pidinet.pth")) == SHIPPED_WEIGHTS
    # The official table5_pidinet.pth of github.com/hellozhuo/pidinet, 2871148 bytes.
    data = (resource / "table5_pidinet.pth").read_bytes()
    assert len(data) == 2_871_148
    assert hashlib.sha256(data).hexdigest() == SHIPPED_SHA256 == (
        "80860ac267258b5f27486e0ef152a211d0b08120f62aeb185a050acc30da486c")
    licence = (resource / "LICENSE").read_text()
    assert "Copyright (c) 2021 Zhuo Su" in licence and "Permission is hereby granted" in licence
    # Both go into the wheel: listed as package data of edgedog.edges.
    package_data = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert sorted(package_data["edgedog.edges"]) == ["weights/LICENSE", "weights/table5_pidinet.pth"]


def test_without_configured_weights_pidinet_and_auto_use_the_shipped_ones(monkeypatch, tmp_path):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    assert pidinet_weights("bsds", None) == SHIPPED_WEIGHTS
    for name in ("auto", "pidinet", "pidinet:side2"):
        require_detector(name)
        detector = make_detector(name)
        assert isinstance(detector, PidinetDetector) and detector.weights == SHIPPED_WEIGHTS
    assert make_detector("auto").name == "pidinet"
    # Only the BSDS weights ship: the other training sets still need theirs.
    with pytest.raises(InputError, match="edgedog ships only the BSDS ones"):
        require_detector("pidinet-nyud")
    # --weights and $EDGEDOG_PIDINET override the shipped file (here with a file of another name).
    other = tmp_path / "mine.pth"
    other.write_bytes(SHIPPED_WEIGHTS.read_bytes())
    assert make_detector("auto", other).weights == other
    monkeypatch.setenv("EDGEDOG_PIDINET", str(other))
    assert make_detector("pidinet").weights == other


class _Unpickled:
    """Leaves a file behind when unpickled: proof that a weights file was read by pickle."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (Path.touch, (self.marker,))


@pytest.mark.parametrize("damage", ["truncated", "another network", "a pickle that runs code", "missing"])
def test_a_damaged_or_replaced_shipped_file_is_one_line_and_never_unpickled(tmp_path, monkeypatch, damage):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    marker = tmp_path / "unpickled"
    replaced = tmp_path / "table5_pidinet.pth"
    if damage == "truncated":
        replaced.write_bytes(SHIPPED_WEIGHTS.read_bytes()[:-1000])
    elif damage == "another network":  # a valid checkpoint, not ours
        torch.save({"state_dict": {"init_block.weight": torch.zeros(60, 3, 3, 3)}}, replaced)
    elif damage == "a pickle that runs code":
        torch.save({"state_dict": _Unpickled(marker)}, replaced)
    monkeypatch.setattr(pidinet, "SHIPPED_WEIGHTS", replaced)
    for build in (lambda: make_detector("auto"), lambda: require_detector("pidinet")):
        with pytest.raises(InputError) as info:
            build()
        message = _one_line(info.value)
        assert message.startswith(f"{replaced}: ") and "reinstall edgedog" in message
        if damage != "missing":
            assert SHIPPED_SHA256[:16] in message
    assert not marker.exists()


# --- reproducing the provided ABC-NEF PiDiNet maps -------------------------------------------


@pytest.mark.parametrize("view", [0, 24, 49])  # spread over the 50 training views
def test_reproduces_the_abc_nef_pidinet_maps(bsds, view):
    scene = shared_path("abc_nef/00000006")
    image_path = scene / "train_img" / f"{view}_colors.png"
    map_path = scene / "train" / f"{view}_colors.png"
    if not (image_path.is_file() and map_path.is_file()):
        pytest.skip(f"shared data not present: {image_path}")
    rgba = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED)
    assert rgba.shape[2] == 4
    rgb = cv2.cvtColor(rgba[..., :3], cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0  # alpha dropped
    provided = cv2.imread(str(map_path), cv2.IMREAD_UNCHANGED).astype(np.int32)

    edges = bsds.detect(rgb)
    assert edges.shape == provided.shape and edges.dtype == np.float32

    rounded = np.abs(np.round(255.0 * edges).astype(np.int32) - provided)
    assert (rounded <= 2).mean() >= 0.999
    # The provided maps truncate (uint8(255 p)): then all but float-noise pixels match exactly.
    truncated = np.abs(np.floor(255.0 * edges).astype(np.int32) - provided)
    assert (truncated == 0).mean() >= 0.99
    assert (truncated <= 1).mean() >= 0.999


# --- all official checkpoints, outputs -------------------------------------------------------


@pytest.mark.parametrize(
    "name, channels, dil",
    [
        ("table5_pidinet.pth", 60, 24),
        ("table5_pidinet-small.pth", 30, 12),
        ("table5_pidinet-tiny.pth", 20, 8),
        ("table6_pidinet.pth", 60, 24),
        ("table7_pidinet.pth", 60, 24),
    ],
)
def test_official_checkpoints_load_and_detect(name, channels, dil):
    detector = PidinetDetector(_weights(name))
    assert (detector.model.channels, detector.model.dil) == (channels, dil)
    image = np.random.default_rng(0).random((45, 70, 3), dtype=np.float32)  # not a multiple of 8
    edges = detector.detect(image)
    assert edges.shape == (45, 70) and edges.dtype == np.float32
    assert np.isfinite(edges).all() and edges.min() >= 0.0 and edges.max() <= 1.0


def test_side_outputs_are_selectable(bsds):
    weights = bsds.weights
    image = np.random.default_rng(1).random((40, 56, 3), dtype=np.float32)
    maps = {"fused": bsds.detect(image)}
    for output in ("side1", "side2", "side3", "side4"):
        detector = PidinetDetector(weights, output=output)
        assert detector.fingerprint.endswith(f"-{output}")
        maps[output] = detector.detect(image)
        assert maps[output].shape == (40, 56) and 0.0 <= maps[output].min() <= maps[output].max() <= 1.0
    names = list(maps)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not np.allclose(maps[a], maps[b]), (a, b)
    with pytest.raises(ValueError, match="side5"):
        PidinetDetector(weights, output="side5")


def test_fingerprint_and_name(bsds):
    import hashlib

    digest = hashlib.sha256(bsds.weights.read_bytes()).hexdigest()[:12]
    assert bsds.fingerprint == f"pidinet-{digest}-fused"
    assert bsds.name == "pidinet"


def test_detect_rejects_a_grey_image(bsds):
    with pytest.raises(ValueError, match="RGB"):
        bsds.detect(np.zeros((8, 8), np.float32))


# --- resolving and loading weight files: one-line errors -------------------------------------


def _one_line(error: InputError) -> str:
    message = str(error)
    assert "\n" not in message
    return message


def test_missing_file_names_the_path_and_the_url(tmp_path):
    missing = tmp_path / "nope.pth"
    with pytest.raises(InputError) as info:
        load_pidinet(missing)
    message = _one_line(info.value)
    assert message.startswith(f"{missing}: ") and URL in message and "EDGEDOG_PIDINET" in message


def test_corrupt_file_is_a_one_line_error(tmp_path):
    corrupt = tmp_path / "table5_pidinet.pth"
    corrupt.write_bytes(b"\x80\x02 this is not a checkpoint" * 10)
    with pytest.raises(InputError) as info:
        PidinetDetector(corrupt)
    assert _one_line(info.value).startswith(f"{corrupt}: ")


def test_truncated_checkpoint_is_a_one_line_error(tmp_path):
    truncated = tmp_path / "table5_pidinet.pth"
    truncated.write_bytes(SHIPPED_WEIGHTS.read_bytes()[:100_000])
    with pytest.raises(InputError) as info:
        load_pidinet(truncated)
    assert _one_line(info.value).startswith(f"{truncated}: ")


@pytest.mark.parametrize(
    "content",
    [
        {"epoch": 1, "state_dict": {"module.conv.weight": torch.zeros(8, 3, 3, 3)}},  # another net
        {"epoch": 1, "state_dict": {"module.init_block.weight": torch.zeros(8, 3, 3, 3)}},  # partial
        [1, 2, 3],  # not a dict at all
    ],
)
def test_another_network_is_a_one_line_error(tmp_path, content):
    path = tmp_path / "other.pth"
    torch.save(content, path)
    with pytest.raises(InputError, match="not a PiDiNet") as info:
        load_pidinet(path)
    assert _one_line(info.value).startswith(f"{path}: ")


def test_checkpoint_with_an_extra_key_is_rejected(tmp_path):
    state = torch.load(_weights("table5_pidinet-tiny.pth"), weights_only=True)["state_dict"]
    state["module.extra.weight"] = torch.zeros(1)
    path = tmp_path / "extra.pth"
    torch.save({"epoch": 0, "state_dict": state}, path)
    with pytest.raises(InputError, match="extra.weight"):
        load_pidinet(path)


def test_weights_resolution(tmp_path, monkeypatch):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    folder = tmp_path / "models"
    folder.mkdir()
    for name in ("table5_pidinet.pth", "table6_pidinet.pth", "table7_pidinet.pth"):
        (folder / name).write_bytes(b"x")

    explicit = folder / "table6_pidinet.pth"
    assert pidinet_weights("bsds", explicit) == explicit  # an explicit file wins over the variant
    assert pidinet_weights("bsds", str(folder)) == folder / "table5_pidinet.pth"
    assert pidinet_weights("nyud", folder) == folder / "table6_pidinet.pth"
    assert pidinet_weights("multicue", folder) == folder / "table7_pidinet.pth"

    monkeypatch.setenv("EDGEDOG_PIDINET", str(folder))
    assert pidinet_weights("multicue", None) == folder / "table7_pidinet.pth"
    monkeypatch.setenv("EDGEDOG_PIDINET", str(explicit))
    assert pidinet_weights("bsds", None) == explicit
    assert pidinet_weights("bsds", folder / "table5_pidinet.pth") == folder / "table5_pidinet.pth"

    with pytest.raises(ValueError, match="unknown PiDiNet variant"):
        pidinet_weights("hed", folder)


@pytest.mark.parametrize("where", ["argument", "environment", "nowhere"])
def test_weights_not_found_names_the_path_and_the_url(tmp_path, monkeypatch, where):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    empty = tmp_path / "empty"
    empty.mkdir()
    if where == "environment":
        monkeypatch.setenv("EDGEDOG_PIDINET", str(empty))
    with pytest.raises(InputError) as info:
        pidinet_weights("nyud", empty if where == "argument" else None)
    message = _one_line(info.value)
    assert message.endswith(WEIGHTS_MISSING) and URL in message
    expected = Path("table6_pidinet.pth") if where == "nowhere" else empty / "table6_pidinet.pth"
    assert info.value.path == expected
