"""`edgedog make-scene --shape NAME | --family INDEX | --cad FILE | --abc MESH FEATURES --out DIR`:
a built-in CAD part, a design of the procedural family, any STEP or BREP file, or an ABC object as
ABC distributes it, as an ABC-NEF-style scene with its exact sharp edges as ground truth."""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from edgedog.edges.registry import WEIGHTS_HELP
from edgedog.errors import ConfigError

MAX_VIEWS = 1000
"""Most training views: twenty times ABC-NEF's 50 (each view is rendered and written)."""
MAX_SIZE = 4096
"""Largest image side: five times ABC-NEF's 800 px, within every GPU's render target size."""


def add_parser(subparsers) -> None:
    from edgedog.synthetic.render import LIGHTINGS
    from edgedog.synthetic.shapes import SHAPES

    parser = subparsers.add_parser(
        "make-scene", help="render a built-in CAD part or a STEP/BREP file as a scene with exact edges",
        description="Render a procedural CAD part, the solid of a STEP or BREP file, or an ABC object's "
                    "mesh, offscreen (EGL) from cameras on a sphere of radius 4, as ABC-NEF does, with "
                    "pseudo-edge maps of a detector and ground-truth points sampled every 5 mm from the "
                    "part's exact sharp edges (where its faces' normals turn by more than 20 degrees: "
                    "chamfers are sharp, fillets are not; an ABC object's `sharp` curves). The part is "
                    "normalised into [0, 1]^3 like an ABC object. Optional degradations spoil the "
                    "training views for robustness tests.",
        epilog="shapes: " + "; ".join(f"{name}: {description}" for name, description in SHAPES.items()))
    part = parser.add_mutually_exclusive_group(required=True)
    part.add_argument("--shape", choices=list(SHAPES), metavar="NAME", help="a built-in part (see below)")
    part.add_argument("--cad", type=Path, metavar="FILE",
                      help="a STEP (.step, .stp) or BREP (.brep) file holding one part's closed solid(s)")
    part.add_argument("--family", type=int, metavar="INDEX",
                      help="design INDEX (from 0) of the procedural family of 42 ABC-like parts, sizes "
                           "drawn from --seed")
    part.add_argument("--abc", type=Path, nargs=2, metavar=("MESH", "FEATURES"),
                      help="an ABC object: its triangle mesh (.obj) and features file (.yml); ground "
                           "truth: its sharp curves by the ABC protocol")
    parser.add_argument("--unit", default=None, metavar="UNIT",
                        help="length unit (mm, cm, m or in) of a --cad file that declares none (BREP "
                             "files, unit-less STEP files)")
    parser.add_argument("--out", type=Path, required=True, help="scene folder to create (must not exist)")
    parser.add_argument("--views", type=int, default=50,
                        help=f"training views, at most {MAX_VIEWS} (default 50)")
    parser.add_argument("--size", type=int, default=800,
                        help=f"image width and height in pixels, 16 to {MAX_SIZE}; the focal length scales "
                             "with it (default 800)")
    parser.add_argument("--seed", type=int, default=0,
                        help="draws the built-in part's dimensions and the degradations (default 0)")
    parser.add_argument("--detector", default="auto",
                        help="edge maps by this detector (see `edgedog edges`), or 'exact': the visible "
                             "ground-truth curves (default auto)")
    parser.add_argument("--weights", type=Path, default=None, help=WEIGHTS_HELP)
    parser.add_argument("--lighting", choices=LIGHTINGS, default="abc-nef",
                        help="the images' grey shading: ABC-NEF's bright, soft look (fitted to its "
                             "renders) or the built-in scenes' two lights, with stronger contrast "
                             "between faces (default abc-nef)")
    spoil = parser.add_argument_group("degradations (training views only)")
    spoil.add_argument("--image-noise", type=float, default=0.0, metavar="STD",
                       help="Gaussian noise on the object's colours, std in [0, 1] units")
    spoil.add_argument("--pose-noise-deg", type=float, default=0.0, metavar="DEG",
                       help="turn every written pose by this angle (images keep the true poses)")
    spoil.add_argument("--pose-noise-mm", type=float, default=0.0, metavar="MM",
                       help="move every written camera centre this far (1 unit = 1000 mm)")
    spoil.add_argument("--drop-edges", type=float, default=0.0, metavar="FRACTION",
                       help="share of the views whose edge maps lose a few edge segments")
    spoil.add_argument("--keep-views", type=int, default=None, metavar="N",
                       help="keep a random subset of N of the views (uneven coverage)")
    parser.set_defaults(run=run)


def degradations_from(args: argparse.Namespace):
    """The degradations the options ask for; ConfigError for values out of range."""
    from edgedog.synthetic.degrade import Degradations

    if not 1 <= args.views <= MAX_VIEWS:
        raise ConfigError(f"--views {args.views}: must be between 1 and {MAX_VIEWS}")
    if not 16 <= args.size <= MAX_SIZE:
        raise ConfigError(f"--size {args.size}: must be between 16 and {MAX_SIZE} pixels")
    if args.seed < 0:
        raise ConfigError(f"--seed {args.seed}: must not be negative")
    for option, value in (("--image-noise", args.image_noise), ("--pose-noise-deg", args.pose_noise_deg),
                          ("--pose-noise-mm", args.pose_noise_mm)):
        if not (math.isfinite(value) and value >= 0):
            raise ConfigError(f"{option} {value}: noise levels must not be negative (nor NaN or infinite)")
    if not 0 <= args.drop_edges <= 1:
        raise ConfigError(f"--drop-edges is a fraction in [0, 1], got {args.drop_edges}")
    if args.keep_views is not None and not 1 <= args.keep_views <= args.views:
        raise ConfigError(f"--keep-views must be between 1 and --views ({args.views}), got {args.keep_views}")
    return Degradations(image_noise=args.image_noise, rotation_deg=args.pose_noise_deg,
                        translation_mm=args.pose_noise_mm, drop_fraction=args.drop_edges,
                        keep_views=args.keep_views)


def run(args: argparse.Namespace) -> None:
    from edgedog.builtin.writer import MANIFEST, write_scene
    from edgedog.files import read_json
    from edgedog.synthetic.shapes import make_part

    degradations = degradations_from(args)
    if args.unit is not None and args.cad is None:
        raise ConfigError("--unit is the length unit of a --cad file; leave it out otherwise")
    start = time.perf_counter()
    if args.cad is not None:
        from edgedog.synthetic.cad_file import cad_part  # the CAD kernel reads the file

        part, made = cad_part(args.cad, args.unit), str(args.cad)
    elif args.family is not None:
        from edgedog.synthetic.family import family_part

        part = family_part(args.family, args.seed)
        made = f"family design {args.family}, {part.name} (seed {args.seed})"
    elif args.abc is not None:
        from edgedog.synthetic.abc_file import abc_part

        part, made = abc_part(*args.abc), str(args.abc[0])
    else:
        part, made = make_part(args.shape, args.seed), f"{args.shape} (seed {args.seed})"
    folder = write_scene(args.out, part, args.views, args.size, seed=args.seed, detector=args.detector,
                         weights=args.weights, degradations=degradations, progress=True,
                         lighting=args.lighting)
    detector = read_json(folder / MANIFEST)["edge_detector"]
    print(f"{folder}: {made}, {degradations.keep_views or args.views} views at "
          f"{args.size}x{args.size} with {detector} edge maps, {len(part.curves)} feature curves, "
          f"{len(part.ground_truth())} ground-truth points; done in {time.perf_counter() - start:.1f} s")
