"""Keyboard shortcuts, turned into the same requests and state changes as the panels' widgets,
and the help window (F1 or h) that lists them with the mouse gestures."""

from __future__ import annotations

from edgedog.app.worker import FINISHING, PAUSED, STARTING, TRAINING
from imgui_bundle import imgui

SHORTCUTS = (
    ("space", "pause or resume training (start when nothing runs)"),
    ("r", "reset the 3D view"),
    ("1 - 9", "select training view 1 - 9 and look through its camera"),
    ("Ctrl+O", "open a scene or run folder, or a folder of photos (offers to recover their cameras)"),
    ("Ctrl+E", "export the curves of the latest snapshot in the checked formats"),
    ("F1 or h", "show or hide this help"),
    ("Esc", "close the topmost window (the folder browser, then this help); with none open, "
            "ask to quit"),
    ("q", "quit (asks first while a run is under way: training stops, the run keeps its last "
          "checkpoint)"),
    ("Enter / Esc", "answer a question: yes / no"),
)
GESTURES = (
    ("left drag", "orbit the 3D view"),
    ("right or middle drag, shift drag", "pan"),
    ("wheel", "zoom"),
    ("click in the 3D view", "pick the curve and the splat under the mouse (read out over the view)"),
    ("click an inspector", "enlarge it: the wheel zooms, a drag pans, 'all inspectors' goes back"),
    ("hover an inspector", "read out the pixel: value, view, pixel"),
    ("drop a folder", "open it"),
)
DIGITS = [getattr(imgui.Key, f"_{digit}") for digit in range(1, 10)]


def _pressed(key: imgui.Key, ctrl: bool = False) -> bool:
    """Whether `key` was pressed this frame, with Ctrl held (`ctrl`) or not. At a low frame rate
    (while training) imgui's input queue spreads a quick Ctrl+O over two frames: Ctrl's press in
    the first, O's press with Ctrl's release in the second; so for a Ctrl shortcut a Ctrl released
    this frame still counts (a plain key then pressed, e.g. Esc right after Ctrl+O, is plain)."""
    if not imgui.is_key_pressed(key, False):
        return False
    held = imgui.get_io().key_ctrl
    return held or imgui.is_key_released(imgui.Key.mod_ctrl) if ctrl else not held


def handle_keys(studio) -> None:
    """Act on this frame's shortcuts (none while a text field has the keyboard or a question
    waits for its answer: `confirm.Confirm` reads its own keys)."""
    io, state = imgui.get_io(), studio.state
    if io.want_text_input or studio.confirm is not None:
        return
    if _pressed(imgui.Key.space):
        phase = None if studio.worker is None else studio.worker.phase
        if phase in (TRAINING, STARTING):
            state.request("pause")
        elif phase == PAUSED:
            state.request("resume")
        elif phase == FINISHING:
            state.status = "space: the run is extracting its final curves; it can start again once finished"
        else:
            state.request("start")
    if _pressed(imgui.Key.r):
        state.request("reset_view")
    views = len(studio.session.scene)
    for index, key in enumerate(DIGITS):
        if _pressed(key) and index < views:
            state.view = index
            state.request("snap")
        elif _pressed(key):
            state.status = f"{index + 1}: no such view, the scene has {views}"
    if _pressed(imgui.Key.o, ctrl=True):
        state.request("open")
    if _pressed(imgui.Key.e, ctrl=True):
        state.request("export")
    if _pressed(imgui.Key.f1) or _pressed(imgui.Key.h):
        state.request("help")
    if _pressed(imgui.Key.escape) and not studio.close_top():
        state.request("quit", ask=True)  # never quits at once: a stray Esc only asks
    elif _pressed(imgui.Key.q):
        state.request("quit")


def draw_help(studio) -> None:
    """The help window, while `state.show_help`."""
    state = studio.state
    if not state.show_help:
        return
    viewport = imgui.get_main_viewport()
    # Always: on its first frame an auto-resized window has no size yet to centre by.
    imgui.set_next_window_pos(viewport.get_center(), imgui.Cond_.always, imgui.ImVec2(0.5, 0.5))
    expanded, state.show_help = imgui.begin("Help", state.show_help, imgui.WindowFlags_.always_auto_resize)
    if expanded:
        for title, rows in (("Keys", SHORTCUTS), ("Mouse", GESTURES)):
            imgui.separator_text(title)
            if imgui.begin_table(f"##{title}", 2):
                for key, what in rows:
                    imgui.table_next_row()
                    imgui.table_next_column()
                    imgui.text(key)
                    imgui.table_next_column()
                    imgui.text(what)
                imgui.end_table()
        imgui.separator_text("Settings")
        # Lines of their own: wrapped text in an auto-sized window starts as tall as a word per
        # line and settles frames later, moving the window.
        imgui.text("Live settings (pruning p, w(U)) reach the trainer at its next step;\n"
                   "the others apply at the next Start or Restart. Hover a control for more.")
    imgui.end()
