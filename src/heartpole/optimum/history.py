"""What the work and time so far are worth: a sleep rule that reads them, against the optimum, on paired episodes.

The solved policy sees ``(decisions left n, alertness, half-hours awake t)``; it is the best of the policies that see
that, not of all policies. The score is a ratio, ``work / time``, so the best decision also depends on how the
episode has gone: an episode that has worked well so far has a higher final score to protect and should sleep a
little earlier. [`history_gain`][heartpole.optimum.history.history_gain] builds such a rule and measures what it
gains over the optimum: at each decision it takes the thresholds the sleep-timing program gives at the rate its own
work so far implies, ``(work so far + rate x F) / (time so far + F)`` with ``F`` the expected time still to come,
interpolated between programs solved at rates around the optimum's. It is measured against the solution's played
policy ([`OptimumSolution.decide`][heartpole.optimum.solution.OptimumSolution.decide]: the history-aware optimum up to
3,000 decisions, where it should gain nothing). Both rules run on the same episodes (the same
waking alertness for each one's ``k``-th day), in float64, so their difference is measured far more precisely than
either score: against the sleep-timing policy it gained 1.2e-5 of expected return on v0 and 0.3e-5 to 2.0e-5 on the
default cohort's people; against the played optimum it must gain nothing beyond the solution's
[`margin`][heartpole.optimum.solution.OptimumSolution.margin]. No drinks: their heart-attack part is the floor for
both rules, so the difference of returns is the difference of scores.

This is a check of [`heartpole.optimum.whole`][heartpole.optimum.whole]'s solved optimum from outside it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from heartpole.model import ALERTNESS, TIME_ELAPSED, TIME_SINCE_SLEPT, WORK_DONE, productivity
from heartpole.parameters import Params

from .sleep import _DayModel

if TYPE_CHECKING:
    from .solution import OptimumSolution

RATE_OFFSETS = np.linspace(-0.02, 0.02, 9)
"""The rates (offsets from the optimum's) at which the history-aware rule's thresholds are solved."""


@dataclass(frozen=True)
class HistoryGain:
    """A history-aware rule's expected return minus the optimum's, measured on paired episodes.

    Attributes:
        gain: the mean difference of the two rules' scores (= returns) per episode.
        ci95: its 95% interval (normal approximation over the paired differences).
        optimal_score: the optimum's mean score on these episodes (a check against its exact expected score).
        episodes: paired episodes.
    """

    gain: float
    ci95: tuple[float, float]
    optimal_score: float
    episodes: int


def history_thresholds(params: Params, grid: int, rates: np.ndarray) -> np.ndarray:
    """The sleep-timing program's thresholds at each of ``rates``: ``(rates, rows, max_awake)``, each solution's
    rows past the one where it settled repeating it."""
    model = _DayModel(params, grid)
    sweeps = [model.backward(float(rate)).thresholds for rate in rates]
    rows = max(len(s) for s in sweeps)
    return np.stack([np.concatenate([s, np.repeat(s[-1:], rows - len(s), axis=0)]) for s in sweeps])


def history_gain(
    solution: OptimumSolution, *, episodes: int = 200_000, seed: int = 0, chunk: int = 25_000
) -> HistoryGain:
    """Measure the history-aware rule (module docstring) against ``solution``'s policy on ``episodes`` paired
    episodes (``seed`` draws their waking alertness; ``chunk`` episodes at a time bound the memory).

    Raises:
        TypeError: ``solution`` is not an [`OptimumSolution`][heartpole.optimum.solution.OptimumSolution].
    """
    from .solution import OptimumSolution

    if not isinstance(solution, OptimumSolution):
        raise TypeError(f"solution must be an OptimumSolution, got {type(solution).__name__}")
    params = solution.params
    rates = solution.rate + RATE_OFFSETS
    family = history_thresholds(params, solution.grid, rates)
    steps, rest = params.max_steps, params.sleep_half_hours
    mean_time = steps + rest * solution.expected_sleeps
    low, high = params.wake_alertness
    awake = solution.max_awake
    drained = _DayModel(params, 1).drained  # alertness lost after t half-hours awake, t < max_awake
    days = int(2 * solution.expected_sleeps) + 32  # more days than any episode of either rule has
    rng = np.random.default_rng(seed)
    differences, optimal_scores = [], []
    for start in range(0, episodes, chunk):
        size = min(chunk, episodes - start)
        wakes = low + (high - low) * rng.random((size, days))  # the k-th day's waking alertness
        scores = []
        for history in (False, True):
            work, sleeps, t = np.zeros(size), np.zeros(size, dtype=np.int64), np.zeros(size, dtype=np.int64)
            w = wakes[:, 0].copy()
            for n in range(steps, 0, -1):
                if history:
                    future = n * mean_time / steps
                    rate = (work + solution.rate * future) / (steps - n + rest * sleeps + future)
                    position = np.interp(rate, rates, np.arange(len(rates)))
                    below = np.minimum(position.astype(np.int64), len(rates) - 2)
                    row = min(n, family.shape[1] - 1)
                    column = np.minimum(t, awake - 1)
                    lo, hi = family[below, row, column], family[below + 1, row, column]
                    with np.errstate(invalid="ignore"):  # an infinite threshold (all sleep, or none) stays one
                        threshold = np.where(np.isfinite(lo + hi), lo + (position - below) * (hi - lo), lo)
                    alertness = w - drained[np.minimum(t, awake - 1)]
                    sleep = (t >= awake) | (alertness < threshold)
                else:
                    sleep = _played(
                        solution, w - drained[np.minimum(t, awake - 1)], t, steps - n + rest * sleeps, work, n
                    )
                sleeps += sleep
                w = np.where(sleep, wakes[np.arange(size), np.minimum(sleeps, days - 1)], w)
                t = np.where(sleep, 0, t)
                work += productivity(w - drained[np.minimum(t, awake - 1)], 0.0)
                t += 1
            scores.append(work / (steps + rest * sleeps))
        differences.append(scores[1] - scores[0])
        optimal_scores.append(scores[0])
    difference = np.concatenate(differences)
    gain = float(difference.mean())
    half = 1.959964 * float(difference.std(ddof=1)) / np.sqrt(len(difference))
    return HistoryGain(gain, (gain - half, gain + half), float(np.concatenate(optimal_scores).mean()), episodes)


def _played(
    solution: OptimumSolution, alertness: np.ndarray, t: np.ndarray, elapsed: np.ndarray, work: np.ndarray, left: int
) -> np.ndarray:
    """Whether ``solution``'s played policy ([`OptimumSolution.decide`][heartpole.optimum.solution.OptimumSolution.
    decide]) sleeps, from the no-drink state's numbers."""
    obs = np.zeros((len(t), 6))
    obs[:, ALERTNESS], obs[:, TIME_SINCE_SLEPT], obs[:, TIME_ELAPSED], obs[:, WORK_DONE] = alertness, t, elapsed, work
    return solution.decide(obs, left)
