"""`edgedog train SCENE --out RUN`: fit EdgeDoG primitives to a scene's pseudo-edge maps."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from edgedog.errors import InputError


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "train", help="train EdgeDoG primitives on a scene's pseudo-edge maps",
        description="Train (or, with --resume, continue) a run, then extract its curves. The run "
                    "folder gets config.json, checkpoint.pt, primitives.ply, points.ply, log.json, "
                    "and from the extraction curves.json/.obj/.ply, edge_points.ply and "
                    "extract.json (with scores when the scene has ground truth).")
    parser.add_argument("scene", help="scene folder")
    parser.add_argument("--out", type=Path, required=True, help="run folder")
    parser.add_argument("--preset", choices=("paper", "fast"), default="paper",
                        help="paper: EdgeGaussians' 400 epochs at full resolution; fast: 100 at half")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a setting of edgedog.train.config.TrainConfig (repeatable)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    from edgedog.commands.extract import print_report
    from edgedog.curves.report import extract_with_report
    from edgedog.files import read_json
    from edgedog.scenes import load_scene
    from edgedog.train.config import preset, with_overrides
    from edgedog.train.run_folder import RunFolder, read_run, write_run
    from edgedog.train.trainer import CHECKPOINT, Trainer

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
