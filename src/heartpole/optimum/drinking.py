"""``heart_attack_proclivity = 0``: where drinking pays. A grid DP over (alertness, intoxication, half-hours
awake) whose stationary policy is a lower bound and whose whole-episode value an upper bound on the grid,
not a certified optimum (see docs/optimum.md)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole.model import alertness_decay, productivity
from heartpole.parameters import Params, check_integer

from .common import NotCoveredError

if TYPE_CHECKING:
    from heartpole.dynamics import Dynamics

DRINKING_ACTIONS = ("do_nothing", "drink_coffee", "drink_beer", "sleep")
"""The actions the drinking grid solves over, in v0's order."""
NEVER = -1e9
"""The value of an action that leaves the grid (or of staying awake at the last half-hour awake)."""


@dataclass(frozen=True)
class DrinkingSolution:
    """A grid policy for a variant without heart-attack risk, where coffee and beer pay
    ([`solve_drinking`][heartpole.optimum.drinking.solve_drinking]).

    Not a certified optimum: its score, measured through the evaluator, is a lower bound on what drinking
    can reach. ``start_value`` is the grid's best ``E[work - rate * time]`` over ``sweeps`` decisions from
    the episode's start (waking alertness, no alcohol); with ``sweeps == max_steps`` it is the whole
    episode's, end-game included, and [`rate_bound`][heartpole.optimum.drinking.DrinkingSolution.rate_bound] bounds
    every policy's ``E[work] / E[time]``, as far as the grid is exact. ``q`` holds each action's value of
    [`DRINKING_ACTIONS`][heartpole.optimum.drinking.DRINKING_ACTIONS] on the grid; the policy picks the best by
    bilinear interpolation."""

    params: Params
    rate: float
    sweeps: int
    start_value: float
    grid: DrinkingGrid = field(repr=False)
    q: np.ndarray = field(repr=False)  # (4, intoxication, awake, alertness window) float32

    @property
    def rate_bound(self) -> float:
        """What no policy's ``E[work] / E[time]`` reaches on the grid, if ``sweeps == max_steps`` (else ``nan``).

        ``E[work - lam * time] <= start_value - (lam - rate) * max_steps`` for every policy and ``lam > rate``
        (time is at least ``max_steps``), so the ratio stays below ``rate + max(start_value, 0) / max_steps``;
        a negative ``start_value`` means no policy reaches ``rate`` itself.
        """
        if self.sweeps != self.params.max_steps:
            return math.nan
        return self.rate + max(self.start_value, 0.0) / self.params.max_steps

    def policy(self, dynamics: Dynamics) -> Callable[[np.ndarray], np.ndarray]:
        """This solution as a [`Policy`][heartpole.policies.Policy] for ``dynamics`` (v0's four actions)."""
        return _DrinkingPolicy(self, [dynamics.action_index(name) for name in DRINKING_ACTIONS])


class _DrinkingPolicy:
    """The greedy action of a [`DrinkingSolution`][heartpole.optimum.drinking.DrinkingSolution] at each observation."""

    name = "drinking-dp"

    def __init__(self, solution: DrinkingSolution, indices: list[int]) -> None:
        self.solution = solution
        self.indices = np.asarray(indices, dtype=np.int64)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        q = self.solution.q
        (j, fj), t, (k, fk) = self.solution.grid.locate(obs[:, 0], obs[:, 2], obs[:, 3])
        value = (
            q[:, j, t, k] * ((1 - fj) * (1 - fk))
            + q[:, j + 1, t, k] * (fj * (1 - fk))
            + q[:, j, t, k + 1] * ((1 - fj) * fk)
            + q[:, j + 1, t, k + 1] * (fj * fk)
        )
        return self.indices[np.argmax(value, axis=0)]


def solve_drinking(
    params: Params,
    rate: float,
    *,
    sweeps: int = 300,
    alertness_step: float = 0.05,
    fade_substeps: int = 2,
    alertness_range: tuple[float, float] = (-2.0, 5.0),
    max_intoxication: float = 0.3,
    max_awake: int = 90,
) -> DrinkingSolution:
    """Value iteration for ``E[work - rate * time]`` with free drinks (no heart-attack risk), on a drift-free grid.

    The state is (alertness, intoxication, half-hours awake); hypertension is left out because it costs
    nothing when ``heart_attack_proclivity * heart_attack_penalty == 0``. The grid
    ([`DrinkingGrid`][heartpole.optimum.drinking.DrinkingGrid])
    follows the dynamics without interpolating them: alertness is stored as alertness plus the drain so
    far, which a half-hour does not change, and intoxication on a geometric grid that a half-hour's and a
    sleep's fading map onto itself. Only the drinks' uniform effects and the waking draw are integrated
    (exactly for the piecewise-linear interpolant). ``sweeps`` backward steps from 0 give the best policy
    with ``sweeps`` decisions left, used as a stationary policy. ``rate`` should be the score the policy
    reaches (Dinkelbach): ``scripts/optimum_drinking.py`` iterates it through the evaluator.

    Args:
        params: the variant's numbers (``heart_attack_proclivity * heart_attack_penalty`` must be 0).
        rate: the rate of Dinkelbach's ``E[work - rate * time]``.
        sweeps: value-iteration sweeps (decisions before the end); ``max_steps`` gives the episode's optimum.
        alertness_step: the alertness grid's step (1 and 0.5, a coffee's and a beer's ranges, and the waking
            interval's ends must be multiples of it).
        fade_substeps: geometric intoxication grid points per half-hour's fading (``decay_rate`` apart).
        alertness_range: the alertness covered at every time awake; drinks that leave it are not taken.
        max_intoxication: the intoxication covered; a beer that may leave it is not taken.
        max_awake: half-hours awake after which the policy always sleeps.

    Raises:
        NotCoveredError: if heart attacks cost anything (use `solve` there).
        ValueError: a grid that does not fit the actions' ranges.
    """
    if params.heart_attack_proclivity * params.heart_attack_penalty != 0:
        raise NotCoveredError("solve_drinking leaves hypertension out: it needs heart_attack_proclivity=0")
    grid = DrinkingGrid(params, alertness_step, fade_substeps, alertness_range, max_intoxication, max_awake)
    value = np.zeros(grid.shape, dtype=np.float32)
    q = np.zeros((4, *grid.shape), dtype=np.float32)
    total = 0.0
    for _ in range(check_integer("sweeps", sweeps, 1)):
        q = grid.action_values(value, rate)
        value = q.max(axis=0)
        total += grid.recentre(value)  # relative value iteration: float32 stays precise
    return DrinkingSolution(params, float(rate), int(sweeps), total, grid, q)


def drinking_rule_value(
    params: Params, rule: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray], decisions: int, **grid: Any
) -> tuple[float, float]:
    """``(E[work], E[time])`` of a fixed rule over ``decisions`` decisions from the episode's start, on the grid.

    ``rule(alertness, intoxication, t)`` gets arrays of grid states and returns the index of the action in
    [`DRINKING_ACTIONS`][heartpole.optimum.drinking.DRINKING_ACTIONS] order; it must only take actions the grid
    covers. This is how the grid is checked against the env's own dynamics (the evaluator's episodes of the same rule
    with ``max_steps=decisions`` agree within their interval). ``grid``:
    [`solve_drinking`][heartpole.optimum.drinking.solve_drinking]'s grid arguments."""
    if params.heart_attack_proclivity * params.heart_attack_penalty != 0:
        raise NotCoveredError("drinking_rule_value leaves hypertension out: it needs heart_attack_proclivity=0")
    model = DrinkingGrid(params, **grid)
    actions = np.asarray(rule(*model.states()), dtype=np.int64)[None]
    idle = np.zeros_like(model.work)
    work = np.zeros(model.shape, dtype=np.float32)
    time = np.zeros(model.shape, dtype=np.float32)
    totals = [0.0, 0.0]
    for _ in range(check_integer("decisions", decisions, 1)):
        work = np.take_along_axis(model.action_values(work, 0.0), actions, 0)[0]
        time = np.take_along_axis(model.action_values(time, -1.0, idle), actions, 0)[0]
        totals[0] += model.recentre(work)
        totals[1] += model.recentre(time)
    if min(totals) < NEVER / 2:
        raise ValueError(
            "the rule takes an action the grid does not cover from the episode's start (a drink that leaves "
            "alertness_range or max_intoxication, or staying awake at max_awake - 1)"
        )
    return totals[0], totals[1]


class DrinkingGrid:
    """[`solve_drinking`][heartpole.optimum.drinking.solve_drinking]'s drift-free discretisation of (alertness,
    intoxication, half-hours awake).

    * **Alertness** is stored as ``b = alertness + drain(t)``, with ``drain(t)`` the alertness a day has lost
      after ``t`` half-hours awake: a half-hour of work does not change ``b``, so no interpolation smears
      it. ``b`` lies on one grid ``alertness_step`` apart; at each ``t`` a window of it covers
      ``alertness_range``. A coffee adds ``U(0, 1)`` to ``b`` and a beer ``U(-0.5, 0)``: trapezoid rule.
    * **Intoxication** lies on 0 and a geometric grid with ratio ``decay_rate ** (1 / fade_substeps)``
      from 0.002 to ``max_intoxication``: a half-hour's fading moves a point exactly ``fade_substeps``
      points down, a sleep's ``sleep_half_hours * fade_substeps`` (only below 0.002 does it interpolate
      towards 0). A beer's ``U(0.01, 0.03)`` is integrated exactly for the piecewise-linear interpolant.

    An earlier grid interpolated the half-hour's drain and fading linearly on uniform grids; that smeared
    intoxication across the Ballmer peak (0.005 wide) every half-hour and undervalued riding it: for a fixed
    rule it lost 0.9% of the work the env measures, and its policy scored 1.110-1.113.

    Arrays are laid out ``(intoxication, t, alertness window)``.
    """

    MIN_INTOXICATION = 0.002

    def __init__(
        self,
        params: Params,
        alertness_step: float = 0.05,
        fade_substeps: int = 2,
        alertness_range: tuple[float, float] = (-2.0, 5.0),
        max_intoxication: float = 0.3,
        max_awake: int = 90,
    ) -> None:
        step = float(alertness_step)
        low, high = alertness_range
        self.params, self.step, self.awake = params, step, check_integer("max_awake", max_awake, 2)
        check_integer("fade_substeps", fade_substeps, 1)
        self.coffee, self.beer = _grid_points(1.0, step, "a coffee's U(0, 1)"), _grid_points(0.5, step, "a beer's")
        self.drained = np.concatenate([[0.0], np.cumsum(alertness_decay(np.arange(max_awake, dtype=np.float64)))])
        self.width = int(round((high - low) / step)) + 1
        self.start = np.floor((low + self.drained[:max_awake]) / step + 1e-9).astype(np.int64)
        alertness = (self.start[:, None] + np.arange(self.width)[None, :]) * step - self.drained[:max_awake, None]
        self.ratio = params.decay_rate ** (1.0 / fade_substeps)
        points = int(np.ceil(np.log(self.MIN_INTOXICATION / max_intoxication) / np.log(self.ratio))) + 1
        self.x = np.concatenate([[0.0], max_intoxication * self.ratio ** np.arange(points - 1, -1, -1)])
        self.alertness = alertness
        self.work = productivity(alertness[None, :, :], self.x[:, None, None]).astype(np.float32)
        self.shape = self.work.shape
        self.fade = self._bracket(self.x * params.decay_rate)
        self.fade_asleep = self._bracket(self.x * params.decay_rate**params.sleep_half_hours)
        self.gaps = np.diff(self.x).astype(np.float32)
        self.beer_x = (self._bracket(self.x + 0.01), self._bracket(self.x + 0.03))
        self.beer_off = self.x + 0.03 > self.x[-1] + 1e-12
        wake_low, wake_high = params.wake_alertness
        b0 = (self.start[0] + np.arange(self.width)) * step
        waking = ((b0 >= wake_low - 1e-9) & (b0 <= wake_high + 1e-9)).astype(np.float64)
        ends = np.flatnonzero(waking)
        if len(ends) < 2 or abs(b0[ends[0]] - wake_low) > 1e-9 or abs(b0[ends[-1]] - wake_high) > 1e-9:
            raise ValueError(f"alertness_step {step} must divide the waking interval's ends {params.wake_alertness}")
        waking[ends[[0, -1]]] = 0.5  # the trapezoid rule over the waking interval
        self.waking = (waking / waking.sum()).astype(np.float32)

    def states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(alertness, intoxication, t) of every grid point, each of the grid's shape."""
        shape = self.shape
        return (
            np.broadcast_to(self.alertness[None], shape),
            np.broadcast_to(self.x[:, None, None], shape),
            np.broadcast_to(np.arange(self.awake)[None, :, None], shape),
        )

    def action_values(self, value: np.ndarray, rate: float, work: np.ndarray | None = None) -> np.ndarray:
        """``(4, *shape)``: each action's value, given the next decision's ``value``.

        ``work``: what a half-hour earns at each grid point (default: its productivity; zeros and
        ``rate=-1`` count the time instead).
        """
        stay = (self.work if work is None else work) - np.float32(rate)  # the value after the action's effects
        stay[:, :-1] += self._after_half_hour(value)
        stay[:, -1] = NEVER
        coffee = _window_mean(stay, 0, self.coffee)
        beer = _window_mean(self._beer_intoxication(stay), -self.beer, 0)
        woken = _interpolate(stay[:, 0], self.fade_asleep)  # (intoxication, alertness window) at t = 0
        sleep = woken @ self.waking - np.float32(rate * self.params.sleep_half_hours)
        return np.stack([stay, coffee, beer, np.broadcast_to(sleep[:, None, None], stay.shape)])

    def recentre(self, value: np.ndarray) -> float:
        """Subtract the value of the episode's start from ``value`` in place and return it."""
        offset = float(value[0, 0] @ self.waking)
        value -= np.float32(offset)
        return offset

    def locate(
        self, alertness: np.ndarray, intoxication: np.ndarray, time_since_slept: np.ndarray
    ) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """Grid brackets of observed states: (intoxication index, weight), t, (alertness index, weight)."""
        t = np.clip(np.asarray(time_since_slept).astype(np.int64), 0, self.awake - 1)
        b = np.asarray(alertness, dtype=np.float64) + self.drained[t]
        k = _bracket(b / self.step - self.start[t], self.width)
        x = np.asarray(intoxication, dtype=np.float64)
        low = self.x[1]
        above = 1.0 + np.log(np.maximum(x, low) / low) / -math.log(self.ratio)
        j = _bracket(np.where(x < low, x / low, above), len(self.x))
        return j, t, k

    def _bracket(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        y = np.minimum(y, self.x[-1])
        lower = np.clip(np.searchsorted(self.x, y * (1 + 1e-12), side="right") - 1, 0, len(self.x) - 2)
        weight = np.clip((y - self.x[lower]) / (self.x[lower + 1] - self.x[lower]), 0.0, 1.0)
        weight[weight < 1e-9] = 0.0  # exact grid points stay exact
        weight[weight > 1 - 1e-9] = 1.0
        return lower, weight.astype(np.float32)

    def _after_half_hour(self, value: np.ndarray) -> np.ndarray:
        """The next decision's value seen from each (x, t < last, b) before the half-hour: same ``b``, faded x."""
        moved = np.empty((value.shape[0], self.awake - 1, self.width), dtype=np.float32)
        for t, shift in enumerate(np.diff(self.start)):
            moved[:, t, shift:] = value[:, t + 1, : self.width - shift]
            moved[:, t, :shift] = value[:, t + 1, :1]  # below the window: its lowest alertness
        return _interpolate(moved, self.fade)

    def _beer_intoxication(self, values: np.ndarray) -> np.ndarray:
        """Mean of ``values`` over intoxication + U(0.01, 0.03), exact for the piecewise-linear interpolant."""
        gaps = self.gaps.reshape(-1, 1, 1)
        integral = np.empty_like(values)
        integral[0] = 0.0
        np.cumsum((values[1:] + values[:-1]) * (gaps * np.float32(0.5)), axis=0, out=integral[1:])
        out = np.zeros_like(values)
        for sign, (lower, weight) in ((-1.0, self.beer_x[0]), (1.0, self.beer_x[1])):
            into = (weight * self.gaps[lower]).reshape(-1, 1, 1)
            share = weight.reshape(-1, 1, 1)
            here = values[lower]
            out += np.float32(sign) * (integral[lower] + here * into + (values[lower + 1] - here) * (into * share / 2))
        out /= np.float32(0.02)
        out[self.beer_off] = NEVER
        return out


def _grid_points(length: float, step: float, what: str) -> int:
    points = int(round(length / step))
    if points < 1 or abs(points * step - length) > 1e-9:
        raise ValueError(f"alertness_step {step} must divide {what} range of {length} (e.g. 0.05 or 0.025)")
    return points


def _interpolate(values: np.ndarray, bracket: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """``values`` at fractional first-axis positions ``bracket`` (lower index, weight)."""
    lower, weight = bracket
    shape = (-1,) + (1,) * (values.ndim - 1)
    return values[lower] * (1 - weight).reshape(shape) + values[lower + 1] * weight.reshape(shape)


def _bracket(position: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower grid index and interpolation weight of fractional grid ``position`` s, clamped to the grid."""
    position = np.clip(position, 0.0, size - 1 - 1e-9)
    lower = np.floor(position).astype(np.int64)
    return lower, position - lower


def _window_mean(values: np.ndarray, start: int, stop: int) -> np.ndarray:
    """Mean of ``values`` over last-axis offsets ``[start, stop]`` (trapezoid rule); off the window: NEVER."""
    size = values.shape[-1]
    cumulative = np.empty_like(values)
    cumulative[..., 0] = 0.0
    np.cumsum((values[..., 1:] + values[..., :-1]) * np.float32(0.5), axis=-1, out=cumulative[..., 1:])
    out = np.full_like(values, NEVER)
    first, last = max(0, -start), min(size, size - stop)
    out[..., first:last] = cumulative[..., first + stop : last + stop] - cumulative[..., first + start : last + start]
    out[..., first:last] /= np.float32(stop - start)
    return out
