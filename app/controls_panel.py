"""The controls panel (run, live and restart settings, display, curves and export) and the
status line. Widgets only edit the UI state or make requests; the studio acts on them."""

from __future__ import annotations

from edgedog.app import layout
from edgedog.app.extraction import EXPORT_FORMATS
from edgedog.app.layers import layer_members, list_new_layers
from edgedog.app.state import COLOR_MODES, KERNELS, WEIGHTINGS
from edgedog.app.worker import FAILED, FINISHED, PAUSED, STOPPED
from imgui_bundle import imgui

from edgedog.train.config import PRESETS

ERROR_COLOR = imgui.ImVec4(1.0, 0.4, 0.35, 1.0)
KEEP_RATIO_RANGE = (0.1, 1.0)


def _combo(label: str, value: str, items: tuple[str, ...]) -> str:
    """A combo box over `items` that returns the chosen item."""
    _, index = imgui.combo(label, items.index(value), list(items))
    return items[index]


def _checkbox(label: str, value: bool) -> bool:
    return imgui.checkbox(label, value)[1]


def _scene(studio) -> None:
    session, state = studio.session, studio.state
    imgui.text(f"Scene  {session.scene_path.name}")
    imgui.set_item_tooltip(str(session.scene_path))
    imgui.same_line()
    if imgui.small_button("Open..."):
        state.request("open")
    imgui.text_disabled("or drop a scene or run folder on the window")
    imgui.text_wrapped(f"Run  {session.run_dir or '(not started)'}")


def _training(studio) -> None:
    imgui.separator_text("Training")
    worker, state, session = studio.worker, studio.state, studio.session
    phase = None if worker is None else worker.phase
    if phase in (None, FINISHED, STOPPED, FAILED):
        if imgui.button("Resume run" if session.resumable else "Start"):
            state.request("start")
    elif phase == PAUSED:
        if imgui.button("Resume"):
            state.request("resume")
    elif imgui.button("Pause"):
        state.request("pause")
    imgui.same_line()
    if imgui.button("Restart"):
        state.request("restart")
    imgui.set_item_tooltip("a new run folder with the settings below")
    latest = studio.latest
    if worker is not None:
        info = worker.info
        imgui.text(f"{phase}  {worker.steps_per_second:.0f} steps/s")
        if latest is not None and info is not None:
            snapshot = latest.snapshot
            imgui.progress_bar(min(snapshot.epoch / info.epochs, 1.0), imgui.ImVec2(-1, 0),
                               f"epoch {snapshot.epoch}/{info.epochs}  step {snapshot.step}")
            imgui.text(f"{len(snapshot.means)} primitives  loss {snapshot.loss:.4f}")
        if worker.error:
            imgui.text_colored(ERROR_COLOR, "the trainer stopped with an error:")
            imgui.text_wrapped(worker.error)
            if imgui.tree_node("traceback"):
                imgui.text_wrapped(worker.traceback)
                imgui.tree_pop()


def _live(state) -> None:
    imgui.separator_text("Live (at the next step)")
    live = state.live
    live.keep_ratio = imgui.slider_float("pruning p", live.keep_ratio, *KEEP_RATIO_RANGE, "%.2f")[1]
    imgui.set_item_tooltip("share of primitives kept by each Fisher pruning")
    live.weighting = _combo("w(Up)", live.weighting, WEIGHTINGS)


def _restart(studio) -> None:
    imgui.separator_text("At restart")
    restart = studio.state.restart
    if studio.session.resumable:
        imgui.text_disabled("Resume run continues the opened run as saved")
    preset = _combo("preset", restart.preset, PRESETS)
    if preset != restart.preset:
        restart.preset, restart.epochs = preset, studio.session.base_config(preset).epochs
    restart.epochs = max(1, imgui.input_int("epochs", restart.epochs, 10, 100)[1])
    restart.k_init = tuple(imgui.input_float2("k init", list(restart.k_init), "%.2f")[1])
    restart.kernel = _combo("kernel", restart.kernel, KERNELS)
    restart.pixel_uncertainty = _checkbox("pixel uncertainty w(Up)", restart.pixel_uncertainty)
    restart.primitive_uncertainty = _checkbox("primitive uncertainty (Fisher)", restart.primitive_uncertainty)


def _display(studio) -> None:
    imgui.separator_text("3D view")
    display, latest = studio.state.display, studio.latest
    display.splats = _checkbox("splats", display.splats)
    imgui.same_line()
    display.edges = _checkbox("curves", display.edges)
    imgui.same_line()
    display.cameras = _checkbox("cameras", display.cameras)
    imgui.begin_disabled(studio.session.ground_truth is None)
    display.ground_truth = _checkbox("ground truth", display.ground_truth)
    imgui.end_disabled()
    imgui.same_line()
    pruned = 0 if latest is None else len(latest.snapshot.pruned_positions)
    display.pruned = _checkbox(f"pruned ({pruned}, red)", display.pruned)
    display.color_by = _combo("colour by", display.color_by, COLOR_MODES)
    if studio.view.color_range is not None:
        imgui.text_disabled("viridis: {:.3g} .. {:.3g}".format(*studio.view.color_range))
    imgui.text("Layers")
    members = {} if latest is None else layer_members(latest.snapshot)
    if latest is not None:
        list_new_layers(display.layers, latest.snapshot)
    for name in list(display.layers):
        display.layers[name] = _checkbox(f"{name}##layer", display.layers[name])
        imgui.same_line()
        imgui.text_disabled(f"{len(members.get(name, ()))} primitives")


def _curves(studio) -> None:
    imgui.separator_text("Curves")
    state, extraction = studio.state, studio.extraction
    if imgui.button("Extract now"):
        state.request("extract")
    imgui.same_line()
    state.auto_extract = _checkbox(f"every {state.auto_extract_seconds:.0f} s", state.auto_extract)
    if studio.extract_job.busy:
        imgui.text_disabled("extracting...")
    if extraction is not None:
        imgui.text(f"step {extraction.step}: {len(extraction.curves.lines)} lines, "
                   f"{len(extraction.curves.beziers)} Beziers")
        if extraction.fscore:
            imgui.text("F " + "  ".join(f"{mm} mm {f:.1f}" for mm, f in extraction.fscore.items()))
    imgui.text("Export")
    for fmt in EXPORT_FORMATS:
        imgui.same_line()
        if imgui.button(fmt.upper()):
            state.request("export", format=fmt)
    imgui.set_item_tooltip("extracts the latest snapshot and writes <run>/exports/")


def draw(studio, area: layout.Area) -> None:
    if layout.begin("Controls", area):
        _scene(studio)
        _training(studio)
        _live(studio.state)
        _restart(studio)
        _display(studio)
        _curves(studio)
    imgui.end()


def draw_status(studio, area: layout.Area) -> None:
    """One line: the last thing done, or the trainer's error."""
    if layout.begin("##status", area, imgui.WindowFlags_.no_title_bar | imgui.WindowFlags_.no_scrollbar):
        worker = studio.worker
        if worker is not None and worker.error:
            imgui.text_colored(ERROR_COLOR, f"trainer error: {worker.error}")
        else:
            imgui.text(studio.state.status)
    imgui.end()
