"""A scripted UI driver: actions fed to the UI state between frames, as a user's clicks would be,
for tests and demos (`edgedog studio --script FILE`).

The script is JSON: {"report": "report.json", "actions": [...]}, each action one of
    {"wait": seconds}
    {"set": {"live.keep_ratio": 0.7, "display.layers.L0": false}}   dotted paths into UIState
    {"request": "export", "format": "obj"}                          a UIState request and its args
    {"expect": {"controls.weighting": "up", "steps": [">", 10]}, "timeout": 10}
        wait until every probe (Studio.probe) matches: a value, or [op, value] with op one of
        > >= < <= !=; fails the script after `timeout` seconds (default 10).
    {"mark": "name"}                                                  record the probes now
    {"click": "reset view"}                 a left click on the widget of that label (last frame's)
    {"drag": "3D view", "by": [dx, dy]}     a left drag from the widget's centre, in points, over
                                            "frames" frames (default 8)
    {"key": "space"}, {"key": "ctrl+o"}     a key press (imgui.Key names, with ctrl+ or shift+)
    {"wheel": "inspector depth enlarged", "by": 2}   mouse-wheel notches over the widget's centre
    {"move": "inspector depth enlarged", "at": [0.4, 0.6]}   the pointer to that point of the
                                            widget's rectangle (fractions of its width and height)
    {"click_curve": 3}                      a left click on the middle of shown curve 3 in the 3D view
                                            ("longest": of the longest curve shown)
    {"expect_state": {"view.picked.curve.index": 3}, "timeout": 10}
        as "expect", on dotted paths into the Studio (attributes, dict keys, list indices); a
        value, or [op, value]
    {"record": {"name": "view.picked.lines"}}  the values at dotted paths, into the report's marks
    {"save_rects": "rects.json"}            the widgets' rectangles (points) as last drawn, for
                                            tests that click with a real mouse
Clicks, drags, wheels and keys go through imgui's input queue, as the mouse and keyboard's do.
A failed expectation closes the window; the report (probes, failure, closing time) is written
when the window closes and the command exits 1 if the script failed.
"""

from __future__ import annotations

import json
import operator
import time
from collections.abc import Callable
from pathlib import Path

from edgedog.app import widgets
from edgedog.app.picking import pixel_point
from imgui_bundle import imgui

from edgedog.errors import InputError
from edgedog.files import atomic_write_json, read_json

COMPARISONS = {">": operator.gt, ">=": operator.ge, "<": operator.lt, "<=": operator.le, "!=": operator.ne}
DEFAULT_TIMEOUT = 10.0
FLOAT_TOLERANCE = 1e-6
DRAG_STEPS = 8
"""Mouse moves a scripted drag is cut into."""
MODIFIERS = {"ctrl": imgui.Key.mod_ctrl, "shift": imgui.Key.mod_shift}
INPUT_ACTIONS = {"click", "drag", "key", "wheel", "click_curve", "move"}
"""Actions that send input events (one action a frame, its events over several)."""


def matches(actual, expected) -> bool:
    """Whether a probe value meets an expectation (a value, or [op, value])."""
    if isinstance(expected, list) and len(expected) == 2 and expected[0] in COMPARISONS:
        return actual is not None and COMPARISONS[expected[0]](actual, expected[1])
    if isinstance(expected, float) and isinstance(actual, (int, float)):
        return abs(actual - expected) <= FLOAT_TOLERANCE
    return actual == expected


def assign(root, path: str, value) -> None:
    """Set the attribute (or dict item) at dotted `path` under `root`."""
    *parents, last = path.split(".")
    target = root
    for name in parents:
        target = target[name] if isinstance(target, dict) else getattr(target, name)
    if isinstance(target, dict):
        target[last] = value
    elif hasattr(target, last):
        setattr(target, last, value)
    else:
        raise AttributeError(f"the UI state has no {path!r}")


def lookup(root, path: str):
    """The value at dotted `path` under `root`: attributes, dict keys and list indices; None where
    a step finds None."""
    value = root
    for name in path.split("."):
        if value is None:
            return None
        if isinstance(value, dict):
            value = value[name]
        elif isinstance(value, (list, tuple)) and name.lstrip("-").isdigit():
            value = value[int(name)]
        else:
            value = getattr(value, name)
    return value


def _mouse_move(x: float, y: float) -> Callable[[], None]:
    return lambda: imgui.get_io().add_mouse_pos_event(x, y)


def _mouse_button(down: bool) -> Callable[[], None]:
    return lambda: imgui.get_io().add_mouse_button_event(imgui.MouseButton_.left, down)


def _both(first: Callable[[], None], second: Callable[[], None]) -> Callable[[], None]:
    """Both events in one frame's batch (imgui's input queue still takes them a frame apart)."""
    return lambda: (first(), second())


def click(x: float, y: float) -> list[Callable[[], None]]:
    """The frames of a left click at (x, y) points: the pointer comes first, as a mouse's does
    (imgui gives hover to an item a frame after the pointer reaches it)."""
    return [_mouse_move(x, y), _both(_mouse_button(True), _mouse_button(False))]


def drag(start: tuple[float, float], by: list[float], frames: int = DRAG_STEPS) -> list[Callable[[], None]]:
    """The frames of a left drag from `start` by (dx, dy) points, moving over `frames` frames."""
    moves = [_mouse_move(start[0] + by[0] * step / frames, start[1] + by[1] * step / frames)
             for step in range(1, frames + 1)]
    return [_mouse_move(*start), _mouse_button(True), *moves, _mouse_button(False)]


def wheel(x: float, y: float, notches: float) -> list[Callable[[], None]]:
    """The frames of mouse-wheel `notches` (positive: away from the user) with the pointer at (x, y)."""
    return [_mouse_move(x, y), lambda: imgui.get_io().add_mouse_wheel_event(0.0, notches)]


def curve_point(studio, index: int | str) -> tuple[float, float]:
    """Where on screen (points) the middle of shown curve `index` ("longest": the longest shown)
    lies in the 3D view (ValueError when it is not in sight)."""
    view = studio.view
    if index == "longest" and view.curves_shown:
        index = max(range(view.curves_shown), key=view.curve_length)
    if not isinstance(index, int) or not 0 <= index < view.curves_shown:
        raise ValueError(f"no curve {index}: the 3D view shows {view.curves_shown}")
    pixel = view.curve_pixel(index)
    if pixel is None:
        raise ValueError(f"curve {index} is not in sight")
    x0, y0 = widgets.RECTS["3D view"][:2]
    scale = imgui.get_io().display_framebuffer_scale
    return pixel_point(pixel, (x0, y0), (scale.x, scale.y))


def press(chord: str) -> list[Callable[[], None]]:
    """The frames of a key press, e.g. "space", "1", "ctrl+o" (ValueError for an unknown name)."""
    *modifiers, name = chord.lower().split("+")
    key = getattr(imgui.Key, f"_{name}" if name.isdigit() else name, None)
    if key is None or any(m not in MODIFIERS for m in modifiers):
        raise ValueError(f"unknown key {chord!r}")

    def send() -> None:  # imgui takes the release a frame after the press
        for down in (True, False):
            for held in [*(MODIFIERS[m] for m in modifiers), key]:
                imgui.get_io().add_key_event(held, down)

    return [send]


class ScriptDriver:
    """Runs a script's actions in order, one or more per frame."""

    def __init__(self, script: dict, clock=time.monotonic):
        self.actions: list[dict] = list(script.get("actions", []))
        self.report_path = Path(script["report"]) if script.get("report") else None
        self.clock = clock
        self.index = 0
        self.failure: str | None = None
        self.log: list[dict] = []
        self.marks: dict[str, dict] = {}
        self._input: list[Callable[[], None]] = []
        """The input events of the action under way, one batch per frame."""
        self.sent_input = False
        """Whether the last tick sent input (the window then runs at its interactive rate)."""
        self._origin = self._since = clock()

    @classmethod
    def load(cls, path: Path) -> ScriptDriver:
        script = read_json(path)
        if not isinstance(script, dict) or not isinstance(script.get("actions"), list):
            raise InputError(path, 'expected {"actions": [...]} (see edgedog.app.script)')
        return cls(script)

    @property
    def finished(self) -> bool:
        return self.failure is not None or self.index >= len(self.actions)

    def tick(self, studio) -> None:
        """Run every action that is due; stop at one that is still waiting."""
        self.sent_input = False
        while not self.finished:
            action = self.actions[self.index]
            try:
                done = self._run(action, studio)
            except Exception as error:  # a bad script must fail the run, not the window
                self._fail(studio, f"action {self.index} {action}: {type(error).__name__}: {error}")
                return
            if not done:
                return
            self.log.append({"action": action, "at": round(self.clock() - self._origin, 3)})
            self.index += 1
            self._since = self.clock()
            if action.keys() & {"request", *INPUT_ACTIONS}:
                return  # one per frame: a screenshot shows the frame as it was asked for

    def _run(self, action: dict, studio) -> bool:
        waited = self.clock() - self._since
        if "wait" in action:
            return waited >= action["wait"]
        if "set" in action:
            for path, value in action["set"].items():
                assign(studio.state, path, value)
            return True
        if "request" in action:
            args = {key: value for key, value in action.items() if key != "request"}
            studio.state.request(action["request"], **args)
            return True
        if action.keys() & INPUT_ACTIONS:
            return self._send_input(action, studio)
        if "mark" in action:
            self.marks[action["mark"]] = {"at": self.clock() - self._origin, **studio.probe()}
            return True
        if "record" in action:
            self.marks.update({name: lookup(studio, path) for name, path in action["record"].items()})
            return True
        if "save_rects" in action:
            atomic_write_json(Path(action["save_rects"]), {k: list(v) for k, v in widgets.RECTS.items()})
            return True
        if "expect" in action or "expect_state" in action:
            expected = action.get("expect") or action["expect_state"]
            probe = studio.probe() if "expect" in action else {k: lookup(studio, k) for k in expected}
            missed = {k: probe.get(k) for k, v in expected.items() if not matches(probe.get(k), v)}
            if missed and waited > action.get("timeout", DEFAULT_TIMEOUT):
                self._fail(studio, f"action {self.index}: expected {expected}, got {missed}")
            return not missed
        raise ValueError("unknown action")

    def _send_input(self, action: dict, studio) -> bool:
        """Feed the action's next frame of input events; True once all are sent."""
        if not self._input:
            if "click" in action:
                self._input = click(*widgets.center(action["click"]))
            elif "click_curve" in action:
                self._input = click(*curve_point(studio, action["click_curve"]))
            elif "drag" in action:
                frames = action.get("frames", DRAG_STEPS)
                self._input = drag(widgets.center(action["drag"]), action["by"], frames)
            elif "wheel" in action:
                self._input = wheel(*widgets.center(action["wheel"]), action["by"])
            elif "move" in action:
                x0, y0, x1, y1 = widgets.RECTS[action["move"]]
                fx, fy = action["at"]
                self._input = [_mouse_move(x0 + fx * (x1 - x0), y0 + fy * (y1 - y0))]
            else:
                self._input = press(action["key"])
        self._input.pop(0)()
        self.sent_input = True
        return not self._input

    def _fail(self, studio, message: str) -> None:
        self.failure = message
        studio.state.request("close")

    def write_report(self, studio) -> None:
        """The report: success, failure, every action's time, the marks, the final probes and how
        long closing took."""
        if self.report_path is None:
            return
        report = {"ok": self.failure is None and self.finished, "failure": self.failure, "log": self.log,
                  "marks": self.marks, "probe": studio.probe(), "stop_seconds": studio.stop_seconds}
        atomic_write_json(self.report_path, json.loads(json.dumps(report, default=str)))
