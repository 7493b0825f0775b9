"""`edgedog train SCENE --out RUN`: fit EdgeDoG primitives to a scene's pseudo-edge maps."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from edgedog.errors import InputError
from edgedog.train.config import PRESETS


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "train", help="train EdgeDoG primitives on a scene's pseudo-edge maps",
        description="Train (or, with --resume, continue) a run, then extract its curves. The run "
                    "folder gets config.json, checkpoint.pt, primitives.ply, points.ply, log.json, "
                    "and from the extraction curves.json/.obj/.ply, edge_points.ply and "
                    "extract.json (with scores when the scene has ground truth). --out must be a "
                    "new or empty folder (or a run, with --resume); it is locked while training.")
    parser.add_argument("scene", help="scene folder")
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--preset", choices=PRESETS, default=None,
                        help="paper (default): EdgeGaussians' 400 epochs at full resolution; fast: 200 "
                             "at full; preview: 100 at half")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a setting of edgedog.train.config.TrainConfig (repeatable)")
    parser.add_argument("--layers", default=None, metavar="L0,L1,...",
                        help="multi-granularity: train these levels bottom up, each layer fitted to "
                             "its own maps with the layers below fixed (RUN/L0, RUN/L1, ...), then "
                             "extract curves per layer and cumulatively (RUN/curves/)")
    parser.add_argument("--level", dest="levels", action="append", default=[],
                        metavar="NAME=DETECTOR[@FLOOR]",
                        help="define a level's maps, e.g. L0=pidinet-nyud or L1=canny:50,150@0.3 "
                             "(defaults: PiDiNet NYUD / BSDS / Multicue when its weights are found, "
                             "else Canny at 150,300 / 50,150 / 20,60)")
    parser.add_argument("--resume", action="store_true",
                        help="continue the run in --out from its checkpoint, with its own settings, on "
                             "the scene it was trained on")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=run, resume_hint=resume_hint)


def resume_hint(args: argparse.Namespace) -> str:
    """What to type after Ctrl-C: the last checkpoint (every `checkpoint_every` epochs) is kept."""
    return f"continue from the last checkpoint with: edgedog train {args.scene} --out {args.out} --resume"


def run(args: argparse.Namespace) -> None:
    from edgedog.train.layered import is_layered

    if args.layers is not None or is_layered(args.out):
        return run_layered(args)
    from edgedog.train.run_folder import RunFolder, RunLock, check_new_run_folder, write_run

    if args.resume:
        reject_settings_on_resume(args)
        run = resumable_run(args.out)
        scene = scene_of_run(run, args.scene)
        with RunLock.acquire(args.out):
            train_and_report(run, scene, args.quiet)
        return
    config = _config(args)
    check_new_run_folder(args.out)
    scene = scene_for(args.scene, config)
    run = RunFolder(args.out, scene.root, args.preset or "paper", config, _fingerprint(scene))
    with RunLock.acquire(args.out):
        check_new_run_folder(args.out)  # again under the lock: another process may have started here
        write_run(run)
        train_and_report(run, scene, args.quiet)


def _config(args: argparse.Namespace):
    from edgedog.train.config import preset, with_overrides

    return with_overrides(preset(args.preset or "paper"), args.overrides)


def _fingerprint(scene) -> str:
    from edgedog.scenes.fingerprint import scene_fingerprint

    return scene_fingerprint(scene)


def scene_for(path: str, config):
    """The scene at the config's resolution, with the config's edge maps known to be available
    (the scene's own, or a detector's): checked before anything is written."""
    from edgedog.edges.registry import make_detector
    from edgedog.scenes import load_scene

    scene = load_scene(path, downscale=config.downscale)
    if len(scene) == 0:
        raise InputError(scene.root, "the scene has no views")
    if config.detector != "auto" and config.detector not in scene.detectors:
        make_detector(config.detector)
    if scene.damaged:  # training reads every view's files: refuse now, not mid-run
        path, problem = next(iter(scene.damaged.items()))
        others = f" (and {len(scene.damaged) - 1} more damaged images)" if len(scene.damaged) > 1 else ""
        raise InputError(path, problem + others)
    return scene


def reject_settings_on_resume(args: argparse.Namespace) -> None:
    """A resumed run continues with the settings it was started with; an option that would change
    them is refused rather than ignored."""
    given = [option for option, value in (("--preset", args.preset), ("--set", args.overrides),
                                          ("--level", args.levels)) if value]
    if given:
        raise InputError(args.out, f"--resume continues the run with its own settings; {' and '.join(given)} "
                                   "cannot change them (start a new run with another --out)")


def resumable_run(path: Path):
    """The run in `path`, for --resume."""
    from edgedog.train.run_folder import RUN_CONFIG, read_run

    if not path.is_dir():
        raise InputError(path, "run folder not found; nothing to resume")
    if not (path / RUN_CONFIG).is_file():
        raise InputError(path, "is not an edgedog run folder (no config.json of ours); nothing to resume")
    return read_run(path)


def scene_of_run(run, path: str):
    """The scene `path` loaded for `run`, refused when it is not the scene the run trained on: the
    same cameras and images (by fingerprint; the folder may have moved), or, for runs that
    recorded no fingerprint, the same folder."""
    scene = scene_for(path, run.config)
    if run.scene_fingerprint is None:
        if scene.root != run.scene.resolve():
            raise InputError(run.path, f"was trained on {run.scene}, not {scene.root}; pass that scene")
    elif _fingerprint(scene) != run.scene_fingerprint:
        raise InputError(run.path, f"was trained on {run.scene} (fingerprint {run.scene_fingerprint}); "
                                   f"{scene.root} has other cameras or images "
                                   f"(fingerprint {_fingerprint(scene)}); pass the run's scene")
    return scene


def train_and_report(run, scene, quiet: bool) -> None:
    """Train (or continue) `run` on `scene`, write its outputs, extract and print its curves."""
    from edgedog.commands.extract import print_report
    from edgedog.curves.report import extract_with_report
    from edgedog.files import read_json
    from edgedog.train.trainer import Trainer

    trainer = Trainer(scene, run.config, run.path, progress=not quiet)
    print(json.dumps({"detector": trainer.detector, "init": trainer.init_report.get("method"),
                      "initial_primitives": trainer.initial_count, "resumed_at_step": trainer.step_index}))
    trainer.run()
    log = read_json(run.path / "log.json")
    print(f"trained {log['final_primitives']} primitives (from {log['initial_primitives']}) in "
          f"{log['train_seconds']} s")
    _, report = extract_with_report(run.path, scene, trainer.detector)
    print_report(report)
    print(f"outputs in {run.path}")


def run_layered(args: argparse.Namespace) -> None:
    """`--layers`: progressive training of the levels, then curves per layer and cumulative."""
    from edgedog.edges.levels import check_level_maps, resolve_levels
    from edgedog.train.layered import LayeredRun, is_layered, read_layered, write_layered
    from edgedog.train.run_folder import RunLock, check_new_run_folder

    if args.resume:
        if args.layers is not None:
            raise InputError(args.out, "--resume continues the layered run with its own layers; "
                                       "drop --layers")
        reject_settings_on_resume(args)
        if not is_layered(args.out):
            raise InputError(args.out, "no layered run to resume (layers.json is missing)")
        run = read_layered(args.out)
        scene = scene_for(args.scene, run.base)
        if scene.root != run.scene.resolve():
            raise InputError(args.out, f"was trained on {run.scene}, not {scene.root}; pass that scene")
    else:
        if is_layered(args.out):
            raise InputError(args.out, "already holds a layered run; pass --resume to continue it, or "
                                       "choose another --out")
        check_new_run_folder(args.out)
        names = [name.strip() for name in (args.layers or "").split(",") if name.strip()]
        if not names:
            raise InputError(args.out, f"--layers {args.layers!r}: name at least one layer, e.g. L0,L1")
        config = _config(args)
        levels = resolve_levels(names, args.levels)
        scene = scene_for(args.scene, config)
        check_level_maps(levels, scene.detectors)
        run = LayeredRun(args.out, scene.root, args.preset or "paper", config, levels)
    with RunLock.acquire(args.out):
        if not args.resume:
            check_new_run_folder(args.out)
            write_layered(run)

        def announce(index, trainer) -> None:
            level = run.levels[index]
            print(json.dumps({"layer": level.name, "maps": trainer.detector, "floor": level.floor,
                              "lower_primitives": len(trainer.lower),
                              "initial_primitives": trainer.initial_count,
                              "resumed_at_step": trainer.step_index}))

        train_layered_and_report(run, scene, progress=not args.quiet, on_layer=announce)


def train_layered_and_report(run, scene, progress: bool, on_layer=None) -> dict:
    """Train a layered run, extract every selection and print the table."""
    from edgedog.train.layered import extract_layered, train_layered

    train_layered(run, scene, progress=progress, on_layer=on_layer)
    report = extract_layered(run, scene)
    print_layers_report(report)
    print(f"outputs in {run.path}")
    return report


def print_layers_report(report: dict) -> None:
    """One row per selection: primitives, curves, and the curves' scores when there is ground truth."""
    print(f"{'layers':<12} {'primitives':>10} {'curves':>6} {'Acc':>6} {'Comp':>6} {'P10':>6} {'R10':>6} "
          f"{'F10':>6} {'F20':>6}")
    for name, selection in report["selections"].items():
        counts = selection["counts"]
        row = f"{name:<12} {selection['primitives']:>10} {counts['lines'] + counts['beziers']:>6}"
        curves = selection.get("metrics", {}).get("curves")
        if curves:
            row += (f" {curves['acc_mm']:6.2f} {curves['comp_mm']:6.2f} {curves['precision_10mm']:6.1f} "
                    f"{curves['recall_10mm']:6.1f} {curves['fscore_10mm']:6.1f} {curves['fscore_20mm']:6.1f}")
        print(row)
