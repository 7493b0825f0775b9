"""`edgedog bench steps`: the profiler's windows over a whole run, and the per-stage table."""

from __future__ import annotations

import json

import pytest

from edgedog.bench.steps import STAGES, run_steps_bench, window_schedule
from edgedog.errors import ConfigError
from tests.helpers.tiny_runs import tiny_config


def test_the_recorded_steps_are_split_into_the_trainers_stages(small_box_scene, tmp_path):
    config = tiny_config(epochs=4)
    result = run_steps_bench(small_box_scene, tmp_path, "preview", config, windows=2, window_steps=3,
                             progress=False)
    assert result.steps == 6 and result.total_steps == 4 * 12  # 12 views, 4 epochs
    rows = {row["stage"]: row for row in result.rows()}
    assert list(rows) == [*STAGES, "rest of the step"]
    for stage in ("rasterize", "pixel uncertainty", "loss", "backward", "adam"):
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
