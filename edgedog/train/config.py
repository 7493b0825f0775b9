"""Training settings: `TrainConfig`, its sections, its named presets, and the old flat names.

Every setting's allowed values are written once, in its type (see `edgedog.settings`); each
section checks its fields when it is made, so presets, `--set` and the config.json of a run
folder read by `from_dict` all are checked. Settings are named `section.field` (`loss.weighting`);
a bare field name stands for the one section that has it, and `RENAMED` maps the flat names of
run folders written before the sections (format version 2) to their dotted names.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal

from edgedog.errors import ConfigError
from edgedog.hull import MAX_HULL_CELLS
from edgedog.init.settings import MAX_LOGIT, MAX_PRIMITIVES, Count, InitSettings, Logit
from edgedog.renderer.config import KActivation, Kernel
from edgedog.settings import (
    Check,
    Range,
    Settings,
    check_setting,
    item_kind,
    rules,
    setting_paths,
    shown,
    to_dict,
    value_at,
    with_values,
)
from edgedog.settings import from_dict as settings_from_dict
from edgedog.settings import setting_name as settings_setting_name
from edgedog.settings import with_overrides as settings_with_overrides


def _maps_name(name: str) -> None:
    """A detector's name must be one `make_detector` builds, with options it takes ('canny:5' is
    refused). Other names may be a scene's own maps (e.g. 'dexined'): the scene is checked when
    it is loaded."""
    from edgedog.edges.registry import is_detector_name

    if not name.strip():
        raise ConfigError(f"maps.detector must name a detector or a scene's maps, got {shown(name)}")
    is_detector_name(name)


# Bounds of the settings that size an allocation or a loop, or past which a value means nothing
# (MAX_PRIMITIVES and MAX_LOGIT: edgedog.init.settings, which the init section shares).
MAX_EPOCHS = 10_000
"""25 times the paper's 400; every epoch is one step per view."""
MAX_DOWNSCALE = 16
"""An 800 px view becomes 50 px: coarser, the views hold no edges worth fitting."""
MAX_WIDTH_PX = 32.0
"""Widths and shifts in px: the measured bands and offsets are 1-3 px. The blur kernels grow
with their width (profile_sigma: 6 sigma + 1 taps, each a pass over the image per step); one
reaching 3 x 32 px to each side spans much of a view and merges its edges into one smear."""
MAX_NEIGHBOURS = 32
"""Each orientation step builds (N, k, 3) offsets; EdgeGaussians use 5."""
MAX_COPIES = 8
"""Copies of one primitive at one place: EdgeGaussians make 2; the copies share their source's
parameters, so many more add nothing but noise."""
MAX_EDGE_BUDGET = 100.0
"""Primitives per vote spacing of edge (about 10 mm of an ABC object): 100 is one per 0.1 mm,
far denser than any edge needs; the budget stays under `max_primitives` anyway."""
MIN_SPACING = 1e-6
"""The spacing control hashes centres into cells of half the spacing: a millionth of a scene unit
(or of the object's size) is far below any edge detail, and keeps the cell indices small."""
MAX_LAYERS = 8
"""Multi-granularity levels (the paper uses 3); each trains a whole run."""
MAX_SEED = 2**32 - 1
"""Seeds are 32-bit integers, which torch's and numpy's generators all take."""
MAX_RATE = 1.0
"""Adam moves a parameter by about its learning rate per step whatever the gradient: 1 scene unit
(or 1 px, 1 log-scale unit) per step is already far past any useful rate."""
MAX_DECAY = 1 / MAX_RATE
"""Weight decay: each step shrinks a parameter by its learning rate times this, at most all of it."""
MAX_VIEWS = 100_000
"""More views than any capture holds."""


@dataclass(frozen=True)
class InEpochs:
    """Marks a setting counted in epochs: `with_epochs` scales it with the run's length."""


IN_EPOCHS = InEpochs()

Epoch = Annotated[int, Range(0, MAX_EPOCHS), IN_EPOCHS]
"""An epoch (0-based) at which something starts or happens."""
EpochPeriod = Annotated[int, Range(1), IN_EPOCHS]
"""A period in epochs."""
Every = Annotated[int, Range(1)]
"""A period in steps."""
Share = Annotated[float, Range(0, 1)]
Rate = Annotated[float, Range(0, MAX_RATE)]
Width = Annotated[float, Range(0, MAX_WIDTH_PX, open_low=True)]
Shift = Annotated[float, Range(-MAX_WIDTH_PX, MAX_WIDTH_PX)]

Weighting = Literal["one", "exp_neg", "one_minus", "up", "exp"]
"""w(Up) of the pixel uncertainty (see `LossSettings.weighting`)."""
EdgeProfile = Literal["auto", "raw", "thin", "profile"]
MapCorrection = Literal["none", "calibrated", "shift", "learned"]
SilhouetteCorrection = Literal["auto", "measured", "none"]
StopMode = Literal["off", "run", "coarse", "both"]
"""What convergence ends (see `ScheduleSettings.stop`)."""
Occlusion = Literal["off", "hull", "auto"]
"""Whether the visual hull hides primitives (see `ModelSettings.occlusion`)."""


@dataclass(frozen=True)
class MapsSettings(Settings):
    """The pseudo-edge maps fitted, and how they are prepared."""

    detector: Annotated[str, Check(_maps_name)] = "auto"
    """Pseudo-edge maps to fit: a scene's own maps by name (e.g. 'pidinet'), or a detector name."""
    downscale: Annotated[int, Range(1, MAX_DOWNSCALE)] = 1
    """Train at 1/downscale resolution."""
    floor: Annotated[float, Range(0, 1, open_high=True)] = 0.0
    """Map values below this are set to zero: a coarse layer keeps only the strong edges."""
    contrast: Annotated[float, Range(0, 1, open_high=True)] = 0.0
    """Contrast-normalised targets: each map value divided by the largest within 2 pixels of it,
    or by this where that is smaller (capped at 1), so that an edge the detector draws faintly (a
    rib's top edge at 0.6, a concave corner in shadow) is fitted as fully as a strong one, while
    responses weaker than this stay weaker; the edge masks are the maps' own. 0: the maps as they
    are. At 0.7 with `lean`: design 25's six seeds F10 92.5 -> 94.3 (`quick` 94.7), 16 other CAD
    designs +1.2 +- 0.5, ABC 00000006 +2.5 to +3.5, but more primitives on the built-in box; not
    yet the whole suite (docs/notes/2026-12-08-contrast-targets.md)."""
    correction: MapCorrection = "none"
    """Correct the maps' sub-pixel offset: 'calibrated' shifts them by the correction of their
    detector's record (`edgedog calibrate-detector`); 'shift' by `shift`; 'learned' fits one 2D
    shift of all maps jointly with the primitives, from `shift_from_epoch` on."""
    shift: tuple[Shift, Shift] = (0.0, 0.0)
    """The shift of 'shift' in px of the maps as stored (x right, y down: content moves by it)."""
    shift_from_epoch: Epoch = 100
    """'learned': the shift is fitted once the primitives have settled (from this epoch)."""
    lr_shift: Rate = 0.002
    """'learned': Adam's learning rate of the shift, px per step."""
    silhouette_correction: SilhouetteCorrection = "auto"
    """'measured': measure where the maps draw the object's outline against the scene's masks
    (alpha or mask files) and pull them onto it (edgedog.edges.silhouette). Maps made from
    RGBA images with the alpha dropped draw it 1-1.5 px outside, and the model grows outwards.
    'auto': 'measured' when the images carry an alpha channel (a render's exact outline), else
    'none' (hand-drawn mask files of photos are not exact enough to correct maps with)."""
    silhouette_reach: Width = 3.0
    """'measured': px from the outline within which the full correction applies (fading to 0 at
    twice this)."""
    edge_profile: EdgeProfile = "auto"
    """'auto': the maps' detector's choice (`for_detector`: 'profile' for DexiNed maps, 'raw' for
    others); 'raw': fit the maps as they are; 'thin': fit their ridge drawn with a narrow Gaussian
    profile (edgedog.edges.thin), which removes the bias of thick, asymmetric detector bands;
    'profile': fit the render blurred by `profile_sigma` (the band's measured width) to the maps,
    so that thin primitives explain a thick band."""
    thin_sigma: Width = 0.7
    """Width (px, standard deviation) of the 'thin' profile."""
    profile_sigma: Width = 1.0
    """'profile': standard deviation (px at the training resolution) of the render's blur."""
    edge_threshold: Annotated[float, Range(0, 1, open_low=True)] = 0.5
    """Edge pixels of a map are those >= this value (the sampled loss's and the layers' residual
    edges)."""


@dataclass(frozen=True)
class ModelSettings(Settings):
    """The primitives' kernel."""

    kernel: Kernel = "dog"
    """'dog' (EdgeDoG) or 'gaussian' (the EdgeGaussians baseline)."""
    k_activation: KActivation = "sigmoid"
    """Activation of k: 'sigmoid' for ABC, 'exp' for other data (docs/METHOD.md)."""
    view_opacity: bool = True
    """A view-dependent opacity: each primitive's opacity logit in a view is a + b . d, with d the
    unit direction from its centre to the camera and b (3,) trained from `view_opacity_from_epoch`
    (edgedog.train.view_opacity), so that an edge hidden from most views (a concave corner) is
    not penalised as a false edge where it is hidden. primitives.ply then holds b and, as
    `opacity`, the largest over the views. False: one opacity for every view (the paper's
    model), which keeps F5 higher on some objects (docs/RESULTS.md, the CAD benchmark)."""
    view_opacity_cap: Annotated[float, Range(0, MAX_LOGIT)] = 6.0
    """Largest |b| (logit units): a primitive's logit varies by at most twice this over the sphere
    of directions."""
    occlusion: Occlusion = "off"
    """'hull': a primitive is not drawn in a view where the object's visual hull, carved from the
    scene's masks, stands in front of it by more than `occlusion_margin` cells
    (edgedog.train.occlusion), so that the views a wall hides an edge from do not penalise its
    primitive, and density control counts only the views that see it. Needs masks (mask files
    or RGBA images). 'auto': 'hull' when the scene has masks, else 'off'. 'off': every primitive
    is drawn in every view (the paper's model)."""
    occlusion_cells: Annotated[int, Range(16, MAX_HULL_CELLS)] = 128
    """Cells per side of the visual hull's grid over the scene's cube (`init.side`)."""
    occlusion_margin: Annotated[float, Range(0, MAX_HULL_CELLS)] = 3.0
    """Cells a primitive must lie behind the hull's depth in a view to be hidden from it."""
    occlusion_min_views: Annotated[int, Range(1, MAX_VIEWS)] = 4
    """A primitive that fewer of the views it projects into see (one inside the hull, where the
    masks leave it larger than the object) is drawn in every view."""
    occlusion_downscale: Annotated[int, Range(1, MAX_DOWNSCALE)] = 4
    """The hull's depth in each view is taken at 1/this of the view's size."""
    occlusion_shading: bool = False
    """Carve the hull further where the views that see a cell of its surface read different grey
    values there (edgedog.shaded_hull: a pocket or a corner between walls that no silhouette
    shows), before taking its depth; the masks' hull still bounds the primitives. Needs images
    of a matte object under a fixed light (renders such as ABC-NEF's)."""
    occlusion_shading_tolerance: Annotated[float, Range(0, 1, open_low=True)] = 0.03
    """Grey values (0 to 1) a surface cell's views may spread over (between their 20th and 80th
    percentiles) before it is carved."""


@dataclass(frozen=True)
class ScheduleSettings(Settings):
    """The run's length and Adam's learning rates. Epochs count passes over the views, one view
    per step, in a seeded random order."""

    epochs: Annotated[int, Range(1, MAX_EPOCHS)] = 400
    """Length of the run (EdgeGaussians: 400); `with_epochs` scales every setting in epochs with it."""
    coarse_downscale: Annotated[int, Range(1, MAX_DOWNSCALE)] = 1
    """Coarse-to-fine: before `fine_from_epoch`, steps render at 1/coarse_downscale of the maps'
    resolution against the maps area-averaged (edgedog.train.resolution); 1: never coarse."""
    fine_from_epoch: Epoch = 0
    """Coarse-to-fine: the epoch from which every step renders the maps' own resolution."""
    lr_means: Rate = 2e-3
    """Adam's learning rate of the centres (scene units per step)."""
    lr_means_decay_epochs: tuple[Epoch, ...] = (10, 20, 30, 40, 50)
    """Epochs at which lr_means decays."""
    lr_means_decay: Share = 0.75
    """Factor of lr_means at each of lr_means_decay_epochs."""
    lr_scales: Rate = 1e-4
    """Learning rate of the log scales, from `scales_from_epoch` on (0 before)."""
    scales_from_epoch: Epoch = 30
    lr_opacity: Rate = 0.03
    """Learning rate of the opacity logits, from `opacity_from_epoch` on."""
    opacity_from_epoch: Epoch = 20
    lr_quats: Rate = 1e-3
    """Learning rate of the rotations, from `quats_from_epoch` on."""
    quats_from_epoch: Epoch = 30
    lr_k: Rate = 1e-4
    """Learning rate of the DoG shape k (none for the 'gaussian' kernel)."""
    lr_view_opacity: Rate = 0.03
    """Learning rate of the view-dependent opacity's b (`model.view_opacity`), from
    `view_opacity_from_epoch` on."""
    view_opacity_from_epoch: Epoch = 20
    stop: StopMode = "off"
    """Stop when done (edgedog.train.convergence): 'run' ends the run at the end of the first
    epoch from `stop_from_epoch` on at which the primitives have settled (`stop_patience` epochs
    in a row with no primitives added, their centres' median shift below `stop_shift` and the
    epoch loss's relative change below `stop_loss_change`, then the Fisher scores' change below
    `stop_fisher_change`): `epochs` becomes a ceiling, and the density events scheduled after
    the stop do not happen. 'coarse' ends only the coarse stage: the run skips to
    `fine_from_epoch` (the epochs and density events between are left out) and trains the fine
    stage to its end. 'both': the coarse stage ends when settled, then the run
    when settled again in the fine stage. 'off': every epoch is trained."""
    stop_from_epoch: Epoch = 0
    """The first epoch at whose end the run may stop ('run', 'both'); the coarse stage has its
    own, `coarse_stop_from_epoch`."""
    coarse_stop_from_epoch: Epoch = 0
    """The first epoch at whose end a settled coarse stage may end ('coarse', 'both'): the density
    events scheduled before it (the first opacity cull, its refills) happen in every run."""
    stop_patience: Annotated[int, Range(1, MAX_EPOCHS)] = 3
    """Epochs in a row that must meet `stop_shift` and `stop_loss_change` with no primitives
    added by density control (not scaled with `epochs`)."""
    stop_shift: Annotated[float, Range(0)] = 3e-3
    """Largest median distance (scene units) the primitives' centres move over an epoch that
    counts as settled (3e-3: 3 mm of an ABC object; with `quick`'s rates, Adam's step-to-step
    jitter alone moves settled centres about 2.5 mm per epoch)."""
    stop_loss_change: Share = 0.1
    """Largest relative difference of the epoch's mean projection loss from the mean of the last
    `stop_patience` epochs since primitives were last added that counts as settled."""
    stop_fisher_change: Share = 1.0
    """Largest change of the Fisher scores from one epoch to the next that counts as settled,
    measured once the other tests have held for `stop_patience` epochs (one Fisher pass over the
    views per epoch): half the L1 distance between the scores normalised to sum 1, the share of
    the information that moved between primitives. 1: not measured."""


@dataclass(frozen=True)
class LossSettings(Settings):
    """The projection loss, EdgeGaussians' orientation losses, and EdgeDoG's pixel uncertainty."""

    sampled_from_epoch: Epoch = 50
    """After this epoch, every `sampled_every` steps the L1 is taken on the edge pixels plus as
    many random background pixels instead of the whole image."""
    sampled_every: Every = 5
    """Steps between two sampled losses."""
    direction_from_epoch: Epoch = 250
    """The direction loss (major axes aligned with their neighbours') is on from this epoch."""
    ratio_from_epoch: Epoch = 100
    """The scale-ratio loss (elongated primitives) is on from this epoch."""
    orientation_every: Every = 5
    """The direction and scale-ratio losses are applied every this many steps."""
    direction_neighbours: Annotated[int, Range(2, MAX_NEIGHBOURS)] = 5
    """Neighbours whose directions a primitive's major axis is aligned with (the extraction's
    principal axes take as many, the point itself included)."""
    neighbours_every: Every = 1
    """The direction loss's neighbours are searched anew every this many of its steps and after
    each epoch's density events; the steps between reuse the last search's (the centres move
    little within an epoch; the search, a k-d tree on the host, is most of the loss's time)."""
    direction_factor: Annotated[float | None, Range(0)] = None
    """Direction loss weight: the term is scaled to this fraction of the running sum of the epoch's
    projection losses, as EdgeGaussians does; None: theirs for the maps' detector (0.01 for
    DexiNed maps, 0.1 for others: `for_detector`)."""
    ratio_factor: Annotated[float | None, Range(0)] = None
    """Scale-ratio loss weight, scaled like `direction_factor`; None: 0.01 for DexiNed maps, 0.05
    for others."""
    pixel_uncertainty: bool = True
    """Weight the L1 per pixel by w(Up), Up = normalised Sobel magnitude of the rendered depth."""
    weighting: Weighting = "exp_neg"
    """w(Up): 'one' 1, 'exp_neg' exp(-Up), 'one_minus' 1 - Up, 'up' Up, 'exp' exp(Up). The paper
    chose exp(Up); measured here, exp(Up) fits the occluding contours of curved surfaces (where the
    rendered depth jumps) and exp(-Up) scores higher (docs/BENCHMARKS.md, "the weighting of the
    pixel uncertainty")."""
    view_opacity_decay: Annotated[float, Range(0, MAX_DECAY)] = 0.1
    """Decoupled weight decay of the view-dependent opacity's b (AdamW): each step shrinks b by
    lr_view_opacity x this, so b holds about 1 / this (logit units) only where the views agree
    on it, and falls back to 0 where their pushes cancel (one view's noise)."""


@dataclass(frozen=True)
class StrategySettings(Settings):
    """Density control: EdgeDoG's Fisher pruning and EdgeGaussians' duplication and culls
    (their PiDiNet settings)."""

    primitive_uncertainty: bool = True
    """Every `fisher_every` epochs keep the `keep_ratio` best primitives by Fisher information."""
    fisher_every: EpochPeriod = 50
    """Epochs between Fisher prunings (none in the last epoch)."""
    keep_ratio: Annotated[float, Range(0, 1, open_low=True)] = 0.9
    """The pruning ratio p: the fraction of primitives kept at each Fisher pruning."""
    duplicate_epochs: tuple[Epoch, ...] = (40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140, 150, 160,
                                         210, 220, 350, 375)
    """Epochs after which the primitives with large gradients are duplicated."""
    duplicate_threshold: Share = 0.5
    """Duplicate primitives whose min-max normalised accumulated absgrad norm (the per-pixel
    |dL/dmean2d| summed over pixels and steps, as gsplat's absgrad) exceeds this."""
    duplicate_copies: Annotated[int, Range(1, MAX_COPIES)] = 2
    """Copies made of each primitive chosen for duplication."""
    duplicate_noise: Annotated[float, Range(0)] = 0.05
    """Standard deviation of the noise added to the copies' means (scene units)."""
    cull_opacity_epochs: tuple[Epoch, ...] = (125, 310)
    """Epochs after which the faint primitives are culled."""
    cull_opacity_below: Share = 0.05
    """Cull primitives whose opacity is below this."""
    cull_projection_epochs: tuple[Epoch, ...] = (145, 175, 190)
    """Epochs after which the primitives off the edges are culled (with `model.occlusion`, also
    those farther outside the visual hull than `model.occlusion_margin`)."""
    cull_projection_below: Share = 0.1
    """Cull primitives whose centre lands on edge pixels in fewer than this share of the views
    that see it."""
    opacity_logit_cap: Logit = 0.08
    """After each cull the opacity logits are clamped to at most this (EdgeGaussians)."""
    max_primitives: Count = 200_000
    """Duplication never grows the model beyond this."""
    edge_budget: Annotated[float, Range(0, MAX_EDGE_BUDGET)] = 0.0
    """Primitives per `init.vote_spacing` of edge that the start draws: with 'edge-vote' and a
    vote spacing, duplication and splits never grow the model beyond this times the start's count
    (`primitive_limit`), so that the count follows the length of edge the maps draw, not the
    duplication's fixed share. 0, or another initialisation: `max_primitives` alone."""
    spacing_epochs: tuple[Epoch, ...] = ()
    """Epochs after which the primitives are held at `spacing` along the edges
    (edgedog.spacing): of primitives closer than `spacing` where the edge runs in similar
    directions (the principal axes of their neighbours' centres) the one ranked higher by
    `spacing_keep` stays and the others are removed, and an elongated primitive whose largest
    scale exceeds `spacing` is split along its major axis (`spacing_split`). Empty: no spacing
    control."""
    spacing: Annotated[float, Range(MIN_SPACING)] = 0.01
    """Target distance between neighbouring primitives along an edge, in scene units (0.01: 1 cm
    of an ABC object, twice its 5 mm ground-truth spacing), or with `spacing_relative` as a share
    of the primitives' extent."""
    spacing_relative: bool = False
    """`spacing` is a share of the largest side of the box holding the central 98 % of the
    primitives' centres along each axis (the object's size, whatever its unit)."""
    spacing_angle: Annotated[float, Range(0, 90)] = 30.0
    """Largest angle (degrees) between the edge's directions at two primitives (the principal
    axes of their `spacing_neighbours` nearest centres) for them to cover the same stretch of
    edge (more: two edges that meet, both kept)."""
    spacing_neighbours: Annotated[int, Range(1, MAX_NEIGHBOURS)] = 8
    """The edge's direction at a primitive is the principal axis of the centres averaged in its
    cell of side `spacing` / 2 and in this many nearest such cells (about this many half
    spacings of edge on either side)."""
    spacing_keep: Literal["opacity", "fisher"] = "opacity"
    """Which of a redundant group stays: the most opaque (largest over the views with a
    view-dependent opacity), or the largest Fisher score (one Fisher pass over the views)."""
    spacing_split: bool = True
    """Split the elongated primitives (largest scale at least twice the second) longer than
    `spacing` (largest scale above it) into ceil(scale / spacing) pieces, at most `MAX_COPIES`,
    along their major axis (within `max_primitives`)."""


@dataclass(frozen=True)
class LayerSettings(Settings):
    """Multi-granularity layers (edgedog.train.layers)."""

    layer: Annotated[int, Range(0, MAX_LAYERS - 1)] = 0
    """Index of the layer this run adds; the layers below it are given to the trainer, fixed."""
    lower_lr_scale: Share = 0.0
    """Fine-tune the layers below at this fraction of the learning rates (0: frozen)."""
    residual_min_share: Share = 0.1
    """Above layer 0, initial points are kept where they land on the residual edges (the map
    minus the render of the layers below, >= maps.edge_threshold) in at least this share of the
    views that see them."""


@dataclass(frozen=True)
class RunSettings(Settings):
    """The seed and what the run writes as it goes."""

    seed: Annotated[int, Range(0, MAX_SEED)] = 0
    """Seed of every random draw of the run (the same seed and threads: the same run)."""
    checkpoint_every: EpochPeriod = 50
    """Epochs between checkpoints (one is always written at the end)."""
    damaged_views: Literal["refuse", "skip"] = "refuse"
    """Views whose image cannot be read (cut short, undecodable): 'refuse' the scene, naming the
    first such file; 'skip' train on the other views (log.json lists the views left out)."""
    device: Literal["auto", "cpu", "cuda"] = "auto"
    """Where training computes: 'auto' is CUDA when torch sees a GPU and the extension was built
    with its kernels, else the CPU. The scores of a run on either agree within the seeds' spread,
    not to the bit (the CUDA kernels sum gradients with atomics)."""


@dataclass(frozen=True)
class TrainConfig(Settings):
    """Every setting of a run, by section. Defaults are the `full` preset: our defaults with
    EdgeGaussians' 400-epoch schedule for ABC (`paper` is the paper's exact settings)."""

    maps: MapsSettings = field(default_factory=MapsSettings)
    init: InitSettings = field(default_factory=InitSettings)
    model: ModelSettings = field(default_factory=ModelSettings)
    schedule: ScheduleSettings = field(default_factory=ScheduleSettings)
    loss: LossSettings = field(default_factory=LossSettings)
    strategy: StrategySettings = field(default_factory=StrategySettings)
    layers: LayerSettings = field(default_factory=LayerSettings)
    run: RunSettings = field(default_factory=RunSettings)


RENAMED = {
    "init_method": "init.method",
    "init_count": "init.count",
    "init_side": "init.side",
    "init_opacity": "init.opacity",
    "k_init": "init.k",
    "map_floor": "maps.floor",
    "map_correction": "maps.correction",
    "map_shift": "maps.shift",
    "map_shift_from_epoch": "maps.shift_from_epoch",
    "lr_map_shift": "maps.lr_shift",
    "edge_threshold": "maps.edge_threshold",
    "sampled_loss_from_epoch": "loss.sampled_from_epoch",
    "sampled_loss_every": "loss.sampled_every",
}
"""Flat names of the settings before the sections (run format version 2) whose field name
changed or is no longer one section's -> their dotted names. Every other flat name is its
field's bare name. `--set` takes both; `from_dict` migrates old flat configs through them."""


def setting_name(key: str) -> str:
    """The dotted name of the setting `key` names: dotted, bare, or an old flat name."""
    return settings_setting_name(TrainConfig, key, RENAMED)


def with_settings(config: TrainConfig, changes: Mapping[str, Any]) -> TrainConfig:
    """`config` with `changes` applied, each setting named as `setting_name` takes it (dotted, a
    bare field name, or an old flat name) and given its value."""
    return with_values(config, {setting_name(key): value for key, value in changes.items()})


def with_overrides(config: TrainConfig, assignments: Iterable[str]) -> TrainConfig:
    """`config` with the `--set KEY=VALUE` strings applied (KEY as `setting_name` takes it)."""
    return settings_with_overrides(config, assignments, RENAMED)


PRESETS_RENAMED = {"paper": "full"}
"""Preset names of runs written before the sections (run format version 2) -> today's name for
the same settings: 'paper' then named what `full` is now."""


def is_flat(values: Any) -> bool:
    """Whether a config dict was written before the sections: settings, and no section, by name."""
    sections = {f.name for f in dataclasses.fields(TrainConfig)}
    return isinstance(values, dict) and bool(values) and not sections & set(values)


RETIRED = ("run.snapshot_every",)
"""Settings that no longer exist and changed nothing a run computes: a saved config's value of one
is dropped when it is read."""

ABSENT_MEANS = {"model.view_opacity": False}
"""Settings whose default changed after they were added: a saved config that lacks one was
written before it existed, and its run trained as this value, not as today's default."""


def from_dict(values: Any) -> TrainConfig:
    """A config from `to_dict`'s output (a run folder's config.json, log.json, a checkpoint), or
    from the flat dict of a run written before the sections (migrated through `RENAMED`).
    Settings it lacks (written before they existed) take their defaults, or their `ABSENT_MEANS`
    value; one in `RETIRED` is dropped; an unknown or bad one raises ConfigError naming it."""
    if not is_flat(values):
        return settings_from_dict(TrainConfig, _without_retired(values), ABSENT_MEANS)
    retired_names = {path.rsplit(".", 1)[1] for path in RETIRED}
    flat = {name: value for name, value in values.items() if name not in retired_names}
    return with_values(TrainConfig(), {**ABSENT_MEANS, **{setting_name(str(key)): value
                                                          for key, value in flat.items()}})


def _without_retired(values: Any) -> Any:
    """A sectioned config dict without the `RETIRED` settings (anything else as it is)."""
    if not isinstance(values, dict):
        return values
    kept = dict(values)
    for path in RETIRED:
        section, name = path.split(".")
        if isinstance(kept.get(section), dict) and name in kept[section]:
            kept[section] = {key: value for key, value in kept[section].items() if key != name}
    return kept


def for_detector(config: TrainConfig, detector: str) -> TrainConfig:
    """The config with its detector-dependent settings left open (None, or 'auto') set for the
    maps of `detector` (a name as the scene or registry gives it, any case) by the detector
    registry's `training_defaults`."""
    from edgedog.edges.registry import training_defaults

    tuned = training_defaults(detector)
    return with_values(config, {path: value for path, value in tuned.items()
                                if value_at(config, path) in (None, "auto")})


def _scale_epochs(config: TrainConfig, factor: float) -> dict[str, Any]:
    """Every setting marked `IN_EPOCHS` (or a list of them) multiplied by `factor`, by dotted
    name: a shorter run keeps the same shape. Epoch 0 (from the start) stays 0; any other epoch
    stays at least 1, so an event never moves to the start."""
    def scale(e: int) -> int:
        return 0 if e == 0 else max(1, round(e * factor))

    changes = {}
    for path, kind in setting_paths(TrainConfig).items():
        value, item = value_at(config, path), item_kind(kind)
        if IN_EPOCHS in rules(kind):
            changes[path] = scale(value)
        elif item is not None and IN_EPOCHS in rules(item):
            changes[path] = tuple(sorted({scale(e) for e in value}))
    return changes


def with_epochs(config: TrainConfig, epochs: int) -> TrainConfig:
    """The config's whole schedule (decays, starts, density-control events, Fisher period,
    checkpoints) stretched or compressed to `epochs`."""
    epochs = check_setting("schedule.epochs", setting_paths(TrainConfig)["schedule.epochs"], epochs)
    if epochs == config.schedule.epochs:
        return config
    changes = _scale_epochs(config, epochs / config.schedule.epochs)
    return with_values(config, {**changes, "schedule.epochs": epochs})


@dataclass(frozen=True)
class Preset:
    """A named starting configuration: `description` in one line (for --help and errors) and
    `make()`, which builds it."""

    description: str
    make: Callable[[], TrainConfig]


def full() -> TrainConfig:
    """Our defaults with EdgeGaussians' 400-epoch schedule at full resolution."""
    return TrainConfig()


def fast() -> TrainConfig:
    """`full` compressed to 200 epochs, still at full resolution (at half resolution the 200
    epochs cost ABC 00000006 4 F10 points; docs/BENCHMARKS.md)."""
    return with_epochs(full(), 200)


def quick() -> TrainConfig:
    """`full` compressed to 100 epochs, coarse to fine: the first 70 at half resolution, the last
    30 at the maps' own (docs/RESULTS.md, "Time to accuracy")."""
    return with_values(with_epochs(full(), 100), {"schedule.coarse_downscale": 2,
                                                  "schedule.fine_from_epoch": 70})


def preview() -> TrainConfig:
    """`full` compressed to 100 epochs at half resolution: a quick look for the demo and the
    studio."""
    return with_values(with_epochs(full(), 100), {"maps.downscale": 2})


def lean() -> TrainConfig:
    """`quick` with a primitive budget that follows the edges and a stop when settled, so that
    the time follows the scene (docs/RESULTS.md, "A run as long as the scene needs: `lean`"):

    - init: the edge vote (`edge-vote`) thinned to one point per 10 mm of drawn edge
      (`vote_spacing` 0.009 of the cube), each point's view-dependent opacity started toward the
      views that voted for it (`vote_sight` 4), at most 30,000 points.
    - strategy.edge_budget 3.5: duplication capped at 3.5 primitives per start point.
    - schedule.stop 'both' from the epoch after `quick`'s first opacity cull (`coarse_stop_from_epoch`
      32): the coarse stage ends when settled, then the run when settled again.
    - loss.neighbours_every 10: the direction loss's neighbours searched once an epoch.
    """
    base = quick()
    after_first_cull = min(base.strategy.cull_opacity_epochs) + 1
    return with_values(base, {"init.method": "edge-vote", "init.vote_spacing": 0.009,
                              "init.vote_sight": 4.0, "init.count": 30000, "strategy.edge_budget": 3.5,
                              "schedule.stop": "both", "schedule.coarse_stop_from_epoch": after_first_cull,
                              "loss.neighbours_every": 10})


def paper() -> TrainConfig:
    """The EdgeDoG paper's settings: `full` without what edgedog changed or added.

    - loss.weighting 'exp': the paper's w = exp(Up) (ours: exp(-Up), docs/BENCHMARKS.md).
    - init.method 'uniform', init.count 2500: EdgeGaussians' uniform cube of 2500 points (ours:
      the scene's SfM or triangulated points when there are enough, else 10,000 uniform ones).
    - maps.edge_profile 'raw': the maps fitted as they are (ours: the profile loss on DexiNed
      maps).
    - maps.silhouette_correction 'none': the maps' outline left where the detector drew it
      (ours: pulled onto the alpha outline of renders).
    - maps.correction 'none' and maps.floor 0, as in `full`: no sub-pixel shift, no floor.
    - model.view_opacity False: one opacity for every view (ours: one that varies with the
      direction, so that an edge most views cannot see is not trained away).
    """
    return with_values(full(), {"loss.weighting": "exp", "init.method": "uniform", "init.count": 2500,
                                "maps.edge_profile": "raw", "maps.silhouette_correction": "none",
                                "maps.correction": "none", "maps.floor": 0.0, "model.view_opacity": False})


PRESETS = {
    "full": Preset("our defaults, EdgeGaussians' 400 epochs at full resolution", full),
    "fast": Preset("full compressed to 200 epochs, at full resolution", fast),
    "quick": Preset("full compressed to 100 epochs, the first 70 at half resolution", quick),
    "preview": Preset("full compressed to 100 epochs at half resolution", preview),
    "lean": Preset("quick with a primitive budget from the edge vote, stopped when settled (100 epochs "
                   "at most)", lean),
    "paper": Preset("the EdgeDoG paper's exact settings (w = exp(Up), 2500 uniform points, none of "
                    "our additions), 400 epochs", paper),
}
"""The named starting configurations (`preset`)."""
DEFAULT_PRESET = "full"


def presets_help() -> str:
    """Every preset with its description, for --help: 'full: ...; fast: ...'."""
    return "; ".join(f"{name}: {p.description}" for name, p in PRESETS.items())


def preset(name: str) -> TrainConfig:
    """The named configuration of `PRESETS`; ConfigError listing them for another name."""
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}; choose one of: {presets_help()}")
    return PRESETS[name].make()


__all__ = ["DEFAULT_PRESET", "MAX_DOWNSCALE", "MAX_EPOCHS", "MAX_LAYERS", "MAX_LOGIT", "MAX_PRIMITIVES",
           "MAX_SEED", "PRESETS", "PRESETS_RENAMED", "RENAMED", "InitSettings", "LayerSettings",
           "LossSettings", "MapsSettings", "ModelSettings", "Preset", "RunSettings", "ScheduleSettings",
           "StrategySettings", "TrainConfig", "for_detector", "from_dict", "is_flat", "preset",
           "presets_help", "setting_name", "to_dict", "with_epochs", "with_overrides", "with_settings"]
