"""The CUDA backend. Everywhere: how a device is chosen and refused. On a machine with a GPU and
a CUDA build (the CUDA tests skip elsewhere, CI included): the CUDA kernels against the CPU
kernels on a scene larger than the reference can render, and a seeded short training run whose
scores match the CPU's within the seeds' spread. The kernels' parity with the float64 reference
is in test_rasterizer.py and test_rasterizer_hard_cases.py, which run on every device.
"""

from __future__ import annotations

import json

import pytest
import torch
from edgedog.renderer import ops
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.ops import kernel_devices, resolve_device
from edgedog.renderer.primitives import RasterCamera, activate
from edgedog.renderer.rasterize import fisher_information, rasterize

from edgedog.errors import ConfigError
from tests.helpers.backends import on_device
from tests.helpers.cli_runner import edgedog
from tests.helpers.paths import shared_path
from tests.helpers.raster_builders import random_primitives

HAS_CUDA = "cuda" in kernel_devices()
PARAMETERS = ("means", "log_scales", "quats", "opacity_logits", "k_raw")
needs_cuda = pytest.mark.skipif(not HAS_CUDA, reason="no CUDA kernels here (a CUDA build and a GPU)")


def test_auto_is_cuda_exactly_when_it_has_kernels():
    assert resolve_device("cpu") == torch.device("cpu")
    assert resolve_device("auto").type == ("cuda" if HAS_CUDA else "cpu")
    if HAS_CUDA:
        assert resolve_device("cuda") == torch.empty(0, device="cuda").device  # with its index
    else:
        with pytest.raises(ConfigError, match="device 'cuda' asked for, but "):
            resolve_device("cuda")


@pytest.mark.skipif(HAS_CUDA, reason="the refusal needs a machine without CUDA kernels")
def test_train_refuses_cuda_here_in_one_line_writing_nothing(tmp_path):
    scene, out = tmp_path / "scene", tmp_path / "run"
    scene.mkdir()
    result = edgedog("train", scene, "--out", out, "--device", "cuda")
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "device 'cuda' asked for, but" in lines[0], result.stderr
    assert not out.exists()


def _camera(width: int, height: int) -> RasterCamera:
    K = torch.tensor([[1.2 * width, 0, (width - 1) / 2], [0, 1.2 * width, (height - 1) / 2], [0, 0, 1]],
                     dtype=torch.float64)
    w2c = torch.eye(4, dtype=torch.float64)
    w2c[:3, 3] = torch.tensor([-0.5, -0.5, 2.0], dtype=torch.float64)
    return RasterCamera(K, w2c, width, height)


def _render(prims, camera, config, cotangent):
    """image, alpha, depth, the parameters' gradients of <image, cotangent>, and the Fisher scores."""
    out = rasterize(prims, camera, config)
    (out.image * cotangent.to(out.image.device)).sum().backward()
    grads = [getattr(prims, name).grad for name in PARAMETERS]
    fisher = fisher_information(prims, [camera], config)
    return [out.image, out.alpha, out.depth, out.absgrad.value, *grads, fisher]


@needs_cuda
@pytest.mark.parametrize("kernel,channels", [("dog", 1), ("gaussian", 3)])
def test_cuda_kernels_match_the_cpu_kernels_on_thousands_of_primitives(kernel, channels):
    """3,000 primitives over 320x240 px (a few hundred per tile where they crowd): every output,
    gradient and Fisher score within 1e-4 of its scale of the CPU kernels' (float32 both; the
    CUDA kernels use the device's exp and sum with atomics)."""
    config = RasterConfig(kernel=kernel, background=(0.1,) * channels)
    host = random_primitives(3000, channels, seed=3, spread=0.15, dtype=torch.float32)
    camera = _camera(320, 240)
    cotangent = torch.randn(240, 320, channels, generator=torch.Generator().manual_seed(0))
    on_cpu = _render(on_device(host, "cpu", leaves=True), camera, config, cotangent)
    on_gpu = _render(on_device(host, "cuda", leaves=True), camera, config, cotangent)
    assert (on_cpu[1] > 0.5).sum() > 5000  # a crowded render, not an empty one
    names = ("image", "alpha", "depth", "absgrad", *PARAMETERS, "fisher")
    for name, expected, actual in zip(names, on_cpu, on_gpu):
        if expected is None:  # k_raw of the gaussian kernel: no gradient on either device
            assert actual is None and name == "k_raw" and kernel == "gaussian"
            continue
        assert actual.device.type == "cuda", name
        scale = max(expected.abs().max().item(), 1e-12)
        torch.testing.assert_close(actual.cpu(), expected, rtol=0, atol=1e-4 * scale,
                                   msg=lambda m: f"{name}: {m}")


@needs_cuda
def test_cuda_tile_lists_equal_the_cpu_lists():
    """Same projected inputs, the same lists to the entry (depth ties in index order)."""
    host = random_primitives(5000, 1, seed=4, spread=0.2, dtype=torch.float32)
    camera = _camera(400, 300)
    act = activate(host, RasterConfig())
    means2d, _, depths, extents, valid = ops.project(host.means, act.scales, host.quats, act.support_q,
                                                     camera, 0.3)
    depths[100:200] = depths[50]  # ties
    lists = [ops.tile_lists(*(x.to(device) for x in (means2d, depths, extents, valid)), 400, 300)
             for device in ("cpu", "cuda")]
    assert lists[0][1].numel() > 10000
    for cpu, cuda in zip(*lists):
        assert torch.equal(cpu, cuda.cpu())


def _train_f10(scene, out, device: str, seed: int) -> float:
    result = edgedog("train", scene, "--out", out, "--preset", "quick", "--device", device, "--quiet",
                     "--set", "epochs=20", "--set", f"seed={seed}")
    assert result.returncode == 0, result.stderr
    log = json.loads((out / "log.json").read_text())
    assert log["device"].startswith(device)
    return json.loads((out / "extract.json").read_text())["metrics"]["curves"]["fscore_10mm"]


@needs_cuda
@pytest.mark.slow
@pytest.mark.shared_data
def test_a_seeded_short_run_on_cuda_scores_as_on_the_cpu(tmp_path):
    """`quick` cut to 20 epochs on 00000006, seed 0 on CUDA against seeds 0 and 1 on the CPU:
    F10 within the CPU seeds' spread of their mean (at least 2 points: two seeds understate it)."""
    scene = shared_path("abc_nef/00000006")
    cpu = [_train_f10(scene, tmp_path / f"cpu{seed}", "cpu", seed) for seed in (0, 1)]
    cuda = _train_f10(scene, tmp_path / "cuda0", "cuda", 0)
    spread = max(abs(cpu[0] - cpu[1]), 2.0)
    assert abs(cuda - sum(cpu) / 2) <= spread, (cuda, cpu)
