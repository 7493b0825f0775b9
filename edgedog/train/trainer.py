"""The training loop, stepwise, with checkpoints, resume, live controls and snapshots.

A viewer calls `step()` from a worker thread (or `run()`), takes `snapshot()`s (immutable copies,
never live tensors) when it wants to draw and changes `controls`, which apply at the next step
boundary.
"""

from __future__ import annotations

import dataclasses
import resource
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch.profiler import record_function
from tqdm import tqdm

from edgedog.edges.cache import ensure_edge_maps
from edgedog.edges.correct import blur_to_profile
from edgedog.edges.registry import make_detector
from edgedog.errors import ConfigError, InputError
from edgedog.files import atomic_write_json
from edgedog.init import initialize
from edgedog.primitives import VIEW_OPACITY, PrimitiveArrays
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.ops import device_name, resolve_device
from edgedog.renderer.primitives import RasterCamera
from edgedog.renderer.rasterize import rasterize
from edgedog.scenes import Scene
from edgedog.train import losses
from edgedog.train.checkpoint import CHECKPOINT, model_arrays, read_checkpoint, to_numpy, write_checkpoint
from edgedog.train.config import TrainConfig, for_detector, from_dict, to_dict
from edgedog.train.convergence import Convergence
from edgedog.train.layers import LowerLayers, keep_on_residual, lower_layer_config, residual_maps
from edgedog.train.model import EdgeModel
from edgedog.train.occlusion import drawn_in_view, scene_occlusion
from edgedog.train.optim import Optimizers
from edgedog.train.readback import EpochLosses, zero_non_finite
from edgedog.train.resolution import ViewSet, coarser
from edgedog.train.strategy import DensityStrategy, StrategyState, primitive_limit
from edgedog.train.targets import (
    LearnedShift,
    corrects_silhouettes,
    fixed_shift,
    prepare_maps,
    scene_outlines,
)
from edgedog.train.view_opacity import camera_centres, cap_, largest_logits, seen_from


@dataclass
class Controls:
    """Settings a user may change while training runs; read at step boundaries."""

    keep_ratio: float
    weighting: str
    paused: bool = False
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def read(self) -> tuple[float, str, bool]:
        with self.lock:
            return self.keep_ratio, self.weighting, self.paused

    def update(self, **changes) -> None:
        with self.lock:
            for key, value in changes.items():
                setattr(self, key, value)


@dataclass(frozen=True)
class Snapshot:
    """An immutable copy of the model for display.

    Attributes:
        step, epoch: where training was; loss: the last projection loss.
        means (N, 3), scales (N, 3), quats (N, 4), opacity (N,), k_raw (N, 2): numpy copies of
            the activated parameters (edgedog.primitives.SCHEMA), the fixed lower layers' first.
        pruned_positions: (M, 3) centres removed by the last Fisher pruning.
        layers: (N,) int64 layer index of each primitive (None: all in layer 0).
        opacity_dirs: (N, 3) b of a view-dependent opacity (None: the same from every view); with
            it, `opacity` is each primitive's largest over the training views.
    """

    step: int
    epoch: int
    loss: float
    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    opacity: np.ndarray
    k_raw: np.ndarray
    pruned_positions: np.ndarray
    layers: np.ndarray | None = None
    opacity_dirs: np.ndarray | None = None

    @property
    def primitives(self) -> PrimitiveArrays:
        """The snapshot's primitives (its arrays, not copies)."""
        return PrimitiveArrays(self.means, self.scales, self.quats, self.opacity, self.k_raw, self.layers,
                               opacity_dirs=self.opacity_dirs)


def _zero_bad_grads(*models: EdgeModel) -> int | torch.Tensor:
    """Zero the models' non-finite gradient entries; returns how many (`readback.zero_non_finite`)."""
    grads = [t.grad for model in models for t in model.tensors().values() if t.grad is not None]
    return zero_non_finite(grads)


def stack_snapshot(stack: LowerLayers, step: int = 0, epoch: int = 0, loss: float = float("nan"),
                   pruned_positions: np.ndarray | None = None,
                   view_centres: torch.Tensor | None = None) -> Snapshot:
    """A Snapshot (activated copies) of a whole layered model.

    `view_centres`: (V, 3) camera centres of the training views of a view-dependent opacity; the
    snapshot then keeps b, and its opacity is each primitive's largest over those views.
    """
    arrays = stack.model.to_numpy()
    dirs = None
    if view_centres is not None:
        m = stack.model
        largest = largest_logits(m.opacity_logits, m.opacity_dirs, m.means, view_centres.to(m.device))
        arrays["opacity_logits"], dirs = largest.cpu().numpy(), arrays[VIEW_OPACITY.raw]
    p = PrimitiveArrays.from_raw(arrays, stack.layers.numpy())
    pruned = np.zeros((0, 3), np.float32) if pruned_positions is None else pruned_positions.copy()
    return Snapshot(step, epoch, loss, p.means, p.scales, p.quats, p.opacity, p.k_raw, pruned, p.layers, dirs)


def saved_model(saved: dict, key: str, path: Path, with_layers: bool = False) -> dict[str, np.ndarray]:
    """`model_arrays` of a read checkpoint, with the view-dependent opacity's b (N, 3) where it
    holds one (a checkpoint written before b existed has none: zeros)."""
    arrays = model_arrays(saved, key, path, with_layers)
    dirs = saved[key].get(VIEW_OPACITY.raw)
    if dirs is None:
        return arrays
    if (not isinstance(dirs, torch.Tensor) or dirs.dtype != torch.float32
            or tuple(dirs.shape) != (len(arrays["means"]), 3) or not bool(torch.isfinite(dirs).all())):
        raise InputError(path, f"malformed checkpoint: '{key}.{VIEW_OPACITY.raw}' must be finite float32 "
                               f"of shape ({len(arrays['means'])}, 3)")
    return {**arrays, VIEW_OPACITY.raw: dirs.numpy()}


def read_stack(run_dir: Path) -> LowerLayers:
    """The whole model of a run folder from its checkpoint: its lower layers and its own."""
    path = Path(run_dir) / CHECKPOINT
    saved = read_checkpoint(path)
    lower = LowerLayers.from_numpy(saved_model(saved, "lower", path, with_layers=True))
    top = EdgeModel.from_numpy(saved_model(saved, "model", path))
    return lower.plus(top, _saved_config(saved, path).layers.layer)


def _saved_config(saved: dict, path: Path) -> TrainConfig:
    """The config a checkpoint was saved with; a malformed one is an InputError naming the file."""
    try:
        return from_dict(saved["config"])
    except (ConfigError, TypeError, AttributeError) as exc:
        raise InputError(path, f"malformed checkpoint: config: {exc}") from None


class Trainer:
    """Trains an EdgeModel on a scene's pseudo-edge maps; writes its run folder `out`.

    `lower`: for a layer above the first (config.layers.layer > 0), the layers below it, rendered with
    the model and kept fixed (or fine-tuned at `layers.lower_lr_scale`). A resumed run takes them from
    its checkpoint.

    Every random draw comes from `generator` (seeded with `config.run.seed`, saved in checkpoints),
    from `pixel_generator` (the sampled loss's, on the run's device: `generator` itself on the
    CPU; seeded and saved likewise) or from numpy generators seeded from `config.run.seed` where
    they are used: no process-global random state is read or set, so a run gives the same result
    whatever ran before it.
    """

    def __init__(self, scene: Scene, config: TrainConfig, out: Path, progress: bool = True,
                 lower: LowerLayers | None = None):
        self.scene, self.out, self.progress = scene, Path(out), progress
        self.device = resolve_device(config.run.device)
        self.raster = RasterConfig(kernel=config.model.kernel, k_activation=config.model.k_activation)
        self.detector = self._edge_maps(config.maps.detector)
        # The settings left to the maps' detector are fixed now: checkpoints and log.json hold them.
        self.config = config = for_detector(config, self.detector)
        self.map_shift = fixed_shift(config, scene, self.detector, self.own_maps)
        outlines, unreadable = (scene_outlines(scene, config.maps.silhouette_reach)
                                if corrects_silhouettes(config, scene) else (None, []))
        raw_maps = [scene.load_edge_map(i, self.detector) for i in range(len(scene))]
        maps, masks, self.silhouette = prepare_maps(raw_maps, config, self.map_shift, outlines)
        if self.silhouette is not None:
            self.silhouette["views_without_mask"] = unreadable
        pinholes = scene.cameras
        fine = ViewSet(1, pinholes, [RasterCamera.from_camera(c) for c in pinholes],
                       [torch.from_numpy(m) for m in maps], [torch.from_numpy(m) for m in masks])
        coarse = coarser(fine, config.schedule.coarse_downscale)
        self.views = fine.to(self.device)
        self.coarse = self.views if coarse is fine else coarse.to(self.device)
        # (V, 3) camera centres of the views when the opacity depends on the view, else None.
        self.centres = camera_centres(self.cameras, self.device) if config.model.view_opacity else None
        # The visual hull's depth in each view (model.occlusion), and the (V, N) primitives it hides
        # from each view, found at each epoch's start (the centres move little within an epoch).
        self.occlusion = scene_occlusion(scene, config.model, config.init.side, self.device)
        self._hidden: torch.Tensor | None = None
        self.learned_shift = (LearnedShift(config, self.device) if config.maps.correction == "learned"
                              else None)
        self.strategy = DensityStrategy(config, self.raster, self.occlusion)
        self.controls = Controls(config.strategy.keep_ratio, config.loss.weighting)
        self.generator = torch.Generator().manual_seed(config.run.seed)
        # The sampled loss's draws, on the run's device: the run's own generator on the CPU (its
        # runs are unchanged), a generator of the GPU there (no host permutation, no copy).
        self.pixel_generator = (self.generator if self.device.type == "cpu"
                                else torch.Generator(self.device).manual_seed(config.run.seed))
        self.step_index = 0
        self.history: list[dict] = []
        self.events: list[dict] = []
        # Non-finite gradient entries zeroed: an int, or a tensor on the run's device (`bad_gradients`).
        self._bad_gradients: int | torch.Tensor = 0
        self.seconds = 0.0
        self._epoch_losses = EpochLosses()
        self._order = torch.zeros(0, dtype=torch.long)
        # The direction loss's (N, k) neighbours and how many of its steps have used them.
        self._neighbours: torch.Tensor | None = None
        self._neighbours_used = 0
        # The convergence test (schedule.stop), and where it ended the run (None: not stopped).
        self.convergence = None if config.schedule.stop == "off" else Convergence()
        self.stopped: dict | None = None
        if (self.out / CHECKPOINT).exists():
            self._load(self.out / CHECKPOINT)
        else:
            self.lower = (LowerLayers.empty() if lower is None else lower).to(self.device)
            self._bind_lower()
            self._initialise()

    # --- set-up
    def _edge_maps(self, wanted: str) -> str:
        """The name of the maps to fit, `wanted` or the scene's first for 'auto' (computed now when
        needed); sets `own_maps`: whether they are the scene's own maps rather than edgedog's."""
        if wanted == "auto" and self.scene.detectors:
            wanted = self.scene.detectors[0]
        self.own_maps = wanted in self.scene.detectors
        if self.own_maps:
            return wanted
        return ensure_edge_maps(self.scene, make_detector(wanted), progress=self.progress).detector

    def _initialise(self) -> None:
        c = self.config
        points = initialize(self.scene, c.init, detector=self.detector, seed=c.run.seed)
        if len(self.lower):
            residuals = residual_maps(self.lower, self.cameras, self.targets, self.raster)
            points = keep_on_residual(points, self.scene.cameras, residuals, c.maps.edge_threshold,
                                      c.layers.residual_min_share)
        self.init_report = {"method": points.method, "points": len(points), **points.report}
        sight_gain = c.init.vote_sight if c.model.view_opacity else 0.0
        self.model = EdgeModel.from_points(points, c.init.opacity, c.init.k, self.generator,
                                           sight_gain).to(self.device)
        self.optimizers = Optimizers(self.model, c)
        self.state = self.strategy.initial_state(len(self.model), self.device)
        self.initial_count = len(self.model)

    def _bind_lower(self) -> None:
        """Lower layers are fixed, or fine-tuned by their own Adams at the scaled rates."""
        tune = self.config.layers.lower_lr_scale > 0 and len(self.lower) > 0
        for tensor in self.lower.model.tensors().values():
            tensor.requires_grad_(tune)
        self.lower_optimizers = None
        if tune:
            lower = lower_layer_config(self.config)
            rate = self.config.schedule.lr_view_opacity * self.config.layers.lower_lr_scale
            self.lower_optimizers = Optimizers(self.lower.model, dataclasses.replace(
                lower, schedule=dataclasses.replace(lower.schedule, lr_view_opacity=rate)))

    # --- training
    @property
    def cameras(self) -> list[RasterCamera]:
        """The rasterizer's cameras of the views, at the maps' resolution."""
        return self.views.cameras

    @property
    def targets(self) -> list[torch.Tensor]:
        """(H, W) maps fitted, at their own resolution (after the map corrections)."""
        return self.views.targets

    @property
    def epoch(self) -> int:
        return self.step_index // len(self.cameras)

    @property
    def primitive_limit(self) -> int:
        """The most primitives density control may grow the model to (`strategy.primitive_limit`
        of the run's start)."""
        return primitive_limit(self.config.strategy, self.init_report)

    @property
    def total_steps(self) -> int:
        """Steps of the whole run: one per view per epoch."""
        return self.config.schedule.epochs * len(self.cameras)

    @property
    def done(self) -> bool:
        """Whether the run is over: its last epoch trained, or stopped when converged."""
        return self.stopped is not None or self.epoch >= self.config.schedule.epochs

    def step(self) -> None:
        """One view: render, loss, backward, Adam; density control at the end of an epoch.

        The step's projection loss stays on the run's device (`last_loss` reads it).
        """
        c, epoch, position = self.config.loss, self.epoch, self.step_index % len(self.cameras)
        keep_ratio, weighting, _ = self.controls.read()
        started = time.perf_counter()
        if position == 0:
            self._order = torch.randperm(len(self.cameras), generator=self.generator)
            self.optimizers.set_epoch(epoch)
            if self.lower_optimizers is not None:
                self.lower_optimizers.set_epoch(epoch)
            self._epoch_losses = EpochLosses()
        view = int(self._order[position])
        views = self.views_at(epoch)
        # The stages' names label the step for `edgedog bench steps` (torch.profiler); outside a
        # profiler they cost a few microseconds.
        with record_function("rasterize"):
            primitives = self.lower.stacked_with(self.model)
            if self.centres is not None:
                primitives = seen_from(primitives, self._stacked_dirs(), self.centres[view])
            if self.occlusion is not None:
                if position == 0 or self._hidden is None or self._hidden.shape[1] != len(primitives):
                    self._hidden = self.occlusion.hidden(primitives.means)
                primitives = drawn_in_view(primitives, self._hidden[view])
            out = rasterize(primitives, views.cameras[view], self.raster)
        with record_function("loss"):
            sample = None
            # A view without edge pixels has nothing to sample around: its loss stays the full one.
            if (epoch >= c.sampled_from_epoch and self.step_index % c.sampled_every == 0
                    and len(views.edge_pixels[view])):
                sample = losses.edge_and_background_sample(
                    views.edge_pixels[view], views.edge_masks[view].numel(), self.pixel_generator)
            # The edge model renders one channel: a view of it (selecting it would make the
            # backward pass fill a zero image and copy into it).
            render, target = out.image.squeeze(-1), views.targets[view]
            if self.config.maps.edge_profile == "profile":
                render = blur_to_profile(render, self.config.maps.profile_sigma / views.factor)
            if self.learned_shift is not None:
                target = self.learned_shift.target(target, epoch, views.factor)
            depth = out.depth.detach() if c.pixel_uncertainty else None  # the pixel uncertainty's source
            loss = losses.edge_loss(render, target, depth, weighting, sample)
        with record_function("backward"):
            loss.backward()
        with record_function("density statistics"):
            self._bad_gradients += _zero_bad_grads(self.model, self.lower.model)
            self.strategy.after_backward(self.state, out, skip=len(self.lower))
        with record_function("adam"):
            for optimizers in (self.optimizers, self.lower_optimizers, self.learned_shift):
                if optimizers is not None:
                    optimizers.step()
                    optimizers.zero_grad()
            if self.centres is not None:
                for model in (self.model, self.lower.model):
                    if len(model):
                        cap_(model.opacity_dirs, self.config.model.view_opacity_cap)
            self._epoch_losses.append(loss)
        if self.step_index % c.orientation_every == 0:
            with record_function("orientation losses"):
                self._orientation_losses(epoch)
        self.step_index += 1
        self.seconds += time.perf_counter() - started
        if position == len(self.cameras) - 1:
            self._end_epoch(epoch, keep_ratio)

    @property
    def last_loss(self) -> float:
        """The latest step's projection loss (NaN before this epoch's first step); on a GPU,
        reading it waits for the queued work."""
        return self._epoch_losses.last()

    @property
    def bad_gradients(self) -> int:
        """Non-finite gradient entries zeroed so far (on a GPU, reading waits for the queued work)."""
        return int(self._bad_gradients)

    def _stacked_dirs(self) -> torch.Tensor:
        """(N, 3) b of the lower layers' primitives and this run's, in the render's order."""
        if not len(self.lower):
            return self.model.opacity_dirs
        return torch.cat([self.lower.model.opacity_dirs, self.model.opacity_dirs])

    def views_at(self, epoch: int) -> ViewSet:
        """The views a step of `epoch` renders: coarse before `schedule.fine_from_epoch`."""
        return self.coarse if epoch < self.config.schedule.fine_from_epoch else self.views

    def _orientation_losses(self, epoch: int) -> None:
        """EdgeGaussians' direction and scale-ratio terms, each weighted to `factor` times the
        running sum of the epoch's projection losses and stepped on the geometry alone."""
        c = self.config.loss
        terms = []
        if epoch >= c.ratio_from_epoch:
            terms.append((c.ratio_factor, lambda: losses.ratio_loss(self.model)))
        if epoch >= c.direction_from_epoch and len(self.model) > c.direction_neighbours:
            if self._neighbours is None or self._neighbours_used >= c.neighbours_every:
                self._neighbours = losses.nearest_neighbours(self.model, c.direction_neighbours)
                self._neighbours_used = 0
            self._neighbours_used += 1
            neighbours = self._neighbours
            terms.append((c.direction_factor, lambda: losses.direction_loss(self.model, neighbours)))
        if not terms:
            return
        # EdgeGaussians' balance: the sum of this epoch's projection losses so far, times the factor.
        running = self._epoch_losses.sum()
        for factor, term in terms:
            value = term()
            size = value.item()
            if size > 0:
                (factor * running / size * value).backward()
                self._bad_gradients += _zero_bad_grads(self.model)
                self.optimizers.step()  # the terms have gradients in the geometry groups only
                self.optimizers.zero_grad()

    def _end_epoch(self, epoch: int, keep_ratio: float) -> None:
        before = len(self.model)
        started = time.perf_counter()
        centres = None if self.convergence is None else self.model.means.detach().clone()
        with record_function("density control"):
            events = self.strategy.at_epoch_end(epoch, self.model, self.optimizers, self.state, self.views,
                                                self.generator, keep_ratio, self.primitive_limit)
        self.events += events
        self._neighbours = None  # the events renumber the primitives
        entry = {"epoch": epoch, "loss": self._epoch_losses.mean(),
                 "primitives_before_events": before, "primitives": len(self.model)}
        if self.convergence is not None:
            with record_function("convergence"):
                added = any(e["after"] > e["before"] or e.get("split", 0) > 0 for e in events)
                entry.update(self._settle(epoch, centres, entry["loss"], added))
        self.seconds += time.perf_counter() - started
        self.history.append({**entry, "seconds": round(self.seconds, 2)})
        if ((epoch + 1) % self.config.run.checkpoint_every == 0 or epoch + 1 == self.config.schedule.epochs
                or self.stopped is not None):
            with record_function("checkpoint"):
                self.save_checkpoint()

    def _settle(self, epoch: int, centres: torch.Tensor, loss: float, added: bool) -> dict:
        """The convergence test at the end of `epoch` (edgedog.train.convergence); when it has
        converged, end the run ('run', or 'both' in the fine stage, from
        `schedule.stop_from_epoch` on: `stopped` is set) or the coarse stage ('coarse', 'both',
        from `schedule.coarse_stop_from_epoch` on: the next step is the first of
        `schedule.fine_from_epoch`), with an event saying so.
        Returns the epoch's record for the history.

        Args:
            centres: (N, 3) the centres before the epoch's density events; `added`: whether
                those events added primitives.
        """
        s = self.config.schedule
        views = self.views_at(epoch)
        record = self.convergence.update(s, centres, loss, added, self.model.means,
                                         lambda: self.strategy.fisher_scores(self.model, views))
        if not record["converged"] or epoch + 1 >= s.epochs:
            return record
        coarse = epoch + 1 < s.fine_from_epoch
        if (s.stop == "run" or (s.stop == "both" and not coarse)) and epoch >= s.stop_from_epoch:
            self.stopped = {"epoch": epoch, "ceiling": s.epochs, "reason": "converged"}
            self.events.append({"event": "converged", "ended": "run", "epoch": epoch})
        elif coarse and s.stop != "run" and epoch >= s.coarse_stop_from_epoch:
            self.events.append({"event": "converged", "ended": "coarse stage",
                                "skipped_to": s.fine_from_epoch, "epoch": epoch})
            self.step_index = s.fine_from_epoch * len(self.cameras)
            self.convergence.restart()
        return record

    def run(self) -> None:
        """Train to the end (resuming where a checkpoint left off), then write the outputs."""
        with tqdm(total=self.total_steps, initial=self.step_index, unit="step", disable=not self.progress,
                  desc="train") as bar:
            while not self.done:
                if self.controls.read()[2]:
                    time.sleep(0.05)
                    continue
                self.step()
                bar.update(self.step_index - bar.n)  # a coarse stage ended early skips steps
                if self.progress and self.step_index % 25 == 0:  # on a GPU, reading the loss waits
                    bar.set_postfix(epoch=self.epoch, loss=f"{self.last_loss:.4f}",
                                    primitives=len(self.model))
        self.write_outputs()

    # --- snapshots, checkpoints, outputs
    def stack(self) -> LowerLayers:
        """The lower layers with this run's model on top (detached): the whole layered model,
        and the lower layers of the next layer."""
        return self.lower.plus(self.model, self.config.layers.layer)

    def snapshot(self, loss: float = float("nan")) -> Snapshot:
        return stack_snapshot(self.stack(), self.step_index, self.epoch, loss, self.state.pruned_positions,
                              self.centres)

    def save_checkpoint(self) -> Path:
        """Everything needed to continue exactly: model, Adam moments, strategy, random state."""
        payload = {
            "config": to_dict(self.config), "step_index": self.step_index, "model": self.model.to_numpy(),
            "optimizers": self.optimizers.state_dict(), "absgrad": self.state.absgrad.cpu(),
            "pruned_positions": self.state.pruned_positions, "fisher": self.state.fisher,
            "generator": self.generator.get_state(),
            "pixel_generator": (None if self.pixel_generator is self.generator
                                else self.pixel_generator.get_state().cpu()),
            "history": self.history, "events": self.events, "seconds": self.seconds,
            "bad_gradients": self.bad_gradients, "init_report": self.init_report,
            "initial_count": self.initial_count, "detector": self.detector,
            "lower": self.lower.to_numpy(),
            "lower_optimizers": None if self.lower_optimizers is None else self.lower_optimizers.state_dict(),
            "learned_shift": None if self.learned_shift is None else self.learned_shift.state_dict(),
            "convergence": None if self.convergence is None else self.convergence.state_dict(),
            "stopped": self.stopped,
        }
        return write_checkpoint(self.out / CHECKPOINT, payload)

    def _load(self, path: Path) -> None:
        saved = read_checkpoint(path)
        if _saved_config(saved, path) != self.config:
            raise InputError(path, "the checkpoint was made with another configuration")
        self.model = EdgeModel.from_numpy(saved_model(saved, "model", path)).to(self.device).requires_grad_()
        lower = LowerLayers.from_numpy(saved_model(saved, "lower", path, with_layers=True))
        self.lower = lower.to(self.device)
        try:
            self._restore(saved)
        except (AttributeError, KeyError, IndexError, TypeError, ValueError, RuntimeError) as exc:
            # The parts that model_arrays does not check (optimiser moments, random states) are
            # checked by torch and numpy as they are restored.
            raise InputError(path, f"malformed checkpoint ({type(exc).__name__}: {exc})") from None

    def _restore(self, saved: dict) -> None:
        """Everything of a read checkpoint but the models (set by `_load`)."""
        self.optimizers = Optimizers(self.model, self.config)
        self.optimizers.load_state_dict(saved["optimizers"])
        self.state = StrategyState(saved["absgrad"].to(self.device), to_numpy(saved["pruned_positions"]),
                                   to_numpy(saved["fisher"]))
        if len(self.state.absgrad) != len(self.model):
            raise ValueError(f"absgrad has {len(self.state.absgrad)} rows for {len(self.model)} primitives")
        self._bind_lower()
        if self.lower_optimizers is not None:
            self.lower_optimizers.load_state_dict(saved["lower_optimizers"])
        if self.learned_shift is not None:
            self.learned_shift.load_state_dict(saved["learned_shift"])
        self.generator.set_state(saved["generator"])
        pixel_state = saved.get("pixel_generator")
        # Resumed on another kind of device, the draws go on from the seed.
        if self.pixel_generator is not self.generator and pixel_state is not None:
            self.pixel_generator.set_state(pixel_state)
        self.step_index = int(saved["step_index"])
        self.history, self.events = saved["history"], saved["events"]
        self.seconds, self._bad_gradients = float(saved["seconds"]), int(saved["bad_gradients"])
        self.init_report, self.initial_count = saved["init_report"], int(saved["initial_count"])
        if self.convergence is not None:  # the same config: a checkpoint written with the test on
            self.convergence = Convergence.from_state_dict(saved["convergence"], self.device)
            self.stopped = saved["stopped"]

    def shift_px(self) -> list[float]:
        """The maps' total correction shift (dx, dy) in px at the training resolution: the fixed
        one ('shift', 'calibrated') and the fitted one ('learned')."""
        learned = [0.0, 0.0] if self.learned_shift is None else self.learned_shift.value()
        return [round(f + g, 4) for f, g in zip(self.map_shift, learned)]

    def write_outputs(self) -> None:
        """primitives.ply (all parameters, with each primitive's layer), points.ply (centres, for
        `edgedog eval`), log.json. Both PLYs hold the lower layers too: the whole layered model."""
        from edgedog.train.export import write_points, write_primitives

        snapshot = self.snapshot()
        write_primitives(self.out / "primitives.ply", snapshot)
        write_points(self.out / "points.ply", snapshot.means)
        atomic_write_json(self.out / "log.json", {
            "scene": str(self.scene.root), "detector": self.detector, "config": to_dict(self.config),
            "skipped_views": {str(path): problem for path, problem in self.scene.skipped.items()},
            "init": self.init_report, "initial_primitives": self.initial_count,
            "primitive_limit": self.primitive_limit,
            "final_primitives": len(self.model), "lower_primitives": len(self.lower),
            "map_shift_px": self.shift_px(),
            "silhouette_correction": self.silhouette,
            "occlusion": None if self.occlusion is None else self.occlusion.report,
            "train_seconds": round(self.seconds, 2), "device": device_name(self.device),
            "peak_rss_mib": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
            "peak_gpu_mib": (round(torch.cuda.max_memory_allocated(self.device) / 2**20, 1)
                             if self.device.type == "cuda" else None),
            "non_finite_gradients_zeroed": self.bad_gradients, "events": self.events,
            "history": self.history,
            **({} if self.convergence is None else {"stopped": self.stopped}),
        })
