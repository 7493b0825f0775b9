"""`edgedog info SCENE`: what a scene folder holds."""

from __future__ import annotations

import argparse

import numpy as np

from edgedog.commands.scene_args import add_scene_options, open_scene
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import Scene


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser("info", help="print a scene's format, views, edge maps, ground truth",
                                   description="Print what a scene folder holds.")
    parser.add_argument("scene", help="scene folder (NeRF/Blender, EMAP, NeuS/DTU or COLMAP)")
    add_scene_options(parser)
    parser.set_defaults(run=run)


def _masks(scene: Scene) -> str:
    """Where the views' masks come from, and which views lack one when only some have one."""
    masked = scene.masked_views
    if not masked:
        return "none"
    view = scene.views[masked[0]]
    source = "from the images' alpha" if view.mask_path is None else f"files in {view.mask_path.parent.name}/"
    lacking = [view.name for view in scene.views if view.alpha is False and view.mask_path is None]
    if not lacking:  # damaged images (alpha unknown) are listed on their own row
        return source
    listed = ", ".join(lacking[:5]) + (", ..." if len(lacking) > 5 else "")
    return f"{source}, but none in {len(lacking)} of the {len(scene)} views ({listed})"


def summary(scene: Scene) -> str:
    """A few aligned lines describing the scene (reads the ground truth, no image)."""
    cam = scene.camera(0)
    sizes = {(v.camera.width, v.camera.height) for v in scene.views}
    focal = np.mean([scene.camera(i).K[0, 0] for i in range(len(scene))])
    lo, hi = scene.bounds
    rows = [
        ("scene", f"{scene.root}"),
        ("format", scene.format),
        ("views", f"{len(scene)} at {cam.width}x{cam.height}"
                  + (f" (downscaled {scene.downscale}x)" if scene.downscale > 1 else "")
                  + ("" if len(sizes) == 1 else f", {len(sizes)} different sizes on disk")),
        ("mean focal", f"{focal:.1f} px"),
        ("edge maps", ", ".join(scene.detectors) or "none (compute them with a detector)"),
        ("masks", _masks(scene)),
        ("bounds", f"[{lo[0]:.3f}, {lo[1]:.3f}, {lo[2]:.3f}] to [{hi[0]:.3f}, {hi[1]:.3f}, {hi[2]:.3f}]"),
    ]
    for path, problem in scene.damaged.items():
        rows.append(("damaged", f"{path}: {problem}"))
    if scene.sfm_points is not None:
        rows.append(("sfm points", f"{len(scene.sfm_points)}"))
    ground_truth = ground_truth_for(scene.root)
    if ground_truth is None:
        rows.append(("ground truth", "none"))
    else:
        points = ground_truth.load()
        rows.append(("ground truth", f"{len(points)} edge points from {ground_truth.description}"))
    width = max(len(name) for name, _ in rows)
    return "\n".join(f"{name:<{width}}  {value}" for name, value in rows)


def run(args: argparse.Namespace) -> None:
    print(summary(open_scene(args.scene, args)))
