"""`edgedog eval PRED --scene SCENE | --gt POINTS.ply [--per-curve]`: score predicted edges by the
ABC protocol, and with --per-curve diagnose every ground-truth curve (`edgedog.diagnosis`)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from edgedog.curve_files import read_edges
from edgedog.errors import InputError, OutputError
from edgedog.files import atomic_write_json
from edgedog.groundtruth import ground_truth_for, read_points_ply
from edgedog.metrics import SAMPLE_SPACING, VOXELS_PER_AXIS, EdgeMetrics, evaluate
from edgedog.outputs import check_new_file, output_file
from edgedog.scenes import load_scene
from edgedog.train.run_folder import enclosing_scene
from edgedog.world import check_coordinates


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "eval", help="score predicted edges against ground truth (Acc, Comp, P/R/F at 5/10/20 mm)",
        description="Score predicted 3D edges: EMAP's parametric_edges.json, a PLY of points or "
                    "edges, or an OBJ of polylines. Curves are sampled every 5 mm, voxel-averaged "
                    "on a 256^3 grid over [-1, 1]^3 and compared with the ground-truth points.")
    parser.add_argument("pred", type=Path,
                        help="predicted edges (.json, .ply or .obj), or a run folder (its curves.json)")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--scene", type=Path, help="scene folder whose ground truth to use")
    source.add_argument("--gt", type=Path, help="ground-truth points .ply (in the ground-truth frame)")
    parser.add_argument("--frame", choices=("world", "gt"), default="world",
                        help="frame of the prediction: the scene's world frame (default; mapped "
                             "with the scene's world-to-gt transform) or already the gt frame")
    parser.add_argument("--no-voxel", action="store_true",
                        help="skip the 256^3 voxel averaging of the prediction")
    parser.add_argument("--json", type=Path, default=None,
                        help="where to write the metrics (default: PRED's name + .eval.json, replaced by "
                             "each eval); never a run's own file nor inside a scene folder")
    parser.add_argument("--force", action="store_true", help="replace the --json file if it exists")
    parser.add_argument("--per-curve", action="store_true",
                        help="with --scene: a row per ground-truth curve (id, type, kind: outline, convex "
                             "or concave, length, recall at 5/10/20 mm) saying where a missed one was "
                             "lost (occluded, not drawn in the maps, no primitive, which extraction "
                             "filter, curve fitting), the predicted curves on no edge and why, and recall "
                             "by kind and type; in the --json file under 'per_curve'")
    parser.add_argument("--figure", type=Path, default=None,
                        help="with --per-curve: a PNG of the views that show the most missed curves, the "
                             "ground truth drawn over each by outcome (found, missed and why) with the "
                             "predicted curves on no edge; never a run's own file nor inside a scene folder")
    parser.add_argument("--figure-views", type=int, default=2, choices=range(1, 5), metavar="{1..4}",
                        help="how many views the --figure shows (default 2)")
    parser.set_defaults(run=run)


RUN_CURVES = ("curves.json", "curves.obj", "curves.ply")
"""A run folder's curve files, the first found is scored."""


def prediction_and_run(pred: Path) -> tuple[Path, Path | None]:
    """The curve file to score and the run folder it belongs to (None for a file outside one)."""
    if pred.is_dir():
        found = next((pred / name for name in RUN_CURVES if (pred / name).is_file()), None)
        if found is None:
            raise InputError(pred, f"a folder without {' or '.join(RUN_CURVES)}: not an extracted run")
        return found, pred
    return pred, pred.parent if (pred.parent / "log.json").is_file() else None


def score_file(pred: Path, gt_points, world_to_gt=None, voxelize: bool = True) -> EdgeMetrics:
    """Read, sample, map to the ground-truth frame and score one prediction file."""
    curves = read_edges(pred)
    if world_to_gt is not None:
        curves = curves.transformed(world_to_gt)
    samples = curves.sample(SAMPLE_SPACING)
    if not np.all(np.isfinite(samples)):  # the protocol's voxel grid would drop them silently
        raise InputError(pred, "some points are not finite once mapped into the ground-truth frame")
    if len(samples) == 0:
        raise InputError(pred, "no edge samples to evaluate (empty, or every curve shorter than 5 mm)")
    return evaluate(samples, gt_points, voxelize=voxelize)


def run(args: argparse.Namespace) -> None:
    if args.per_curve and args.scene is None:
        raise InputError(args.gt, "--per-curve needs --scene: the curves, cameras and maps, not only points")
    if args.figure is not None and not args.per_curve:
        raise InputError(args.figure, "--figure draws the per-curve diagnosis: add --per-curve")
    if args.figure is not None and args.figure.suffix.lower() != ".png":
        raise InputError(args.figure, "--figure writes a PNG: name a .png file")
    default = args.pred.with_name(args.pred.name + ".eval.json")
    out = args.json or default
    if args.json is None and enclosing_scene(default) is not None:  # the user named no output there
        raise OutputError(default, "would lie inside a scene folder, where edgedog never writes: pass "
                                   "--json FILE outside it")
    check_new_file(out, args.force, default)  # before the work, not after it
    if args.figure is not None:
        check_new_file(args.figure, args.force)  # also refuses a scene folder
    args.pred, run_folder = prediction_and_run(args.pred)
    if args.scene is not None:
        scene = load_scene(args.scene)
        ground_truth = ground_truth_for(scene.root)
        if ground_truth is None:
            raise InputError(scene.root, "no ground truth found beside the scene; pass --gt POINTS.ply")
        gt_points, gt_source = ground_truth.load(), ground_truth.description
        world_to_gt = scene.world_to_gt if args.frame == "world" else None
    else:
        gt_points, gt_source, world_to_gt = read_points_ply(args.gt), str(args.gt), None
        check_coordinates(args.gt, gt_points)  # farther ones overflow the distances to Infinity
    metrics = score_file(args.pred, gt_points, world_to_gt, voxelize=not args.no_voxel)
    print(f"{args.pred}  vs  {gt_source}")
    print(metrics.table())
    report = {}
    if args.per_curve:
        diagnosis, figure = per_curve(args.pred, run_folder, scene, ground_truth, gt_points, world_to_gt,
                                      not args.no_voxel, args.figure, args.figure_views, args.force)
        print(diagnosis.table())
        report = {"per_curve": diagnosis.to_dict()}
        if figure:
            print(f"figure written to {args.figure} (views {', '.join(map(str, figure))})")
    with output_file(out, args.force, default):
        atomic_write_json(out, {
            "prediction": str(args.pred.resolve()),
            "ground_truth": gt_source,
            "protocol": {"sample_spacing": SAMPLE_SPACING, "voxels_per_axis": VOXELS_PER_AXIS,
                         "voxelized": not args.no_voxel},
            "metrics": metrics.to_dict(),
            **report,
        })
    print(f"metrics written to {out}")


def per_curve(pred: Path, run_folder: Path | None, scene, ground_truth, gt_points: np.ndarray,
              world_to_gt: np.ndarray | None, voxelize: bool, figure: Path | None = None, views: int = 2,
              force: bool = False):
    """The per-curve diagnosis of `pred` against the scene's ground truth, and with `figure` its
    picture written there (`edgedog.diagnosis_figure`; the views shown are returned, else []).
    The views are the run's (as it was trained: resolution, damaged views left out, its edge
    maps) where `pred` belongs to a run, the scene's otherwise."""
    from edgedog.curves.extract import run_scene
    from edgedog.diagnosis import diagnose, ground_truth_curves

    source = ground_truth_curves(ground_truth, scene.root)
    if run_folder is not None:
        scene_views, detector = run_scene(run_folder)
    else:
        scene_views, detector = scene, next(iter(scene.detectors), None)
    curves = read_edges(pred)
    if world_to_gt is not None:
        curves = curves.transformed(world_to_gt)
    diagnosis = diagnose(curves, gt_points, source, scene_views, detector, run_folder, voxelize)
    shown: list[int] = []
    if figure is not None:
        from edgedog.diagnosis_figure import draw_missed_edges

        with output_file(figure, force):
            name = pred.parent.name if run_folder is not None else pred.name
            shown = draw_missed_edges(diagnosis, source, curves, scene_views, figure, views,
                                      title=f"{scene.root.name}, {name}")
    return diagnosis, shown
