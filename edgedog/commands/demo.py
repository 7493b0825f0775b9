"""`edgedog demo`: the main job on the built-in scene: generate it on first use, train with the
preview preset, extract and export the curves, and score them against the exact ground truth."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from edgedog.builtin.scene import builtin_scene_path
from edgedog.commands.reports import print_report
from edgedog.files import default_cache


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "demo", help="train, extract and score on the built-in scene (generated on first use)",
        description="Generate the built-in scene (a CAD part with exact ground truth) if needed, train "
                    "it with the preview preset (resuming or reusing an earlier demo run), extract and "
                    "export its curves, and print a short report.")
    parser.add_argument("--cache", type=Path, default=None,
                        help=f"folder for generated scenes and the demo run (default: $EDGEDOG_CACHE or "
                             f"{default_cache()})")
    parser.add_argument("--out", type=Path, default=None,
                        help="run folder (default: <cache>/runs/demo-boss-canny-<config digest>, named "
                             "after the scene and the configuration)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    from edgedog.train.config import preset
    from edgedog.train.lifecycle import FINISHED, REUSE, execute, plan_run
    from edgedog.train.run_folder import config_digest

    start = time.perf_counter()
    folder = builtin_scene_path(args.cache, progress=not args.quiet)
    generated = time.perf_counter() - start
    config = preset("preview")
    # Named after the scene and the configuration: a demo run of an older version's scene or
    # defaults is never resumed, nor refused in the way of this one.
    out = args.out or (args.cache or default_cache()) / "runs" / f"demo-{folder.name}-{config_digest(config)}"
    plan = plan_run(out, folder, "preview", config, REUSE).check()
    if plan.state == FINISHED:
        print(f"reusing the finished demo run in {out}")
    result = execute(plan, progress=not args.quiet)  # on the scene the plan loaded
    log, report = result.log, result.report
    print(f"scene      {folder} ({len(plan.scene)} views, {log['detector']} edge maps; "
          f"ready in {generated:.1f} s)")
    print(f"trained    {log['final_primitives']} primitives (from {log['initial_primitives']}) "
          f"in {log['train_seconds']:.1f} s")
    print_report(report)
    print(f"curves     {out / 'curves.obj'}, {out / 'curves.ply'}, {out / 'curves.json'}")
    print(f"done in {time.perf_counter() - start:.1f} s")
