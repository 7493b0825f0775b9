"""The controls panel (the scene, structure from motion from photos, run, live and restart
settings, display, curves and export) and the status line. Widgets only edit the UI state or
make requests; the studio acts on them. Every widget's tooltip says what it does and when it
applies: live (at the next training step), at the next (re)start, or at the next SfM.
"""

from __future__ import annotations

import math
import time

from edgedog.app import STUDIO_PRESET, layout, widgets
from edgedog.app.layers import layer_members, list_new_layers
from edgedog.app.sfm_job import CANCELLED, DONE
from edgedog.app.state import COLOR_MODES, EXPORT_FORMATS, KERNELS, WEIGHTING_FORMULAS, WEIGHTINGS
from edgedog.app.worker import FAILED, FINISHED, PAUSED, STOPPED
from imgui_bundle import imgui

from edgedog.scenes.sfm import MATCHERS
from edgedog.train.config import MAX_LAYERS, PRESETS, presets_help

ERROR_COLOR = imgui.ImVec4(1.0, 0.4, 0.35, 1.0)
PROGRESS_COLOR = imgui.ImVec4(0.22, 0.45, 0.75, 1.0)
"""The progress bar's fill: dark enough for its white text."""
KEEP_RATIO_RANGE = (0.1, 1.0)
IMAGE_SIZE_RANGE = (200, 10000)
"""The max image sizes of structure from motion the panel takes, in pixels."""
AT_RESTART = "Applies at the next Start or Restart (a running trainer cannot change it)."
LIVE = "Live: applied at the next training step, and recorded in the run's log.json."


def _scene(studio) -> None:
    session, state = studio.session, studio.state
    imgui.text(f"Scene  {session.scene_path.name}")
    imgui.set_item_tooltip(str(session.scene_path))
    imgui.same_line()
    if widgets.button("Open...", "open a scene folder (a new run), a run folder (to resume or view "
                      "it) or a folder of photos (to recover their cameras first) in a folder browser "
                      "(Ctrl+O), or drop one on the window", small=True):
        state.request("open")
    if session.run_dir is None:
        imgui.text("Run  (not started)")
    else:
        imgui.text(f"Run  {session.run_dir.name}")
        imgui.set_item_tooltip(str(session.run_dir))


def _sfm(studio) -> None:
    """Structure from motion under way (its progress and Cancel), or how the last one ended."""
    job, outcome = studio.sfm, studio.sfm_outcome
    if job is None or (outcome is not None and outcome.status == CANCELLED):
        return
    imgui.separator_text("Cameras from photos (SfM)")
    imgui.text(f"Photos  {job.photos.name}")
    imgui.set_item_tooltip(f"{job.photos} -> {job.out}")
    progress = job.progress
    if studio.recovering:
        imgui.push_style_color(imgui.Col_.plot_histogram, PROGRESS_COLOR)
        imgui.progress_bar(progress.fraction, imgui.ImVec2(-1, 0), f"{progress.label}  {job.elapsed:.0f} s")
        imgui.pop_style_color()
        widgets.note("sfm progress", f"edgedog sfm: {progress.message}")
        if widgets.button("Cancel##sfm", "stop the structure from motion now; nothing of it is kept"):
            studio.state.request("cancel_sfm")
    elif outcome is not None and outcome.status == DONE:
        points = "" if progress.points is None else f", {progress.points} points"
        imgui.text_disabled(f"{progress.registered} of {progress.photos} registered{points}, "
                            f"{outcome.seconds:.0f} s")
    elif outcome is not None:
        imgui.text_colored(ERROR_COLOR, "structure from motion failed:")
        imgui.text_wrapped(outcome.error or "")
        imgui.text_disabled("the matcher and max image size: under 'Photos to cameras (SfM)'")
        if imgui.tree_node("output##sfm"):
            imgui.text_wrapped("\n".join(outcome.tail))
            imgui.tree_pop()


def _sfm_settings(state) -> None:
    """How the next folder of photos goes through structure from motion."""
    if not imgui.collapsing_header("Photos to cameras (SfM)"):
        return
    sfm = state.sfm
    sfm.matcher = widgets.combo("matcher", sfm.matcher, MATCHERS,
                                "exhaustive: every pair of photos (up to a few hundred); sequential: "
                                "ordered video frames (each with its neighbours). For the next SfM.")
    low, high = IMAGE_SIZE_RANGE
    sfm.max_image_size = min(max(widgets.input_int(
        "max image size", sfm.max_image_size,
        "Longest side in pixels for the features and the undistorted images the scene keeps; "
        "larger finds more in detailed photos, and takes longer. For the next SfM.", 100, 400), low), high)
    sfm.train_after = widgets.checkbox("train once the cameras are shown", sfm.train_after,
                                       "start training on the recovered scene as soon as it opens")


def _start_label(studio) -> str:
    if studio.session.resumable:
        return "Resume run"
    return "Start new run" if studio.session.saved is not None else "Start"


def _training(studio) -> None:
    imgui.separator_text("Training")
    worker, state = studio.worker, studio.state
    phase = None if worker is None else worker.phase
    if worker is not None:  # above the buttons: their tooltips open below the mouse
        if worker.alive:  # the rate now, over the last few seconds
            imgui.text(f"{phase}  {studio.step_rate.readout(time.monotonic()):.1f} steps/s")
            imgui.set_item_tooltip(f"steps per second over the last {studio.step_rate.seconds:.0f} s; "
                                   f"{worker.steps_per_second:.1f} on average")
        else:
            imgui.text(f"{phase}  {worker.steps} steps at {worker.steps_per_second:.1f}/s")
    if phase in (None, FINISHED, STOPPED, FAILED):
        if widgets.button(_start_label(studio), "train: the opened run folder continues where it was saved; "
                          "otherwise a new run folder under the runs folder (space)"):
            state.request("start")
    elif phase == PAUSED:
        if widgets.button("Resume", "continue training (space)"):
            state.request("resume")
    elif widgets.button("Pause", "pause training between two steps (space)"):
        state.request("pause")
    imgui.same_line()
    if widgets.button("Restart", "stop this run and train a new run folder with the settings below "
                      "(the stopped run keeps its last checkpoint)"):
        state.request("restart")
    latest = studio.latest
    if worker is not None:
        info = worker.info
        if latest is not None and info is not None:
            snapshot = latest.snapshot
            imgui.push_style_color(imgui.Col_.plot_histogram, PROGRESS_COLOR)
            imgui.progress_bar(min(snapshot.epoch / info.epochs, 1.0), imgui.ImVec2(-1, 0),
                               f"epoch {snapshot.epoch}/{info.epochs}  step {snapshot.step}")
            imgui.pop_style_color()
            # No loss before the first step; "-": the font has no en dash.
            loss = "-" if math.isnan(snapshot.loss) else f"{snapshot.loss:.4f}"
            imgui.text(f"{len(snapshot.means)} primitives  loss {loss}")
        if worker.error:
            imgui.text_colored(ERROR_COLOR, "the trainer stopped with an error:")
            imgui.text_wrapped(worker.error)
            if imgui.tree_node("traceback"):
                imgui.text_wrapped(worker.traceback)
                imgui.tree_pop()


def _live(state) -> None:
    imgui.separator_text("Live (at the next step)")
    live = state.live
    live.keep_ratio = widgets.slider_float(
        "pruning p", live.keep_ratio, *KEEP_RATIO_RANGE,
        f"Share p of the primitives each Fisher pruning keeps (the most informative ones). {LIVE}")
    formulas = [f"w = {WEIGHTING_FORMULAS[name]}" for name in WEIGHTINGS]
    live.weighting = widgets.combo(
        "w(U)", live.weighting, WEIGHTINGS,
        "The loss weight of each pixel as a function of its uncertainty U (the normalised depth "
        f"gradient): 1 ignores U, exp(-U) and 1 - U trust smooth depth, U and exp(U) edges. {LIVE}",
        formulas)


def _restart(studio) -> None:
    imgui.separator_text("At restart")
    restart = studio.state.restart
    if studio.session.resumable:
        imgui.text_disabled("Resume run continues the opened run as saved")
    preset = widgets.combo("preset", restart.preset, tuple(PRESETS), f"{presets_help()}. {AT_RESTART}")
    imgui.text_disabled(f"studio default: {STUDIO_PRESET}")
    if preset != restart.preset:
        restart.preset, restart.epochs = preset, studio.session.base_config(preset).schedule.epochs
    restart.epochs = max(1, widgets.input_int(
        "epochs", restart.epochs,
        f"Epochs of the next run; the preset's schedule stretches with them. {AT_RESTART}",
        10, 100))
    restart.k_init = widgets.input_float2(
        "k init", restart.k_init, f"Initial DoG shape logits (inner scale a, surround ratio t). {AT_RESTART}")
    restart.kernel = widgets.combo("kernel", restart.kernel, KERNELS,
                                   f"dog: difference of Gaussians; gaussian: plain Gaussians. {AT_RESTART}")
    restart.pixel_uncertainty = widgets.checkbox(
        "pixel uncertainty w(U)", restart.pixel_uncertainty,
        f"Weight the loss by w(U) (chosen above); off: every pixel counts the same. {AT_RESTART}")
    restart.primitive_uncertainty = widgets.checkbox(
        "primitive uncertainty (Fisher)", restart.primitive_uncertainty,
        f"Prune by Fisher information every few epochs, keeping the share p. {AT_RESTART}")
    restart.layers = min(max(widgets.input_int(
        "layers", restart.layers,
        "Multi-granularity: train layers L0, L1, ... bottom up, each on finer edge maps with the layers "
        "below fixed, as `edgedog train --layers L0,L1,...` (PiDiNet NYUD / BSDS / Multicue maps when "
        f"its weights are found, else Canny at falling thresholds); 1: one layer. {AT_RESTART}"), 1),
        MAX_LAYERS)


def _display(studio) -> None:
    imgui.separator_text("3D view")
    display, latest = studio.state.display, studio.latest
    display.splats = widgets.checkbox("splats", display.splats, "show the primitives as DoG splats")
    imgui.same_line()
    display.edges = widgets.checkbox("curves", display.edges, "show the latest extracted curves")
    imgui.same_line()
    display.cameras = widgets.checkbox("cameras", display.cameras,
                                       "show the training cameras (the selected view in yellow)")
    imgui.begin_disabled(studio.session.ground_truth is None)
    display.ground_truth = widgets.checkbox("ground truth", display.ground_truth,
                                            "show the scene's ground-truth edge points (green)")
    imgui.end_disabled()
    imgui.same_line()
    pruned = 0 if latest is None else len(latest.snapshot.pruned_positions)
    display.pruned = widgets.checkbox(f"pruned ({pruned}, red)##pruned", display.pruned,
                                      "show the centres removed by the last Fisher pruning")
    display.color_by = widgets.combo("colour by", display.color_by, COLOR_MODES,
                                     "colour the splats by their opacity or DoG shape (a: inner scale, "
                                     "t: surround ratio) on viridis; white: no colouring")
    if display.color_by != "white" and studio.view.color_range is not None:
        imgui.text_disabled("viridis: {:.3g} .. {:.3g}".format(*studio.view.color_range))
    if studio.session.scene.sfm_points is not None:
        display.sfm_points = widgets.checkbox("SfM points", display.sfm_points,
                                              "show the scene's sparse structure-from-motion points "
                                              "in their colours")
    imgui.text("Layers")
    members = {} if latest is None else layer_members(latest.snapshot)
    if latest is not None:
        list_new_layers(display.layers, latest.snapshot)
    for name in list(display.layers):
        display.layers[name] = widgets.checkbox(
            f"{name}##layer", display.layers[name],
            f"show layer {name} in the 3D view and the inspectors; the curves and exports are of the "
            "layers shown")
        imgui.same_line()
        imgui.text_disabled(f"{len(members.get(name, ()))} primitives")


def _curves(studio) -> None:
    imgui.separator_text("Curves")
    state, extraction = studio.state, studio.extraction
    if widgets.button("Extract now", "fit curves to the latest snapshot (scored against the ground truth "
                      "when the scene has one)"):
        state.request("extract")
    imgui.same_line()
    state.auto_extract = widgets.checkbox(f"every {state.auto_extract_seconds:.0f} s", state.auto_extract,
                                          "extract again on a timer while training")
    if studio.extract_job.busy:
        imgui.text_disabled("extracting...")
    if extraction is not None:
        layers = f" ({extraction.selection})" if extraction.selection else ""
        imgui.text(f"step {extraction.step}{layers}: {len(extraction.curves.lines)} lines, "
                   f"{len(extraction.curves.beziers)} Beziers")
        if extraction.fscore:
            imgui.text("F " + "  ".join(f"{mm} mm {f:.1f}" for mm, f in extraction.fscore.items()))
    if widgets.button("Export", "extract the latest snapshot once and write it in every checked format "
                      "to <run>/exports/curves_step<N>.<format> (Ctrl+E)"):
        state.request("export")
    for fmt in EXPORT_FORMATS:
        imgui.same_line()
        state.export_formats[fmt] = widgets.checkbox(fmt.upper(), state.export_formats[fmt],
                                                     f"Export writes {fmt.upper()}")


def draw(studio, area: layout.Area) -> None:
    if layout.begin("Controls", area):
        _scene(studio)
        _sfm(studio)
        _training(studio)
        _live(studio.state)
        _curves(studio)  # before the longer sections: Export in sight on a 700 px high window
        _display(studio)
        _restart(studio)
        _sfm_settings(studio.state)
    imgui.end()


def draw_status(studio, area: layout.Area) -> None:
    """One line: where help is, and the last thing done or the trainer's error."""
    if layout.begin("##status", area, imgui.WindowFlags_.no_title_bar | imgui.WindowFlags_.no_scrollbar):
        imgui.text_disabled(f"F1: help | {studio.frame_rate.readout(time.monotonic()):.0f} fps |")
        imgui.set_item_tooltip("frames the window draws per second, over the last few seconds (it draws "
                               "one when something changed: at once for a key)")
        imgui.same_line()
        worker = studio.worker
        if worker is not None and worker.error:
            imgui.text_colored(ERROR_COLOR, f"trainer error: {worker.error}")
        else:
            imgui.text(studio.state.status)
            if studio.state.status:  # a long one runs off the line: all of it on hover
                imgui.set_item_tooltip(studio.state.status)
    imgui.end()
