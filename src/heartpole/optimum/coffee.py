"""The optimum where coffee may pay ([`solve_coffee`][heartpole.optimum.coffee.solve_coffee]): the program of
[`heartpole.optimum.pressure`][heartpole.optimum.pressure] iterated to its fixed point, its policy played in the
env's dynamics by Monte Carlo, and the interval on the optimum's expected return."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from heartpole.kernel import CACHE
from heartpole.model import ballmer
from heartpole.parameters import Params, check_integer

from .pressure import COFFEE, MAX_ITERATIONS, SLEEP, PressureGrid, Sweep, backward
from .sleep import solve_params

KEPT_ROWS = 300
"""Decisions before the end with their own policy row; further from the end the policy plays the row of the
episode's first decision (the played policy's value is measured, so this only costs what it costs)."""
Z95 = 1.959963984540054


@dataclass(frozen=True)
class CoffeeSolution:
    """The solved policy where coffee may pay, and an interval on the optimum's expected return.

    Attributes:
        params: what was solved.
        rate, scale: the fixed point's ``E[work] / E[time]`` and ``E[time]`` (on the grid).
        grid_value: the program's best ``rate - penalty * attacks`` at the fixed point, on the grid: what no policy
            on the grid beats, to first order in the ratio (see docs/optimum.md).
        expected_return: the played policy's expected-risk return by Monte Carlo (``episodes`` episodes), with its
            95% half-width ``return_ci``.
        expected_score, expected_attacks: its parts (``expected_attacks`` is the summed risk).
        coffees_per_episode, beers_per_episode, sleeps_per_episode: what it does.
        upper: ``grid_value + grid_error``: the bound above, as far as the grid and the linearisation hold.
        grid_error: how far the grid's value moved from a grid half as fine (alertness step doubled).
        seconds: the solve's wall time.
        actions: ``(rows, t, hypertension, alertness)`` the policy's actions (row ``k``: ``k + 1`` decisions left).
    """

    params: Params
    rate: float
    scale: float
    grid_value: float
    expected_return: float
    return_ci: float
    expected_score: float
    expected_attacks: float
    coffees_per_episode: float
    beers_per_episode: float
    sleeps_per_episode: float
    grid_error: float
    episodes: int
    seconds: float
    grid: PressureGrid = field(repr=False, compare=False)
    actions: np.ndarray = field(repr=False, compare=False)

    @property
    def drinks_per_episode(self) -> float:
        """Coffees and beers per episode."""
        return self.coffees_per_episode + self.beers_per_episode

    @property
    def lower(self) -> float:
        """The bound below: the played policy's return less its 95% half-width (what a policy truly gets)."""
        return self.expected_return - self.return_ci

    @property
    def upper(self) -> float:
        """The bound above (see the class docstring)."""
        return self.grid_value + self.grid_error

    def act(self, alertness: np.ndarray, hypertension: np.ndarray, t: np.ndarray, left: np.ndarray) -> np.ndarray:
        """The policy's action codes (``pressure.NOTHING`` ...) for observed states and decisions left (1: the last)."""
        ti, j, i = self.grid.locate(alertness, hypertension, t)
        row = np.clip(np.asarray(left, dtype=np.int64), 1, len(self.actions)) - 1
        return self.actions[row, ti, j, i].astype(np.int64)


def solve_coffee(
    params: Params,
    *,
    alertness_step: float = 0.1,
    episodes: int = 20000,
    seed: int = 0,
    error: bool = True,
    **grid: Any,
) -> CoffeeSolution:
    """Solve where coffee may pay: the program's fixed point, its policy's Monte Carlo value, the grid's error.

    Args:
        params: v0's numbers (any ``heart_attack_penalty >= 0``, proclivity, ``max_steps``).
        alertness_step: the alertness lattice's step; the grid error compares twice this step.
        episodes: Monte Carlo episodes of the played policy (seeded, ``seed``).
        error: whether to solve the coarser grid for ``grid_error`` (else it is ``nan``).
        grid: further [`PressureGrid`][heartpole.optimum.pressure.PressureGrid] arguments.
    """
    begun = time.perf_counter()
    check_integer("episodes", episodes, 2)
    fine = PressureGrid(params, alertness_step, **grid)
    sweep = fixed_point(fine)
    coarse = math.nan
    if error:
        coarse = _grid_value(fixed_point(PressureGrid(params, 2 * alertness_step, **grid)), params)
    played = play(fine, sweep.actions, episodes, seed)
    return CoffeeSolution(
        params=params,
        rate=sweep.rate,
        scale=sweep.scale,
        grid_value=_grid_value(sweep, params),
        expected_return=played["return"],
        return_ci=played["return_ci"],
        expected_score=played["score"],
        expected_attacks=played["attacks"],
        coffees_per_episode=played["coffees"],
        beers_per_episode=0.0,
        sleeps_per_episode=played["sleeps"],
        grid_error=abs(_grid_value(sweep, params) - coarse),
        episodes=int(episodes),
        seconds=time.perf_counter() - begun,
        grid=fine,
        actions=sweep.actions,
    )


def _grid_value(sweep: Sweep, params: Params) -> float:
    """The policy's ``E[work] / E[time] - penalty * E[attacks]`` on the grid (attacks: the floor and the extra)."""
    attacks = params.max_steps * sweep.floor + sweep.attacks
    return sweep.work / sweep.time - params.heart_attack_penalty * attacks


def ratio(sweep: Sweep, params: Params) -> float:
    """Dinkelbach's ratio of a sweep's policy: ``E[work - scale * penalty * extra] / E[time]``."""
    return (sweep.work - sweep.scale * params.heart_attack_penalty * sweep.attacks) / sweep.time


def fixed_point(grid: PressureGrid, kept: int = KEPT_ROWS) -> Sweep:
    """The policy whose ``E[time]`` is the program's scale and whose ratio is its rate: iterate ``rate <- ratio``
    (Dinkelbach's step, for ``(E[work] - scale * penalty * E[extra]) / E[time]``) and ``scale <- E[time]`` until
    both repeat (1e-12, 1e-9 relative), from the no-drink optimum's. Its ``E[work] / E[time] - penalty *
    E[attacks]`` then equals the scale's Dinkelbach ratio less the floor's penalty."""
    start = solve_params(grid.params, 50)
    rate, scale = start.rate, start.expected_time
    for _ in range(MAX_ITERATIONS):
        sweep = backward(grid, rate, scale, kept)
        new_rate, new_scale = ratio(sweep, grid.params), sweep.time
        if abs(new_rate - rate) <= 1e-12 and abs(new_scale - scale) <= 1e-9 * scale:
            return sweep
        rate, scale = new_rate, new_scale
    raise RuntimeError(f"the rate and scale did not settle (rate {rate}, scale {scale})")


def bound(grid: PressureGrid, scale: float, rate: float) -> float:
    """Dinkelbach's maximum of ``(E[work] - scale * penalty * E[extra]) / E[time]`` over every policy on the grid
    (from ``rate``), less the floor's penalty: no policy whose ``E[time] >= scale`` has a larger ``E[work] / E[time]
    - penalty * E[attacks]`` on the grid (for those, ``E[time] * penalty * E[extra] >= scale * penalty * E[extra]``)."""
    params = grid.params
    for _ in range(MAX_ITERATIONS):
        sweep = backward(grid, rate, scale, 1)
        new_rate = ratio(sweep, params)
        if abs(new_rate - rate) <= 1e-12:
            return new_rate - params.heart_attack_penalty * params.max_steps * sweep.floor
        rate = new_rate
    raise RuntimeError(f"Dinkelbach's iteration did not settle (rate {rate})")


def play(grid: PressureGrid, actions: np.ndarray, episodes: int, seed: int = 0) -> dict[str, float]:
    """Monte Carlo of the policy in the env's dynamics (float64, continuous draws): the expected-risk return (final
    score less penalty times the summed risk), its 95% half-width and what the policy does, per episode."""
    params, tab = grid.params, grid.tables
    out = _episodes(
        int(episodes),
        int(seed),
        actions,
        tab["drained"],
        tab["start"],
        tab["h"],
        grid.alertness_step,
        params.max_steps,
        params.decay_rate,
        params.sleep_half_hours,
        params.heart_attack_proclivity,
        params.wake_alertness[0],
        params.wake_alertness[1] - params.wake_alertness[0],
        float(ballmer(0.0)),
    )
    returns = out[:, 0] - params.heart_attack_penalty * out[:, 1]
    return {
        "return": float(returns.mean()),
        "return_ci": float(Z95 * returns.std(ddof=1) / math.sqrt(episodes)),
        "score": float(out[:, 0].mean()),
        "attacks": float(out[:, 1].mean()),
        "coffees": float(out[:, 2].mean()),
        "sleeps": float(out[:, 3].mean()),
    }


@njit(cache=CACHE)
def _nearest(
    h: Any,
    x: Any,
) -> Any:
    lo, hi = 0, len(h) - 1
    if x >= h[hi]:
        return hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if h[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo if x - h[lo] <= h[hi] - x else hi


@njit(cache=CACHE)
def _episodes(
    episodes: Any,
    seed: Any,
    actions: Any,
    drained: Any,
    start: Any,
    h: Any,
    step: Any,
    steps: Any,
    decay: Any,
    sleep_half_hours: Any,
    proclivity: Any,
    wake_low: Any,
    wake_width: Any,
    ballmer0: Any,
) -> Any:
    """Each episode's (score, summed risk, coffees, sleeps) under the policy, the env's step in float64."""
    np.random.seed(seed)
    rows, awake, hp, width = actions.shape
    out = np.zeros((episodes, 4))
    for e in range(episodes):
        a, x, t, work, elapsed = wake_low + wake_width * np.random.random(), 0.0, 0, 0.0, 0.0
        for s in range(steps):
            left = steps - s
            ti = min(t, awake - 1)
            i = int(round((a + drained[ti]) / step)) - start[ti]
            i = min(max(i, 0), width - 1)
            act = actions[min(left, rows) - 1, ti, _nearest(h, x), i]
            u = np.random.random(4)
            if act == COFFEE:
                a += u[0]
                x += 0.3 * u[1]
                out[e, 2] += 1
            elif act == SLEEP:
                x *= decay**sleep_half_hours
                a = wake_low + wake_width * u[3]
                t = 0
                elapsed += sleep_half_hours
                out[e, 3] += 1
            work += a * (1.0 - 1.0 / (1.0 + math.exp(-(a - 3.0)))) * ballmer0
            a -= 1.0 / (1.0 + math.exp(-(t - 40.0) / 10.0))
            x *= decay
            t += 1
            elapsed += 1.0
            risk = proclivity / (1.0 + math.exp(-(x - 6.0)))
            out[e, 1] += risk
            if u[2] < risk:
                x = 0.0
        out[e, 0] = work / elapsed
    return out
