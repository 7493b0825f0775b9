"""How fluid the studio is while it trains: frames per second, training steps per second and the
process's CPU use, with and without the user orbiting the 3D view.

    python -m edgedog.bench.studio SCENE [--seconds 8] [--size 1280x800] [--set KEY=VALUE ...]

Runs `edgedog studio SCENE` on the current display (e.g. under Xvfb: DISPLAY=:1) with a scripted
session: start a run, let it train untouched, orbit the view continuously (one mouse move per
frame, as a drag does), then pause and orbit again (the UI alone). Prints one row per phase and
writes the figures as JSON (--out). A measurement, not a test: the figures depend on the machine
and on what else runs on it.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

WARM_UP = 3.0
"""Seconds of training before the first phase (the first epochs compile and allocate)."""
DRAG_FPS = 30
"""Frames a scripted drag is spread over per second (at most the window's interactive rate)."""
PHASES = {"training": ("0", "1"), "training + orbiting": ("1", "2"), "paused + orbiting": ("3", "4")}
"""Each phase's first and last mark in the script."""


def script(seconds: float, report: Path) -> dict:
    """The scripted session: a mark at each phase boundary."""
    frames = round(seconds * DRAG_FPS)
    orbit = {"drag": "3D view", "by": [6 * frames, 0], "frames": frames}
    return {"report": str(report), "actions": [
        {"request": "start"},
        {"expect": {"phase": "training", "version": [">=", 2]}, "timeout": 120},
        {"wait": WARM_UP}, {"mark": "0"},
        {"wait": seconds}, {"mark": "1"},
        orbit, {"mark": "2"},
        {"request": "pause"}, {"expect": {"phase": "paused"}, "timeout": 10}, {"mark": "3"},
        orbit, {"mark": "4"},
        {"request": "close"}]}


def phase_figures(start: dict, end: dict) -> dict:
    """Rates between two marks of the report."""
    seconds = end["at"] - start["at"]
    return {"seconds": round(seconds, 2), "fps": round((end["frames"] - start["frames"]) / seconds, 1),
            "steps_per_second": round((end["steps"] - start["steps"]) / seconds, 1),
            "view_renders_per_second": round((end["view_renders"] - start["view_renders"]) / seconds, 1),
            "cpu_percent": round(100 * (end["cpu_seconds"] - start["cpu_seconds"]) / seconds)}


def measure(scene: Path, seconds: float, size: str, overrides: list[str]) -> dict[str, dict]:
    """Run the scripted session; returns the figures of each phase."""
    with tempfile.TemporaryDirectory(prefix="edgedog-bench-studio-") as folder:
        folder = Path(folder)
        (folder / "script.json").write_text(json.dumps(script(seconds, folder / "report.json")))
        sets = [arg for override in overrides for arg in ("--set", override)]
        command = [sys.executable, "-m", "edgedog", "studio", str(scene), "--runs", str(folder / "runs"),
                   "--size", size, "--script", str(folder / "script.json"), *sets]
        result = subprocess.run(command, capture_output=True, text=True, env=os.environ)
        report_file = folder / "report.json"
        report = json.loads(report_file.read_text()) if report_file.is_file() else {}
    if result.returncode != 0 or not report.get("ok"):
        raise SystemExit(f"the studio failed: {report.get('failure')}\n{result.stderr[-3000:]}")
    marks = report["marks"]
    return {name: phase_figures(marks[start], marks[end]) for name, (start, end) in PHASES.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m edgedog.bench.studio",
                                     description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("scene", type=Path)
    parser.add_argument("--seconds", type=float, default=8.0, help="length of each phase (default 8)")
    parser.add_argument("--size", default="1280x800", help="window size (default 1280x800)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="training settings of the run (see edgedog studio --set)")
    parser.add_argument("--out", type=Path, default=None, help="write the figures as JSON here")
    args = parser.parse_args(argv)
    figures = measure(args.scene, args.seconds, args.size, args.overrides)
    print(f"{'phase':<22} {'fps':>6} {'steps/s':>8} {'renders/s':>9} {'CPU %':>6}")
    for name, row in figures.items():
        print(f"{name:<22} {row['fps']:6.1f} {row['steps_per_second']:8.1f} "
              f"{row['view_renders_per_second']:9.1f} "
              f"{row['cpu_percent']:6d}")
    if args.out is not None:
        args.out.write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
