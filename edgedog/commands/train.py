"""`edgedog train SCENE --out RUN`: fit EdgeDoG primitives to a scene's pseudo-edge maps."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from edgedog.commands.reports import print_layers_report, print_report
from edgedog.errors import InputError
from edgedog.train.config import DEFAULT_PRESET, PRESETS, presets_help


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
                        help=f"the starting settings (default {DEFAULT_PRESET}). {presets_help()}")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a setting of edgedog.train.config.TrainConfig (repeatable): KEY "
                             "is SECTION.FIELD (loss.weighting=exp), or a field one section has "
                             "(epochs=200)")
    parser.add_argument("--device", choices=("auto", "cpu", "cuda"), default=None,
                        help="where training computes (the setting run.device; default auto: CUDA when "
                             "the extension was built with it and torch sees a GPU, else the CPU)")
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
    """What to type after Ctrl-C: the last checkpoint (every `run.checkpoint_every` epochs) is kept."""
    return f"continue from the last checkpoint with: edgedog train {args.scene} --out {args.out} --resume"


def run(args: argparse.Namespace) -> None:
    """Plan the run (a new one, layered with --layers, or the one in --out with --resume), train
    it, extract its curves and print what it did."""
    from edgedog.train.levels import resolve_levels
    from edgedog.train.lifecycle import CONTINUE, START, plan_run

    if args.resume:
        if args.layers is not None:
            raise InputError(args.out, "--resume continues the run with its own layers; drop --layers")
        reject_settings_on_resume(args)
        plan = plan_run(args.out, args.scene, policy=CONTINUE)
    else:
        levels = ()
        if args.layers is not None:
            names = [name.strip() for name in args.layers.split(",") if name.strip()]
            if not names:
                raise InputError(args.out, f"--layers {args.layers!r}: name at least one layer, e.g. L0,L1")
            levels = resolve_levels(names, args.levels)
        plan = plan_run(args.out, args.scene, args.preset or DEFAULT_PRESET, _config(args), START, levels)
    train_and_report(plan, args.quiet)


def _config(args: argparse.Namespace):
    """The run's settings from --preset, --set and --device; a device this machine cannot compute
    on is refused here, before anything is written."""
    from edgedog.renderer.ops import resolve_device
    from edgedog.train.config import preset, with_overrides

    device = [] if args.device is None else [f"run.device={args.device}"]
    config = with_overrides(preset(args.preset or DEFAULT_PRESET), [*args.overrides, *device])
    resolve_device(config.run.device)
    return config


def reject_settings_on_resume(args: argparse.Namespace) -> None:
    """A resumed run continues with the settings it was started with; an option that would change
    them is refused rather than ignored."""
    given = [option for option, value in (("--preset", args.preset), ("--set", args.overrides),
                                          ("--device", args.device), ("--level", args.levels)) if value]
    if given:
        raise InputError(args.out, f"--resume continues the run with its own settings; {' and '.join(given)} "
                                   "cannot change them (start a new run with another --out)")


def train_and_report(plan, quiet: bool) -> None:
    """Execute `plan` (a new run, or one continued from its checkpoints), print where each layer
    starts, its training and its curves."""
    from edgedog.train.layers import layer_name
    from edgedog.train.lifecycle import execute

    def announce(trainer) -> None:
        print(json.dumps({"layer": layer_name(trainer.config.layers.layer), "detector": trainer.detector,
                          "floor": trainer.config.maps.floor, "init": trainer.init_report.get("method"),
                          "lower_primitives": len(trainer.lower), "initial_primitives": trainer.initial_count,
                          "resumed_at_step": trainer.step_index}))
        for path, problem in trainer.scene.skipped.items():
            print(f"skipped the view of {path}: {problem}")

    result = execute(plan.check(), progress=not quiet, on_trainer=announce)
    if "selections" in result.report:
        print_layers_report(result.report)
    else:
        log = result.log
        print(f"trained {log['final_primitives']} primitives (from {log['initial_primitives']}) in "
              f"{log['train_seconds']} s")
        if log.get("stopped"):
            stop = log["stopped"]
            print(f"stopped at epoch {stop['epoch'] + 1} of {stop['ceiling']} ({stop['reason']})")
        print_report(result.report)
    print(f"outputs in {plan.run.path}")
