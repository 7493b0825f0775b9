"""A layered run folder: the record of a stack of layers, and its per-layer / cumulative curves.

Layout of RUN (each layer folder is an ordinary run folder, so `edgedog extract`, `export`,
`studio` and `--resume` work on it; its primitives.ply holds the layers below it too):

    RUN/layers.json             the scene, the preset, the levels and the base config
    RUN/L0/, RUN/L1/, ...       one training run per layer, each started from the one below
    RUN/curves/L1/              curves of layer L1's own primitives
    RUN/curves/L0+L1/           curves of the cumulative model up to L1
    RUN/layers_report.json      counts and scores of every selection

A `LayeredRun` answers what a `RunFolder` answers (path, scene, preset, config, fingerprints,
`layers()`, `curves_folder`, `selection_folder()`, `report_file`, `extraction_scene()`,
`extract()`, `write()`), so a caller holding either holds a stack of layers: a run folder is a
stack of one. `edgedog.train.run` trains them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from edgedog.curves.config import ExtractConfig
from edgedog.edges.cache import attach_edge_maps
from edgedog.errors import InputError
from edgedog.files import atomic_write_json, read_json
from edgedog.primitives import read_ply
from edgedog.scenes import Scene, load_scene
from edgedog.settings import with_values
from edgedog.train.config import DEFAULT_PRESET, PRESETS_RENAMED, TrainConfig, from_dict, is_flat, to_dict
from edgedog.train.levels import Level
from edgedog.train.run_folder import LOG, RunFolder

LAYERS_FILE = "layers.json"
REPORT = "layers_report.json"


@dataclass(frozen=True)
class LayeredRun:
    """path: the layered run folder; scene: the scene folder; preset: the preset named;
    base: the config every layer starts from; levels: bottom first; scene_fingerprint,
    maps_fingerprint: of the scene trained on, as a `RunFolder`'s (None in layered runs written
    before they were recorded)."""

    path: Path
    scene: Path
    preset: str
    base: TrainConfig
    levels: tuple[Level, ...]
    scene_fingerprint: str | None = None
    maps_fingerprint: str | None = None

    @property
    def config(self) -> TrainConfig:
        """The base config (a run folder's `config`): every layer's but for its maps."""
        return self.base

    @property
    def curves_folder(self) -> Path:
        """Where the curves of the whole model are: the cumulative selection of every layer."""
        return self.selection_folder()

    def layer_dir(self, index: int) -> Path:
        return self.path / self.levels[index].name

    def layer_config(self, index: int) -> TrainConfig:
        level = self.levels[index]
        return with_values(self.base, {"maps.detector": level.detector, "maps.floor": level.floor,
                                       "layers.layer": index})

    def layers(self) -> tuple[RunFolder, ...]:
        """The run folder of each layer, bottom first, with its level's maps."""
        return tuple(RunFolder(self.layer_dir(index), self.scene, self.preset, self.layer_config(index),
                               self.scene_fingerprint, self.maps_fingerprint)
                     for index in range(len(self.levels)))

    @property
    def report_file(self) -> Path:
        """The extraction's report: every selection's (layers_report.json)."""
        return self.path / REPORT

    def extraction_scene(self, config: ExtractConfig) -> Scene:
        """The scene as layers.json records it, at the run's resolution (each selection's maps
        are attached as it is extracted)."""
        return load_scene(self.scene, downscale=self.base.maps.downscale)

    def extract(self, scene: Scene, config: ExtractConfig = ExtractConfig()) -> dict:
        """Extract every selection (`extract_layered`); returns the report."""
        return extract_layered(self, scene, config)

    def selection_folder(self, name: str | None = None) -> Path:
        """Where the curves of the selection `name` are (a layer, L1, or a cumulative stack, L0+L1;
        None: the whole stack's); InputError naming the run for a selection it does not have."""
        names = [chosen for chosen, _ in selections(len(self.levels))]
        name = name or names[-1]
        if name not in names:
            raise InputError(self.path, f"no layer selection {name!r}; choose from {', '.join(names)}")
        return self.path / "curves" / name

    def write(self) -> None:
        """Write layers.json (the layers' config.json are written as each starts)."""
        write_layered(self)


def is_layered(path: Path) -> bool:
    return (Path(path) / LAYERS_FILE).is_file()


def write_layered(run: LayeredRun) -> None:
    atomic_write_json(run.path / LAYERS_FILE, {
        "scene": str(run.scene), "scene_fingerprint": run.scene_fingerprint,
        "maps_fingerprint": run.maps_fingerprint, "preset": run.preset,
        "config": to_dict(run.base), "levels": [dataclasses.asdict(level) for level in run.levels]})


def read_layered(path: Path) -> LayeredRun:
    data = read_json(Path(path) / LAYERS_FILE)
    if not isinstance(data, dict) or not {"scene", "config", "levels"} <= data.keys():
        raise InputError(Path(path) / LAYERS_FILE, "expected 'scene', 'config' and 'levels' keys")
    levels = tuple(Level(**level) for level in data["levels"])
    preset = data.get("preset", DEFAULT_PRESET)
    if is_flat(data["config"]):  # written before the sections, when 'paper' named today's 'full'
        preset = PRESETS_RENAMED.get(preset, preset)
    recorded = data.get("scene_fingerprint"), data.get("maps_fingerprint")
    for name, value in zip(("scene_fingerprint", "maps_fingerprint"), recorded):
        if not isinstance(value, str | None):
            raise InputError(Path(path) / LAYERS_FILE, f"'{name}' must be a string, got {value!r}")
    return LayeredRun(Path(path), Path(data["scene"]), preset, from_dict(data["config"]), levels, *recorded)


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
        detector = read_json(finest / LOG)["detector"]
        attach_edge_maps(scene, detector)
        _, selection = extract_with_report(top, scene, detector, config, layers, run.path / "curves" / name)
        selection["primitives"] = int(sum((counts == i).sum() for i in layers))
        report["selections"][name] = selection
    atomic_write_json(run.path / REPORT, report)
    return report
