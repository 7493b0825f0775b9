"""`edgedog bench steps`: the profiler's windows over a whole run, and the per-stage table."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from edgedog.bench.steps import STAGES, StepProfile, markdown, run_steps_bench, window_schedule
from edgedog.errors import ConfigError
from tests.helpers.tiny_runs import tiny_config


def test_the_recorded_steps_are_split_into_the_trainers_stages(small_box_scene, tmp_path):
    config = tiny_config(epochs=4)
    result = run_steps_bench(small_box_scene, tmp_path, "preview", config, windows=2, window_steps=3,
                             progress=False)
    assert result.steps == 6 and result.total_steps == 4 * 12  # 12 views, 4 epochs
    rows = {row["stage"]: row for row in result.rows()}
    assert list(rows) == [*STAGES, "rest of the step"]
    for stage in ("rasterize", "loss", "backward", "adam"):
        assert rows[stage]["ms_per_step"] > 0, stage
    # The stages do not overlap: together they take at most the steps' time.
    assert rows["rest of the step"]["ms_per_step"] >= 0
    operators = [row["operator"] for row in result.top_operators(count=100)]
    assert "edgedog::rasterize_forward" in operators and "edgedog::rasterize_backward" in operators
    summary = json.loads((tmp_path / "steps.json").read_text())
    assert summary["recorded_steps"] == 6 and "| rasterize |" in (tmp_path / "steps.md").read_text()
    assert (tmp_path / "run" / "log.json").is_file()  # the run was trained to its end


@pytest.mark.parametrize("windows, steps", [(0, 3), (2, 0), (10, 5)])
def test_windows_that_do_not_fit_are_refused(windows, steps):
    with pytest.raises(ConfigError, match="bench steps"):
        window_schedule(48, windows, steps)


def test_a_gpu_windows_kernels_and_launches_are_told_apart_from_its_labels():
    """On a GPU the profiler's averages mix host operators, kernels, launches and the device's
    spans of the step's labels (which hold idle time): only kernels count as kernel time."""
    def event(key, count=1, cpu=0.0, self_cpu=0.0, device=0.0, self_device=0.0, annotation=False):
        return SimpleNamespace(key=key, count=count, cpu_time_total=cpu, self_cpu_time_total=self_cpu,
                               device_time_total=device, self_device_time_total=self_device,
                               is_user_annotation=annotation)

    profile = StepProfile(device=True)
    profile.add_window([
        event("ProfilerStep*", count=2, cpu=20_000),
        event("rasterize", count=2, cpu=6_000, self_cpu=500, device=9_000),  # the host's label
        event("rasterize", count=2, self_device=8_000, annotation=True),    # the device's span of it
        event("cudaLaunchKernel", count=300, cpu=3_000, self_cpu=3_000),
        event("aten::mul", count=40, cpu=800, self_cpu=700, device=50),
        event("forward_kernel", count=2, self_device=400),
        event("void at::native::vectorized_elementwise_kernel", count=40, self_device=50),
    ])
    summary = profile.to_dict()
    assert summary["launches_per_step"] == 150
    assert summary["kernel_ms_per_step"] == pytest.approx(0.225)  # (400 + 50) us over 2 steps
    assert [row["kernel"] for row in summary["kernels"]] == ["forward_kernel",
                                                             "void at::native::vectorized_elementwise_kernel"]
    assert {row["stage"]: row["ms_per_step"] for row in summary["stages"]}["rasterize"] == pytest.approx(3.0)
    assert "aten::mul" in [row["operator"] for row in summary["operators"]]
    assert "kernel launches" in markdown({**summary, "threads": 2})
