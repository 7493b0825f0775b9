"""`edgedog eval PRED --scene SCENE | --gt POINTS.ply`: score predicted edges by the ABC protocol."""

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
    parser.add_argument("pred", type=Path, help="predicted edges (.json, .ply or .obj)")
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
    parser.set_defaults(run=run)


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
    default = args.pred.with_name(args.pred.name + ".eval.json")
    out = args.json or default
    if args.json is None and enclosing_scene(default) is not None:  # the user named no output there
        raise OutputError(default, "would lie inside a scene folder, where edgedog never writes: pass "
                                   "--json FILE outside it")
    check_new_file(out, args.force, default)  # before the work, not after it
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
    with output_file(out, args.force, default):
        atomic_write_json(out, {
            "prediction": str(args.pred.resolve()),
            "ground_truth": gt_source,
            "protocol": {"sample_spacing": SAMPLE_SPACING, "voxels_per_axis": VOXELS_PER_AXIS,
                         "voxelized": not args.no_voxel},
            "metrics": metrics.to_dict(),
        })
    print(f"metrics written to {out}")
