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
                    "extract.json (with scores when the scene has ground truth).")
    parser.add_argument("scene", help="scene folder")
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--preset", choices=PRESETS, default="paper",
                        help="paper: EdgeGaussians' 400 epochs at full resolution; fast: 200 at full; "
                             "preview: 100 at half")
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
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    from edgedog.commands.extract import print_report
    from edgedog.curves.report import extract_with_report
    from edgedog.files import read_json
    from edgedog.scenes import load_scene
    from edgedog.train.config import preset, with_overrides
    from edgedog.train.layered import is_layered
    from edgedog.train.run_folder import RunFolder, read_run, write_run
    from edgedog.train.trainer import CHECKPOINT, Trainer

    if args.layers or is_layered(args.out):
        return run_layered(args)
    if args.resume:
        if not (args.out / CHECKPOINT).is_file():
            raise InputError(args.out, "no checkpoint to resume from")
        config = read_run(args.out).config
    else:
        if (args.out / CHECKPOINT).is_file():
            raise InputError(args.out, "already holds a run; pass --resume to continue it, or choose "
                                       "another --out")
        config = with_overrides(preset(args.preset), args.overrides)
        write_run(RunFolder(args.out, Path(args.scene).resolve(), args.preset, config))
    scene = load_scene(args.scene, downscale=config.downscale)
    trainer = Trainer(scene, config, args.out, progress=not args.quiet)
    print(json.dumps({"detector": trainer.detector, "init": trainer.init_report.get("method"),
                      "initial_primitives": trainer.initial_count, "resumed_at_step": trainer.step_index}))
    trainer.run()
    log = read_json(args.out / "log.json")
    print(f"trained {log['final_primitives']} primitives (from {log['initial_primitives']}) in "
          f"{log['train_seconds']} s")
    _, report = extract_with_report(args.out, scene, trainer.detector)
    print_report(report)
    print(f"outputs in {args.out}")


def run_layered(args: argparse.Namespace) -> None:
    """`--layers`: progressive training of the levels, then curves per layer and cumulative."""
    from edgedog.edges.levels import resolve_levels
    from edgedog.scenes import load_scene
    from edgedog.train.config import preset, with_overrides
    from edgedog.train.layered import LayeredRun, is_layered, read_layered, write_layered

    if args.resume:
        if not is_layered(args.out):
            raise InputError(args.out, "no layered run to resume (layers.json is missing)")
        run = read_layered(args.out)
    else:
        if is_layered(args.out) or args.out.joinpath("L0").exists():
            raise InputError(args.out, "already holds a layered run; pass --resume to continue it, or "
                                       "choose another --out")
        names = [name.strip() for name in args.layers.split(",") if name.strip()]
        run = LayeredRun(args.out, Path(args.scene).resolve(), args.preset,
                         with_overrides(preset(args.preset), args.overrides),
                         resolve_levels(names, args.levels))
        write_layered(run)
    scene = load_scene(run.scene, downscale=run.base.downscale)

    def announce(index, trainer) -> None:
        level = run.levels[index]
        print(json.dumps({"layer": level.name, "maps": trainer.detector, "floor": level.floor,
                          "lower_primitives": len(trainer.lower), "initial_primitives": trainer.initial_count,
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
