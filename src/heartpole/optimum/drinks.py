"""Why drinks never pay on v0 (and where that cannot be shown): the drink floor, the beer bound, the coffee
check, and which variants the no-drink program covers at all."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from heartpole.actions import V0_ACTIONS
from heartpole.model import alertness_decay, ballmer, heart_attack_risk, productivity
from heartpole.parameters import V0_VARIABLES, Params

from .common import SOLVED_PARAMS, NotCoveredError, Settling, max_awake, peak_productivity, unmodelled
from .sleep import solve_params

if TYPE_CHECKING:
    from heartpole.dynamics import Dynamics


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
    must buy more than ``max_steps * floor`` units of work each (17.9 on v0).
    [`check_beer`][heartpole.optimum.drinks.check_beer] and [`check_coffee`][heartpole.optimum.drinks.check_coffee] show
    they cannot.

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
    peak = peak_productivity()
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
    """Coffee never pays, by the solver: [`coffee_check`][heartpole.optimum.drinks.coffee_check] finds no state where a
    coffee beats the optimum.

    By the verification theorem of finite-horizon dynamic programming, a value function that no action
    improves in any state is optimal: no policy gains by coffee in the states checked (alertness in
    [`COFFEE_CHECK_ALERTNESS`][heartpole.optimum.drinks.COFFEE_CHECK_ALERTNESS], every ``t`` awake and number of
    decisions left).

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
"""Alertness range in which [`coffee_check`][heartpole.optimum.drinks.coffee_check] tests every state."""


def coffee_check(params: Params, rate: float, charge: float, step: float = 0.01) -> float:
    """The most a coffee (charged ``charge`` units of work) gains over the no-drink optimum, in any state.

    A backward pass over an alertness grid (``step`` apart, covering the checked range and a coffee's +1
    above it) and ``t`` awake maximises ``E[work - rate * time]`` without drinks; in every state with
    alertness in [`COFFEE_CHECK_ALERTNESS`][heartpole.optimum.drinks.COFFEE_CHECK_ALERTNESS] and every number of
    decisions left it compares a coffee (``alertness + U(0, 1)``, the trapezoid rule over the grid, minus ``charge``)
    with the best no-drink choice. Returns the largest ``coffee - best`` seen: negative means coffee never pays. The
    pass stops once its values have settled (`Settling`): further ``n`` only repeat the same gains."""
    low, high = COFFEE_CHECK_ALERTNESS
    per_unit = int(round(1.0 / step))
    grid = np.round(np.arange(low - 1.0, high + 1.0 + step / 2, step), 10)
    awake = max_awake(params)
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
    settling = Settling(awake + 2)  # once the values have settled, every further n repeats the same gains
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
        if settling.update((stay >= sleep,), (value[:, :awake],)):
            break
    return best_gain


def check_covered(env_id: str, dynamics: Dynamics) -> None:
    """Refuse dynamics other than v0's six variables and four actions (in any order), and parameters the
    solvers do not model set away from their defaults ([`unmodelled`][heartpole.optimum.common.unmodelled]).

    Raises:
        NotCoveredError: naming the variables, actions or parameters that differ.
    """
    unknown = unmodelled(dynamics.params)
    if unknown:
        raise NotCoveredError(
            f"{env_id} sets {unknown}; the optimum's solvers model the parameters {sorted(SOLVED_PARAMS)} and "
            "take any other at its default only"
        )
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
