"""A layered run folder: progressive training of the levels, and per-layer / cumulative curves.

Layout of RUN (each layer folder is an ordinary run folder, so `edgedog extract`, `export`,
`studio` and `--resume` work on it; its primitives.ply holds the layers below it too):

    RUN/layers.json             the scene, the preset, the levels and the base config
    RUN/L0/, RUN/L1/, ...       one training run per layer, each started from the one below
    RUN/curves/L1/              curves of layer L1's own primitives
    RUN/curves/L0+L1/           curves of the cumulative model up to L1
    RUN/layers_report.json      counts and scores of every selection
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from edgedog.curves.config import ExtractConfig
from edgedog.edges.cache import attach_edge_maps
from edgedog.errors import InputError
from edgedog.files import atomic_write_json, read_json
from edgedog.primitives import read_ply
from edgedog.scenes import Scene
from edgedog.settings import with_values
from edgedog.train.config import DEFAULT_PRESET, PRESETS_RENAMED, TrainConfig, from_dict, is_flat, to_dict
from edgedog.train.levels import Level, check_level_maps
from edgedog.train.lifecycle import check_scene_of_run, fingerprint, is_finished, load_run_scene
from edgedog.train.run_folder import RUN_CONFIG, RunFolder, check_new_run_folder, write_run

if TYPE_CHECKING:
    from edgedog.train.trainer import Trainer

LAYERS_FILE = "layers.json"
REPORT = "layers_report.json"


@dataclass(frozen=True)
class LayeredRun:
    """path: the layered run folder; scene: the scene folder; preset: the preset named;
    base: the config every layer starts from; levels: bottom first; scene_fingerprint: of the
    scene trained on (None in layered runs written before it was recorded)."""

    path: Path
    scene: Path
    preset: str
    base: TrainConfig
    levels: tuple[Level, ...]
    scene_fingerprint: str | None = None

    def layer_dir(self, index: int) -> Path:
        return self.path / self.levels[index].name

    def layer_config(self, index: int) -> TrainConfig:
        level = self.levels[index]
        return with_values(self.base, {"maps.detector": level.detector, "maps.floor": level.floor,
                                       "layers.layer": index})


def is_layered(path: Path) -> bool:
    return (Path(path) / LAYERS_FILE).is_file()


def write_layered(run: LayeredRun) -> None:
    atomic_write_json(run.path / LAYERS_FILE, {
        "scene": str(run.scene), "scene_fingerprint": run.scene_fingerprint, "preset": run.preset,
        "config": to_dict(run.base), "levels": [dataclasses.asdict(level) for level in run.levels]})


def read_layered(path: Path) -> LayeredRun:
    data = read_json(Path(path) / LAYERS_FILE)
    if not isinstance(data, dict) or not {"scene", "config", "levels"} <= data.keys():
        raise InputError(Path(path) / LAYERS_FILE, "expected 'scene', 'config' and 'levels' keys")
    levels = tuple(Level(**level) for level in data["levels"])
    preset = data.get("preset", DEFAULT_PRESET)
    if is_flat(data["config"]):  # written before the sections, when 'paper' named today's 'full'
        preset = PRESETS_RENAMED.get(preset, preset)
    recorded = data.get("scene_fingerprint")
    if not isinstance(recorded, str | None):
        raise InputError(Path(path) / LAYERS_FILE, f"'scene_fingerprint' must be a string, got {recorded!r}")
    return LayeredRun(Path(path), Path(data["scene"]), preset, from_dict(data["config"]), levels, recorded)


def plan_layered(out: Path, scene_path: Path, preset: str, base: TrainConfig,
                 levels: tuple[Level, ...]) -> tuple[LayeredRun, Scene]:
    """A new layered run of `levels` in `out` (a new or empty folder) and its scene at the base
    resolution, checked as `lifecycle.plan_run` checks a run's (the maps of every level, readable
    views); writes nothing."""
    if is_layered(out):
        raise InputError(out, "already holds a layered run; pass --resume to continue it, or choose "
                              "another --out")
    check_new_run_folder(out)
    scene = load_run_scene(scene_path, base)
    check_level_maps(levels, scene.detectors)
    return LayeredRun(Path(out), scene.root, preset, base, levels, fingerprint(scene)), scene


def continue_layered(out: Path, scene_path: Path) -> tuple[LayeredRun, Scene]:
    """The layered run in `out` and `scene_path` loaded at its resolution, which must be the scene
    it trained on (by fingerprint, or by folder for runs that recorded none)."""
    if not is_layered(out):
        raise InputError(out, "no layered run to resume (layers.json is missing)")
    run = read_layered(out)
    scene = load_run_scene(scene_path, run.base)
    check_scene_of_run(run.path, run.scene, run.scene_fingerprint, scene)
    return run, scene


def layer_trainers(run: LayeredRun, scene: Scene, progress: bool = True) -> Iterator[Trainer]:
    """The trainers of the unfinished layers, bottom up, each built once the layers below it are
    trained (finished layers are reused: a layer's checkpoint holds the whole stack up to it; an
    interrupted one resumes). The caller trains each trainer before asking for the next.

    Args:
        scene: loaded at the base config's resolution.
    """
    from edgedog.train.trainer import Trainer, read_stack

    lower = None
    for index in range(len(run.levels)):
        folder, config = run.layer_dir(index), run.layer_config(index)
        if is_finished(folder):
            lower = read_stack(folder)
            continue
        if not (folder / RUN_CONFIG).is_file():
            write_run(RunFolder(folder, run.scene, run.preset, config, run.scene_fingerprint))
        trainer = Trainer(scene, config, folder, progress=progress, lower=lower)
        yield trainer
        lower = trainer.stack()


def train_layered(run: LayeredRun, scene: Scene, progress: bool = True, on_layer=None) -> None:
    """Train the levels bottom up, each layer on its maps with the layers below fixed
    (`layer_trainers`); `on_layer` is called with (index, trainer) before each layer trains."""
    for trainer in layer_trainers(run, scene, progress):
        if on_layer is not None:
            on_layer(trainer.config.layers.layer, trainer)
        trainer.run()


def selections(count: int) -> list[tuple[str, set[int]]]:
    """(name, layers) of each layer alone and of each cumulative stack: L0, L1, L0+L1, L2, L0+L1+L2."""
    chosen = []
    for top in range(count):
        chosen.append((f"L{top}", {top}))
        if top:
            chosen.append(("+".join(f"L{i}" for i in range(top + 1)), set(range(top + 1))))
    return chosen


def extract_layered(run: LayeredRun, scene: Scene, config: ExtractConfig = ExtractConfig()) -> dict:
    """Curves of every selection (each layer alone, each cumulative stack) into RUN/curves/NAME,
    with their reports gathered in RUN/layers_report.json.

    The projection filter of a selection uses the maps of its finest layer.
    """
    from edgedog.curves.report import extract_with_report

    top = run.layer_dir(len(run.levels) - 1)
    counts = read_ply(top / "primitives.ply").layers
    report = {"levels": [dataclasses.asdict(level) for level in run.levels], "selections": {}}
    for name, layers in selections(len(run.levels)):
        finest = run.layer_dir(max(layers))
        detector = read_json(finest / "log.json")["detector"]
        attach_edge_maps(scene, detector)
        _, selection = extract_with_report(top, scene, detector, config, layers, run.path / "curves" / name)
        selection["primitives"] = int(sum((counts == i).sum() for i in layers))
        report["selections"][name] = selection
    atomic_write_json(run.path / REPORT, report)
    return report
