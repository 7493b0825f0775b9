"""How fluid the studio is while it trains: frames per second, how soon typed keys are drawn,
training steps per second against the same steps trained headless, and the process's CPU use.

    python -m edgedog.bench.studio SCENE [--seconds 8] [--size 1280x800] [--set KEY=VALUE ...]

Runs `edgedog studio SCENE` on the current display (e.g. under Xvfb: DISPLAY=:1) with a scripted
session: start a run, let it train untouched, orbit the view continuously (one mouse move per
frame, as a drag does), type a path into the folder browser with real key presses (the X
server's XTest extension, as xdotool does; the window under the pointer gets them when no window
manager runs), then pause and orbit again (the UI alone). Then trains the same run headless to
the same step, so that each phase's rate is compared with the headless rate over the same steps.
Prints one row per phase (fps: frames built, each showing what changed; drawn/s: those that
differed from the last and were drawn; CPU %: the studio process's; UI CPU %: its window's
threads', the main thread and a software OpenGL's rasterizer threads, i.e. what the window takes
from the training where the CPU is shared) and writes the figures as JSON (--out). A measurement,
not a test: the figures depend on the machine and on what else runs on it.
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

WARM_UP = 3.0
"""Seconds of training before the first phase (the first epochs compile and allocate)."""
DRAG_FPS = 30
"""Frames a scripted drag is spread over per second (at most the window's interactive rate)."""
TYPED = "/tmp/edgedog/studio-bench/typing-01"
"""What is typed into the folder browser's path (35 keys, none with Shift on a US keymap)."""
EPOCHS = 1000
"""The run's epochs: a fast machine trains the studio preset's 100 before the last phase."""
KEY_INTERVAL = 0.15
"""Seconds between two typed keys (a brisk typist)."""
KEYSYMS = {"/": "slash", "-": "minus", ".": "period"}
"""X keysym names of the typed characters that are not their own name."""
PHASES = {"training": ("0", "1"), "training + orbiting": ("1", "2"), "training + typing": ("3", "4"),
          "paused + orbiting": ("5", "6")}
"""Each phase's first and last mark in the script."""


def script(seconds: float, report: Path, typing: Path) -> dict:
    """The scripted session: a mark at each phase boundary; `typing` is written when the folder
    browser waits for the keys."""
    frames = round(seconds * DRAG_FPS)
    orbit = {"drag": "3D view", "by": [6 * frames, 0], "frames": frames}
    typing_seconds = max(seconds, len(TYPED) * KEY_INTERVAL + 1.0)
    return {"report": str(report), "actions": [
        {"request": "start"},
        {"expect": {"phase": "training", "version": [">=", 2]}, "timeout": 120},
        {"wait": WARM_UP}, {"mark": "0"},
        {"wait": seconds}, {"mark": "1"},
        orbit, {"mark": "2"},
        {"request": "open"}, {"expect": {"dialog_text": [">", ""]}, "timeout": 10}, {"mark": "3"},
        {"save_rects": str(typing)}, {"wait": typing_seconds}, {"mark": "4"},
        # The browser closed (Esc), else the last phase's drag lands on it, not on the 3D view.
        {"key": "escape"}, {"expect": {"dialog": None}, "timeout": 10},
        {"request": "pause"}, {"expect": {"phase": "paused"}, "timeout": 10}, {"mark": "5"},
        orbit, {"mark": "6"},
        {"request": "close"}]}


class XKeyboard:
    """Real key presses through the X server's XTest extension, to the window with the keyboard
    focus (under the pointer when no window manager runs)."""

    def __init__(self, display: str):
        x11, xtst = (ctypes.util.find_library(name) for name in ("X11", "Xtst"))
        if x11 is None or xtst is None:
            raise OSError("typing needs libX11 and libXtst")
        self._x11, self._xtst = ctypes.CDLL(x11), ctypes.CDLL(xtst)
        self._x11.XOpenDisplay.restype = ctypes.c_void_p
        self._x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
        self._x11.XStringToKeysym.restype = ctypes.c_ulong
        self._x11.XStringToKeysym.argtypes = [ctypes.c_char_p]
        self._x11.XKeysymToKeycode.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
        self._x11.XFlush.argtypes = self._x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
        self._xtst.XTestFakeKeyEvent.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_ulong]
        self._xtst.XTestFakeMotionEvent.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                                    ctypes.c_ulong]
        self._display = self._x11.XOpenDisplay(display.encode())
        if not self._display:
            raise OSError(f"cannot open the X display {display!r}")

    def point_at(self, x: int, y: int) -> None:
        self._xtst.XTestFakeMotionEvent(self._display, -1, x, y, 0)
        self._x11.XFlush(self._display)

    def type(self, char: str) -> None:
        """Press and release the key of `char` (one without Shift)."""
        keysym = self._x11.XStringToKeysym(KEYSYMS.get(char, char).encode())
        keycode = self._x11.XKeysymToKeycode(self._display, keysym)
        for down in (1, 0):
            self._xtst.XTestFakeKeyEvent(self._display, keycode, down, 0)
        self._x11.XFlush(self._display)

    def close(self) -> None:
        self._x11.XCloseDisplay(self._display)


def type_when_asked(keyboard: XKeyboard, asked: Path, studio: subprocess.Popen, size: tuple[int, int]
                    ) -> list[float]:
    """Once the studio writes `asked`, type TYPED one key every KEY_INTERVAL; returns when each
    key was sent (time.monotonic())."""
    keyboard.point_at(size[0] // 2, size[1] // 2)
    while not asked.is_file():
        if studio.poll() is not None:
            return []
        time.sleep(0.05)
    sent = []
    for char in TYPED:
        sent.append(time.monotonic())
        keyboard.type(char)
        time.sleep(KEY_INTERVAL)
    return sent


def phase_figures(start: dict, end: dict, headless: np.ndarray) -> dict:
    """Rates between two marks of the report; `headless`: when each step ended, trained headless."""
    seconds = end["at"] - start["at"]
    first, last = start["steps"], end["steps"]
    headless_rate = None
    if last > first and last < len(headless):
        headless_rate = round((last - first) / (headless[last] - headless[first]), 1)
    rate = (last - first) / seconds
    return {"seconds": round(seconds, 2), "fps": round((end["frames"] - start["frames"]) / seconds, 1),
            "drawn_per_second": round((end["frames_drawn"] - start["frames_drawn"]) / seconds, 1),
            "steps_per_second": round(rate, 1), "headless_steps_per_second": headless_rate,
            "share_of_headless": None if not headless_rate else round(rate / headless_rate, 2),
            "view_renders_per_second": round((end["view_renders"] - start["view_renders"]) / seconds, 1),
            "cpu_percent": round(100 * (end["cpu_seconds"] - start["cpu_seconds"]) / seconds),
            "ui_cpu_percent": round(100 * (end["ui_cpu_seconds"] - start["ui_cpu_seconds"]) / seconds)
            if "ui_cpu_seconds" in start else None}


def typing_figures(sent: list[float], end: dict) -> dict:
    """How long each typed key took to be drawn (ms), and how many never reached the text."""
    drawn = end["typed_drawn"]
    latencies = []
    for index, at in enumerate(sent):
        shown = next((time for time, typed in drawn if typed > index), None)
        if shown is not None:
            latencies.append(1000 * (shown - at))
    text = end.get("dialog_text") or ""
    kept = len(TYPED) if text.endswith(TYPED) else 0
    return {"keys": len(sent), "keys_lost": len(sent) - kept,
            "latency_ms_median": round(float(np.median(latencies)), 1) if latencies else None,
            "latency_ms_max": round(max(latencies), 1) if latencies else None}


def headless_step_times(studio_run: Path, steps: int, folder: Path) -> np.ndarray:
    """(steps + 1,) seconds since the first step when each step ended (0: the start), of a new
    run in `folder` with the scene, preset and settings of the studio's run `studio_run`, trained
    with no window."""
    from edgedog.train.lifecycle import START, load_run_scene, plan_run
    from edgedog.train.run import open_run
    from edgedog.train.run_folder import read_run

    run = read_run(studio_run)
    plan = plan_run(folder, load_run_scene(run.scene, run.config), run.preset, run.config, START)
    with open_run(plan.check(), progress=False) as run:
        run.current()  # the set-up is not timed
        times = [time.perf_counter()]
        while len(times) <= steps and not run.done:
            run.step()
            times.append(time.perf_counter())
    return np.array(times) - times[0]


def measure(scene: Path, seconds: float, size: str, options: list[str]) -> dict[str, dict]:
    """Run the scripted session and the headless run; returns the figures of each phase."""
    width, height = (int(side) for side in size.split("x"))
    with tempfile.TemporaryDirectory(prefix="edgedog-bench-studio-") as folder:
        folder = Path(folder)
        typing = folder / "typing.json"
        (folder / "script.json").write_text(json.dumps(script(seconds, folder / "report.json", typing)))
        command = [sys.executable, "-m", "edgedog", "studio", str(scene), "--runs", str(folder / "runs"),
                   "--size", size, "--script", str(folder / "script.json"), *options]
        keyboard = XKeyboard(os.environ.get("DISPLAY", ""))
        studio = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            sent = type_when_asked(keyboard, typing, studio, (width, height))
            _, stderr = studio.communicate()
        finally:
            keyboard.close()
            if studio.poll() is None:
                studio.kill()
        report_file = folder / "report.json"
        report = json.loads(report_file.read_text()) if report_file.is_file() else {}
        if studio.returncode != 0 or not report.get("ok"):
            raise SystemExit(f"the studio failed: {report.get('failure')}\n{stderr[-3000:]}")
        marks = report["marks"]
        last_step = max(mark["steps"] for mark in marks.values() if isinstance(mark, dict))
        headless = headless_step_times(Path(marks["0"]["run_dir"]), last_step, folder / "headless")
    figures = {name: phase_figures(marks[first], marks[last], headless)
               for name, (first, last) in PHASES.items()}
    figures["training + typing"].update(typing_figures(sent, marks["4"]))
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m edgedog.bench.studio",
                                     description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("scene", type=Path)
    parser.add_argument("--seconds", type=float, default=8.0, help="length of each phase (default 8)")
    parser.add_argument("--size", default="1280x800", help="window size (default 1280x800)")
    parser.add_argument("--preset", default=None, help="the run's preset (default: the studio's)")
    parser.add_argument("--epochs", type=int, default=EPOCHS,
                        help=f"the run's epochs (default {EPOCHS}: it must still train when the last phase "
                             "pauses it; the preset's schedule stretches to them)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="training settings of the run (see edgedog studio --set)")
    parser.add_argument("--out", type=Path, default=None, help="write the figures as JSON here")
    args = parser.parse_args(argv)
    options = ["--set", f"epochs={args.epochs}"]
    options += [arg for override in args.overrides for arg in ("--set", override)]
    options += [] if args.preset is None else ["--preset", args.preset]
    figures = measure(args.scene, args.seconds, args.size, options)
    print(f"{'phase':<22} {'fps':>6} {'drawn/s':>8} {'steps/s':>8} {'headless':>8} {'share':>6} {'CPU %':>6} "
          f"{'UI CPU %':>8}")
    for name, row in figures.items():
        headless, share = row["headless_steps_per_second"], row["share_of_headless"]
        headless = "-" if headless is None else f"{headless:.1f}"
        share = "-" if share is None else f"{share:.0%}"
        ui = "-" if row["ui_cpu_percent"] is None else f"{row['ui_cpu_percent']:d}"
        print(f"{name:<22} {row['fps']:6.1f} {row['drawn_per_second']:8.1f} {row['steps_per_second']:8.1f} "
              f"{headless:>8} {share:>6} "
              f"{row['cpu_percent']:6d} {ui:>8}")
    typing = figures["training + typing"]
    print(f"typing {typing['keys']} keys: {typing['keys_lost']} lost, drawn after "
          f"{typing['latency_ms_median']} ms (median), {typing['latency_ms_max']} ms at most")
    if args.out is not None:
        args.out.write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
