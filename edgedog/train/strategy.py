"""Density control with explicit state (gsplat's Strategy pattern): EdgeGaussians' duplication
and culling, EdgeDoG's primitive-level (Fisher) pruning, and the spacing control that holds
the primitives at a target spacing along the edges (edgedog.spacing)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from edgedog.renderer.config import RasterConfig
from edgedog.renderer.rasterize import RenderOutput, fisher_information
from edgedog.scenes.camera import Camera
from edgedog.spacing import edge_directions, redundant, spacing_length, split_offsets, split_pieces
from edgedog.train.config import MAX_COPIES, StrategySettings, TrainConfig
from edgedog.train.model import EdgeModel
from edgedog.train.occlusion import Occlusion, drawn_in_view
from edgedog.train.optim import Optimizers
from edgedog.train.resolution import ViewSet
from edgedog.train.view_opacity import camera_centres, largest_logits, relative_opacity, seen_from

MIN_DRAWN = 1e-6
"""The Fisher scores' divisor (how much the views draw a primitive) is at least this."""


@dataclass
class StrategyState:
    """What density control accumulates between its events.

    Attributes:
        absgrad: (N,) sum over steps of the norm of the means' absgrad (the per-pixel absolute
            dL/dmean2d summed over pixels, as gsplat's absgrad), reset after each change.
        pruned_positions: (M, 3) centres removed by the last Fisher pruning (for display).
        fisher: (N,) Fisher scores of the last pruning, of the primitives it kept.
    """

    absgrad: torch.Tensor
    pruned_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    fisher: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))


def edge_hit_share(points: np.ndarray, pinholes: list[Camera], edge_masks: list[torch.Tensor],
                   weights: torch.Tensor | None = None) -> torch.Tensor:
    """(N,) share of the views seeing a point (N, 3) in which it lands on an edge pixel of that
    view's (H, W) bool mask (0 for a point no view sees), on the masks' device.

    `weights`: (V, N) how much each view counts for each point (None: 1), e.g. a view-dependent
    opacity's share of its largest, so that only the views where a primitive is drawn count.
    """
    device = edge_masks[0].device if edge_masks else torch.device("cpu")
    seen = torch.zeros(len(points), device=device)
    on_edge = torch.zeros(len(points), device=device)
    for view, (camera, mask) in enumerate(zip(pinholes, edge_masks)):
        pixels, inside = camera.pixels(points)  # projected on the host, in float64
        inside_t = torch.from_numpy(inside).to(device)
        hit = torch.zeros(len(points), dtype=torch.bool, device=device)
        rows, cols = (torch.from_numpy(pixels[inside, k]).to(device) for k in (1, 0))
        hit[inside_t] = mask[rows, cols]
        counts, hits = inside_t.float(), hit.float()
        if weights is not None:
            counts, hits = counts * weights[view], hits * weights[view]
        seen += counts
        on_edge += hits
    return on_edge / seen.clamp_min(1)


def primitive_limit(settings: StrategySettings, init_report: dict) -> int:
    """The most primitives duplication and splits may grow the model to: `max_primitives`, or
    with `edge_budget` and an edge-vote start thinned to a spacing (its report's "spacing" > 0)
    that budget times the start's points, the count that follows the length of edge the maps
    draw (each point stands for about one spacing of edge)."""
    thinned = init_report.get("method") == "edge-vote" and init_report.get("spacing", 0) > 0
    if settings.edge_budget <= 0 or not thinned:
        return settings.max_primitives
    return min(settings.max_primitives, round(settings.edge_budget * init_report["points"]))


class DensityStrategy:
    """Decides, at the end of each epoch, which primitives to duplicate, cull, space or prune."""

    def __init__(self, config: TrainConfig, raster: RasterConfig, occlusion: Occlusion | None = None):
        self.settings, self.epochs = config.strategy, config.schedule.epochs
        self.raster = raster
        self.view_opacity = config.model.view_opacity
        self.occlusion = occlusion

    def initial_state(self, n: int, device: torch.device) -> StrategyState:
        return StrategyState(absgrad=torch.zeros(n, device=device))

    def after_backward(self, state: StrategyState, out: RenderOutput, skip: int = 0) -> None:
        """Accumulate the absgrad norm of the view just rendered (EdgeGaussians' duplication signal).

        `skip`: the render's first primitives are fixed lower layers, not the strategy's model.
        """
        if out.absgrad.value is None:
            raise RuntimeError("density control needs the render's absgrad: the means must require gradients")
        state.absgrad += out.absgrad.value[skip:].norm(dim=1)

    def at_epoch_end(self, epoch: int, model: EdgeModel, optimizers: Optimizers, state: StrategyState,
                     views: ViewSet, generator: torch.Generator, keep_ratio: float,
                     limit: int | None = None) -> list[dict]:
        """Apply the events scheduled after `epoch` (0-based); returns a log entry per event.

        `limit`: the most primitives duplication and splits grow the model to
        (`primitive_limit`; None: `max_primitives`)."""
        c, events = self.settings, []
        limit = c.max_primitives if limit is None else limit
        if epoch in c.duplicate_epochs:
            events.append(self._duplicate(model, optimizers, state, generator, limit))
        if epoch in c.cull_projection_epochs:
            events.append(self._cull(model, optimizers, state, "projection",
                                     self._edge_hit_share(model, views) < c.cull_projection_below, views))
            if self.occlusion is not None:  # off the object: outside its visual hull
                outside = self.occlusion.outside(model.means)
                events.append(self._cull(model, optimizers, state, "hull", outside, views))
        if epoch in c.cull_opacity_epochs:
            opacity = torch.sigmoid(self._largest_logits(model, views))
            events.append(self._cull(model, optimizers, state, "opacity", opacity < c.cull_opacity_below,
                                     views))
        if epoch in c.spacing_epochs:
            events.append(self._space(model, optimizers, state, views, limit))
        if c.primitive_uncertainty and (epoch + 1) % c.fisher_every == 0 and epoch + 1 < self.epochs:
            events.append(self._fisher_prune(model, optimizers, state, views, keep_ratio))
        for event in events:
            event["epoch"] = epoch
        return events

    def _apply(self, model: EdgeModel, optimizers: Optimizers, state: StrategyState, rows: torch.Tensor,
               copies_from: int | None = None, means_noise: torch.Tensor | None = None) -> None:
        """Rebuild every tensor from `rows` of the old ones. Rows from position `copies_from` on
        are new copies: their Adam moments start at zero."""
        tensors = {name: tensor.detach()[rows] for name, tensor in model.tensors().items()}
        if means_noise is not None:
            tensors["means"] = tensors["means"] + means_noise
        model.replace(tensors)
        moment_source = rows.clone()
        if copies_from is not None:
            moment_source[copies_from:] = -1
        optimizers.remap(model, moment_source)
        state.absgrad = torch.zeros(len(model), device=model.device)

    def _duplicate(self, model, optimizers, state, generator, limit: int) -> dict:
        grads = state.absgrad
        span = grads.max() - grads.min()
        normalised = (grads - grads.min()) / span if span > 0 else torch.zeros_like(grads)
        chosen = torch.nonzero(normalised > self.settings.duplicate_threshold).squeeze(1)
        room = max(0, (limit - len(model)) // self.settings.duplicate_copies)
        if len(chosen) > room:  # the largest gradients first: where the maps are least explained
            largest = torch.topk(normalised[chosen], room).indices
            chosen = torch.sort(chosen[largest]).values
        before = len(model)
        copies = chosen.repeat(self.settings.duplicate_copies)
        # Copies keep their source's parameters, start with zero Adam moments, and move by
        # N(0, noise^2) so that they can spread along the edge (drawn on the host: the run's
        # generator, whatever the device).
        rows = torch.cat([torch.arange(before, device=model.device), copies])
        noise = torch.zeros(len(rows), 3)
        noise[before:] = torch.randn(len(copies), 3, generator=generator) * self.settings.duplicate_noise
        noise = noise.to(model.device)
        self._apply(model, optimizers, state, rows, copies_from=before, means_noise=noise)
        return {"event": "duplicate", "before": before, "after": len(model)}

    def _largest_logits(self, model: EdgeModel, views: ViewSet) -> torch.Tensor:
        """(N,) each primitive's opacity logit, its largest over the views when it depends on the
        view (no gradient)."""
        if not self.view_opacity:
            return model.opacity_logits.detach()
        return largest_logits(model.opacity_logits, model.opacity_dirs, model.means,
                              camera_centres(views.cameras, model.device))

    def _cull(self, model, optimizers, state, reason: str, cull: torch.Tensor, views: ViewSet) -> dict:
        before = len(model)
        self._apply(model, optimizers, state, torch.nonzero(~cull).squeeze(1))
        cap = self.settings.opacity_logit_cap
        with torch.no_grad():  # EdgeGaussians resets opacities after a cull by capping the logits
            if self.view_opacity:  # a view-dependent one: its largest over the views
                model.opacity_logits.sub_((self._largest_logits(model, views) - cap).clamp_min(0))
            else:
                model.opacity_logits.clamp_(max=cap)
        return {"event": f"cull_{reason}", "before": before, "after": len(model)}

    def _hidden(self, model: EdgeModel) -> torch.Tensor | None:
        """(V, N) bool: the primitives the visual hull hides from each view; None without occlusion."""
        return None if self.occlusion is None else self.occlusion.hidden(model.means)

    def _drawn(self, model: EdgeModel, views: ViewSet, hidden: torch.Tensor | None) -> torch.Tensor | None:
        """(V, N) how much each view draws each primitive, relative to its largest opacity: the
        view-dependent opacity's share, 0 where `hidden` (`_hidden`) (no gradient); None when
        every view draws every primitive alike."""
        weights = None
        if self.view_opacity:
            weights = relative_opacity(model.opacity_logits, model.opacity_dirs, model.means,
                                       camera_centres(views.cameras, model.device))
        if hidden is not None:
            drawn = (~hidden).float()
            weights = drawn if weights is None else weights * drawn
        return weights

    def _edge_hit_share(self, model: EdgeModel, views: ViewSet) -> torch.Tensor:
        """(N,) `edge_hit_share` of the centres, each view counted by how much it draws the
        primitive (`_drawn`): a primitive hidden from a view is not expected on its edges."""
        return edge_hit_share(model.means.detach().double().cpu().numpy(), views.pinholes, views.edge_masks,
                              self._drawn(model, views, self._hidden(model)))

    def _space(self, model: EdgeModel, optimizers: Optimizers, state: StrategyState, views: ViewSet,
               limit: int) -> dict:
        """Hold the primitives at the target spacing along the edges (edgedog.spacing): remove
        the redundant ones, then split the long ones into new primitives (zero Adam moments)."""
        c, before = self.settings, len(model)
        means = model.means.detach().double().cpu().numpy()
        length = spacing_length(means, c.spacing, c.spacing_relative)
        if c.spacing_keep == "fisher":
            rank = self.fisher_scores(model, views)
        else:
            rank = self._largest_logits(model, views)
        removed = redundant(means, edge_directions(means, c.spacing_neighbours, length),
                            rank.double().cpu().numpy(), length, c.spacing_angle)
        kept = torch.nonzero(torch.from_numpy(~removed)).squeeze(1).to(model.device)
        self._apply(model, optimizers, state, kept)
        split = 0
        if c.spacing_split and length > 0:
            split = self._split(model, optimizers, state, length, limit)
        return {"event": "spacing", "before": before, "after": len(model), "spacing": round(length, 6),
                "removed": int(removed.sum()), "split": split}

    def _split(self, model: EdgeModel, optimizers: Optimizers, state: StrategyState, length: float,
               limit: int) -> int:
        """Cut each elongated primitive whose largest scale exceeds `length` into pieces along its
        major axis (`split_pieces`, within `limit` primitives); returns how many were cut. The pieces are new
        primitives after the others, with their source's parameters but the centre moved along
        the axis and the largest scale divided by the pieces."""
        with torch.no_grad():
            log_scales = model.log_scales.detach()
            largest, major = log_scales.max(dim=1)
            axes = model.major_axes().detach()
        room = max(0, limit - len(model))
        pieces = split_pieces(log_scales.exp().double().cpu().numpy(), length, MAX_COPIES, room)
        cut = torch.from_numpy(pieces > 1).to(model.device)
        if not bool(cut.any()):
            return 0
        sources = torch.nonzero(cut).squeeze(1)
        repeats = torch.from_numpy(pieces[pieces > 1]).to(model.device)
        copies = torch.repeat_interleave(sources, repeats)
        kept = torch.nonzero(~cut).squeeze(1)
        offsets = torch.from_numpy(split_offsets(pieces[pieces > 1])).to(model.device, torch.float32)
        moves = torch.zeros(len(kept) + len(copies), 3, device=model.device)
        moves[len(kept):] = offsets[:, None] * largest[copies].exp()[:, None] * axes[copies]
        self._apply(model, optimizers, state, torch.cat([kept, copies]), copies_from=len(kept),
                    means_noise=moves)
        with torch.no_grad():
            rows = torch.arange(len(kept), len(model), device=model.device)
            model.log_scales[rows, major[copies]] -= torch.log(repeats.repeat_interleave(repeats).float())
        return len(sources)

    def fisher_scores(self, model: EdgeModel, views: ViewSet) -> torch.Tensor:
        """(N,) each primitive's Fisher information over the views, as the pruning ranks them (no
        gradient). With a view-dependent opacity or occlusion, each view renders the primitives
        as it draws them and the sum is divided by how much the views draw each (`_drawn`): a
        primitive that few views can see is not ranked below one that all views see."""
        hidden = self._hidden(model)
        weights = self._drawn(model, views, hidden)
        if weights is None:
            return fisher_information(model.primitives(), views.cameras, self.raster)
        centres = camera_centres(views.cameras, model.device) if self.view_opacity else None
        with torch.no_grad():
            scores = torch.zeros(len(model), device=model.device)
            for view, camera in enumerate(views.cameras):
                primitives = model.primitives()
                if centres is not None:
                    primitives = seen_from(primitives, model.opacity_dirs, centres[view])
                if hidden is not None:
                    primitives = drawn_in_view(primitives, hidden[view])
                scores += fisher_information(primitives, [camera], self.raster)
            return scores / weights.sum(0).clamp_min(MIN_DRAWN)

    def _fisher_prune(self, model, optimizers, state, views: ViewSet, keep_ratio: float) -> dict:
        scores = self.fisher_scores(model, views)
        before = len(model)
        keep_count = max(1, int(round(keep_ratio * before)))
        order = torch.argsort(scores, descending=True, stable=True)
        kept = torch.sort(order[:keep_count]).values
        pruned = torch.ones(before, dtype=torch.bool, device=model.device)
        pruned[kept] = False
        state_positions = model.means.detach()[pruned].cpu().numpy()
        self._apply(model, optimizers, state, kept)
        state.pruned_positions = state_positions
        state.fisher = scores[kept].cpu().numpy()
        return {"event": "fisher_prune", "before": before, "after": len(model), "keep_ratio": keep_ratio}
