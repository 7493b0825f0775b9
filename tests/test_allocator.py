"""The CLI keeps large freed blocks for reuse (edgedog.allocator): PiDiNet's second image does not
fault its tensors' pages in again."""

import subprocess
import sys

import pytest

from edgedog.allocator import on_glibc

pytestmark = pytest.mark.skipif(not on_glibc(), reason="the setting is glibc's")

SECOND_IMAGE_FAULTS = """
import resource, sys
import numpy as np
if sys.argv[1] == "keep":
    from edgedog.allocator import keep_freed_memory
    assert keep_freed_memory()
from edgedog.edges.pidinet import PidinetDetector, shipped_weights
detector = PidinetDetector(shipped_weights())
image = np.random.default_rng(0).random((400, 400, 3), dtype=np.float32)
detector.detect(image)
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
detector.detect(image)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults)
"""


def second_image_faults(mode: str) -> int:
    """Minor page faults while PiDiNet detects a 400 x 400 image a second time (its largest
    tensors, 60 channels, are 38 MB: above glibc's default mmap threshold)."""
    out = subprocess.run([sys.executable, "-c", SECOND_IMAGE_FAULTS, mode], capture_output=True, text=True,
                         check=True)
    return int(out.stdout)


def test_pidinet_reuses_its_freed_tensors_instead_of_faulting_them_in_again():
    returned, kept = second_image_faults("return"), second_image_faults("keep")
    assert kept < 0.5 * returned  # measured: about a quarter (an eighth at 800 x 800)


def test_commands_run_with_the_setting(monkeypatch, tmp_path):
    from edgedog import cli

    calls = []
    monkeypatch.setattr(cli, "keep_freed_memory", lambda: calls.append(True))
    assert cli.main(["info", str(tmp_path / "no-scene")]) == 2  # a user's error, after the setting
    assert calls == [True]
