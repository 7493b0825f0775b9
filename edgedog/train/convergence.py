"""Stop when done: whether training has settled, measured at each epoch's end (issue 43).

An epoch counts as settled when no density event added primitives at its end (new ones have
not trained yet; events that only remove some leave the others where they were), the median
distance the centres moved over it is at most `schedule.stop_shift`, and its mean projection
loss differs by at most `schedule.stop_loss_change` (relative) from the mean of the last
`schedule.stop_patience` epochs since primitives were last added (one epoch's mean loss varies
by about 5 % with the views its sampled losses fall on: a mean is a steadier reference than
the epoch before). Once
`schedule.stop_patience` epochs in a row are settled, the Fisher scores are measured at each
further settled epoch's end and compared with the epoch before's (`fisher_change`); the run has
converged when they moved by at most `schedule.stop_fisher_change` (at once when that is 1: not
measured). The trainer then ends the run, or the coarse stage (`schedule.stop`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import torch

from edgedog.train.config import ScheduleSettings


def fisher_change(before: torch.Tensor, after: torch.Tensor) -> float:
    """Half the L1 distance between two (N,) Fisher scores of the same primitives, each normalised
    to sum 1: the share of the information that moved between primitives, in [0, 1] (1 when
    either sums to 0)."""
    total_before, total_after = before.sum(), after.sum()
    if total_before <= 0 or total_after <= 0:
        return 1.0
    return float(0.5 * (before / total_before - after / total_after).abs().sum())


@dataclass
class Convergence:
    """What the convergence test carries from one epoch's end to the next (saved in checkpoints).

    Attributes:
        centres: (N, 3) the centres after the last epoch's density events (None before the first
            epoch ends).
        losses: the mean projection losses of the last epochs (at most `stop_patience`) since
            primitives were last added.
        settled: epochs in a row that were settled.
        fisher: (N,) Fisher scores at the last settled epoch's end once `settled` reached the
            patience (None: not measured in this streak).
    """

    centres: torch.Tensor | None = None
    losses: list[float] = field(default_factory=list)
    settled: int = 0
    fisher: torch.Tensor | None = None

    def update(self, settings: ScheduleSettings, centres: torch.Tensor, loss: float, added: bool,
               after_events: torch.Tensor, fisher: Callable[[], torch.Tensor]) -> dict:
        """Measure the epoch that just ended; returns its record for the history: `centre_shift`
        (median distance, scene units; None on the first epoch), `loss_change` (relative to the
        mean of `losses`; None on the first epoch after primitives were added),
        `fisher_change` (None when not measured), `settled` and `converged`.

        Args:
            centres: (N, 3) the centres at the epoch's end, before its density events.
            loss: the epoch's mean projection loss.
            added: whether a density event added primitives at the epoch's end.
            after_events: (N', 3) the centres after its density events.
            fisher: computes the (N',) Fisher scores of the primitives as they are now.
        """
        shift = None
        if self.centres is not None and self.centres.shape == centres.shape:
            shift = float((centres.detach() - self.centres.to(centres.device)).norm(dim=1).median())
        change, reference = None, sum(self.losses) / len(self.losses) if self.losses else 0.0
        if reference > 0:
            change = abs(loss - reference) / reference
        settled = (not added and shift is not None and shift <= settings.stop_shift
                   and change is not None and change <= settings.stop_loss_change)
        self.settled = self.settled + 1 if settled else 0
        self.centres = after_events.detach().clone()
        self.losses = [] if added else [*self.losses, loss][-settings.stop_patience:]
        moved, converged = None, False
        if self.settled < settings.stop_patience:
            self.fisher = None
        elif settings.stop_fisher_change >= 1:
            converged = True
        else:
            scores = fisher()
            if self.fisher is not None and self.fisher.shape == scores.shape:
                moved = fisher_change(self.fisher.to(scores.device), scores)
                converged = moved <= settings.stop_fisher_change
            self.fisher = scores
        return {"centre_shift": None if shift is None else round(shift, 7),
                "loss_change": None if change is None else round(change, 5),
                "fisher_change": None if moved is None else round(moved, 5),
                "settled": self.settled, "converged": converged}

    def restart(self) -> None:
        """Forget the streak (the coarse stage ended: the loss and the views change)."""
        self.centres, self.losses, self.settled, self.fisher = None, [], 0, None

    def state_dict(self) -> dict:
        return {"centres": None if self.centres is None else self.centres.cpu(), "losses": self.losses,
                "settled": self.settled, "fisher": None if self.fisher is None else self.fisher.cpu()}

    @classmethod
    def from_state_dict(cls, saved: dict, device: torch.device) -> Convergence:
        centres, fisher = saved["centres"], saved["fisher"]
        return cls(None if centres is None else centres.to(device), [float(x) for x in saved["losses"]],
                   int(saved["settled"]), None if fisher is None else fisher.to(device))
