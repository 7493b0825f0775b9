"""A scene without edge maps trains with PiDiNet on any machine: its BSDS weights ship with
edgedog, so no weights need configuring (the shipped file itself: tests/test_pidinet.py)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from edgedog.edges.pidinet import SHIPPED_SHA256
from tests.helpers.cli_runner import edgedog
from tests.helpers.tiny_runs import QUICK_TRAIN


def test_train_without_maps_or_configured_weights_reports_pidinet(small_box_scene, tmp_path, monkeypatch):
    monkeypatch.delenv("EDGEDOG_PIDINET", raising=False)
    # The small box as plain NeRF: its images listed directly, its Canny maps gone.
    scene = tmp_path / "box"
    shutil.copytree(small_box_scene, scene)
    shutil.rmtree(scene / "train")
    (scene / "train_img").rename(scene / "train")
    info = edgedog("info", scene)
    assert info.returncode == 0, info.stderr
    assert "edge maps     none" in info.stdout

    result = edgedog("train", scene, "--out", tmp_path / "run", *QUICK_TRAIN)
    assert result.returncode == 0, result.stderr
    announced = json.loads(result.stdout.splitlines()[0])
    assert announced["detector"] == "pidinet"
    assert json.loads((tmp_path / "run" / "log.json").read_text())["detector"] == "pidinet"
    # The maps were computed with the shipped weights: the cache folder names their digest.
    cached = Path(os.environ["EDGEDOG_CACHE"]) / "edges"
    assert any(folder.name.startswith(f"pidinet-{SHIPPED_SHA256[:12]}-fused_")
               for folder in cached.glob(f"{scene.name}-*/pidinet/*"))
