"""`edgedog sfm PHOTOS --out SCENE`: cameras for photos without poses (COLMAP via pycolmap)."""

from __future__ import annotations

import argparse

from edgedog.scenes.sfm import MATCHERS, run_sfm


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text!r}")
    return value


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "sfm", help="recover cameras for a folder of photos (structure from motion)",
        description="Run structure from motion (SIFT, matching, incremental mapping, "
                    "undistortion) on a folder of photos and write a COLMAP scene folder "
                    "(images/ and sparse/) that the other commands read.")
    parser.add_argument("photos", help="folder of overlapping photos (.jpg, .png, ...)")
    parser.add_argument("--out", required=True, help="scene folder to create (must not exist)")
    parser.add_argument("--max-image-size", type=_positive, default=1600, metavar="PIXELS",
                        help="longest image side for features and undistorted images (default 1600)")
    parser.add_argument("--matcher", choices=MATCHERS, default="exhaustive",
                        help="exhaustive: every pair (default); sequential: ordered video frames")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> None:
    run_sfm(args.photos, args.out, max_image_size=args.max_image_size, matcher=args.matcher)
