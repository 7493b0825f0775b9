"""`edgedog bench ...`: measured speed and accuracy; results go to docs/BENCHMARKS.md."""

from __future__ import annotations

import argparse
import json
import typing
from pathlib import Path

from edgedog.bench.ablation import TABLES, select_rows
from edgedog.commands.arguments import MAX_SIZE, bounded_integer
from edgedog.edges.registry import WEIGHTS_HELP
from edgedog.errors import ConfigError, OutputError
from edgedog.files import atomic_write_json
from edgedog.outputs import check_new_file, check_output_folder, output_file
from edgedog.train.config import DEFAULT_PRESET, MAX_SEED, PRESETS, Kernel

MAX_BENCH_PRIMITIVES = 100_000
"""The torch reference keeps each tile's (pixels x primitives) matrices for its backward: about
40 KB per primitive at 800 px (1.2 GB at the default 20,000), so about 5 GB at this bound."""
MAX_VIEWS = 1000
"""Views timed; each costs a forward, a backward and a Fisher pass."""


def _seeds(text: str) -> tuple[int, ...]:
    """An argparse type: comma-separated seeds in [0, MAX_SEED], each once."""
    try:
        seeds = tuple(dict.fromkeys(int(item) for item in text.split(",") if item.strip()))
    except ValueError:
        seeds = ()
    if not seeds or any(not 0 <= seed <= MAX_SEED for seed in seeds):
        raise argparse.ArgumentTypeError(f"must be comma-separated integers in [0, {MAX_SEED}], got {text!r}")
    return seeds


def _add_batch_options(parser: argparse.ArgumentParser) -> None:
    """The options of a bench run as a batch: seeds, where its runs execute, --quiet."""
    parser.add_argument("--seeds", type=_seeds, default=(0,), metavar="N,...",
                        help="training seeds: each row or budget trains once per seed (default 0)")
    parser.add_argument("--address", default=None, metavar="auto|HOST:PORT|ray://HOST:PORT",
                        help="a Ray cluster to run on, as for edgedog batch; default: Ray started on this "
                             "machine when it is installed, else one run after another in this process")
    parser.add_argument("--cpus-per-run", type=bounded_integer(1, 1024), default=1, metavar="N",
                        help="CPUs (and torch/OpenMP threads) of each run (default 1)")
    parser.add_argument("--quiet", action="store_true", help="no line per finished run")


def _add_run_arguments(parser: argparse.ArgumentParser, scene_help: str, out_help: str, set_help: str,
                       preset: str | None = DEFAULT_PRESET) -> None:
    """The scene, --out, --preset (default `preset`; None: no --preset) and --set of a bench that
    trains runs."""
    parser.add_argument("scene", type=Path, help=scene_help)
    parser.add_argument("--out", type=Path, required=True, help=out_help)
    if preset is not None:
        parser.add_argument("--preset", choices=PRESETS, default=preset)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help=set_help)


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser("bench", help="run a benchmark and print its JSON")
    kinds = parser.add_subparsers(dest="benchmark", required=True, metavar="BENCHMARK")
    raster = kinds.add_parser("raster", help="rasterizer speed: the kernels against the torch reference",
                              description="Render 800x800 views of an ABC-like scene of thin primitives "
                                          "and time forward, backward and Fisher per view.")
    raster.add_argument("--primitives", type=bounded_integer(1, MAX_BENCH_PRIMITIVES), default=20000)
    raster.add_argument("--size", type=bounded_integer(16, MAX_SIZE), default=800,
                        help="image width and height")
    raster.add_argument("--views", type=bounded_integer(1, MAX_VIEWS), default=50)
    raster.add_argument("--reference-views", type=bounded_integer(1, MAX_VIEWS), default=1,
                        help="views timed with the slow torch reference (at most --views)")
    raster.add_argument("--kernel", choices=typing.get_args(Kernel), default="dog")
    raster.add_argument("--seed", type=bounded_integer(0, MAX_SEED), default=0)
    raster.add_argument("--device", choices=("auto", "cpu", "cuda"), default="auto",
                        help="where the kernels run (auto: CUDA when built with it and a GPU is seen)")
    _add_json_arguments(raster)
    raster.set_defaults(run=run_raster)
    edges = kinds.add_parser("edges", help="2D edge detectors' speed per megapixel",
                             description="Time every available detector on one image of the built-in "
                                         "scene (PiDiNet's NYUD and Multicue variants when their weights "
                                         "are given).")
    edges.add_argument("--size", type=bounded_integer(16, MAX_SIZE), default=800,
                       help="image width and height")
    edges.add_argument("--repeats", type=bounded_integer(1, 100), default=3)
    edges.add_argument("--weights", type=Path, default=None, help=WEIGHTS_HELP)
    _add_json_arguments(edges)
    edges.set_defaults(run=run_edges)
    ablation = kinds.add_parser(
        "ablation", help="EdgeDoG's components, weighting functions (the paper's Tables 3 and 4) and "
                         "corrections of the maps' bias",
        description="Train one run per row and seed (baseline to full model; each weighting w(Up)), "
                    "extract and score its curves, and write OUT/ablation.json and OUT/ablation.md "
                    "(per row: mean and sample standard deviation over the seeds) beside the batch's "
                    "tables (OUT/batch.*). The runs go through the batch path (see edgedog batch); "
                    "finished runs in OUT are reused, unfinished ones resumed.")
    _add_run_arguments(ablation, "scene folder with ground truth", "folder for the runs and the tables",
                       "override a training setting for every row (repeatable)")
    ablation.add_argument("--tables", default="components,weighting",
                          help="comma-separated: components (Table 3), weighting (Table 4), corrections "
                               "(the maps' bias: calibrated shift, learned shift, thin maps, profile loss, "
                               "outline pulled onto the masks)")
    ablation.add_argument("--rows", default=None, metavar="KEY,...",
                          help="only these rows of the tables: " + "; ".join(
                              f"{table} " + ", ".join(row.key for row in select_rows((table,)))
                              for table in TABLES))
    _add_batch_options(ablation)
    ablation.set_defaults(run=run_ablation)
    layers = kinds.add_parser(
        "layers", help="multi-granularity layers against a single run on the finest maps (Fig. 7)",
        description="Train a layered run (OUT/layered: L0, L1, ... each on its own maps with the layers "
                    "below fixed) and a direct run on the finest level's maps (OUT/direct), extract and "
                    "score every layer, every cumulative stack and the direct run, and write "
                    "OUT/layers.json, OUT/layers.md and the figure OUT/layers.png (rendered offscreen). "
                    "Finished runs are reused, unfinished ones resumed.")
    _add_run_arguments(layers, "scene folder", "folder for the runs, the table and the figure",
                       "override a training setting of every run (repeatable)", preset="preview")
    layers.add_argument("--layers", default="L0,L1,L2", metavar="L0,L1,...", help="the levels to stack")
    layers.add_argument("--level", dest="levels", action="append", default=[],
                        metavar="NAME=DETECTOR[@FLOOR]",
                        help="define a level's maps (as for edgedog train --level)")
    layers.add_argument("--no-figure", action="store_true", help="skip the figure (needs EGL)")
    layers.add_argument("--quiet", action="store_true", help="no progress bars")
    layers.set_defaults(run=run_layers)
    _add_steps(kinds)
    _add_speed_error(kinds)
    _add_sfm_vs_cameras(kinds)
    _add_distorted_copy(kinds)
    _add_edge_length(kinds)
    _add_extraction(kinds)


def _add_steps(kinds) -> None:
    steps = kinds.add_parser(
        "steps", help="where a training step's time goes: time per step of each stage of the trainer",
        description="Train one run in OUT/run (a new folder) as edgedog train does, recording evenly "
                    "spaced windows of steps with torch.profiler; write OUT/steps.json and OUT/steps.md: "
                    "each stage's milliseconds per step (rasterize, loss with the pixel uncertainty, "
                    "backward, Adam, ...), the rest of the step, and the operators with the most time of "
                    "their own. The profiler slows the recorded steps a little; the run's own time per "
                    "step is printed beside them.")
    _add_run_arguments(steps, "scene folder", "a new folder for the run and the tables",
                       "override a training setting (repeatable)")
    steps.add_argument("--windows", type=int, default=10, help="recorded windows, spread over the run")
    steps.add_argument("--window-steps", type=int, default=20, help="steps recorded per window")
    steps.add_argument("--quiet", action="store_true", help="no progress bar")
    steps.set_defaults(run=run_steps)


def _add_speed_error(kinds) -> None:
    from edgedog.bench.speed_error import BUDGETS, DEFAULT_BUDGETS, MAX_EVALS

    speed = kinds.add_parser(
        "speed-error", help="error of the extracted curves against training time, for a few budgets",
        description="Train one run per budget and seed in OUT, pausing at evenly spaced epochs to "
                    "extract and score the curves; write OUT/speed_error.csv, .md and .png beside the "
                    "batch's tables (OUT/batch.*). Seconds are training time only. The runs go through "
                    "the batch path (see edgedog batch); finished ones in OUT are reused, unfinished "
                    "ones resumed. Budgets: "
                    + "; ".join(f"{b.name}: {b.description}" for b in BUDGETS.values()) + ".")
    _add_run_arguments(speed, "scene folder with ground truth", "folder for the runs and the summary",
                       "override a training setting for every budget, before the budget's own downscale "
                       "or epoch share (repeatable)", preset=None)
    speed.add_argument("--budgets", default=DEFAULT_BUDGETS,
                       help=f"comma-separated budget names (default {DEFAULT_BUDGETS})")
    speed.add_argument("--evals", type=bounded_integer(1, MAX_EVALS), default=5,
                       help="evaluation points per run, evenly spaced in epochs, the last at the end")
    _add_batch_options(speed)
    speed.set_defaults(run=run_speed_error)


def _add_sfm_vs_cameras(kinds) -> None:
    from edgedog.scenes.sfm import MATCHERS

    sfm = kinds.add_parser(
        "sfm-vs-cameras",
        help="curves from the photos alone (edgedog sfm) against curves from the known cameras",
        description="Recover the cameras of a scene's photos with edgedog sfm (OUT/sfm-scene), train on it "
                    "(OUT/sfm-run) and on the scene's own cameras at the same resolution (OUT/cameras-run), "
                    "carry the SfM run's curves into the scene's frame by the similarity between the two "
                    "camera sets (Umeyama on the centres, matched by image name), and write the distances "
                    "between the two curve sets (median and 90th percentile, each direction and both, in "
                    "scene units and as a share of the object's size; also on the object alone when the "
                    "scene has masks) to OUT/sfm_vs_cameras.json and .md. The SfM scene and finished runs "
                    "in OUT are reused, unfinished runs resumed.")
    _add_run_arguments(sfm, "scene folder with known cameras (its photos in one folder)",
                       "folder for the SfM scene, the two runs and the tables",
                       "override a training setting of both runs (repeatable)")
    sfm.add_argument("--max-image-size", type=bounded_integer(16, MAX_SIZE), default=800, metavar="PIXELS",
                     help="longest side of the SfM scene's images (edgedog sfm --max-image-size); the "
                          "known-camera run is downscaled to match (default 800)")
    sfm.add_argument("--matcher", choices=MATCHERS, default="exhaustive", help="as for edgedog sfm")
    sfm.add_argument("--quiet", action="store_true", help="no progress bars")
    sfm.set_defaults(run=run_sfm_vs_cameras)


def _add_distorted_copy(kinds) -> None:
    copy = kinds.add_parser(
        "distorted-copy", help="a nerfstudio copy with distorted cameras against the original scene",
        description="Write a nerfstudio copy of a pinhole scene with ground truth (OUT/copy/NAME: "
                    "transforms.json, camera_model OPENCV with synthetic k1 k2 p1 p2; images, masks and "
                    "edge maps distorted with OpenCV; the ground truth linked), train the original for "
                    "each of --seeds and the copy for each of --copy-seeds (OUT/original-seedN, "
                    "OUT/copy-seedN), and write their scores, with each scene's mean and spread, to "
                    "OUT/distorted_copy.json and .md. The copy and finished runs in OUT are reused.")
    _add_run_arguments(copy, "pinhole scene folder with ground truth (e.g. an ABC-NEF object)",
                       "folder for the copy, the runs and the tables",
                       "override a training setting of every run (repeatable)")
    copy.add_argument("--seeds", type=_seeds, default=(0,), metavar="N,...",
                      help="training seeds of the original (default 0)")
    copy.add_argument("--copy-seeds", type=_seeds, default=(0,), metavar="N,...",
                      help="training seeds of the copy (default 0)")
    copy.add_argument("--computed-maps", action="store_true",
                      help="neither scene keeps the original's edge maps: the detector computes them from "
                           "each scene's undistorted images, as from a user's capture (the original is then "
                           "its pinhole nerfstudio copy, OUT/pinhole/NAME)")
    copy.add_argument("--quiet", action="store_true", help="no progress bars")
    copy.set_defaults(run=run_distorted_copy)


def _add_edge_length(kinds) -> None:
    length = kinds.add_parser(
        "edge-length", help="final primitives and training seconds against ground-truth edge length",
        description="Read finished runs (run folders, or batch folders of them) grouped by variant, find "
                    "each run's scene's ground-truth edge length (the total length of its sharp-edge "
                    "curves), and write OUT/edge_length.json, .md and .png: per scene its primitives, "
                    "training seconds and primitives per unit of edge length; per variant that ratio's "
                    "median, its spread as shares of the median, the scenes within ±30 % of it, and "
                    "lines of primitives and seconds against length. Trains nothing.")
    length.add_argument("--runs", action="append", required=True, metavar="NAME=FOLDER",
                        help="a variant's name and a run folder or a batch's --out (repeatable; a name "
                             "given twice gathers both folders)")
    length.add_argument("--out", type=Path, required=True,
                        help="folder for the record, the table and the figure")
    length.add_argument("--figure", type=Path, default=None, metavar="PNG",
                        help="also write the figure (PNG) here, e.g. under docs/")
    length.add_argument("--force", action="store_true", help="replace the --figure file if it exists")
    length.set_defaults(run=run_edge_length)


def _add_extraction(kinds) -> None:
    extraction = kinds.add_parser(
        "extraction", help="curve extraction settings against each other on finished runs",
        description="Extract every finished run of the folders given (run folders, or a batch's --out) "
                    "twice with today's code, with the base settings and with the variant's, into "
                    "OUT/runs/NNN-NAME/base and .../variant (the runs are only read), score both "
                    "extractions' curves against the scene's ground truth, and write "
                    "OUT/extraction.json and .md: per run each score, base -> variant, and per score "
                    "both sides' mean and standard deviation, the paired difference (mean and "
                    "standard error), the runs made better and worse and the worst run. Trains nothing.")
    extraction.add_argument("--runs", action="append", required=True, type=Path, metavar="FOLDER",
                            help="a run folder or a folder of runs (repeatable)")
    extraction.add_argument("--set", dest="variant_set", action="append", default=[], metavar="KEY=VALUE",
                            help="a setting of the variant (as for edgedog extract --set; repeatable)")
    extraction.add_argument("--base-set", action="append", default=[], metavar="KEY=VALUE",
                            help="a setting of the base (default: the defaults; repeatable)")
    extraction.add_argument("--out", type=Path, required=True, help="a new or empty folder")
    extraction.set_defaults(run=run_extraction)


def _add_json_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", type=Path, default=None, help="also write the result here (never over a "
                        "run's own file nor inside a scene folder)")
    parser.add_argument("--force", action="store_true", help="replace the --json file if it exists")


def _check_json(args: argparse.Namespace) -> None:
    """Refuse a --json file that may not be written before the benchmark runs, not after."""
    if args.json is not None:
        check_new_file(args.json, args.force)


def _report(result: dict, args: argparse.Namespace) -> None:
    """Print a benchmark's JSON, and write it atomically to --json when given."""
    print(json.dumps(result, indent=2))
    if args.json is not None:
        with output_file(args.json, args.force):
            atomic_write_json(args.json, result)


def run_raster(args: argparse.Namespace) -> None:
    from edgedog.bench.raster import RasterBenchConfig, run, summary

    if args.reference_views > args.views:
        raise ConfigError(f"--reference-views {args.reference_views}: at most --views ({args.views})")
    _check_json(args)
    result = run(RasterBenchConfig(args.primitives, args.size, args.views, args.reference_views, args.kernel,
                                   args.seed, args.device))
    _report(result, args)
    print(summary(result))


def _check_no_seed(overrides: list[str]) -> None:
    """Seeds are --seeds: a --set of the seed would make every seed one run."""
    from edgedog.train.config import setting_name

    for assignment in overrides:
        key = assignment.partition("=")[0].strip()
        try:
            named = setting_name(key)
        except ConfigError:
            continue  # an unknown setting: applying the overrides names it
        if named == "run.seed":
            raise ConfigError(f"--set {assignment!r}: give seeds with --seeds")


def _executor_and_progress(args: argparse.Namespace):
    """The executor the options ask for and the progress callback (None with --quiet)."""
    from edgedog.batch.executors import choose_executor
    from edgedog.commands.batch import print_progress

    _check_no_seed(args.overrides)
    return choose_executor(args.address, args.cpus_per_run), None if args.quiet else print_progress


def run_ablation(args: argparse.Namespace) -> None:
    """A row whose runs failed (e.g. a correction with no calibration record) says why in the
    tables; the others stand."""
    from edgedog.bench.ablation import markdown, run_ablation

    tables = tuple(t.strip() for t in args.tables.split(",") if t.strip())
    if not tables or any(t not in TABLES for t in tables):
        raise ConfigError(f"--tables must list some of {', '.join(TABLES)}, got {args.tables!r}")
    keys = None if args.rows is None else tuple(k.strip() for k in args.rows.split(",") if k.strip())
    rows = select_rows(tables, keys)
    executor, report = _executor_and_progress(args)
    result = run_ablation(args.scene, args.out, args.preset, args.overrides, rows, args.seeds, executor,
                          report)
    print(markdown(result.rows))
    print("wrote " + ", ".join(str(path) for path in result.batch.files))


def run_speed_error(args: argparse.Namespace) -> None:
    from edgedog.bench.speed_error import markdown, parse_budgets, run_speed_error
    from edgedog.errors import InputError

    budgets = parse_budgets(args.budgets)
    executor, report = _executor_and_progress(args)
    result = run_speed_error(args.scene, args.out, budgets, args.overrides, executor, args.evals, args.seeds,
                             report)
    print(markdown(result.results, args.scene.resolve().name))
    print("wrote " + ", ".join(str(path) for path in result.batch.files))
    failed = result.batch.failed
    if failed:
        raise InputError(args.out, f"{len(failed)} of {len(result.batch.outcomes)} runs failed (see "
                                   f"batch.md); {failed[0].spec.name}: {failed[0].error}")


def run_layers(args: argparse.Namespace) -> None:
    from edgedog.bench.layers import LAYERS_FILES, markdown, run_layers_bench
    from edgedog.train.config import preset, with_overrides
    from edgedog.train.levels import resolve_levels

    names = [name.strip() for name in args.layers.split(",") if name.strip()]
    levels = resolve_levels(names, args.levels)
    base = with_overrides(preset(args.preset), args.overrides)
    check_output_folder(args.out, LAYERS_FILES)
    results = run_layers_bench(args.scene, args.out, args.preset, base, levels, progress=not args.quiet,
                               figure=not args.no_figure)
    print(markdown(results))
    print(f"wrote {args.out / 'layers.json'}, {args.out / 'layers.md'}"
          + ("" if args.no_figure else f" and {args.out / 'layers.png'}"))


def run_steps(args: argparse.Namespace) -> None:
    from edgedog.bench.steps import STEPS_FILES, markdown, run_steps_bench
    from edgedog.files import read_json
    from edgedog.train.config import preset, with_overrides

    config = with_overrides(preset(args.preset), args.overrides)
    check_output_folder(args.out, STEPS_FILES)
    run_steps_bench(args.scene, args.out, args.preset, config, args.windows, args.window_steps,
                    progress=not args.quiet)
    print(markdown(read_json(args.out / STEPS_FILES[0])))
    print(f"wrote {args.out / STEPS_FILES[0]} and {args.out / STEPS_FILES[1]}")


def run_sfm_vs_cameras(args: argparse.Namespace) -> None:
    from edgedog.bench.sfm_cameras import FILES, markdown, run_sfm_vs_cameras
    from edgedog.train.config import preset, with_overrides

    config = with_overrides(preset(args.preset), args.overrides)
    record = run_sfm_vs_cameras(args.scene, args.out, args.preset, config, args.max_image_size, args.matcher,
                                progress=not args.quiet)
    print(markdown(record))
    print("wrote " + ", ".join(str(args.out / name) for name in FILES))


def run_distorted_copy(args: argparse.Namespace) -> None:
    from edgedog.bench.distorted_copy import FILES, markdown, run_distorted_copy
    from edgedog.train.config import preset, with_overrides

    _check_no_seed(args.overrides)
    config = with_overrides(preset(args.preset), args.overrides)
    record = run_distorted_copy(args.scene, args.out, args.preset, config, args.seeds, args.copy_seeds,
                                args.computed_maps, progress=not args.quiet)
    print(markdown(record))
    print("wrote " + ", ".join(str(args.out / name) for name in FILES))


def run_edge_length(args: argparse.Namespace) -> None:
    from edgedog.bench.edge_length import (
        EDGE_LENGTH_FILES,
        markdown,
        parse_variants,
        plot_png,
        read_runs,
        record,
    )
    from edgedog.files import atomic_write_bytes, create_folder

    variants = parse_variants(args.runs)
    check_output_folder(args.out, EDGE_LENGTH_FILES)
    if args.figure is not None:
        check_new_file(args.figure, args.force)
    points, notes = read_runs(variants)
    if not points:
        raise ConfigError("no finished run in the folders given: " + "; ".join(notes))
    result = record(points, notes)
    figure = plot_png(result)
    create_folder(args.out)
    atomic_write_json(args.out / EDGE_LENGTH_FILES[0], result)
    atomic_write_bytes(args.out / EDGE_LENGTH_FILES[1], markdown(result).encode("utf-8"))
    atomic_write_bytes(args.out / EDGE_LENGTH_FILES[2], figure)
    written = [args.out / name for name in EDGE_LENGTH_FILES]
    if args.figure is not None:
        with output_file(args.figure, args.force):
            atomic_write_bytes(args.figure, figure)
        written.append(args.figure)
    print(markdown(result))
    print("wrote " + ", ".join(str(path) for path in written))


def run_extraction(args: argparse.Namespace) -> None:
    from edgedog.bench.extraction import EXTRACTION_FILES, compare, markdown, record
    from edgedog.curves.config import ExtractConfig, with_overrides
    from edgedog.files import atomic_write_bytes
    from edgedog.train.lifecycle import lock_folder
    from edgedog.train.run_folder import LOCK_FILE

    base, variant = (with_overrides(ExtractConfig(), sets) for sets in (args.base_set, args.variant_set))
    check_output_folder(args.out, EXTRACTION_FILES)

    def refuse_unless_empty():
        if args.out.exists() and any(entry.name != LOCK_FILE for entry in args.out.iterdir()):
            raise OutputError(args.out, "must be a new or empty folder: this bench writes its extractions "
                                        "there")

    refuse_unless_empty()  # before the lock, which would write into a folder that is not ours
    with lock_folder(args.out):  # one bench at a time: another may have filled it meanwhile
        refuse_unless_empty()
        pairs, notes = compare(args.runs, base, variant, args.out)
        if not pairs:
            raise ConfigError("no finished run in the folders given" + "".join(f"; {note}" for note in notes))
        result = record(pairs, notes, args.base_set, args.variant_set)
        atomic_write_json(args.out / EXTRACTION_FILES[0], result)
        atomic_write_bytes(args.out / EXTRACTION_FILES[1], markdown(result).encode("utf-8"))
    print(markdown(result))
    print("wrote " + ", ".join(str(args.out / name) for name in EXTRACTION_FILES))


def run_edges(args: argparse.Namespace) -> None:
    from edgedog.bench.edges import run

    _check_json(args)
    _report(run(args.size, args.repeats, args.weights), args)
