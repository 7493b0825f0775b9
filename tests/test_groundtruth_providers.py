"""Ground truth is found by providers, beside a scene's folder, never by the scene loaders."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from edgedog.commands import evaluate, info
from edgedog.errors import InputError
from edgedog.groundtruth import PROVIDERS, ground_truth_for
from edgedog.scenes import load_scene
from tests.helpers.scene_builders import make_emap, make_nerf

SCAN = "00000042"


def write_abc_cad(folder: Path, stats: bytes | None = None) -> Path:
    """An ABC object's CAD ground truth in `folder`: one sharp 1-unit curve along x, and the
    bbox statistics of the unit cube (or `stats` as they are)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{SCAN}_trimesh_001.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (folder / f"{SCAN}_features_001.yml").write_text("curves:\n  - sharp: true\n    vert_indices: [0, 1]\n")
    bbox = {SCAN: {"bbox": [0, 0, 0, 1, 1, 1, 1, 1, 1]}}
    (folder / "stats.json").write_bytes(json.dumps(bbox).encode() if stats is None else stats)
    return folder


def ply_header(vertices: int) -> str:
    return (f"ply\nformat ascii 1.0\nelement vertex {vertices}\n"
            "property float x\nproperty float y\nproperty float z\nend_header\n")


def test_the_abc_nef_layout_finds_the_cad_ground_truth(tmp_path):
    scene = make_nerf(tmp_path / SCAN)
    write_abc_cad(scene / "gt")
    source = ground_truth_for(load_scene(scene).root)
    assert source.scan_id == SCAN and source.features.name == f"{SCAN}_features_001.yml"
    points = source.load()
    # The one sharp curve, both ends included, resampled at the protocol's 0.005 step.
    np.testing.assert_allclose(points[[0, -1]], [[0, 0, 0], [1, 0, 0]], atol=1e-12)
    assert np.all(np.abs(np.diff(points[:, 0]) - 0.005) < 1e-4) and not points[:, 1:].any()


def test_the_emap_layout_finds_the_sampled_points_two_levels_up(tmp_path):
    scene = make_emap(tmp_path / "emap" / "data" / SCAN)
    sampled = tmp_path / "emap" / "groundtruth" / "sampled_pts"
    sampled.mkdir(parents=True)
    (sampled / f"{SCAN}_0.005.ply").write_text(ply_header(1) + "0.1 0.2 0.3\n")
    source = ground_truth_for(load_scene(scene).root)
    assert source.sampled_ply == (sampled / f"{SCAN}_0.005.ply").resolve()
    np.testing.assert_allclose(source.load(), [[0.1, 0.2, 0.3]], rtol=1e-6)


def run_command(module, argv: list[str]) -> None:
    """`edgedog ARGV` with only `module`'s command known."""
    parser = argparse.ArgumentParser()
    module.add_parser(parser.add_subparsers())
    args = parser.parse_args(argv)
    args.run(args)


def test_a_scene_without_ground_truth_has_none(tmp_path):
    scene = make_nerf(tmp_path / SCAN)
    write_abc_cad(tmp_path / "elsewhere" / "groundtruth")  # not where any provider looks
    assert ground_truth_for(scene) is None
    assert all(provider.find(scene, SCAN) is None for provider in PROVIDERS)
    rows = [line.split() for line in info.summary(load_scene(scene)).splitlines()]
    assert [row for row in rows if row[:2] == ["ground", "truth"]] == [["ground", "truth", "none"]]


def test_the_loader_does_not_look_only_ground_truth_for_reports_a_bad_file(tmp_path):
    scene = make_nerf(tmp_path / SCAN)
    stats = write_abc_cad(scene / "gt", stats=b"\xff\xfe\x00 not json") / "stats.json"
    loaded = load_scene(scene)  # the garbage is not the loader's business
    assert len(loaded) == 3 and not hasattr(loaded, "ground_truth")
    with pytest.raises(InputError, match="not a readable bbox statistics file") as error:
        ground_truth_for(loaded.root)
    assert error.value.path == stats and "\n" not in str(error.value)
    with pytest.raises(InputError, match="not a readable bbox statistics file"):
        info.summary(loaded)  # where a command asks for it


def test_an_explicit_gt_file_wins_over_the_scene(tmp_path):
    pred, gt = tmp_path / "pred.ply", tmp_path / "gt.ply"
    points = "".join(f"{x / 100:.2f} 0.5 0.5\n" for x in range(100))
    pred.write_text(ply_header(100) + points)
    gt.write_text(ply_header(100) + points)
    run_command(evaluate, ["eval", str(pred), "--gt", str(gt), "--no-voxel"])
    record = json.loads((tmp_path / "pred.ply.eval.json").read_text())
    assert record["ground_truth"] == str(gt) and record["metrics"]["acc_mm"] == pytest.approx(0.0)
