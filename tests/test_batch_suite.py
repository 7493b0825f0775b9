"""Benchmark suites (`edgedog batch`): the YAML file's checks, its expansion into runs and their
folder names, and the tables' means and spreads."""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path

import pytest

from edgedog.batch.outcome import RunOutcome
from edgedog.batch.suite import MAX_RUNS, RunSpec, expand, load_suite
from edgedog.batch.table import (
    across_scenes,
    configuration_rows,
    csv_text,
    markdown,
    mean_and_spread,
    run_rows,
)
from edgedog.errors import ConfigError, InputError
from edgedog.train.config import preset, with_overrides
from tests.helpers.bad_inputs import edgedog_in_process

ABLATION = """\
scenes: [scenes/*]
presets: [preview, fast]
grid:
  weighting: [exp_neg, exp]
  opacity_from_epoch: [0, 3]
rows:
  full: []
  no-fisher: [primitive_uncertainty=false]
seeds: [0, 7]
set: [init_count=300]
"""


def write(folder: Path, text: str, name: str = "suite.yaml") -> Path:
    (folder / name).write_text(text)
    return folder / name


@pytest.fixture
def scenes(tmp_path) -> list[Path]:
    """Two (empty) scene folders under tmp_path/scenes and a file the glob must leave out."""
    folders = [tmp_path / "scenes" / name for name in ("b_scene", "a scene")]
    for folder in folders:
        folder.mkdir(parents=True)
    (tmp_path / "scenes" / "notes.txt").write_text("not a scene")
    return sorted(folders)


def test_a_suite_reads_with_globs_relative_to_its_file(tmp_path, scenes, monkeypatch):
    monkeypatch.chdir(scenes[0])  # the working folder plays no part
    suite = load_suite(write(tmp_path, ABLATION))
    assert suite.scenes == tuple(folder.resolve() for folder in scenes)
    assert suite.presets == ("preview", "fast")
    assert suite.grid == (("weighting", ("exp_neg", "exp")), ("opacity_from_epoch", ("0", "3")))
    assert suite.rows == (("full", ()), ("no-fisher", ("primitive_uncertainty=false",)))
    assert suite.seeds == (0, 7) and suite.common == ("init_count=300",)


def test_defaults_and_duplicates(tmp_path, scenes):
    suite = load_suite(write(tmp_path, "scenes: ['scenes/*', 'scenes/a scene']\nseeds: [3, 3]\n"))
    assert suite.scenes == tuple(scenes) and suite.presets == ("full",) and suite.seeds == (3,)
    assert suite.grid == () and suite.rows == () and suite.common == ()
    specs = expand(suite)
    assert [spec.overrides for spec in specs] == [("seed=3",), ("seed=3",)]
    assert [spec.row for spec in specs] == [None, None]


def test_expansion_is_every_combination_in_a_fixed_order(tmp_path, scenes):
    suite = load_suite(write(tmp_path, ABLATION))
    specs = expand(suite)
    assert len(specs) == 2 * 2 * 2 * 2 * 2 * 2
    assert specs == expand(load_suite(suite.path))  # the same file gives the same runs
    first, second = specs[0], specs[1]
    assert first.scene == scenes[0].resolve() and first.preset == "preview" and first.row == "full"
    assert first.overrides == ("init_count=300", "weighting=exp_neg", "opacity_from_epoch=0", "seed=0")
    assert first.changes == ("weighting=exp_neg", "opacity_from_epoch=0")
    assert second.overrides == first.overrides[:-1] + ("seed=7",)  # seeds vary fastest
    assert specs[2].row == "no-fisher"
    assert specs[2].overrides[-2:] == ("primitive_uncertainty=false", "seed=0")
    # Names: unique, filesystem-safe, the seed last; seeds of one configuration share its name.
    assert len({spec.name for spec in specs}) == len(specs)
    assert first.name == f"{first.configuration}_seed0" and second.configuration == first.configuration
    assert first.name.startswith("a-scene_preview_full_") and " " not in first.name
    assert len({spec.configuration for spec in specs}) == len(specs) // 2
    # A different override is a different folder; the seeds' list is not part of the name.
    other = load_suite(write(tmp_path, ABLATION.replace("init_count=300", "init_count=301"), "other.yaml"))
    assert expand(other)[0].name != first.name
    reseeded = load_suite(write(tmp_path, ABLATION.replace("[0, 7]", "[0]"), "reseeded.yaml"))
    assert expand(reseeded)[0].name == first.name


def test_a_run_spec_builds_its_config_from_the_preset(tmp_path, scenes):
    specs = expand(load_suite(write(tmp_path, ABLATION)))
    expected = ["init_count=300", "weighting=exp_neg", "opacity_from_epoch=0", "primitive_uncertainty=false",
                "seed=7"]
    assert specs[3].config() == with_overrides(preset("preview"), expected)  # no-fisher, seed 7
    assert specs[3].config() != specs[2].config()


def test_runs_are_capped(tmp_path, scenes):
    values = ", ".join(str(n) for n in range(1, 101))
    path = write(tmp_path, f"scenes: [scenes/*]\ngrid:\n  epochs: [{values}]\n  init_count: [{values}]\n")
    with pytest.raises(InputError, match=f"{path}: expands to 20000 runs, more than {MAX_RUNS}"):
        expand(load_suite(path))
    with pytest.raises(InputError, match="expands to 20000 runs, more than 100;"):
        expand(load_suite(path), limit=100)


def test_scenes_of_one_name_in_two_parents_are_refused(tmp_path):
    for parent in ("x", "y"):
        (tmp_path / parent / "box").mkdir(parents=True)
    path = write(tmp_path, "scenes: ['*/box']\n")
    with pytest.raises(InputError, match="have one folder name"):
        expand(load_suite(path))


@pytest.mark.parametrize(("text", "words"), [
    ("scenes: [scenes/*\n", "invalid YAML"),
    ("- scenes\n", "expected a mapping"),
    ("scenes: [scenes/*]\nseed: [1]\n", "unknown key 'seed'"),
    ("presets: [fast]\n", "'scenes' is missing"),
    ("scenes: scenes/*\n", "'scenes' must be a non-empty list"),
    ("scenes: []\n", "'scenes' must be a non-empty list"),
    ("scenes: [nowhere]\n", "scenes: 'nowhere' is not a folder"),
    ("scenes: ['nowhere/*']\n", "scenes: 'nowhere/*' matches no folder"),
    ("scenes: [scenes/*]\npresets: [fastest]\n", "presets: unknown preset 'fastest'"),
    ("scenes: [scenes/*]\ngrid: [epochs]\n", "'grid' must map settings"),
    ("scenes: [scenes/*]\ngrid:\n  epochs: 3\n", "grid.epochs: expected a non-empty list"),
    ("scenes: [scenes/*]\ngrid:\n  epochz: [3]\n", "grid.epochz: --set 'epochz=3': unknown setting"),
    ("scenes: [scenes/*]\ngrid:\n  epochs: [0]\n", "grid.epochs: --set 'epochs=0'"),
    ("scenes: [scenes/*]\nrows:\n  'a b': []\n", "rows: name 'a b'"),
    ("scenes: [scenes/*]\nrows:\n  r: [kernel=round]\n", "rows.r: --set 'kernel=round'"),
    ("scenes: [scenes/*]\nrows:\n  r: kernel=dog\n", "'rows.r' must be a list of strings"),
    ("scenes: [scenes/*]\nset: [seed=4]\n", "set: --set 'seed=4': list seeds under the suite's 'seeds'"),
    ("scenes: [scenes/*]\nseeds: [-1]\n", "seeds: -1 is not an integer"),
    ("scenes: [scenes/*]\nseeds: [true]\n", "seeds: True is not an integer"),
    ("scenes: [scenes/*]\nseeds: []\n", "'seeds' must be a non-empty list"),
    ("scenes: [scenes/*]\nset: [epochs]\n", "set: --set 'epochs': expected KEY=VALUE"),
])
def test_a_bad_suite_is_one_error_naming_the_file_and_the_key(tmp_path, scenes, text, words):
    path = write(tmp_path, text)
    with pytest.raises(InputError) as error:
        load_suite(path)
    message = str(error.value)
    assert message.startswith(f"{path}: ") and words in message and "\n" not in message


def test_command_line_overrides_follow_the_suites_set(tmp_path, scenes):
    path = write(tmp_path, ABLATION)
    suite = load_suite(path, ("epochs=3",))
    assert suite.common == ("init_count=300", "epochs=3")
    assert expand(suite)[0].overrides[:2] == ("init_count=300", "epochs=3")
    assert expand(suite)[0].name != expand(load_suite(path))[0].name
    with pytest.raises(ConfigError, match="^--set 'epochz=3': unknown setting"):
        load_suite(path, ("epochz=3",))
    with pytest.raises(ConfigError, match="^--set 'seed=3': list seeds under the suite's 'seeds'"):
        load_suite(path, ("seed=3",))


def test_a_missing_suite_file(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        load_suite(tmp_path / "absent.yaml")


def test_without_ray_the_command_says_how_to_install_it(tmp_path, scenes, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    write(tmp_path, "scenes: [scenes/*]\n")
    result = edgedog_in_process(["batch", "suite.yaml", "--out", "out"], tmp_path)
    assert result.returncode == 2
    assert result.stderr == ("edgedog: error: edgedog batch runs on Ray, which is not installed: "
                             "pip install 'edgedog[cluster]'\n")
    assert not (tmp_path / "out").exists()


def spec(name: str, configuration: str, seed: int) -> RunSpec:
    return RunSpec(name, configuration, Path("/scenes/box"), "fast", "full", ("weighting=exp",),
                   ("weighting=exp", f"seed={seed}"), seed)


def outcome(name: str, configuration: str, seed: int, f10: float | None, seconds: float,
            error: str = "") -> RunOutcome:
    curves = None if f10 is None else {"fscore_5mm": f10 / 2, "fscore_10mm": f10, "fscore_20mm": f10 + 10,
                                        "acc_mm": 1.5, "comp_mm": 2.5}
    if error:
        return RunOutcome(spec(name, configuration, seed), "new", error=error)
    log = {"train_seconds": seconds, "final_primitives": 100 + seed}
    return RunOutcome(spec(name, configuration, seed), "new", 0, log, {"metrics": {"curves": curves}})


def test_mean_and_sample_spread():
    assert mean_and_spread([]) == (None, None)
    assert mean_and_spread([4.0]) == (4.0, None)
    mean, spread = mean_and_spread([2.0, 4.0, 9.0])
    assert mean == 5.0 and spread == pytest.approx(math.sqrt((9 + 1 + 16) / 2))


def test_tables_group_runs_by_configuration():
    outcomes = [outcome("a_s0", "a", 0, 40.0, 10.0), outcome("a_s1", "a", 1, 50.0, 14.0),
                outcome("a_s2", "a", 2, None, 12.0),  # no curve to score: no F-scores, still timed
                outcome("b_s0", "b", 0, 30.0, 5.0), outcome("b_s1", "b", 1, None, 0.0, error="x: bad")]
    runs = run_rows(outcomes)
    assert [row["run"] for row in runs] == ["a_s0", "a_s1", "a_s2", "b_s0", "b_s1"]
    assert runs[0]["f10"] == 40.0 and runs[0]["changes"] == "weighting=exp" and runs[4]["error"] == "x: bad"
    a, b = configuration_rows(runs)
    assert (a["configuration"], a["runs"], a["failed"], a["seeds"]) == ("a", 3, 0, "0 1 2")
    assert a["f10_mean"] == 45.0 and a["f10_std"] == pytest.approx(math.sqrt(50))
    assert a["train_seconds_mean"] == 12.0 and a["train_seconds_std"] == 2.0
    assert a["primitives_mean"] == 101.0
    assert (b["runs"], b["failed"], b["f10_mean"], b["f10_std"]) == (1, 1, 30.0, None)

    table = list(csv.DictReader(io.StringIO(csv_text([a, b]))))
    assert table[0]["f10_mean"] == "45.0" and table[1]["f10_std"] == ""
    text = markdown(runs, [a, b])
    assert "| box fast full weighting=exp | 0 1 2 | 3 | 0 | 22.5 ± 3.5 | 45.0 ± 7.1 |" in text
    assert "| b_s1 | 1 | – | – | – | – | – | – | – | – | x: bad |" in text
    json.dumps({"runs": runs, "configurations": [a, b]})  # plain data
    assert across_scenes([a, b]) == []  # one scene: no setting ran on several
    assert "Per setting, over scenes" not in text


def test_a_setting_on_several_scenes_has_its_mean_spread_and_worst_scene():
    """Two scenes' configurations of one setting: the mean and sample spread of their means, and
    the scene of the lowest F10; another setting on one scene gets no such row."""
    outcomes = [outcome("a_s0", "a", 0, 40.0, 10.0), outcome("a_s1", "a", 1, 50.0, 14.0),
                outcome("c_s0", "c", 0, 70.0, 20.0)]
    runs = run_rows(outcomes)
    runs[2]["scene"] = "other"  # configuration c: the same setting on a second scene
    for row, rss in zip(runs, (900.0, 1000.0, 1200.0)):
        row["peak_rss_mib"] = rss
    configurations = configuration_rows(runs)
    (setting,) = across_scenes(configurations)
    assert (setting["preset"], setting["scenes"]) == ("fast", 2)
    assert (setting["worst"], setting["worst_f10"]) == ("box", 45.0)
    assert setting["f10_mean"] == 57.5 and setting["f10_std"] == pytest.approx(math.sqrt(2 * 12.5 ** 2))
    assert setting["peak_rss_mib_mean"] == 1075.0
    text = markdown(runs, configurations)
    assert "| fast full weighting=exp | 2 | " in text and "| box (45.0) |" in text
