"""`edgedog calibrate-detector`: measure where a detector draws edges relative to the true ones,
on built-in parts (`--detector NAME`, saved as its calibration record) or on a dataset's own
maps against its ground truth (`--scene SCENE --maps NAME`)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from edgedog.bench import calibrate
from edgedog.commands.arguments import MAX_SIZE, bounded_integer
from edgedog.commands.scene_args import add_scene_options, open_scene
from edgedog.edges.calibration import OffsetMeasurement, save_calibration
from edgedog.edges.registry import WEIGHTS_HELP, detector_names
from edgedog.errors import ConfigError
from edgedog.train.config import MAX_SEED

MAX_VIEWS = 1000
"""Orbit views rendered per part and size."""


def _names(text: str) -> list[str]:
    return [name.strip() for name in text.split(",") if name.strip()]


def _sizes(text: str) -> list[int]:
    try:
        sizes = [int(size) for size in _names(text)]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 16 or max(sizes) > MAX_SIZE:
        raise argparse.ArgumentTypeError(f"expected image sizes like 400,800 (px, in [16, {MAX_SIZE}]), "
                                         f"got {text!r}")
    return sizes


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "calibrate-detector", help="measure where a detector draws edges relative to exact ground truth",
        description="With --detector: render built-in parts with exact ground-truth curves, run the "
                    "detector on the renders and measure where its maps peak relative to the curves "
                    "(2D offset, per edge orientation, outward on silhouettes, band width); the record "
                    "is saved under the user cache, keyed by detector and weights. With --scene and "
                    "--maps: the same measurement on a dataset's own maps against its ground truth. "
                    "Offsets are the map's ridge relative to the truth, in px (x right, y down).")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--detector", help=f"detector to calibrate: {', '.join(detector_names())}")
    source.add_argument("--scene", help="scene folder whose own maps to measure (needs ground truth)")
    parser.add_argument("--maps", help="with --scene: which of the scene's edge maps, e.g. pidinet")
    parser.add_argument("--weights", type=Path, default=None,
                        help=WEIGHTS_HELP)
    shapes = ",".join(calibrate.DEFAULT_SHAPES)
    parser.add_argument("--shapes", type=_names, default=list(calibrate.DEFAULT_SHAPES),
                        help=f"built-in parts to render, comma-separated (default {shapes})")
    parser.add_argument("--views", type=bounded_integer(1, MAX_VIEWS), default=8,
                        help="orbit views per part and size (default 8)")
    parser.add_argument("--sizes", type=_sizes, default=[400, 800],
                        help="image sizes in px, comma-separated (default 400,800)")
    parser.add_argument("--seed", type=bounded_integer(0, MAX_SEED), default=0,
                        help="seed of the parts' dimensions (default 0)")
    parser.add_argument("--json", type=Path, default=None, metavar="OUT", help="also write the result here "
                        "(never over a run's own file nor inside a scene folder)")
    parser.add_argument("--force", action="store_true", help="replace the --json file if it exists")
    add_scene_options(parser)
    parser.set_defaults(run=run)


def _measurement_lines(measurement: OffsetMeasurement) -> list[str]:
    """Human summary of an `OffsetMeasurement`."""
    dx, dy = measurement.offset_px
    lines = [f"offset        dx {dx:+.2f} px, dy {dy:+.2f} px  (map ridge relative to the ground truth; "
             f"{measurement.points} points)",
             f"profile       width {measurement.profile.width_px:.2f} px (Gaussian sigma of the band)"]
    silhouette = measurement.silhouette
    if silhouette is not None:
        lines.append(f"silhouettes   peak {silhouette.peak_px:+.2f} px outside the object, asymmetry "
                     f"{silhouette.asymmetry:+.2f}, width {silhouette.width_px:.2f} px "
                     f"({measurement.silhouette_points} points)")
    orientations = ", ".join(f"{o.angle_deg:g}: {o.offset_px:+.2f}" for o in measurement.orientations)
    lines.append(f"along normal  {orientations}  (normal angle in degrees: px)")
    return lines


def _print_and_write(lines: list[str], record: dict, args: argparse.Namespace) -> None:
    from edgedog.files import atomic_write_json
    from edgedog.outputs import output_file

    print("\n".join(lines))
    print(json.dumps(record))  # one line, last: for scripts
    if args.json is not None:
        with output_file(args.json, args.force):
            atomic_write_json(args.json, record)


def run(args: argparse.Namespace) -> None:
    from edgedog.outputs import check_new_file

    if args.json is not None:
        check_new_file(args.json, args.force)  # before the work, not after it
    if args.scene is not None:
        if args.maps is None:
            raise ConfigError("--scene needs --maps NAME: which of the scene's edge maps to measure")
        scene = open_scene(args.scene, args)
        measurement = calibrate.measure_scene_maps(scene, args.maps, progress=True)
        from edgedog.groundtruth import ground_truth_for

        lines = [f"{scene.root}: '{args.maps}' maps against {ground_truth_for(scene.root).description}",
                 *_measurement_lines(measurement)]
        _print_and_write(lines, measurement.to_dict(), args)
        return
    if args.maps is not None:
        raise ConfigError("--maps goes with --scene; with --detector the maps are computed on built-in parts")
    from edgedog.edges.registry import make_detector
    from edgedog.synthetic.shapes import make_part

    for name in args.shapes:
        make_part(name)  # unknown names fail now, not after minutes of detection
    detector = make_detector(args.detector, args.weights)
    calibration = calibrate.calibrate_detector(detector, args.shapes, args.views, args.sizes, args.seed,
                                               progress=True)
    path = save_calibration(calibration)
    lines = [f"{calibration.detector} ({calibration.fingerprint}) on {', '.join(calibration.shapes)}, "
             f"{calibration.views} views at {', '.join(map(str, args.sizes))} px",
             *_measurement_lines(calibration.overall)]
    for size, measurement in calibration.per_size.items():
        dx, dy = measurement.offset_px
        lines.append(f"at {size} px".ljust(14) + f"dx {dx:+.2f} px, dy {dy:+.2f} px, "
                     f"width {measurement.profile.width_px:.2f} px")
    lines.append(f"record        {path}")
    _print_and_write(lines, calibration.to_dict(), args)
