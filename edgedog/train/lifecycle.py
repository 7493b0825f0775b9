"""One run's lifecycle: a plan (what would run, where, from which state) apart from its execution.

`plan_run` reads a run folder and the scene and decides, writing nothing, what a run there does:
start anew (NEW), continue from its checkpoint's step (RESUME), be reused as it is (FINISHED), or
nothing, for a reason (REFUSED). A `RunPlan` is plain data (paths, numbers, strings and a frozen
config), so one process may plan and another execute. `execute` takes the folder's lock, checks
the folder again under it, trains what is left, and extracts the curves when their report is
missing.

"Finished" means one thing to every caller (`is_finished`): the folder's log.json records the
training of the folder's own configuration to its last epoch. What each caller may do with a
folder is its policy: START (`edgedog train`: a new or empty folder), CONTINUE (`--resume`: the
run there, with its own settings) or REUSE (the demo, the benchmarks: a new folder, or this very
run, resumed or reused).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from edgedog.errors import ConfigError, InputError
from edgedog.files import read_json
from edgedog.train.config import DEFAULT_PRESET, TrainConfig, for_detector, from_dict
from edgedog.train.memory import check_memory
from edgedog.train.run_folder import (
    RUN_CONFIG,
    RunFolder,
    RunLock,
    check_new_run_folder,
    check_same_run,
    read_run,
    write_run,
)

if TYPE_CHECKING:  # torch and the scene loaders load only when a run is planned
    from edgedog.scenes import Scene
    from edgedog.train.trainer import Trainer

LOG = "log.json"
"""Written by the trainer at its end (and by the speed bench at each evaluation)."""

NEW, RESUME, FINISHED, REFUSED = "new", "resume", "finished", "refused"
START, CONTINUE, REUSE = "start", "continue", "reuse"
POLICIES = (START, CONTINUE, REUSE)


@dataclass(frozen=True)
class RunPlan:
    """What executing a run does.

    run: the run (folder, scene, preset, effective config, scene fingerprint);
    policy: START, CONTINUE or REUSE; state: NEW, RESUME, FINISHED or REFUSED;
    step: where training starts (RESUME: the checkpoint's step; FINISHED: the last step);
    extracted: whether the curves' report is there and current (`has_current_report`; a FINISHED run
        is extracted, again, only when not);
    refused_path, reason: for REFUSED, the error `check` raises (`InputError(refused_path, reason)`).
    """

    run: RunFolder
    policy: str
    state: str
    step: int = 0
    extracted: bool = False
    refused_path: Path | None = None
    reason: str = ""

    def check(self) -> RunPlan:
        """This plan, unless it is refused: then the InputError saying why."""
        if self.state == REFUSED:
            raise InputError(self.refused_path, self.reason)
        return self


@dataclass(frozen=True)
class RunResult:
    """An executed run: its plan, its log.json and its extraction report."""

    plan: RunPlan
    log: dict
    report: dict


def is_finished(path: Path) -> bool:
    """Whether `path` holds a finished run: its config.json is ours and its log.json records
    that configuration (with the settings its maps' detector fixed) trained to its last epoch.
    A log.json written mid-run (the speed bench writes one at each evaluation) is not."""
    path = Path(path)
    if not (path / LOG).is_file() or not (path / RUN_CONFIG).is_file():
        return False
    try:
        config, log = read_run(path).config, read_json(path / LOG)
        detector = log["detector"]
        return (isinstance(log, dict) and isinstance(detector, str)
                and len(log["history"]) == config.schedule.epochs
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


def _check_continuable(path: Path) -> None:
    if not path.is_dir():
        raise InputError(path, "run folder not found; nothing to resume")
    if not (path / RUN_CONFIG).is_file():
        raise InputError(path, "is not an edgedog run folder (no config.json of ours); nothing to resume")


def _folder_plan(run: RunFolder, policy: str) -> RunPlan:
    """The plan from the folder alone (no scene read): `run` is the run to make (START, REUSE)
    or the one read from the folder (CONTINUE)."""
    from edgedog.curves.report import has_current_report

    path = run.path
    if policy == START:
        check_new_run_folder(path)
        return RunPlan(run, policy, NEW)
    if policy == CONTINUE:
        _check_continuable(path)
    elif policy == REUSE:
        check_same_run(run)
        if not (path / RUN_CONFIG).is_file():
            return RunPlan(run, policy, NEW)
    else:
        raise ValueError(f"no run policy {policy!r}; one of {POLICIES}")
    extracted = has_current_report(path)
    if is_finished(path):
        return RunPlan(run, policy, FINISHED, _checkpoint_step(path), extracted)
    return RunPlan(run, policy, RESUME, _checkpoint_step(path), extracted)


def _refused(run: RunFolder, policy: str, error: InputError) -> RunPlan:
    return RunPlan(run, policy, REFUSED, refused_path=error.path, reason=error.problem)


def plan_run(out: Path, scene: str | Path, preset: str = DEFAULT_PRESET, config: TrainConfig | None = None,
             policy: str = START) -> RunPlan:
    """What a run of `config` (preset `preset`) on `scene` in `out` would do under `policy`;
    with CONTINUE, the run's own scene record, preset and config are the folder's (`config` is
    ignored) and `scene` must be the scene it trained on. Writes nothing.

    A folder the policy does not allow, or a scene that cannot be trained, gives a REFUSED plan
    (`RunPlan.check` raises its error); ConfigErrors (e.g. an unknown detector) are raised.
    """
    out = Path(out)
    pending = RunFolder(out, Path(scene), preset, config if config is not None else TrainConfig())
    try:
        if policy == CONTINUE:
            _check_continuable(out)
            run = read_run(out)
            check_scene_of_run(run.path, run.scene, run.scene_fingerprint, load_run_scene(scene, run.config),
                               run.maps_fingerprint)
            return _folder_plan(run, policy)
        if policy == START:
            _folder_plan(pending, policy)  # a refused folder is reported before the scene is read
        loaded = load_run_scene(scene, pending.config)
        run = dataclasses.replace(pending, scene=loaded.root, scene_fingerprint=fingerprint(loaded),
                                  maps_fingerprint=maps_fingerprint(loaded))
        return _folder_plan(run, policy)
    except InputError as error:
        return _refused(pending, policy, error)


def replan(plan: RunPlan) -> RunPlan:
    """`plan` with its folder read again (no scene read): for a writer holding the folder's lock,
    as another process may have started or finished a run there since it was planned."""
    try:
        return _folder_plan(plan.check().run, plan.policy)
    except InputError as error:
        return _refused(plan.run, plan.policy, error)


def execute(plan: RunPlan, scene: Scene | None = None, progress: bool = True,
            on_trainer: Callable[[Trainer], None] | None = None) -> RunResult:
    """Carry out `plan` under the folder's lock: write config.json (NEW), train what is left
    (NEW, RESUME; CONTINUE loads a FINISHED run too, and rewrites its outputs), and extract the
    curves when a trainer ran or their report is missing.

    Args:
        scene: the run's scene at its resolution, when the caller has it loaded (else loaded here).
        on_trainer: called with the trainer before it trains (e.g. to print where it starts).
    Raises:
        InputError: the plan is refused, or the folder changed since it was planned.
    """
    from edgedog.curves.report import REPORT, extract_with_report
    from edgedog.train.trainer import Trainer

    run = plan.check().run
    made = not run.path.exists()
    with RunLock.acquire(run.path) as lock:
        try:
            current = replan(plan).check()
            if scene is None:
                scene = load_run_scene(run.scene, run.config)
            # --resume of a finished run loads it all the same: its checkpoint is checked, its outputs
            # written again (no step is left to train).
            trained = current.state != FINISHED or plan.policy == CONTINUE
            trainer = Trainer(scene, run.config, run.path, progress=progress) if trained else None
            if current.state == NEW:
                write_run(run)
        except BaseException:
            if plan.state == NEW:  # refused before training: leave the folder as it was
                lock.discard(remove_folder=made)
            raise
        if trainer is not None:
            if on_trainer is not None:
                on_trainer(trainer)
            trainer.run()
        log = read_json(run.path / LOG)
        if trained or not current.extracted:
            report = extract_with_report(run.path, scene, log["detector"])[1]
        else:
            report = read_json(run.path / REPORT)
    return RunResult(current, log, report)
