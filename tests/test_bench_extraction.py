"""`edgedog bench extraction`: two extraction settings on the same finished runs, scored in pairs,
without writing into the runs."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from edgedog.bench.extraction import Pair, compare, markdown, record, summary
from edgedog.cli import main
from edgedog.curves.config import ExtractConfig
from edgedog.primitives import PrimitiveArrays, write_ply
from edgedog.synthetic.features import sample_curve
from edgedog.synthetic.shapes import make_part
from edgedog.train.lifecycle import lock_folder

FLOATERS = 40
"""Primitives the synthetic run holds off the part, beside the sampled edges: what the silhouette
filter removes."""


@pytest.fixture(scope="module")
def bracket_scene(tmp_path_factory) -> Path:
    """The L-bracket (seed 0) as a scene: 12 views at 160 px with exact edge maps."""
    from edgedog.builtin.writer import write_scene

    return write_scene(tmp_path_factory.mktemp("bench-extraction") / "bracket", make_part("l-bracket"),
                       views=12, size=160, detector="exact")


def _write_run(folder: Path, scene: Path) -> Path:
    """A finished run's files: primitives every 5 mm along every ground-truth curve, and
    FLOATERS more in a line well outside the part (opaque: the filters that read the maps and
    the outlier statistics are switched off in the test, so that only the silhouette filter sees them)."""
    part = make_part("l-bracket")
    edges = np.concatenate([sample_curve(c) for c in part.curves])
    floaters = np.linspace([1.2, 1.2, 0.2], [1.2, 1.2, 0.8], FLOATERS)
    centres = np.concatenate([edges, floaters]).astype(np.float32)
    count = len(centres)
    folder.mkdir()
    write_ply(folder / "primitives.ply", PrimitiveArrays(
        means=centres, scales=np.tile(np.float32([0.004, 0.001, 0.001]), (count, 1)),
        quats=np.tile(np.float32([1, 0, 0, 0]), (count, 1)), opacity=np.full(count, 0.9, np.float32),
        k_raw=np.zeros((count, 2), np.float32)))
    (folder / "log.json").write_text(json.dumps({"scene": str(scene), "detector": "exact",
                                                 "config": {"maps": {"downscale": 1}}, "events": []}))
    (folder / "config.json").write_text("{}")
    return folder


def _digests(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def test_each_run_is_extracted_with_both_settings_beside_it_and_scored(bracket_scene, tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    run = _write_run(runs / "bracket_run", bracket_scene)
    before = _digests(run)
    base = ExtractConfig(filter_projection=False, filter_silhouette=False, filter_outliers="off",
                         filter_contours=False)
    variant = ExtractConfig(filter_projection=False, filter_outliers="off", filter_contours=False)
    lines = []
    pairs, notes = compare([runs], base, variant, tmp_path / "out", finished=lambda path: True,
                           progress=lines.append)
    assert notes == [] and len(pairs) == 1 and len(lines) == 1
    pair = pairs[0]
    assert pair.scene == "bracket"
    # The floaters cost the base precision, and only the base: the silhouette filter drops them.
    assert pair.variant["fscore_10mm"] > pair.base["fscore_10mm"]
    assert pair.variant["fscore_10mm"] > 95
    for side in ("base", "variant"):
        written = tmp_path / "out" / "runs" / "000-bracket_run" / side / "extract.json"
        report = json.loads(written.read_text())
        assert report["metrics"]["curves"]["fscore_10mm"] == pytest.approx(getattr(pair, side)["fscore_10mm"])
    assert _digests(run) == before  # the run is only read


def test_runs_not_finished_are_left_out_with_a_note(bracket_scene, tmp_path):
    run = _write_run(tmp_path / "run", bracket_scene)
    pairs, notes = compare([run], ExtractConfig(), ExtractConfig(), tmp_path / "out",
                           finished=lambda path: False)
    assert pairs == [] and notes == [f"{run} is not finished; left out"]


def _pair(name: str, base: dict, variant: dict) -> Pair:
    scores = ("fscore_5mm", "fscore_10mm", "fscore_20mm", "acc_mm", "comp_mm")
    return Pair(name, "scene", {k: base.get(k, 50.0) for k in scores},
                {k: variant.get(k, 50.0) for k in scores}, (3, 3))


def test_the_summary_pairs_the_runs_and_counts_in_each_scores_good_direction():
    pairs = [_pair("a", {"fscore_10mm": 90.0, "acc_mm": 3.0}, {"fscore_10mm": 92.0, "acc_mm": 4.0}),
             _pair("b", {"fscore_10mm": 80.0, "acc_mm": 5.0}, {"fscore_10mm": 79.0, "acc_mm": 2.0}),
             _pair("c", {"fscore_10mm": 85.0, "acc_mm": 4.0}, {"fscore_10mm": 85.02, "acc_mm": 4.0})]
    s = summary(pairs)
    f10 = s["fscore_10mm"]
    assert f10["base"][0] == pytest.approx(85.0) and f10["base"][1] == pytest.approx(5.0)
    differences = np.array([2.0, -1.0, 0.02])
    assert f10["difference"][0] == pytest.approx(differences.mean())
    assert f10["difference"][1] == pytest.approx(differences.std(ddof=1) / np.sqrt(3))
    assert (f10["better"], f10["worse"]) == (1, 1)  # c moved by less than CHANGE
    assert f10["worst"] == (80.0, 79.0)
    acc = s["acc_mm"]  # lower is better: a got worse, b better
    assert (acc["better"], acc["worse"]) == (1, 1)
    assert acc["worst"] == (5.0, 4.0)
    text = markdown(record(pairs, ["x is not finished; left out"], [], ["max_outside_pixels=3"]))
    assert "base (the defaults) against variant (max_outside_pixels=3)" in text
    assert "| F10 | 85.00 ± 5.00 |" in text and "- x is not finished; left out" in text


def test_the_command_refuses_a_folder_that_is_not_empty_and_folders_without_finished_runs(tmp_path, capsys):
    (tmp_path / "runs").mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["bench", "extraction", "--runs", str(tmp_path / "runs"), "--out", str(out)]) != 0
    error = capsys.readouterr().err.strip()
    assert "new or empty folder" in error and len(error.splitlines()) == 1
    new = tmp_path / "new"
    assert main(["bench", "extraction", "--runs", str(tmp_path / "runs"), "--out", str(new)]) != 0
    error = capsys.readouterr().err.strip()
    assert "no finished run" in error and len(error.splitlines()) == 1
    held = tmp_path / "held"
    with lock_folder(held):  # another bench is writing there
        assert main(["bench", "extraction", "--runs", str(tmp_path / "runs"), "--out", str(held)]) != 0
    error = capsys.readouterr().err.strip()
    assert "in use by another edgedog process" in error and len(error.splitlines()) == 1
