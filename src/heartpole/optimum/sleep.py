"""The sleep timing of a policy that never drinks: Dinkelbach's method over a backward dynamic program.

State ``(decisions left n, waking alertness w, half-hours awake t)``, ``w`` on a midpoint grid. For a rate
``lam`` the program maximises ``E[work - lam * time]``; ``lam <- E[work] / E[time]`` of its policy until it
repeats. The backward pass stops where the policy has settled (`Settling`): from there on
the decisions no longer depend on ``n``, the expected work and time grow by a fixed amount a decision, and
the thresholds of the last ``n`` serve every ``n`` beyond. Time and memory then grow with the horizon only
through `episode_outcome`'s day-by-day pass; where the policy never settles (nearly
deterministic days) the pass runs to ``max_steps``, still in memory linear in it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from heartpole.model import alertness_decay, productivity
from heartpole.parameters import Params
from heartpole.rewards import expected_risk, least_heart_attacks

from .common import DEFAULT_GRID, NotCoveredError, Settling, max_awake
from .days import DayKernels, episode_outcome

MAX_DINKELBACH_ITERATIONS = 50


@dataclass(frozen=True)
class GridSolution:
    """The optimum on one grid: Dinkelbach's rate, the exact expected score of its policy, its thresholds.

    ``thresholds[n, t]``: with ``n`` decisions left and ``t`` half-hours awake, sleep when alertness is
    below it; rows beyond the last are the last row (the policy has settled).
    """

    rate: float
    expected_score: float
    expected_sleeps: float
    expected_work: float
    expected_time: float
    thresholds: np.ndarray = field(repr=False)


def solve_params(params: Params, grid: int) -> GridSolution:
    """Solve the no-drink sleep-timing problem of ``params`` on a ``grid``-point waking-alertness grid."""
    model = _DayModel(params, grid)
    rate = _initial_rate(model)
    for _ in range(MAX_DINKELBACH_ITERATIONS):
        sweep = model.backward(rate)
        new_rate = sweep.work / sweep.time
        if abs(new_rate - rate) <= 1e-13:
            break
        rate = new_rate
    else:
        raise RuntimeError(f"Dinkelbach's iteration did not converge (rate {rate}, next {new_rate})")
    outcome = episode_outcome(sweep.days, model.steps, model.sleep_time)
    return GridSolution(
        rate=float(rate),
        expected_score=outcome.score,
        expected_sleeps=outcome.sleeps,
        expected_work=outcome.work,
        expected_time=outcome.time,
        thresholds=sweep.thresholds,
    )


@dataclass
class _Sweep:
    """A backward pass at one rate: its policy's expected work and time from the start, days and thresholds."""

    rate: float
    work: float
    time: float
    days: DayKernels
    thresholds: np.ndarray  # (settled n + 1, max_awake): sleep when alertness < thresholds[n, t]


class _Rows:
    """A growing ``(rows, width)`` float array: doubled when full, so memory stays within twice its rows."""

    def __init__(self, width: int, capacity: int) -> None:
        self.data = np.empty((max(capacity, 1), width))
        self.size = 0

    def append(self, row: np.ndarray) -> None:
        if self.size == len(self.data):
            grown = np.empty((2 * len(self.data), self.data.shape[1]))
            grown[: self.size] = self.data
            self.data = grown
        self.data[self.size] = row
        self.size += 1

    def array(self) -> np.ndarray:
        return self.data[: self.size].copy()


class _DayModel:
    """A day as the DP sees it: productivity ``work[w, t]`` of waking alertness ``w`` after ``t`` half-hours."""

    def __init__(self, params: Params, grid: int) -> None:
        self.params = params
        self.steps = params.max_steps
        self.sleep_time = params.sleep_half_hours
        low, high = params.wake_alertness
        self.wake = low + (high - low) * (np.arange(grid) + 0.5) / grid
        self.awake = max_awake(params)
        decay = alertness_decay(np.arange(self.awake - 1, dtype=np.float64))
        self.drained = np.concatenate([[0.0], np.cumsum(decay)])  # alertness lost after t half-hours awake
        self.work = productivity(self.wake[:, None] - self.drained[None, :], 0.0)  # (grid, max_awake)

    def backward(self, rate: float) -> _Sweep:
        """Maximise ``E[work - rate * time]`` and follow that policy's expected work, time and days.

        ``value``, ``work`` and ``time`` are functions of ``(w, t)`` for ``n - 1`` decisions left, with an
        extra column for ``t = max_awake`` (never reached: the last column always sleeps); ``length`` and
        ``earned`` the decisions until the day's sleep and their work. Stops once the policy has settled;
        the expected work and time of the remaining decisions are the settled gain a decision.
        """
        grid, awake, steps = len(self.wake), self.awake, self.steps
        value, work, time = (np.zeros((grid, awake + 1)) for _ in range(3))
        length = np.zeros((grid, awake + 1), dtype=np.int64)
        earned = np.zeros((grid, awake + 1))
        days = DayKernels()
        days.add(length[:, 1], earned[:, 1] + self.work[:, 0])  # n = 0: the sleep's step ends the episode
        thresholds = _Rows(awake, min(steps + 1, 4096))
        thresholds.append(np.full(awake, np.inf))
        settling = Settling(awake + 2)
        rest = 1.0 + self.sleep_time
        before = (0.0, 0.0)
        n = 0
        for n in range(1, steps + 1):
            before = (float(work[:, 0].mean()), float(time[:, 0].mean()))
            stay = self.work - rate + value[:, 1:]
            stay[:, awake - 1] = -np.inf
            sleep = float(np.mean(self.work[:, 0] + value[:, 1])) - rate * rest
            sleep_work = float(np.mean(self.work[:, 0] + work[:, 1]))
            sleep_time = rest + float(np.mean(time[:, 1]))
            go_on = stay >= sleep
            thresholds.append(self._thresholds(go_on, stay - sleep))
            value[:, :awake] = np.where(go_on, stay, sleep)
            work[:, :awake] = np.where(go_on, self.work + work[:, 1:], sleep_work)
            time[:, :awake] = np.where(go_on, 1.0 + time[:, 1:], sleep_time)
            length[:, :awake] = np.where(go_on, 1 + length[:, 1:], 0)
            earned[:, :awake] = np.where(go_on, self.work + earned[:, 1:], 0.0)
            days.add(length[:, 1], earned[:, 1] + self.work[:, 0])
            if go_on[:, awake - 2].any():
                raise RuntimeError(f"a day reached {awake - 1} half-hours awake; the cut at max_awake is too short")
            exact, values = (go_on, length[:, :2]), (value[:, :awake], work[:, :awake], time[:, :awake])
            if n < steps and settling.update(exact, values):
                break
        days.close(length[:, 0], earned[:, 0])
        mean_work, mean_time = float(work[:, 0].mean()), float(time[:, 0].mean())
        rest_of_episode = steps - n  # decisions beyond the settled n: each adds the settled gain
        return _Sweep(
            rate,
            mean_work + rest_of_episode * (mean_work - before[0]),
            mean_time + rest_of_episode * (mean_time - before[1]),
            days,
            thresholds.array(),
        )

    def follow(self, sleeps: Callable[[np.ndarray, np.ndarray, int], np.ndarray]) -> DayKernels:
        """The days of the policy that sleeps where ``sleeps(alertness, t, n)`` (see
        [`sleep_rule_value`][heartpole.optimum.sleep.sleep_rule_value])."""
        grid, awake, steps = len(self.wake), self.awake, self.steps
        alertness = self.wake[:, None] - self.drained[None, :]
        t = np.arange(awake)
        length = np.zeros((grid, awake + 1), dtype=np.int64)
        earned = np.zeros((grid, awake + 1))
        days = DayKernels()
        days.add(length[:, 1], earned[:, 1] + self.work[:, 0])
        for n in range(1, steps + 1):
            go_on = ~np.asarray(sleeps(alertness, t, n), dtype=bool)
            go_on[:, awake - 1] = False
            length[:, :awake] = np.where(go_on, 1 + length[:, 1:], 0)
            earned[:, :awake] = np.where(go_on, self.work + earned[:, 1:], 0.0)
            days.add(length[:, 1], earned[:, 1] + self.work[:, 0])
        return days.close(length[:, 0], earned[:, 0])

    def _thresholds(self, go_on: np.ndarray, gap: np.ndarray) -> np.ndarray:
        """Alertness below which the policy sleeps, per ``t``, interpolated between grid points.

        For each ``t`` the grid's decisions must be a threshold in ``w`` (continuing is worth more for a
        larger ``w``); the zero of ``gap = stay - sleep`` is found by linear interpolation and converted to
        alertness, ``w* - drained[t]``. All continue: ``-inf``; all sleep: ``+inf``.
        """
        if np.any(go_on[:-1] & ~go_on[1:]):
            raise NotCoveredError("the optimal decisions are not a threshold in alertness for these parameters")
        any_on, all_on = go_on.any(axis=0), go_on.all(axis=0)
        if len(self.wake) == 1:
            return np.where(any_on, -np.inf, np.inf)
        index = np.clip(np.argmax(go_on, axis=0), 1, len(self.wake) - 1)
        columns = np.arange(go_on.shape[1])
        g_hi, g_lo = gap[index, columns], gap[index - 1, columns]
        w_hi, w_lo = self.wake[index], self.wake[index - 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            crossing = w_lo + (w_hi - w_lo) * (-g_lo) / (g_hi - g_lo)
        crossing = np.where(np.isfinite(crossing), np.clip(crossing, w_lo, w_hi), w_hi)
        return np.where(all_on, -np.inf, np.where(any_on, crossing - self.drained, np.inf))


def sleep_rule_value(
    params: Params, sleeps: Callable[[np.ndarray, np.ndarray, int], np.ndarray], grid: int = DEFAULT_GRID
) -> float:
    """The exact expected return of a no-drink policy that sleeps by ``sleeps(alertness, t, n)``.

    ``sleeps`` gets the alertness ``(grid, max_awake)`` of every waking alertness ``w`` (rows) after ``t``
    half-hours awake (columns, ``t`` given as a ``(max_awake,)`` array) with ``n`` decisions left, and
    returns where the policy sleeps. The expected score comes from the same forward pass as the optimum's
    (``E[work / time]`` exact on the ``w`` grid); the heart-attack part is the no-drink floor. This is how
    ``expert``'s regret is known without sampling. ``sleeps`` is called once for every ``n`` up to
    ``max_steps`` (a rule may depend on it): time grows with the horizon, memory stays small.
    """
    model = _DayModel(params, grid)
    outcome = episode_outcome(model.follow(sleeps), model.steps, model.sleep_time)
    return float(expected_risk(outcome.score, least_heart_attacks(params), params.heart_attack_penalty))


def _initial_rate(model: _DayModel) -> float:
    """A starting rate for Dinkelbach's iteration: a full day's average productivity, sleep included."""
    return float(np.clip(model.work[:, :16].mean() * 16 / (16 + model.sleep_time), 0.0, None))
