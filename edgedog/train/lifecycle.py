"""One run's lifecycle: a plan (what would run, where, from which state) apart from its execution.

`plan_run` reads a run folder and the scene and decides, writing nothing, what a run there does:
start anew (NEW), continue from its checkpoint's step (RESUME), be reused as it is (FINISHED), or
nothing, for a reason (REFUSED). A run is a stack of layers (`RunPlan.run.layers()`): a run folder
is a stack of one, a layered run (`edgedog.train.layered`) one of several. A `RunPlan` carries the
scene it loaded, so the scene is loaded and fingerprinted once; the rest of it is plain data
(paths, numbers, strings and frozen configs), and a pickled plan leaves the scene behind, so one
process may plan and another execute. `edgedog.train.run.open_run` executes a plan: it takes the
folder's lock, checks the folder again under it and returns the run object that trains the layers
and extracts the curves; `execute` does all of it in one call.

"Finished" means one thing to every caller (`is_finished`): the folder's log.json records the
training of the folder's own configuration to its last epoch. What each caller may do with a
folder is its policy: START (`edgedog train`: a new or empty folder), CONTINUE (`--resume`: the
run there, with its own settings) or REUSE (the demo, the benchmarks: a new folder, or this very
run, resumed or reused).

A folder's record is read here for every caller (`record_kind`, `holds_run`, `read_record`,
`open_record`, `curves_of`): a `RunFolder` or a `LayeredRun`, which answer alike, so that no
caller tells a layered run from a single one. A folder's lock is taken in one place,
`lock_folder`.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from edgedog.errors import ConfigError, InputError
from edgedog.files import read_json
from edgedog.scenes import Scene
from edgedog.train.config import DEFAULT_PRESET, TrainConfig, for_detector, from_dict
from edgedog.train.layered import LayeredRun, is_layered, read_layered
from edgedog.train.levels import Level, check_level_maps
from edgedog.train.memory import check_memory
from edgedog.train.run_folder import (
    LOG,
    RUN_CONFIG,
    RunFolder,
    RunLock,
    check_new_run_folder,
    differ,
    is_run_folder,
    own_curves,
    read_run,
)

if TYPE_CHECKING:  # torch loads only when a run trains
    from edgedog.train.trainer import Trainer

RunRecord = RunFolder | LayeredRun
"""What a run folder records of its run: config.json's run of one layer, or layers.json's
layered run. Both answer the same questions (path, scene, preset, config, fingerprints,
`layers()`, `curves_folder`, `selection_folder()`, `report_file`, `extraction_scene()`,
`extract()`, `write()`): a caller holding either needs no branch."""
LAYERED_RUN, SINGLE_RUN = "layered run", "run"
"""What `record_kind` says a folder records."""

NEW, RESUME, FINISHED, REFUSED = "new", "resume", "finished", "refused"
START, CONTINUE, REUSE = "start", "continue", "reuse"
POLICIES = (START, CONTINUE, REUSE)


@dataclass(frozen=True)
class RunPlan:
    """What executing a run does.

    run: the run's record (folder, scene, preset, effective config, scene fingerprint; a layered
        run's levels), whose `layers()` are the run folders trained, bottom first;
    policy: START, CONTINUE or REUSE; state: NEW, RESUME, FINISHED or REFUSED;
    step: where training starts in the lowest layer left (RESUME: its checkpoint's step;
        FINISHED: the top layer's last step);
    extracted: whether the curves' report is there (and, for a run of one layer, current:
        `has_current_report`; a FINISHED run is extracted, again, only when not);
    refused_path, reason: for REFUSED, the error `check` raises (`InputError(refused_path, reason)`);
    scene: the scene at the run's resolution as `plan_run` loaded it (`load_run_scene`); None in a
        refused plan and in a plan unpickled in another process (`open_run` loads it there).
    """

    run: RunRecord
    policy: str
    state: str
    step: int = 0
    extracted: bool = False
    refused_path: Path | None = None
    reason: str = ""
    scene: Scene | None = field(default=None, compare=False, repr=False)

    def check(self) -> RunPlan:
        """This plan, unless it is refused: then the InputError saying why."""
        if self.state == REFUSED:
            raise InputError(self.refused_path, self.reason)
        return self

    def __getstate__(self) -> dict:
        """Pickled without the scene (its images stay where they are; the executing process
        loads it again)."""
        return {**self.__dict__, "scene": None}


@dataclass(frozen=True)
class RunResult:
    """An executed run: its plan, its log.json and its extraction report."""

    plan: RunPlan
    log: dict
    report: dict


def trained_to_end(log: dict, epochs: int) -> bool:
    """Whether a log.json's history ends its run: it reached the last of `epochs` epochs (a run
    whose coarse stage ended early skips epochs), or the run stopped when converged."""
    history = log["history"]
    return bool(log.get("stopped")) or (bool(history) and history[-1]["epoch"] == epochs - 1)


def is_finished(path: Path) -> bool:
    """Whether `path` holds a finished run: its config.json is ours and its log.json records
    that configuration (with the settings its maps' detector fixed) trained to its end: its last
    epoch, or the epoch it stopped at once converged (`schedule.stop`).
    A log.json written mid-run (the speed bench writes one at each evaluation) is not."""
    path = Path(path)
    if not (path / LOG).is_file() or not (path / RUN_CONFIG).is_file():
        return False
    try:
        config, log = read_run(path).config, read_json(path / LOG)
        detector = log["detector"]
        return (isinstance(log, dict) and isinstance(detector, str)
                and trained_to_end(log, config.schedule.epochs)
                and from_dict(log["config"]) == for_detector(config, detector))
    except (ConfigError, InputError, KeyError, TypeError, ValueError):
        return False


def load_run_scene(path: str | Path, config: TrainConfig) -> Scene:
    """The scene at the config's resolution, with the config's edge maps known to be available
    (the scene's own, or a detector's) and every view's files readable, or the views whose image
    is damaged left out when the config says to skip them: checked before anything is written."""
    from edgedog.edges.registry import make_detector
    from edgedog.scenes import load_scene

    scene = load_scene(path, downscale=config.maps.downscale)
    if len(scene) == 0:
        raise InputError(scene.root, "the scene has no views")
    check_memory(scene, config.maps.downscale)
    if config.maps.detector != "auto" and config.maps.detector not in scene.detectors:
        make_detector(config.maps.detector)
    if scene.damaged and config.run.damaged_views == "skip":
        scene = scene.without_damaged()
        if len(scene) == 0:
            raise InputError(scene.root, "every view's image is damaged")
    if scene.damaged:  # training reads every view's files: refuse now, not mid-run
        path, problem = next(iter(scene.damaged.items()))
        others = f" (and {len(scene.damaged) - 1} more damaged images)" if len(scene.damaged) > 1 else ""
        raise InputError(path, f"{problem}{others}; --set damaged_views=skip trains on the other views")
    return scene


def fingerprint(scene: Scene) -> str:
    from edgedog.scenes.fingerprint import scene_fingerprint

    return scene_fingerprint(scene)


def maps_fingerprint(scene: Scene) -> str:
    from edgedog.scenes import fingerprint as digests

    return digests.maps_fingerprint(scene)


def check_scene_of_run(path: Path, trained_on: Path, trained_fingerprint: str | None, scene: Scene,
                       trained_maps: str | None = None) -> None:
    """`scene` must be the scene the run in `path` trained on (`trained_on`, with
    `trained_fingerprint`): the same cameras and images (by fingerprint; the folder may have
    moved), or, for runs that recorded no fingerprint, the same folder; and, when the run recorded
    them (`trained_maps`), the same shipped edge maps and masks."""
    if trained_fingerprint is None:
        if scene.root != Path(trained_on).resolve():
            raise InputError(path, f"was trained on {trained_on}, not {scene.root}; pass that scene")
    elif fingerprint(scene) != trained_fingerprint:
        raise InputError(path, f"was trained on {trained_on} (fingerprint {trained_fingerprint}); "
                               f"{scene.root} has other cameras or images "
                               f"(fingerprint {fingerprint(scene)}); pass the run's scene")
    if trained_maps is not None and (current := maps_fingerprint(scene)) != trained_maps:
        raise InputError(path, f"was trained on {trained_on} with other edge maps or masks (fingerprint "
                               f"{trained_maps}); {scene.root} now ships {current}: pass the scene as it "
                               "was, or start a new run with another --out")


def _checkpoint_step(path: Path) -> int:
    """The step a run folder's checkpoint continues from (0 without a checkpoint)."""
    from edgedog.train.checkpoint import CHECKPOINT, read_checkpoint

    file = path / CHECKPOINT
    if not file.exists():
        return 0
    step = read_checkpoint(file)["step_index"]
    if not isinstance(step, int) or step < 0:
        raise InputError(file, f"malformed checkpoint: step_index {step!r}")
    return step


def record_kind(path: Path) -> str:
    """What the folder `path` records: LAYERED_RUN (a layered run's layers.json), SINGLE_RUN (a
    config.json of ours) or '' (no run)."""
    if is_layered(path):
        return LAYERED_RUN
    return SINGLE_RUN if is_run_folder(path) else ""


def holds_run(path: Path) -> bool:
    """Whether `path` records a run: a layered run's layers.json, or a config.json of ours."""
    return record_kind(path) != ""


def read_record(path: Path) -> RunRecord:
    """The run a folder records: a layered run (layers.json), else a run of one layer
    (config.json); one InputError naming the folder when it holds neither."""
    if not path.is_dir():
        raise InputError(path, "run folder not found; nothing to resume")
    if is_layered(path):
        return read_layered(path)
    if not (path / RUN_CONFIG).is_file():
        raise InputError(path, "is not an edgedog run folder (no config.json of ours); nothing to resume")
    return read_run(path)


def lock_folder(path: Path) -> RunLock:
    """Lock the folder `path` (made if missing) for this process's writes until released: the one
    place edgedog takes a folder's lock (`RunLock`). A run's folder is locked by
    `edgedog.train.run.open_run` (training) and `open_record` (extracting); a file a command
    writes into a run folder, and a folder of runs (a batch's, a benchmark's), by
    `edgedog.outputs`.

    Raises:
        InputError: another process holds the lock, or the folder cannot be locked.
    """
    return RunLock.acquire(path)


@contextlib.contextmanager
def open_record(path: Path) -> Iterator[RunRecord]:
    """The run the folder `path` records (`read_record`), read under the folder's lock, held
    throughout: for a command that reads a trained run and writes into it (`edgedog extract`).

    Raises:
        InputError: the folder is missing or records no run (no lock is taken then: nothing is
            written into a folder not ours), or another process holds its lock.
    """
    if not path.is_dir():
        raise InputError(path, "run folder not found")
    if not holds_run(path):
        raise InputError(path, "is not an edgedog run folder (no config.json of ours)")
    with lock_folder(path):
        yield read_record(path)


def curves_of(path: Path, selection: str | None = None) -> tuple[Path, Path]:
    """The folder holding the curves of `selection` of the run in `path` (`selection_folder`;
    None: the whole model's) and the run folder whose log.json names their scene (the bottom
    layer's); a folder that records no run holds curves of its own (`own_curves`: `path`, twice).
    Reads, locks nothing."""
    if not holds_run(path):
        return own_curves(path, selection), path
    run = read_record(path)
    return run.selection_folder(selection), run.layers()[0].path


def _check_same_record(run: RunRecord) -> None:
    """REUSE: the folder holds this very run (the same scene, layer by layer the same folders and
    configurations, and fingerprints that do not tell the scenes apart), or nothing at all; a
    benchmark never mixes two runs in one folder."""
    if not holds_run(run.path):
        check_new_run_folder(run.path)
        return
    existing = read_record(run.path)
    if existing.scene != run.scene or _layer_configs(existing) != _layer_configs(run):
        raise InputError(run.path, "holds a run of another scene or configuration; choose another --out")
    if differ(existing.scene_fingerprint, run.scene_fingerprint):
        raise InputError(run.path, "holds a run of this scene as it was before its cameras or images "
                                   "changed; choose another --out")
    if differ(existing.maps_fingerprint, run.maps_fingerprint):
        raise InputError(run.path, "holds a run of this scene as it was before its edge maps or masks "
                                   "changed; choose another --out")


def _layer_configs(run: RunRecord) -> list[tuple[Path, TrainConfig]]:
    return [(layer.path, layer.config) for layer in run.layers()]


def _folder_plan(run: RunRecord, policy: str, scene: Scene | None = None) -> RunPlan:
    """The plan from the folder alone (no scene read): `run` is the run to make (START, REUSE)
    or the one read from the folder (CONTINUE); `scene` is carried as it is."""
    from edgedog.curves.report import has_current_report

    path = run.path
    if policy == START:
        if holds_run(path):
            raise InputError(path, "already holds a run; pass --resume to continue it, or choose another "
                                   "folder")
        check_new_run_folder(path)
        return RunPlan(run, policy, NEW, scene=scene)
    if policy == CONTINUE:
        read_record(path)
    elif policy == REUSE:
        _check_same_record(run)
        if not holds_run(path):
            return RunPlan(run, policy, NEW, scene=scene)
    else:
        raise ValueError(f"no run policy {policy!r}; one of {POLICIES}")
    layers = [layer.path for layer in run.layers()]
    left = [layer for layer in layers if not is_finished(layer)]
    extracted = has_current_report(run.curves_folder) and run.report_file.is_file()
    state = RESUME if left else FINISHED
    return RunPlan(run, policy, state, _checkpoint_step((left or layers[-1:])[0]), extracted, scene=scene)


def _refused(run: RunRecord, policy: str, error: InputError) -> RunPlan:
    return RunPlan(run, policy, REFUSED, refused_path=error.path, reason=error.problem)


def plan_run(out: Path, scene: str | Path | Scene, preset: str = DEFAULT_PRESET,
             config: TrainConfig | None = None, policy: str = START, levels: tuple[Level, ...] = ()
             ) -> RunPlan:
    """What a run of `config` (preset `preset`) on `scene` in `out` would do under `policy`:
    a run of one layer, or, with `levels`, a layered run (a run folder per level, bottom first).
    With CONTINUE, the run's own scene record, preset, config and levels are the folder's
    (`config` and `levels` are ignored) and `scene` must be the scene it trained on. Writes
    nothing; the plan carries the scene it loaded.

    Args:
        scene: the scene folder, or the scene already loaded at the run's resolution by
            `load_run_scene` (the studio keeps its scenes loaded).

    A folder the policy does not allow, or a scene that cannot be trained, gives a REFUSED plan
    (`RunPlan.check` raises its error); ConfigErrors (e.g. an unknown detector, a level whose maps
    cannot be had) are raised.
    """
    out = Path(out)
    folder = scene.root if isinstance(scene, Scene) else Path(scene)
    config = config if config is not None else TrainConfig()
    pending = (LayeredRun(out, folder, preset, config, tuple(levels)) if levels
               else RunFolder(out, folder, preset, config))
    try:
        if policy == CONTINUE:
            run = read_record(out)
            loaded = _loaded(scene, run.config)
            check_scene_of_run(run.path, run.scene, run.scene_fingerprint, loaded, run.maps_fingerprint)
            return _folder_plan(run, policy, loaded)
        if policy == START:
            _folder_plan(pending, policy)  # a refused folder is reported before the scene is read
        loaded = _loaded(scene, config)
        check_level_maps(tuple(levels), loaded.detectors)
        run = dataclasses.replace(pending, scene=loaded.root, scene_fingerprint=fingerprint(loaded),
                                  maps_fingerprint=maps_fingerprint(loaded))
        return _folder_plan(run, policy, loaded)
    except InputError as error:
        return _refused(pending, policy, error)


def _loaded(scene: str | Path | Scene, config: TrainConfig) -> Scene:
    return scene if isinstance(scene, Scene) else load_run_scene(scene, config)


def replan(plan: RunPlan) -> RunPlan:
    """`plan` with its folder read again (no scene read; its scene carried over): for a writer
    holding the folder's lock, as another process may have started or finished a run there
    since it was planned."""
    try:
        return _folder_plan(plan.check().run, plan.policy, plan.scene)
    except InputError as error:
        return _refused(plan.run, plan.policy, error)


def execute(plan: RunPlan, scene: Scene | None = None, progress: bool = True,
            on_trainer: Callable[[Trainer], None] | None = None) -> RunResult:
    """Carry out `plan` in one call: open the run (`edgedog.train.run.open_run`: the folder's lock,
    the folder checked again), train every layer left to its end, extract the curves when a
    layer trained or their report is missing, and close the run.

    Args:
        scene: the run's scene at its resolution, for a plan that does not carry it (else loaded).
        on_trainer: called with each layer's trainer before it trains (e.g. to print where it starts).
    Raises:
        InputError: the plan is refused, or the folder changed since it was planned.
    """
    from edgedog.train.run import open_run  # the run object is built on these plans

    if scene is not None and plan.scene is None:
        plan = dataclasses.replace(plan, scene=scene)
    with open_run(plan, progress) as run:
        run.train(on_trainer=on_trainer)
        return run.finish()
