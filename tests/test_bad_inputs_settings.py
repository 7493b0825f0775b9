"""Bad settings and options, as a user types them: one-line errors naming the setting, given before
anything is written (issue 23: settings checked at parse time).

Every case runs `python -m edgedog ...` in a fresh folder (tests/helpers/bad_inputs.py); SCENE in a case's
command line stands for the session's small box scene (tests/conftest.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from edgedog.train.config import MAX_LAYERS
from edgedog.train.run_folder import RUN_VERSION
from tests.helpers.bad_inputs import Case, assert_fails_cleanly, cases_as_params

SCENE = "SCENE"
"""Stands for the module's tiny scene in a case's command line."""


def train(*options: str, words: list[str]):
    """A case's build: `edgedog train SCENE --out run OPTIONS`, whose error holds `words`."""
    return lambda folder: (["train", SCENE, "--out", folder / "run", *options], words)


def setting(assignment: str, *words: str) -> Case:
    """`edgedog train ... --set ASSIGNMENT`: the error repeats the assignment and holds `words`."""
    return Case(f"set-{assignment}", train("--set", assignment, words=[f"--set {assignment!r}", *words]))


def resume_with(settings: dict, *words: str, version: int = RUN_VERSION) -> Case:
    """`edgedog train --resume` of a run folder of format `version` whose config.json holds
    `settings`."""
    def build(folder: Path):
        run = folder / "run"
        run.mkdir()
        (run / "config.json").write_text(json.dumps({"format": "edgedog-run", "version": version,
                                                     "scene": "scene", "preset": "full", "config": settings}))
        return ["train", SCENE, "--out", run, "--resume"], [str(run / "config.json"), *words]
    names = [f"{section}-{'-'.join(values)}" if isinstance(values, dict) else section
             for section, values in settings.items()]
    return Case(f"config-json-v{version}-{'-'.join(names)}", build)


def bench_raster(*options: str, words: list[str]) -> Case:
    return Case("bench-raster" + "".join(options).replace("--", "-"),
                lambda folder: (["bench", "raster", *options], words))


CASES = [
    # periods of 0 divided by zero once training had started (orientation_every too: every
    # field's range is in test_config_ranges.py)
    setting("checkpoint_every=0", "run.checkpoint_every must be an integer >= 1"),
    setting("fisher_every=0", "fisher_every"),
    setting("sampled_loss_every=0", "loss.sampled_every"),
    # tracebacks, "0 primitives" with rc 0, NaN primitives
    setting("init_opacity=1.5", "init.opacity must be a number in (0, 1)"),
    setting("init.count=0", "init.count"),
    setting("init_side=0", "init.side"),
    setting("seed=-1", "seed"),
    setting("k_init=0.5", "init.k must be 2 values"),
    setting("max_primitives=0", "max_primitives"),
    setting("edge_threshold=nan", "edge_threshold", "nan"),
    setting("lr_means=inf", "lr_means", "inf"),
    # sizes that grow with the value
    setting("profile_sigma=1e9", "profile_sigma must be a number in (0, 32]"),
    setting("duplicate_copies=0", "duplicate_copies"),
    setting("direction_neighbours=1000000", "direction_neighbours"),
    setting("epochs=100000", "schedule.epochs must be an integer in [1, 10000]"),
    # values that cannot be read, names that do not exist
    setting("epochs=two", "epochs", "'two'"),
    setting("detector=canny:5", "canny:LOW,HIGH"),
    setting("epoch=3", "unknown setting", "epochs"),
    Case("unknown-detector", train("--set", "detector=bogus", words=["bogus"])),
    # levels: all checked before the first layer trains
    Case("level-unknown-maps", train("--layers", "L0,L1", "--level", "L1=bogus", "--set", "epochs=1",
                                     words=["L1", "bogus"])),
    Case("level-floor", train("--layers", "L0,L1", "--level", "L1=canny@2",
                              words=["--level 'L1=canny@2'", "maps.floor"])),
    Case("level-detector-options", train("--layers", "L0,L1", "--level", "L1=canny:5",
                                         words=["--level 'L1=canny:5'", "LOW,HIGH"])),
    Case("level-not-among-layers", train("--layers", "L0,L1", "--level", "L2=canny", words=["--level L2"])),
    Case("too-many-layers", train("--layers", ",".join(f"L{i}" for i in range(MAX_LAYERS + 1)),
                                  words=["--layers", f"at most {MAX_LAYERS}"])),
    # a run folder's config.json
    resume_with({"schedule": {"epochs": "two"}}, "schedule.epochs"),
    resume_with({"schedule": {"epochs": 10, "learning_rate": 0.1}}, "unknown setting schedule.learning_rate"),
    resume_with({"epochs": 10, "learning_rate": 0.1}, "unknown setting 'learning_rate'", version=2),
    # benchmarks' options
    bench_raster("--views", "0", words=["--views"]),
    bench_raster("--size", "0", words=["--size"]),
    bench_raster("--primitives", "-5", words=["--primitives"]),
    bench_raster("--primitives", "100000000", words=["--primitives"]),
    bench_raster("--reference-views", "0", words=["--reference-views"]),
    bench_raster("--views", "2", "--reference-views", "3", words=["--reference-views", "--views"]),
    Case("bench-edges-repeats-0", lambda folder: (["bench", "edges", "--repeats", "0"], ["--repeats"])),
    Case("bench-ablation-set", lambda folder: (["bench", "ablation", SCENE, "--out", folder / "out", "--set",
                                               "fisher_every=0"], ["--set 'fisher_every=0'"])),
    Case("bench-layers-level", lambda folder: (["bench", "layers", SCENE, "--out", folder / "out", "--level",
                                               "L1=canny@nan"], ["--level 'L1=canny@nan'", "maps.floor"])),
    Case("extract-set-nan", lambda folder: (["extract", folder, "--set", "min_opacity=nan"],
                                            ["--set 'min_opacity=nan'"])),
]


def _paths(folder: Path) -> set[Path]:
    return {path.relative_to(folder) for path in folder.rglob("*")}


@pytest.mark.parametrize("case", cases_as_params(CASES))
def test_a_bad_setting_fails_before_anything_is_written(case, tmp_path, small_box_scene):
    built = set()

    def build(folder: Path):
        argv, words = case.build(folder)
        built.update(_paths(folder))
        return [small_box_scene if arg == SCENE else arg for arg in argv], words

    assert_fails_cleanly(Case(case.name, build, case.returncode), tmp_path)
    assert _paths(tmp_path) == built  # no file nor folder was made
