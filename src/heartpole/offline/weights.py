"""How much an importance-sampling estimate has to stand on: the effective sample size of its weights, and how far
into the episodes any weight survives.

The estimators of [`heartpole.offline.ope`][heartpole.offline.ope] that weigh episodes (PDIS, WPDIS and DR's
correction) weigh step ``t`` of episode ``i`` by ``w_it``, the product of the importance ratios up to ``t``. At
each step, Kish's effective sample size ``(sum_i w_it)^2 / sum_i w_it^2`` says how many episodes of equal weight
the step's estimate is worth; [`weight_diagnostics`][heartpole.offline.weights.weight_diagnostics] averages it over
the steps with the discount's weights (the steps an estimate of the discounted value leans on). A product of
ratios that meets a ratio of 0 (the behaviour took an action the target never takes) stays 0: past the last step
at which some episode keeps a weight, those estimators see nothing and count the rewards there as 0.

Too small to mean anything (decided here, and warned about): an effective sample size below
[`MIN_ESS`][heartpole.offline.weights.MIN_ESS] episodes or below
[`MIN_ESS_SHARE`][heartpole.offline.weights.MIN_ESS_SHARE] of the dataset's episodes, and below half of them
(a dataset of fewer than 20 episodes is small whatever its weights; equal weights are not what is warned
about), or no weight left past a
step while the steps after it carry more than [`MAX_LOST_SHARE`][heartpole.offline.weights.MAX_LOST_SHARE] of the
discounted weight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_ESS = 10.0
"""Below this many effective episodes, an importance-sampling estimate is warned about."""
MIN_ESS_SHARE = 0.01
"""... or below this share of the dataset's episodes."""
MAX_LOST_SHARE = 0.01
"""The share of the discounted weight (``sum_t gamma^t`` over the steps) that may lie past the last step at which
some episode keeps a weight before the estimate is warned about."""


@dataclass(frozen=True)
class WeightDiagnostics:
    """What the importance weights of a dataset under a target policy leave to estimate with.

    Attributes:
        effective_sample_size: Kish's effective sample size at each step, averaged with the discount's weights.
        episodes: the dataset's episodes.
        weight_horizon: the number of steps at which some episode keeps a weight above 0 (the episodes' length
            when some episode keeps its weight to the end).
        steps: the episodes' length.
        lost_share: the share of the discounted weight on the steps past ``weight_horizon``.
    """

    effective_sample_size: float
    episodes: int
    weight_horizon: int
    steps: int
    lost_share: float

    @property
    def warning(self) -> str | None:
        """Why estimates on these weights mean little, in one line; ``None`` when they have enough to stand on."""
        ess = f"effective sample size {self.effective_sample_size:.1f} of {self.episodes:,} episodes"
        if self.weight_horizon < self.steps and self.lost_share > MAX_LOST_SHARE:
            if self.weight_horizon == 0:
                where = "no episode keeps any weight (the target never takes the behaviour's first action)"
            else:
                where = f"no episode keeps weight past step {self.weight_horizon}"
            return (f"{where}: the {self.steps - self.weight_horizon:,} steps after it ({self.lost_share:.0%} of the "
                    f"discounted weight) count as 0 in PDIS, WPDIS and DR's correction; {ess}")  # fmt: skip
        if self.effective_sample_size < min(max(MIN_ESS, MIN_ESS_SHARE * self.episodes), self.episodes / 2):
            return (
                f"{ess} (Kish, discount-weighted over steps): too few for PDIS, WPDIS and DR's correction to mean much"
            )
        return None


def weight_diagnostics(weights: np.ndarray, gamma: float) -> WeightDiagnostics:
    """The [`WeightDiagnostics`][heartpole.offline.weights.WeightDiagnostics] of cumulative importance weights
    ``(N, T)`` for an estimate with discount ``gamma``."""
    episodes, steps = weights.shape
    totals, squares = weights.sum(axis=0), np.square(weights).sum(axis=0)
    per_step = np.divide(np.square(totals), squares, out=np.zeros_like(totals, dtype=np.float64), where=squares > 0)
    discounts = float(gamma) ** np.arange(steps)
    horizon = int((weights > 0).any(axis=0).sum())  # a cumulative product that reaches 0 stays 0
    return WeightDiagnostics(
        effective_sample_size=float(per_step @ discounts / discounts.sum()) if steps else 0.0,
        episodes=int(episodes),
        weight_horizon=horizon,
        steps=int(steps),
        lost_share=float(discounts[horizon:].sum() / discounts.sum()) if steps else 0.0,
    )
