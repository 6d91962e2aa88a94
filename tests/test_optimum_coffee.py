"""Where coffee may pay (heartpole.optimum.pressure, .coffee): the program against exhaustive search."""

from __future__ import annotations

import numpy as np
import pytest

from heartpole import model
from heartpole.dynamics import Dynamics, step_tables
from heartpole.model import HYPERTENSION, TIME_ELAPSED
from heartpole.optimum.pressure import PressureGrid, backward
from heartpole.parameters import Params

TINY = Params(max_steps=3, sleep_half_hours=2, heart_attack_proclivity=1.0, heart_attack_penalty=1.0,
              wake_alertness=(0.5, 1.5))  # fmt: skip
STEP = 0.25  # the alertness lattice: a coffee's U(0, 1) and the waking interval on 5 points each
RATE, SCALE = 0.3, 300.0  # the linear objective E[work - RATE time - SCALE penalty extra risk]


def _trapezoid(points: int) -> tuple[np.ndarray, np.ndarray]:
    """Uniform draws at ``points`` evenly spaced nodes of [0, 1] with the trapezoid rule's weights."""
    weights = np.ones(points)
    weights[[0, -1]] = 0.5
    return np.linspace(0.0, 1.0, points), weights / weights.sum()


def _search(dynamics: Dynamics, state: tuple[float, ...], left: int, penalty_weight: float, tables: tuple) -> float:
    """The best expected ``work - RATE time - penalty_weight extra risk`` over the ``left`` decisions, by exhaustive
    search over every action (do nothing, coffee, sleep), both outcomes of the heart-attack coin, coffee draws (the
    trapezoid rule on the alertness lattice, 4-point Gauss-Legendre on the hypertension rise: the program integrates
    the latter exactly for its interpolant) and waking draws (the trapezoid rule, as the program)."""
    if left == 0:
        return 0.0
    effects, step = tables
    floor = float(model.heart_attack_risk(0.0, dynamics.params.heart_attack_proclivity))
    lattice, lattice_w = _trapezoid(int(round(1 / STEP)) + 1)
    gauss, gauss_w = np.polynomial.legendre.leggauss(4)
    gauss, gauss_w = (gauss + 1) / 2, gauss_w / 2

    def outcome(action: str, draws: dict[int, float]) -> float:
        total = 0.0
        for coin, attack in ((1.0 - 1e-12, False), (0.0, True)):
            uniforms = [0.0] * (len(state) + 2)
            for index, u in draws.items():
                uniforms[index] = u
            uniforms[len(state) + 1] = coin
            new, _, worked, risk, *_ = model.step(state, effects[dynamics.action_index(action)], uniforms, step)
            share = risk if attack else 1.0 - risk
            if share == 0.0:
                continue
            if attack:
                assert new[HYPERTENSION] == 0.0
            gain = worked - RATE * (new[TIME_ELAPSED] - state[TIME_ELAPSED]) - penalty_weight * (risk - floor)
            total += share * (gain + _search(dynamics, tuple(map(float, new)), left - 1, penalty_weight, tables))
        return total

    nothing = outcome("do_nothing", {})
    coffee = sum(
        wa * wh * outcome("drink_coffee", {0: a, 1: h})
        for a, wa in zip(lattice, lattice_w)
        for h, wh in zip(gauss, gauss_w)
    )
    sleep = sum(w * outcome("sleep", {len(state): u}) for u, w in zip(lattice, lattice_w))
    return max(nothing, coffee, sleep)


def _program_value(params: Params, rate: float, scale: float) -> float:
    grid = PressureGrid(
        params, STEP, alertness_range=(-1.0, 4.0), max_hypertension=2.0, min_hypertension=1e-3, max_awake=10
    )
    return backward(grid, rate, scale, 1).value


def _search_value(params: Params, scale: float) -> float:
    dynamics = Dynamics(params=params)
    tables = step_tables(dynamics.actions, dynamics.variables, params, float)
    zeros = (0.0,) * len(dynamics.variables)
    wakes, weights = _trapezoid(int(round((params.wake_alertness[1] - params.wake_alertness[0]) / STEP)) + 1)
    starts = [tuple(map(float, model.initial_state(zeros, u, tables[1]))) for u in wakes]
    return float(sum(w * _search(dynamics, s, params.max_steps, scale * params.heart_attack_penalty, tables)
                     for s, w in zip(starts, weights)))  # fmt: skip


@pytest.mark.slow  # exhaustive search through the env's step, about 20 s
def test_a_tiny_instance_matches_exhaustive_search() -> None:
    """Three decisions with a heart attack coin that matters (proclivity 1): the program's best value equals the
    exhaustive search's to the interpolation error in hypertension (below 1e-4 of a unit of work here)."""
    searched = _search_value(TINY, SCALE)
    assert _program_value(TINY, RATE, SCALE) == pytest.approx(searched, abs=1e-4)


def test_the_frontier_point_where_no_drink_pays_is_the_no_drink_optimum() -> None:
    """At v0's penalty drinks never pay: the frontier's point is the optimum itself, no drinks, its interval around
    its value by the grid's error and the history's worth."""
    from heartpole.optimum import frontier_point, optimum

    v0 = optimum("HeartPole-v0")
    point = frontier_point("HeartPole-v0")
    assert point.optimal and point.drinks_per_episode == 0.0
    assert point.expected_return == v0.expected_return and point.expected_attacks == v0.expected_heart_attacks
    assert (
        point.lower <= point.expected_return <= point.upper and point.upper - point.lower <= v0.margin + v0.error_bound
    )
    assert point.summary()["drinks_per_episode"] == 0.0


def test_the_frontier_point_refuses_params_with_keywords() -> None:
    from heartpole.optimum import frontier_point

    with pytest.raises(TypeError, match="takes no keyword arguments"):
        frontier_point(Params(), max_steps=10)
    with pytest.raises(TypeError, match="env id or a heartpole.parameters.Params"):
        frontier_point(3)  # type: ignore[arg-type]


@pytest.mark.slow  # the lifetime check at 1,000 decisions (about a minute) and 2,000 episodes through the evaluator
@pytest.mark.audit  # shorter horizons' lifetime checks run in every suite (max_steps 100's solves)
def test_at_penalty_30_no_drink_pays_and_the_evaluator_confirms(capsys) -> None:
    """The own-step floor cannot rule drinks out at penalty 30 (it did refuse), the lifetime check does: the optimum
    is the no-drink one, and the evaluator's 95% interval for `optimal` holds its value."""
    import json

    from heartpole.cli import main
    from heartpole.optimum import NotCoveredError, check_beer

    params = Params(heart_attack_penalty=30.0)
    with pytest.raises(NotCoveredError):
        check_beer(params)
    assert main(["optimum", "--json", "--param", "heart_attack_penalty=30"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["coffee_best_gain"] < 0
    low, high = data["check_optimal"]["expected_ci95"]
    assert low - data["error_bound"] <= data["expected_return"] <= high + data["error_bound"]


@pytest.mark.slow  # the coffee program's fixed point over 60 decisions and 20,000 episodes, about 30 s
def test_the_coffee_policy_played_in_the_env_scores_the_programs_value() -> None:
    """Over 60 decisions at penalty 10 coffee pays (about ten an episode): the policy played by Monte Carlo in the
    env's dynamics (continuous draws, off-grid states rounded to the grid's nearest point) scores the program's value
    of it within the Monte Carlo interval, widened by 5e-4 for the ratio (``E[work / time]`` against ``E[work] /
    E[time]``) and the grid."""
    from heartpole.optimum import solve_coffee

    solved = solve_coffee(Params(max_steps=60, heart_attack_penalty=10.0), episodes=20000, error=False)
    assert solved.coffees_per_episode > 5
    assert abs(solved.expected_return - solved.grid_value) <= solved.return_ci + 5e-4
    assert solved.lower < solved.expected_return and solved.grid_error != solved.grid_error  # error=False: nan
