"""Run the `edgedog` command line in a subprocess, as a user would."""

from __future__ import annotations

import subprocess
import sys


def edgedog(*args, cwd=None) -> subprocess.CompletedProcess:
    """`python -m edgedog ARGS` with captured text output (arguments may be paths)."""
    return subprocess.run([sys.executable, "-m", "edgedog", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True)
