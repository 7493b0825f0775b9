"""Multi-granularity layers: levels, the layer stack, layered training, per-layer curves, the
figure and the studio's layer toggles."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest
import torch
from edgedog.app.inspection import inspect_view
from edgedog.app.layers import layer_members, list_new_layers, visible_subset
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.primitives import RasterCamera
from edgedog.renderer.rasterize import rasterize

from edgedog.edges.registry import make_detector
from edgedog.errors import ConfigError, InputError
from edgedog.scenes import load_scene
from edgedog.train.config import with_settings
from edgedog.train.layers import LowerLayers
from edgedog.train.levels import CANNY_LEVELS, PIDINET_LEVELS, parse_level, resolve_levels
from edgedog.train.model import GROUPS
from edgedog.train.trainer import Trainer, read_stack
from tests.helpers.cli_runner import edgedog
from tests.helpers.tiny_runs import every_fifth_view, tiny_config

LEVELS = ["--level", "L0=canny:150,300", "--level", "L1=canny:30,90"]
TINY = ["--set", "epochs=3", "--set", "downscale=4", "--set", "init_count=400", "--set", "init_side=0.8",
        "--set", "init_method=uniform", "--set", "duplicate_epochs=1", "--set", "cull_projection_epochs=",
        "--set", "cull_opacity_epochs=", "--set", "fisher_every=2", "--set", "opacity_from_epoch=0",
        "--set", "checkpoint_every=3"]






@pytest.fixture
def box(builtin_scene_dir):
    return every_fifth_view(builtin_scene_dir)


# --- levels
def test_default_levels_follow_the_available_weights(monkeypatch):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    assert resolve_levels(["L0", "L1", "L2"]) == CANNY_LEVELS
    assert resolve_levels(["L0", "L1"], weights="somewhere") == PIDINET_LEVELS[:2]
    custom = resolve_levels(["L0", "L1"], ["L1=canny:10,20@0.3"])
    assert custom[1].detector == "canny:10,20" and custom[1].floor == 0.3 and custom[1].index == 1


@pytest.mark.parametrize("names, specs, message", [
    (["L1", "L2"], [], "stack from L0 up"), (["L0", "L1", "L2", "L3"], [], "no level L3"),
    (["L0"], ["X=canny"], "NAME=DETECTOR"), (["L0"], ["L0=canny@high"], "floor"),
])
def test_bad_levels_are_one_line_errors(names, specs, message):
    with pytest.raises(ConfigError, match=message):
        resolve_levels(names, specs)


def test_canny_thresholds_make_coarser_maps():
    image = np.zeros((64, 96, 3), np.float32)
    image[:, 32:] = 0.15  # a weak step at x = 32
    image[:, 64:] = 1.0  # a strong one at x = 64
    strong, weak = make_detector("canny:150,300"), make_detector("canny:20,60")
    assert strong.name == "canny:150,300" and strong.fingerprint != weak.fingerprint
    strong_columns = np.flatnonzero(strong.detect(image).max(axis=0) > 0.5)
    weak_columns = np.flatnonzero(weak.detect(image).max(axis=0) > 0.5)
    # the strong threshold keeps only the strong step, the weak one finds the weak step too
    assert np.abs(strong_columns - 63).max() <= 2 and np.abs(weak_columns - 32).min() <= 2  # weak step found
    with pytest.raises(ConfigError, match="LOW,HIGH"):
        make_detector("canny:high")
    assert parse_level("L2=pidinet-multicue").floor == 0.0


# --- the stack
def test_the_stack_renders_like_its_concatenation(box, tmp_path):
    trainer = Trainer(box, tiny_config(), tmp_path, progress=False)
    lower = LowerLayers.empty().plus(trainer.model, 0)
    top = trainer.model
    camera = RasterCamera.from_camera(box.camera(0))
    stacked = rasterize(lower.stacked_with(top), camera, RasterConfig()).image
    both = lower.plus(top, 1)
    alone = rasterize(both.model.primitives(), camera, RasterConfig()).image
    torch.testing.assert_close(stacked, alone)
    assert both.layers.tolist() == [0] * len(top) + [1] * len(top)
    assert len(both.below(1)) == len(top)
    again = LowerLayers.from_numpy(both.to_numpy())
    assert torch.equal(again.layers, both.layers) and torch.equal(again.model.means, both.model.means)


@pytest.mark.parametrize("scale", [0.0, 0.5])
def test_lower_layers_stay_fixed_unless_fine_tuned(box, tmp_path, scale):
    first = Trainer(box, tiny_config(), tmp_path / "L0", progress=False)
    first.run()
    lower = first.stack()
    before = {name: getattr(lower.model, name).clone() for name in GROUPS}
    second = Trainer(box, tiny_config(layer=1, lower_lr_scale=scale), tmp_path / "L1", progress=False,
                     lower=lower)
    assert second.init_report["residual_filter"]["kept"] < second.init_report["residual_filter"]["candidates"]
    second.run()
    moved = not torch.equal(second.lower.model.means, before["means"])
    assert moved == (scale > 0)
    snapshot = second.snapshot()
    assert snapshot.layers.tolist() == [0] * len(lower) + [1] * len(second.model)
    assert np.isfinite(snapshot.means).all()
    # A resumed layer takes its lower layers from its checkpoint.
    resumed = Trainer(box, tiny_config(layer=1, lower_lr_scale=scale), tmp_path / "L1", progress=False)
    torch.testing.assert_close(resumed.lower.model.means, second.lower.model.means, rtol=0, atol=0)
    stack = read_stack(tmp_path / "L1")
    assert stack.layers.tolist() == snapshot.layers.tolist()


def test_residual_init_skips_edges_the_lower_layers_render(box, tmp_path):
    config = tiny_config(epochs=6, checkpoint_every=6)
    first = Trainer(box, config, tmp_path / "L0", progress=False)
    first.run()
    # Layer 1 on the same maps: most of its edges are rendered already by layer 0.
    same = Trainer(box, with_settings(config, {"layers.layer": 1}), tmp_path / "L1", progress=False,
                   lower=first.stack())
    fresh = Trainer(box, config, tmp_path / "fresh", progress=False)
    assert same.initial_count < fresh.initial_count


# --- layered runs from the command line
@pytest.fixture(scope="module")
def layered_run(builtin_scene_dir, tmp_path_factory):
    run = tmp_path_factory.mktemp("layered") / "run"
    result = edgedog("train", builtin_scene_dir, "--out", run, "--preset", "preview", "--layers", "L0,L1",
                     *LEVELS, *TINY, "--quiet")
    assert result.returncode == 0, result.stderr
    return run, result.stdout


@pytest.mark.slow
def test_layered_training_writes_every_layer_and_selection(layered_run):
    run, stdout = layered_run
    for name in ("L0", "L1", "curves/L0", "curves/L1", "curves/L0+L1"):
        assert (run / name).is_dir(), name
    report = json.loads((run / "layers_report.json").read_text())
    counts = {name: s["primitives"] for name, s in report["selections"].items()}
    assert counts["L0+L1"] == counts["L0"] + counts["L1"] and counts["L1"] > 0
    log = json.loads((run / "L1" / "log.json").read_text())
    assert log["lower_primitives"] == counts["L0"] and log["detector"] == "canny:30,90"
    assert log["config"]["layers"]["layer"] == 1
    assert "L0+L1" in stdout and '"layer": "L1"' in stdout


@pytest.mark.slow
def test_layered_run_resumes_extracts_and_exports(layered_run, builtin_scene_dir, tmp_path):
    run, _ = layered_run
    stamp = (run / "L1" / "checkpoint.pt").stat().st_mtime_ns
    resumed = edgedog("train", builtin_scene_dir, "--out", run, "--resume", "--quiet")
    assert resumed.returncode == 0, resumed.stderr
    assert (run / "L1" / "checkpoint.pt").stat().st_mtime_ns == stamp  # finished layers are reused
    again = edgedog("train", builtin_scene_dir, "--out", run, "--layers", "L0,L1")
    assert again.returncode == 2 and "pass --resume" in again.stderr
    extracted = edgedog("extract", run)
    assert extracted.returncode == 0 and "L0+L1" in extracted.stdout
    out = tmp_path / "l0.obj"
    exported = edgedog("export", run, "--format", "obj", "--layers", "L0", "--out", out)
    assert exported.returncode == 0, exported.stderr
    assert out.is_file()
    bad = edgedog("export", run, "--format", "obj", "--layers", "L7")
    assert bad.returncode == 2 and "no layer selection 'L7'" in bad.stderr
    wrong = edgedog("train", builtin_scene_dir, "--out", tmp_path / "x", "--layers", "L1,L2")
    assert wrong.returncode == 2 and "stack from L0 up" in wrong.stderr


@pytest.mark.slow
def test_a_layered_run_answers_the_record_api_as_its_layers_do(layered_run):
    """What the folder records and where each selection's curves are, with the bottom layer's
    log.json naming their scene; each layer is a run of one layer."""
    from edgedog.train.lifecycle import LAYERED_RUN, SINGLE_RUN, curves_of, read_record, record_kind

    run, _ = layered_run
    assert (record_kind(run), record_kind(run / "L1")) == (LAYERED_RUN, SINGLE_RUN)
    assert curves_of(run) == (run / "curves" / "L0+L1", run / "L0")
    assert read_record(run).curves_folder == run / "curves" / "L0+L1"
    assert curves_of(run, "L1") == (run / "curves" / "L1", run / "L0")
    assert curves_of(run / "L1") == (run / "L1", run / "L1")
    with pytest.raises(InputError, match="no layer selection 'L7'; choose from L0, L1, L0\\+L1"):
        curves_of(run, "L7")


@pytest.mark.slow
def test_a_layered_run_records_its_scene_and_resumes_only_on_it(layered_run, builtin_scene_dir,
                                                               small_box_scene, tmp_path):
    """layers.json and every layer's config.json hold the scene's fingerprint; --resume with a
    scene of other cameras or images is refused, a copy of the same scene elsewhere is fine."""
    run, _ = layered_run
    recorded = json.loads((run / "layers.json").read_text())["scene_fingerprint"]
    assert recorded and all(json.loads((run / name / "config.json").read_text())["scene_fingerprint"]
                            == recorded for name in ("L0", "L1"))
    other = edgedog("train", small_box_scene, "--out", run, "--resume", "--quiet")
    assert other.returncode == 2 and "other cameras or images" in other.stderr, other.stderr
    moved = tmp_path / "moved"
    shutil.copytree(builtin_scene_dir, moved)
    again = edgedog("train", moved, "--out", run, "--resume", "--quiet")
    assert again.returncode == 0, again.stderr


@pytest.mark.slow
def test_the_layers_figure_has_a_column_per_stack(layered_run):
    from edgedog.renderer.gl.context import GLUnavailableError

    from edgedog.bench.layers_figure import render_layers_figure
    from edgedog.train.layered import read_layered

    run, _ = layered_run
    layered = read_layered(run)
    scene = load_scene(layered.scene, downscale=layered.base.maps.downscale)
    try:
        path = render_layers_figure(layered, scene, run / "figure.png", size=160)
    except GLUnavailableError as error:
        pytest.skip(f"no headless OpenGL: {error}")
    figure = cv2.imread(str(path))
    assert figure.shape[1] == 2 * (160 + 4)
    splats = figure[:figure.shape[0] // 2, :160]
    assert (splats[30:] > 0).any()  # below the label: the L0 splats were drawn


# --- the studio's layer toggles
@pytest.mark.slow
def test_layer_toggles_select_primitives_in_the_render(layered_run):
    run, _ = layered_run
    from edgedog.train.layered import read_layered
    from edgedog.train.trainer import stack_snapshot

    layered = read_layered(run)
    snapshot = stack_snapshot(read_stack(run / "L1"))
    members = layer_members(snapshot)
    assert list(members) == ["L0", "L1"]
    shown = {"L0": True}
    list_new_layers(shown, snapshot)
    assert shown == {"L0": True, "L1": True}
    only_l0 = visible_subset(snapshot, {"L0": True, "L1": False})
    assert len(only_l0.means) == len(members["L0"]) and set(only_l0.layers) == {0}
    scene = load_scene(layered.scene, downscale=layered.base.maps.downscale)
    full = inspect_view(snapshot, scene, 0, None, RasterConfig(), "exp", True)
    base = inspect_view(only_l0, scene, 0, None, RasterConfig(), "exp", True)
    render = [p for p in full if p.name == "render"][0].rgba
    assert not np.array_equal(render, [p for p in base if p.name == "render"][0].rgba)


def test_layers_bench_compares_the_stack_with_the_direct_run(builtin_scene_dir, tmp_path):
    from edgedog.bench.layers import markdown, run_layers_bench
    from edgedog.errors import InputError

    levels = resolve_levels(["L0", "L1"], ["L0=canny:150,300", "L1=canny:30,90"])
    config = tiny_config()
    results = run_layers_bench(builtin_scene_dir, tmp_path, "preview", config, levels, progress=False,
                               figure=False)
    names = [row["selection"] for row in results["rows"]]
    assert names == ["L0", "L1", "L0+L1", "direct (L1 maps)"]
    direct = json.loads((tmp_path / "direct" / "log.json").read_text())
    assert direct["detector"] == "canny:30,90" and direct["config"]["layers"]["layer"] == 0
    table = (tmp_path / "layers.md").read_text()
    assert table == markdown(results) and "| direct (L1 maps) |" in table
    stamp = (tmp_path / "direct" / "checkpoint.pt").stat().st_mtime_ns
    again = run_layers_bench(builtin_scene_dir, tmp_path, "preview", config, levels, progress=False,
                             figure=False)
    assert again["rows"] == results["rows"]
    assert (tmp_path / "direct" / "checkpoint.pt").stat().st_mtime_ns == stamp  # reused, not retrained
    with pytest.raises(InputError, match="another scene or configuration"):
        run_layers_bench(builtin_scene_dir, tmp_path, "preview", with_settings(config, {"run.seed": 1}),
                         levels, progress=False, figure=False)
