"""The true optimum of HeartPole-v0 by dynamic programming: the ceiling every policy's regret is measured from.

What is solved. An episode's return telescopes to ``final score - penalty x heart attacks``, with the score
``work_done / time_elapsed`` (fact 0's bookkeeping). The solver finds the policy that maximises the
expected return of HeartPole-v0, with any of its :class:`~heartpole.model.Params` changed, in two steps:

1. **Drinks never pay** (while ``heart_attack_proclivity * heart_attack_penalty > 0`` and the check below
   passes). A step's heart-attack risk ``r(H) = proclivity * sigmoid(H - 6)`` is convex for ``H <= 6`` and
   hypertension never exceeds ``0.3 * decay / (1 - decay)`` (9.7 for v0), so ``r(H) >= r(0) + r'(0) H``
   on every reachable state. A drink adds ``h ~ U(0, 0.3)`` of hypertension, of which ``decay * h`` is still
   there when its own step's coin is flipped: each drink costs at least
   ``penalty * r'(0) * decay * 0.15`` = 0.0179 expected return on v0 (:func:`drink_floor`), whatever the
   policy does. :func:`check_no_drinks` then bounds what a drink can buy (in the ratio-of-expectations
   sense of step 2, where a unit of return is worth at least ``max_steps`` units of work) and refuses
   parameters where the bound does not rule drinks out.
2. **Only the sleep timing is left.** Without drinks hypertension stays 0, the heart-attack part is
   fixed (``max_steps * r(0)`` expected attacks) and a day is deterministic once its waking alertness
   ``w ~ U(wake_alertness)`` is drawn: at ``t`` half-hours after waking the alertness is
   ``w - sum(alertness_decay(j) for j < t)``. The state is ``(decisions left n, w, t)``. The ratio
   ``E[work] / E[time]`` is maximised by Dinkelbach's method: for a rate ``lam`` the dynamic program
   maximises ``E[work - lam * time]``; ``lam <- E[work] / E[time]`` of its policy, until the maximum is 0.

Discretisation. ``t`` and ``n`` are exact integers. ``w`` is a midpoint grid of ``grid`` points on
``wake_alertness``; every decision on the grid is exact for its ``w`` (the day is deterministic), and the
only approximation is the expectation over the next waking alertness (the midpoint rule, error
``O(1/grid**2)``). Days are cut at ``max_awake`` half-hours, where productivity is so negative that a sleep
pays even on the last decision (checked). The reported expected score is the exact ``E[work / time]`` of
the grid policy, computed by a forward pass over days and sleeps (``time = max_steps + sleep_half_hours
x sleeps``); ``error_bound`` is the change of the expected return between ``grid // 2`` and ``grid``.

What it does not cover, refused with a clear error: action sets other than v0's four (HeartPole-v1's
naps, tea, exercise and cannabis), extra state variables, ``heart_attack_proclivity = 0`` or
``heart_attack_penalty = 0`` (drinking then pays: see docs/optimum.md) and parameters where
:func:`check_no_drinks` cannot rule drinks out. The solved policy sees ``(n, alertness, t)``, not the work
and sleeps so far; an exact ``E[work / time]`` optimum would also condition on those, which the issue's
independent solver measured to be worth about 1e-5 of return.

Also here: :func:`sleep_rule_value`, the exact expected return of any no-drink sleep rule (``expert``'s
regret without sampling), and :func:`solve_drinking`, a grid DP for ``heart_attack_proclivity=0``, where
drinking pays: its stationary policy is a lower bound and its whole-episode value an upper bound on the grid,
not a certified optimum.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole import files
from heartpole.actions import V0_ACTIONS
from heartpole.model import (
    V0_VARIABLES,
    Params,
    alertness_decay,
    ballmer,
    check_integer,
    heart_attack_risk,
    productivity,
)

if TYPE_CHECKING:
    from heartpole.dynamics import Dynamics

SOLVER_VERSION = 2
DEFAULT_GRID = 400
MAX_DINKELBACH_ITERATIONS = 50


class NotCoveredError(ValueError):
    """The variant is outside what the dynamic program solves (extra actions or variables, drinks that may pay)."""


@dataclass(frozen=True)
class OptimumSolution:
    """The optimal sleep rule of a HeartPole variant and its expected return.

    Attributes:
        env_id, env_kwargs: the env solved.
        params: its :class:`~heartpole.model.Params`.
        grid: midpoint-grid points of the waking alertness.
        rate: Dinkelbach's optimal ``E[work] / E[time]`` on the grid.
        expected_score: the exact ``E[work / time]`` of the grid policy.
        expected_heart_attacks: ``max_steps * heart_attack_risk(0)``, the floor no policy beats.
        expected_return: ``expected_score - heart_attack_penalty * expected_heart_attacks``.
        error_bound: ``|expected_return(grid) - expected_return(grid // 2)|``, the grid's error bound (the
            midpoint rule converges as ``1/grid**2``, so the fine grid's error is about a third of it).
        expected_sleeps: mean sleeps per episode of the optimal policy.
        drink_floor: expected return each drink costs at least (:func:`drink_floor`).
        coffee_best_gain: the most a coffee gains over the no-drink optimum in any state checked, in units of
            work (:func:`coffee_check`; negative: coffee never pays).
        thresholds: ``(max_steps + 1, max_awake)`` alertness thresholds: with ``n`` decisions left and
            ``t = time_since_slept``, sleep when ``alertness < thresholds[n, t]`` (``t >= max_awake``: sleep).
    """

    env_id: str
    env_kwargs: dict[str, Any]
    params: Params
    grid: int
    rate: float
    expected_score: float
    expected_heart_attacks: float
    expected_return: float
    error_bound: float
    expected_sleeps: float
    drink_floor: float
    coffee_best_gain: float
    thresholds: np.ndarray = field(repr=False, compare=False)

    @property
    def max_awake(self) -> int:
        """Half-hours awake after which the policy always sleeps."""
        return int(self.thresholds.shape[1])

    def sleeps(
        self, alertness: np.ndarray, time_since_slept: np.ndarray, decisions_left: int | np.ndarray
    ) -> np.ndarray:
        """Whether the optimal policy sleeps, elementwise (no-drink states; ``decisions_left`` in 1..max_steps)."""
        n = np.clip(np.asarray(decisions_left, dtype=np.int64), 0, self.params.max_steps)
        t = np.asarray(time_since_slept, dtype=np.int64)
        inside = t < self.max_awake
        threshold = self.thresholds[np.broadcast_to(n, t.shape), np.minimum(t, self.max_awake - 1)]
        return ~inside | (np.asarray(alertness, dtype=np.float64) < threshold)

    def within(self, interval: tuple[float, float]) -> bool:
        """Whether :attr:`expected_return` lies in ``interval`` (an evaluator's 95% interval, say) widened by
        the grid's :attr:`error_bound` on both sides."""
        low, high = interval
        return bool(low - self.error_bound <= self.expected_return <= high + self.error_bound)

    def summary(self) -> dict[str, Any]:
        """JSON-safe figures of the solution (no arrays)."""
        return {
            "env_id": self.env_id,
            "env_kwargs": self.env_kwargs,
            "params": _params_dict(self.params),
            "grid": self.grid,
            "rate": self.rate,
            "expected_score": self.expected_score,
            "expected_heart_attacks": self.expected_heart_attacks,
            "expected_return": self.expected_return,
            "error_bound": self.error_bound,
            "expected_sleeps": self.expected_sleeps,
            "drink_floor": self.drink_floor,
            "coffee_best_gain": self.coffee_best_gain,
            "max_awake": self.max_awake,
            "solver_version": SOLVER_VERSION,
        }

    def save(self, directory: str | Path) -> Path:
        """Write ``optimum.json`` and ``optimum.npz`` into ``directory`` (created), both or neither, atomically."""
        directory = Path(directory)
        with files.atomic_files(directory / "optimum.npz", directory / "optimum.json") as (npz, summary):
            with npz.open("wb") as handle:
                np.savez_compressed(handle, thresholds=self.thresholds)
            summary.write_text(json.dumps(self.summary(), indent=2) + "\n")
        return directory

    @classmethod
    def load(cls, directory: str | Path) -> OptimumSolution:
        """Read a solution saved by :meth:`save`.

        Raises:
            FileNotFoundError: a missing file.
            ValueError: files that are not a solution of this solver version.
        """
        directory = Path(directory)
        for name in ("optimum.json", "optimum.npz"):
            if not (directory / name).is_file():
                raise FileNotFoundError(f"{directory / name} not found; save a solution with OptimumSolution.save")
        try:
            meta = json.loads((directory / "optimum.json").read_text())
            with np.load(directory / "optimum.npz") as arrays:
                thresholds = np.asarray(arrays["thresholds"], dtype=np.float64)
            if meta.get("solver_version") != SOLVER_VERSION:
                raise ValueError(f"solver version {meta.get('solver_version')}, expected {SOLVER_VERSION}")
            params = Params(**{**meta["params"], "wake_alertness": tuple(meta["params"]["wake_alertness"])})
            fields = ("rate", "expected_score", "expected_heart_attacks", "expected_return", "error_bound")
            return cls(
                env_id=meta["env_id"],
                env_kwargs=meta["env_kwargs"],
                params=params,
                grid=int(meta["grid"]),
                expected_sleeps=float(meta["expected_sleeps"]),
                drink_floor=float(meta["drink_floor"]),
                coffee_best_gain=float(meta["coffee_best_gain"]),
                thresholds=thresholds,
                **{key: float(meta[key]) for key in fields},
            )
        except (KeyError, TypeError, ValueError, OSError) as error:
            raise ValueError(f"{directory}: not a HeartPole optimum ({' '.join(str(error).split())})") from None


# ------------------------------------------------------------------------------------------------------
# the public entry points


def solve(env_id: str = "HeartPole-v0", *, grid: int = DEFAULT_GRID, **env_kwargs: Any) -> OptimumSolution:
    """Solve the optimal policy of ``env_id`` built with ``env_kwargs`` (see the module docstring).

    Args:
        env_id: a registered HeartPole id whose dynamics are v0's (actions and variables).
        grid: midpoint-grid points of the waking alertness (>= 4); the error bound compares ``grid // 2``.
        env_kwargs: the env's keyword arguments (``heart_attack_proclivity``, ``max_steps``, ...).

    Raises:
        NotCoveredError: a variant the solver does not cover (the message says why).
        ValueError: an unknown env or bad arguments.
    """
    from heartpole.policies import env_dynamics

    check_integer("grid", grid, 4)
    dynamics = env_dynamics(env_id, env_kwargs)
    _check_covered(env_id, dynamics)
    return _solve(dynamics.params, int(grid), env_id, dict(env_kwargs))


def _solve(params: Params, grid: int, env_id: str, env_kwargs: dict[str, Any]) -> OptimumSolution:
    check_beer(params)
    fine = solve_params(params, grid)
    coffee = check_coffee(params, fine.rate)
    coarse = solve_params(params, grid // 2)
    attacks = params.max_steps * float(heart_attack_risk(0.0, params.heart_attack_proclivity))
    return OptimumSolution(
        env_id=env_id,
        env_kwargs=env_kwargs,
        params=params,
        grid=grid,
        rate=fine.rate,
        expected_score=fine.expected_score,
        expected_heart_attacks=attacks,
        expected_return=fine.expected_score - params.heart_attack_penalty * attacks,
        error_bound=abs(fine.expected_score - coarse.expected_score),
        expected_sleeps=fine.expected_sleeps,
        drink_floor=drink_floor(params),
        coffee_best_gain=coffee["coffee_best_gain"],
        thresholds=fine.thresholds,
    )


def optimum(env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None) -> OptimumSolution:
    """The solution for ``env_id`` and ``env_kwargs``, solved once: kept in memory and in the user cache.

    The disk cache lives in ``$HEARTPOLE_CACHE_DIR``, else ``$XDG_CACHE_HOME/heartpole``, else
    ``~/.cache/heartpole``, under ``optimum/<hash of the parameters and solver version>/``.

    Raises:
        NotCoveredError, ValueError: as :func:`solve`.
    """
    from heartpole.policies import env_dynamics

    kwargs = dict(env_kwargs or {})
    return optimum_for(env_dynamics(env_id, kwargs), env_id, kwargs)


def optimum_for(
    dynamics: Dynamics, env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None
) -> OptimumSolution:
    """:func:`optimum` for a :class:`~heartpole.dynamics.Dynamics` (``env_id`` and ``env_kwargs`` label it)."""
    _check_covered(env_id, dynamics)
    solution = _cached(dynamics.params, str(cache_dir()))
    if isinstance(solution, NotCoveredError):
        raise NotCoveredError(str(solution))
    return replace(solution, env_id=env_id, env_kwargs=dict(env_kwargs or {}))


def available(env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None) -> OptimumSolution | None:
    """:func:`optimum`, or ``None`` for a variant the solver does not cover."""
    try:
        return optimum(env_id, env_kwargs)
    except NotCoveredError:
        return None


@functools.lru_cache(maxsize=32)
def _cached(params: Params, cache_root: str) -> OptimumSolution | NotCoveredError:
    """The solution of ``params`` from memory, the disk cache or a fresh solve; a refusal is kept too."""
    key = hashlib.sha256(
        json.dumps([SOLVER_VERSION, DEFAULT_GRID, _params_dict(params)], sort_keys=True).encode()
    ).hexdigest()[:16]
    directory = Path(cache_root) / "optimum" / key
    try:
        solution = OptimumSolution.load(directory)
        if solution.params == params and solution.grid == DEFAULT_GRID:
            return solution
    except (FileNotFoundError, ValueError):
        pass
    try:
        solution = _solve(params, DEFAULT_GRID, "HeartPole-v0", _changed_params(params))
    except NotCoveredError as error:
        return error
    try:
        solution.save(directory)
    except OSError:  # a read-only home still gets the solution, just not cached on disk
        pass
    return solution


def cache_dir() -> Path:
    """Where solutions are cached on disk (see :func:`optimum`)."""
    if os.environ.get("HEARTPOLE_CACHE_DIR"):
        return Path(os.environ["HEARTPOLE_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "heartpole"


def drink_floor(params: Params) -> float:
    """Expected return that any drink (a hypertension rise ``U(0, 0.3)``) costs at least, on its own step.

    ``penalty * r'(0) * decay_rate * 0.15`` with ``r(H) = heart_attack_risk(H, proclivity)``; 0.0179 for v0.
    ``r'(0)`` is taken as the exact derivative of the sigmoid, ``r(0) * (1 - sigmoid(-6))``.
    """
    risk0 = float(heart_attack_risk(0.0, params.heart_attack_proclivity))
    unit = float(heart_attack_risk(0.0, 1.0))  # sigmoid(-6)
    slope = risk0 * (1.0 - unit)
    return params.heart_attack_penalty * slope * params.decay_rate * _mean_rise()


def check_no_drinks(params: Params, rate: float | None = None) -> dict[str, float]:
    """Check that no drink pays under ``params``; return the figures of the argument.

    With the score ``W / T`` and ``T >= max_steps``, a policy with drinks beats the no-drink optimal rate
    ``lam`` (ratio of expectations) only if ``E[W - lam T] > max_steps * floor * E[drinks]``: the drinks
    must buy more than ``max_steps * floor`` units of work each (17.9 on v0). :func:`check_beer` and
    :func:`check_coffee` show they cannot.

    Args:
        params: the variant's numbers.
        rate: the no-drink optimal rate ``lam``, if already solved (else solved on a coarse grid).

    Raises:
        NotCoveredError: if drinks are not ruled out (e.g. ``heart_attack_proclivity=0``).
    """
    figures = check_beer(params)
    figures.update(check_coffee(params, solve_params(params, 100).rate if rate is None else rate))
    return figures


def check_beer(params: Params) -> dict[str, float]:
    """Beer never pays, by a bound: what a beer can buy is less than what it costs.

    A beer adds at most 0.03 intoxication, which fades by ``decay_rate``: at most ``0.03 / (1 - decay_rate)``
    intoxication-steps (1.0 on v0), each worth at most ``peak productivity / ballmer(0) * max_x (ballmer(x)
    - ballmer(0)) / x`` units of work (12.6 in all on v0, against a charge of 17.9). Its lower alertness
    only costs work while alertness is below the productivity peak, where a day without coffee stays.

    Raises:
        NotCoveredError: if the bound does not rule beer out.
    """
    floor = drink_floor(params)
    charge = params.max_steps * floor
    peak = _peak_productivity()
    x = np.linspace(1e-4, 0.5, 50001)
    b0 = float(ballmer(0.0))
    beer = peak / b0 * float(((ballmer(x) - b0) / x).max()) * 0.03 / max(1.0 - params.decay_rate, 1e-12)
    if not charge > beer:
        raise NotCoveredError(
            f"drinking may pay with these parameters: each drink costs at least {floor:.4g} of return "
            f"({charge:.4g} units of work at max_steps={params.max_steps}), but a beer may buy up to {beer:.4g}; "
            "the optimum covers variants where drinking provably never pays (for v0's other numbers: "
            "max_steps >= 701 at heart_attack_proclivity 0.5, or proclivity >= 0.36 at max_steps 1000)"
        )
    return {"floor": floor, "charge": charge, "beer_gain_bound": beer}


def check_coffee(params: Params, rate: float) -> dict[str, float]:
    """Coffee never pays, by the solver: :func:`coffee_check` finds no state where a coffee beats the optimum.

    By the verification theorem of finite-horizon dynamic programming, a value function that no action
    improves in any state is optimal: no policy gains by coffee in the states checked (alertness in
    :data:`COFFEE_CHECK_ALERTNESS`, every ``t`` awake and number of decisions left).

    Raises:
        NotCoveredError: if a coffee gains somewhere.
    """
    floor = drink_floor(params)
    charge = params.max_steps * floor
    best = coffee_check(params, rate, charge)
    if best > 0:
        raise NotCoveredError(
            f"coffee may pay with these parameters: a coffee charged at least {floor:.4g} of return "
            f"({charge:.4g} units of work) beats the no-drink optimum by {best:.4g} units of work in some state; "
            "the optimum covers variants where drinking never pays"
        )
    return {"coffee_best_gain": best}


COFFEE_CHECK_ALERTNESS = (-3.0, 5.0)
"""Alertness range in which :func:`coffee_check` tests every state."""


def coffee_check(params: Params, rate: float, charge: float, step: float = 0.01) -> float:
    """The most a coffee (charged ``charge`` units of work) gains over the no-drink optimum, in any state.

    A backward pass over an alertness grid (``step`` apart, covering the checked range and a coffee's +1
    above it) and ``t`` awake maximises ``E[work - rate * time]`` without drinks; in every state with
    alertness in :data:`COFFEE_CHECK_ALERTNESS` and every number of decisions left it compares a coffee
    (``alertness + U(0, 1)``, the trapezoid rule over the grid, minus ``charge``) with the best no-drink
    choice. Returns the largest ``coffee - best`` seen: negative means coffee never pays.
    """
    low, high = COFFEE_CHECK_ALERTNESS
    per_unit = int(round(1.0 / step))
    grid = np.round(np.arange(low - 1.0, high + 1.0 + step / 2, step), 10)
    awake = _max_awake(params)
    decay = alertness_decay(np.arange(awake, dtype=np.float64))
    worked = productivity(grid, 0.0)[:, None]
    # after a half-hour at t the alertness is a - decay[t]: linear interpolation weights, clamped at the ends
    shifted = np.clip(grid[:, None] - decay[None, :], grid[0], grid[-1])
    position = (shifted - grid[0]) / step
    below = np.minimum(np.floor(position).astype(np.int64), len(grid) - 2)
    frac = position - below
    columns = np.arange(awake)[None, :]
    checked = (grid >= low - 1e-9) & (grid <= high + 1e-9)
    wake_low, wake_high = params.wake_alertness
    wake = wake_low + (wake_high - wake_low) * (np.arange(200) + 0.5) / 200
    wake_position = np.clip((wake - decay[0] - grid[0]) / step, 0, len(grid) - 1.000001)
    wake_below = np.minimum(np.floor(wake_position).astype(np.int64), len(grid) - 2)
    wake_frac = wake_position - wake_below
    wake_work = productivity(wake, 0.0)
    rest = 1.0 + params.sleep_half_hours
    value = np.zeros((len(grid), awake + 1))
    best_gain = -np.inf
    for _ in range(params.max_steps):
        later = value[:, 1:]  # next decision's values at t + 1
        after = later[below, columns] * (1 - frac) + later[below + 1, columns] * frac
        stay = worked - rate + after
        stay[:, awake - 1] = -np.inf
        ahead = value[:, 1]
        woken = ahead[wake_below] * (1 - wake_frac) + ahead[wake_below + 1] * wake_frac
        sleep = float(np.mean(wake_work + woken)) - rate * rest
        best = np.maximum(stay, sleep)
        finite = np.where(np.isfinite(stay), stay, sleep - 1e6)
        integral = np.concatenate([np.zeros((1, awake)), np.cumsum((finite[1:] + finite[:-1]) * step / 2, axis=0)])
        coffee = integral[per_unit:] - integral[:-per_unit] - charge
        gain = coffee[checked[: len(coffee)]] - best[: len(coffee)][checked[: len(coffee)]]
        best_gain = max(best_gain, float(gain[:, : awake - 1].max()))
        value[:, :awake] = best
    return best_gain


# ------------------------------------------------------------------------------------------------------
# the dynamic program


@dataclass(frozen=True)
class GridSolution:
    """The optimum on one grid: Dinkelbach's rate, the exact expected score of its policy, its thresholds."""

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
    forward = model.forward(sweep)
    return GridSolution(
        rate=float(rate),
        expected_score=forward.score,
        expected_sleeps=forward.sleeps,
        expected_work=sweep.work,
        expected_time=sweep.time,
        thresholds=sweep.thresholds,
    )


@dataclass
class _Sweep:
    """A backward pass at one rate: its policy's expected work and time, days and sleep thresholds."""

    rate: float
    work: float
    time: float
    length: np.ndarray  # (max_steps + 1, grid, 2): decisions until the day's sleep, from t = 0 and t = 1
    earned: np.ndarray  # same shape: the work of those decisions
    thresholds: np.ndarray  # (max_steps + 1, max_awake): sleep when alertness < thresholds[n, t]


@dataclass
class _Forward:
    score: float
    sleeps: float


class _DayModel:
    """A day as the DP sees it: productivity ``work[w, t]`` of waking alertness ``w`` after ``t`` half-hours."""

    def __init__(self, params: Params, grid: int) -> None:
        self.params = params
        self.steps = params.max_steps
        self.sleep_time = params.sleep_half_hours
        low, high = params.wake_alertness
        self.wake = low + (high - low) * (np.arange(grid) + 0.5) / grid
        self.awake = _max_awake(params)
        decay = alertness_decay(np.arange(self.awake - 1, dtype=np.float64))
        self.drained = np.concatenate([[0.0], np.cumsum(decay)])  # alertness lost after t half-hours awake
        self.work = productivity(self.wake[:, None] - self.drained[None, :], 0.0)  # (grid, max_awake)

    def backward(self, rate: float) -> _Sweep:
        """Maximise ``E[work - rate * time]`` and follow that policy's expected work, time and days.

        ``value``, ``work`` and ``time`` are functions of ``(w, t)`` for ``n - 1`` decisions left, with an
        extra column for ``t = max_awake`` (never reached: the last column always sleeps).
        """
        grid, awake, steps = len(self.wake), self.awake, self.steps
        value, work, time = (np.zeros((grid, awake + 1)) for _ in range(3))
        length = np.zeros((grid, awake + 1), dtype=np.int64)
        earned = np.zeros((grid, awake + 1))
        lengths = np.zeros((steps + 1, grid, 2), dtype=np.int64)
        earnings = np.zeros((steps + 1, grid, 2))
        thresholds = np.full((steps + 1, awake), np.inf)
        rest = 1.0 + self.sleep_time
        for n in range(1, steps + 1):
            stay = self.work - rate + value[:, 1:]
            stay[:, awake - 1] = -np.inf
            sleep = float(np.mean(self.work[:, 0] + value[:, 1])) - rate * rest
            sleep_work = float(np.mean(self.work[:, 0] + work[:, 1]))
            sleep_time = rest + float(np.mean(time[:, 1]))
            go_on = stay >= sleep
            thresholds[n] = self._thresholds(go_on, stay - sleep)
            value[:, :awake] = np.where(go_on, stay, sleep)
            work[:, :awake] = np.where(go_on, self.work + work[:, 1:], sleep_work)
            time[:, :awake] = np.where(go_on, 1.0 + time[:, 1:], sleep_time)
            length[:, :awake] = np.where(go_on, 1 + length[:, 1:], 0)
            earned[:, :awake] = np.where(go_on, self.work + earned[:, 1:], 0.0)
            lengths[n], earnings[n] = length[:, :2], earned[:, :2]
            if go_on[:, awake - 2].any():
                raise RuntimeError(f"a day reached {awake - 1} half-hours awake; the cut at max_awake is too short")
        return _Sweep(rate, float(work[:, 0].mean()), float(time[:, 0].mean()), lengths, earnings, thresholds)

    def follow(self, sleeps: Callable[[np.ndarray, np.ndarray, int], np.ndarray]) -> _Sweep:
        """The days of the policy that sleeps where ``sleeps(alertness, t, n)`` (see :func:`sleep_rule_value`)."""
        grid, awake, steps = len(self.wake), self.awake, self.steps
        alertness = self.wake[:, None] - self.drained[None, :]
        t = np.arange(awake)
        length = np.zeros((grid, awake + 1), dtype=np.int64)
        earned = np.zeros((grid, awake + 1))
        lengths = np.zeros((steps + 1, grid, 2), dtype=np.int64)
        earnings = np.zeros((steps + 1, grid, 2))
        for n in range(1, steps + 1):
            go_on = ~np.asarray(sleeps(alertness, t, n), dtype=bool)
            go_on[:, awake - 1] = False
            length[:, :awake] = np.where(go_on, 1 + length[:, 1:], 0)
            earned[:, :awake] = np.where(go_on, self.work + earned[:, 1:], 0.0)
            lengths[n], earnings[n] = length[:, :2], earned[:, :2]
        return _Sweep(math.nan, math.nan, math.nan, lengths, earnings, np.empty((0, awake)))

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

    def forward(self, sweep: _Sweep) -> _Forward:
        """The exact ``E[work / time]`` and mean sleeps of the swept policy, by days: ``time = D + sleep * K``.

        A day begins at a decision with ``t`` = 0 (the episode's start) or 1 (after a sleep step, whose
        half-hour of work at ``t`` = 0 belongs to the new day). Given its ``w`` it runs deterministically for
        ``length`` decisions, then either the episode ends or the next decision sleeps. The pass keeps, per
        (decisions left at a day's start, sleeps so far ``K``), the probability and ``E[work so far; event]``.
        """
        steps = self.steps
        sleeps_so_far = np.arange(steps + 2)
        mass = np.zeros((steps + 1, steps + 2))
        work = np.zeros((steps + 1, steps + 2))
        score = sleeps = 0.0
        for n in range(steps, -1, -1):
            if n == steps:
                day_mass, day_work = np.zeros(steps + 2), np.zeros(steps + 2)
                day_mass[0] = 1.0
                lengths, earned = sweep.length[n, :, 0], sweep.earned[n, :, 0]
            else:
                day_mass, day_work = mass[n], work[n]
                if not day_mass.any():
                    continue
                lengths, earned = sweep.length[n, :, 1], sweep.earned[n, :, 1] + self.work[:, 0]
            for taken in np.unique(lengths):
                share = lengths == taken
                moved_mass = day_mass * (share.mean())
                moved_work = day_work * share.mean() + day_mass * (earned[share].sum() / len(share))
                left = n - int(taken)
                if left == 0:  # the episode ends with this day
                    score += float(np.sum(moved_work / (steps + self.sleep_time * sleeps_so_far)))
                    sleeps += float(np.sum(moved_mass * sleeps_so_far))
                else:  # decision ``left`` sleeps; the new day starts with ``left - 1`` decisions left
                    mass[left - 1, 1:] += moved_mass[:-1]
                    work[left - 1, 1:] += moved_work[:-1]
        return _Forward(score, sleeps)


def sleep_rule_value(
    params: Params, sleeps: Callable[[np.ndarray, np.ndarray, int], np.ndarray], grid: int = DEFAULT_GRID
) -> float:
    """The exact expected return of a no-drink policy that sleeps by ``sleeps(alertness, t, n)``.

    ``sleeps`` gets the alertness ``(grid, max_awake)`` of every waking alertness ``w`` (rows) after ``t``
    half-hours awake (columns, ``t`` given as a ``(max_awake,)`` array) with ``n`` decisions left, and
    returns where the policy sleeps. The expected score comes from the same forward pass as the optimum's
    (``E[work / time]`` exact on the ``w`` grid); the heart-attack part is the no-drink floor. This is how
    ``expert``'s regret is known without sampling.
    """
    model = _DayModel(params, grid)
    forward = model.forward(model.follow(sleeps))
    attacks = params.max_steps * float(heart_attack_risk(0.0, params.heart_attack_proclivity))
    return forward.score - params.heart_attack_penalty * attacks


def _initial_rate(model: _DayModel) -> float:
    """A starting rate for Dinkelbach's iteration: a full day's average productivity, sleep included."""
    return float(np.clip(model.work[:, :16].mean() * 16 / (16 + model.sleep_time), 0.0, None))


def _max_awake(params: Params) -> int:
    """Half-hours awake after which continuing loses more work than any sleep costs, even on the last step.

    From there on every half-hour awake earns less than ``-(sleep_half_hours + 2) * peak productivity``, so
    sleeping (which costs ``sleep_half_hours + 1`` half-hours at a rate below the peak) is better.
    """
    bound = -(params.sleep_half_hours + 2) * _peak_productivity() - 1.0
    high = params.wake_alertness[1]
    t = np.arange(4096, dtype=np.float64)
    drained = np.concatenate([[0.0], np.cumsum(alertness_decay(t))])
    worst = productivity(high - drained, 0.0)
    below = np.nonzero(worst < bound)[0]
    if not len(below):
        raise NotCoveredError("alertness does not drain far enough within 4096 half-hours")
    return int(below[0]) + 2


# ------------------------------------------------------------------------------------------------------
# heart_attack_proclivity = 0: where drinking pays

DRINKING_ACTIONS = ("do_nothing", "drink_coffee", "drink_beer", "sleep")
NEVER = -1e9
"""The value of an action that leaves the grid (or of staying awake at the last half-hour awake)."""


@dataclass(frozen=True)
class DrinkingSolution:
    """A grid policy for a variant without heart-attack risk, where coffee and beer pay (:func:`solve_drinking`).

    Not a certified optimum: its score, measured through the evaluator, is a lower bound on what drinking
    can reach. ``start_value`` is the grid's best ``E[work - rate * time]`` over ``sweeps`` decisions from
    the episode's start (waking alertness, no alcohol); with ``sweeps == max_steps`` it is the whole
    episode's, end-game included, and :attr:`rate_bound` bounds every policy's ``E[work] / E[time]``, as far
    as the grid is exact. ``q`` holds each action's
    value of :data:`DRINKING_ACTIONS` on the grid; the policy picks the best by bilinear interpolation.
    """

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
        """This solution as a :data:`~heartpole.policies.Policy` for ``dynamics`` (v0's four actions)."""
        return _DrinkingPolicy(self, [dynamics.action_index(name) for name in DRINKING_ACTIONS])


class _DrinkingPolicy:
    """The greedy action of a :class:`DrinkingSolution` at each observation."""

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
    nothing when ``heart_attack_proclivity * heart_attack_penalty == 0``. The grid (:class:`DrinkingGrid`)
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
        NotCoveredError: if heart attacks cost anything (use :func:`solve` there).
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
    :data:`DRINKING_ACTIONS` order; it must only take actions the grid covers. This is how the grid is
    checked against the env's own dynamics (the evaluator's episodes of the same rule with
    ``max_steps=decisions`` agree within their interval).
    ``grid``: :func:`solve_drinking`'s grid arguments.
    """
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
    """:func:`solve_drinking`'s drift-free discretisation of (alertness, intoxication, half-hours awake).

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


# ------------------------------------------------------------------------------------------------------
# helpers


def _peak_productivity() -> float:
    """The largest work a half-hour can bring without intoxication (alertness about 2.2)."""
    return float(productivity(np.linspace(-5.0, 10.0, 30001), 0.0).max())


def _changed_params(params: Params) -> dict[str, Any]:
    """The env keyword arguments that give ``params``: the fields that differ from the defaults."""
    defaults = _params_dict(Params())
    return {key: value for key, value in _params_dict(params).items() if defaults[key] != value}


def _check_covered(env_id: str, dynamics: Dynamics) -> None:
    names = [v.name for v in dynamics.variables]
    if tuple(dynamics.variables) != V0_VARIABLES:
        raise NotCoveredError(
            f"{env_id} has state variables {names}; the optimum covers HeartPole-v0's six "
            f"({[v.name for v in V0_VARIABLES]}) only"
        )
    if set(dynamics.actions) != set(V0_ACTIONS) or len(dynamics.actions) != len(V0_ACTIONS):
        raise NotCoveredError(
            f"{env_id} has actions {[a.name for a in dynamics.actions]}; the optimum covers HeartPole-v0's four "
            f"({[a.name for a in V0_ACTIONS]}, in any order) only"
        )


def _mean_rise() -> float:
    """Mean hypertension rise of v0's drinks (both add U(0, 0.3)); checked against the actions' data."""
    rises = {a.effects["hypertension"] for a in V0_ACTIONS if "hypertension" in a.effects}
    (low, high), *others = rises
    if others:
        raise NotCoveredError(f"v0's drinks raise hypertension differently: {sorted(rises)}")
    return (low + high) / 2


def _params_dict(params: Params) -> dict[str, Any]:
    out = asdict(params)
    out["wake_alertness"] = list(params.wake_alertness)
    return out


def _json_default(value: object) -> float | int | list[object]:
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"cannot describe {value!r} as JSON")


__all__ = [
    "NotCoveredError",
    "OptimumSolution",
    "check_no_drinks",
    "drink_floor",
    "available",
    "check_beer",
    "check_coffee",
    "optimum",
    "optimum_for",
    "DrinkingGrid",
    "DrinkingSolution",
    "drinking_rule_value",
    "solve_drinking",
    "sleep_rule_value",
    "solve",
    "solve_params",
    "cache_dir",
]
