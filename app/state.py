"""The studio's UI state: what the user has set, and the actions the user asked for.

Panels (and the scripted driver) only write here; `Studio` reads it each frame and acts, so a
click and a scripted action take the same path.
"""

from __future__ import annotations

import typing
from dataclasses import dataclass, field
from typing import Any

from edgedog.app.zoom import ImageZoom

from edgedog.settings import with_values
from edgedog.train.config import Kernel, TrainConfig, Weighting, with_epochs

WEIGHTINGS: tuple[str, ...] = typing.get_args(Weighting)
WEIGHTING_FORMULAS = {"one": "1", "exp_neg": "exp(-U)", "one_minus": "1 - U", "up": "U", "exp": "exp(U)"}
"""How the UI names each weighting w(U) of the pixel uncertainty U (the paper's Table 4)."""
EXPORT_FORMATS = ("ply", "obj", "json")
KERNELS: tuple[str, ...] = typing.get_args(Kernel)
FISHER = "Fisher U"
COLOR_MODES = ("white", "opacity", "DoG a", "DoG t", FISHER)
"""What the splats are coloured by: nothing, their opacity, the inner scale a or the surround
ratio t of their DoG shape k, or log10 of their Fisher information (the per-primitive score the
pruning ranks by: low is uncertain)."""


@dataclass
class LiveSettings:
    """Applied to the running trainer at its next step boundary."""

    keep_ratio: float
    weighting: str


@dataclass
class RestartSettings:
    """Applied when a run starts or restarts (a running trainer cannot change them)."""

    preset: str
    epochs: int
    k_init: tuple[float, float]
    kernel: str
    pixel_uncertainty: bool
    primitive_uncertainty: bool
    layers: int = 1
    """Multi-granularity levels L0 .. L<layers - 1> (`edgedog train --layers`); 1: one layer."""

    @classmethod
    def from_config(cls, preset: str, config: TrainConfig) -> RestartSettings:
        return cls(preset, config.schedule.epochs, tuple(config.init.k), config.model.kernel,
                   config.loss.pixel_uncertainty, config.strategy.primitive_uncertainty)

    def apply(self, base: TrainConfig, live: LiveSettings) -> TrainConfig:
        """`base` (the preset with the command line's overrides) with these and the live settings."""
        # A new epoch count stretches the preset's whole schedule, not only its end.
        return with_values(with_epochs(base, self.epochs), {
            "init.k": tuple(self.k_init), "model.kernel": self.kernel,
            "loss.pixel_uncertainty": self.pixel_uncertainty, "loss.weighting": live.weighting,
            "strategy.primitive_uncertainty": self.primitive_uncertainty,
            "strategy.keep_ratio": live.keep_ratio})


@dataclass
class Display:
    """What the 3D view shows."""

    splats: bool = True
    edges: bool = True
    cameras: bool = True
    ground_truth: bool = True
    pruned: bool = True
    color_by: str = "white"
    layers: dict[str, bool] = field(default_factory=lambda: {"L0": True})
    """Multi-granularity layers by name -> shown."""
    sfm_points: bool = True
    """The scene's structure-from-motion points (a COLMAP scene's, e.g. from `edgedog sfm`)."""


@dataclass
class SfmSettings:
    """How a folder of photos is taken through structure from motion (`edgedog sfm`'s options),
    and whether training starts once its cameras are shown."""

    matcher: str = "exhaustive"
    max_image_size: int = 1600
    train_after: bool = True


@dataclass(frozen=True)
class Request:
    """An action asked for: "open" (path; none: the folder browser; a folder of photos: asks
    whether to "sfm"), "sfm" (photos, out: recover their cameras, then open that scene),
    "cancel_sfm", "start", "pause", "resume", "restart", "extract", "export" (formats, or one
    format; default the checked ones), "snap" (to the selected view), "reset_view", "help" (show
    or hide), "screenshot" (path),
    "quit" (the user's: asked first while a run is under way, always with ask=True), "close"
    (the window closes at once). "open" with a path, "restart" and "quit" that would stop a run
    wait for the user's yes, which makes them again with confirmed=True."""

    name: str
    args: dict[str, Any] = field(default_factory=dict)


@dataclass
class UIState:
    """Everything the panels edit."""

    live: LiveSettings
    restart: RestartSettings
    display: Display = field(default_factory=Display)
    view: int = 0
    """The selected training view (inspectors, snapping)."""
    auto_extract: bool = False
    """Extract curves from the latest snapshot every `auto_extract_seconds`."""
    auto_extract_seconds: float = 20.0
    export_formats: dict[str, bool] = field(default_factory=lambda: dict.fromkeys(EXPORT_FORMATS, True))
    """The formats one click on Export writes (all from the same snapshot)."""
    sfm: SfmSettings = field(default_factory=SfmSettings)
    show_help: bool = False
    inspector: ImageZoom = field(default_factory=ImageZoom)
    """The inspector enlarged to the whole panel, its zoom and the pixel readout."""
    status: str = ""
    """The status line: the last thing done (e.g. the path written)."""
    requests: list[Request] = field(default_factory=list)

    @classmethod
    def for_config(cls, preset: str, config: TrainConfig) -> UIState:
        live = LiveSettings(config.strategy.keep_ratio, config.loss.weighting)
        return cls(live, RestartSettings.from_config(preset, config))

    def request(self, name: str, **args) -> None:
        self.requests.append(Request(name, args))

    def take_requests(self) -> list[Request]:
        """The requests made since the last call, oldest first."""
        taken, self.requests = self.requests, []
        return taken
