"""The optimum over every policy (heartpole.optimum.whole): brute force on a tiny instance, bounds, the policy."""

from __future__ import annotations

import json

import numpy as np
import pytest

from heartpole import model
from heartpole.dynamics import Dynamics, step_tables
from heartpole.model import TIME_ELAPSED, WORK_DONE
from heartpole.optimum.sleep import solve_params
from heartpole.optimum.whole import solve_history
from heartpole.parameters import Params
from tests.test_optimum import _expectimax


@pytest.mark.slow  # exhaustive search, about 15 s
@pytest.mark.parametrize("sleep_half_hours", [1, 2])
def test_a_tiny_instance_over_every_policy_matches_brute_force(sleep_half_hours: int) -> None:
    """Exhaustive search over every policy (it sees the whole state, work and time included) on a 5-decision
    instance whose time varies by a third: the program's lower value (its policy's) is the search's, and the upper
    value is above it; the sleep-timing optimum, which sees no history, is below."""
    params = Params(max_steps=5, sleep_half_hours=sleep_half_hours, wake_alertness=(0.1, 1.9))
    grid = 5
    dynamics = Dynamics(params=params)
    _, tables = step_tables(dynamics.actions, dynamics.variables, params, float)
    zeros = (0.0,) * len(dynamics.variables)
    starts = [list(model.initial_state(zeros, (i + 0.5) / grid, tables)) for i in range(grid)]
    best = float(np.mean([_expectimax(dynamics, s, 5, grid, lambda s: s[WORK_DONE] / s[TIME_ELAPSED]) for s in starts]))
    solved = solve_history(params, grid=grid, points=401, band=6, spread=40.0)
    markov = solve_params(params, grid).expected_score
    assert solved.lower == pytest.approx(best, abs=1e-9)
    assert solved.upper >= best - 1e-9
    assert markov < best - 1e-4  # the history is worth something here: the test can tell the two apart
    assert solved.gain == pytest.approx(best - markov, abs=1e-9)


@pytest.mark.slow  # a 1,000-decision program (seconds) and 2,000 episodes through the evaluator
def test_the_history_aware_policy_scores_the_programs_value_through_the_evaluator() -> None:
    """The program's policy played in the env (float32 dynamics, continuous waking draws): its expected-risk return's
    95% interval holds the program's lower value (plus the no-drink heart-attack part), widened by the waking grid's
    error (the sleep-timing optimum's grid 50 against 400); and it sees the history, so it reads the work done."""
    from heartpole.evaluation import evaluate
    from heartpole.optimum import optimum
    from heartpole.policies import HistoryOptimalPolicy

    solution = optimum("HeartPole-v0")
    solved = solve_history(solution.params)
    floor = solution.expected_return - solution.expected_score
    grid_error = abs(solution.expected_score - solved.markov)
    result = evaluate(HistoryOptimalPolicy(solved=solved), episodes=2000, seed=0)
    low, high = result.expected_ci95
    assert low - grid_error <= solved.lower + floor <= high + grid_error, (result.expected_ci95, solved.lower + floor)
    assert 0 < solved.gain < 3e-5 and 0 <= solved.gap < 1e-6


@pytest.mark.slow  # a 701-decision program
def test_cli_history_reports_the_bounds(capsys) -> None:
    from heartpole.cli import main

    assert main(["optimum", "--history", "--check", "0", "--json", "--param", "max_steps=701"]) == 0
    history = json.loads(capsys.readouterr().out)["history"]
    assert history["bound above"] >= history["expected return, its policy"]
    assert 0 < history["over the sleep-timing optimum"] < 1e-4


def test_the_hull_finds_the_best_of_every_line() -> None:
    """`_hulls` and `_line_envelope`'s binary search find the best of every lower line at any work, inside the grid
    and past its ends, with lines of equal slope among them (the unsolved rows' -1e9 lines are all alike)."""
    from heartpole.optimum.whole import _hulls, _line_envelope

    rng = np.random.default_rng(7)
    steps, width, points = 40, 3, 9
    offsets = np.linspace(-6.0, 6.0, points)
    work_centre = rng.normal(size=(steps, width))
    work_scale = rng.uniform(0.2, 2.0, size=(steps, width))
    lines = rng.normal(size=(steps, width, points))
    slopes = rng.choice([-1.0, 0.0, 0.5, 1.0, 2.0], size=(steps, width, points))  # equal slopes are common
    lines[0, 1], slopes[0, 1] = -1e9, 0.0
    hull, breaks = _hulls(work_centre, work_scale, offsets, lines, slopes)
    centre = np.full(steps, 2)  # band 1: ``sleeps`` so far is row sleeps + 1 - 2 + 1, the same number
    for after in range(steps):
        for b in range(width):
            x_i = work_centre[after, b] + work_scale[after, b] * offsets
            for x in np.linspace(x_i[0] - 10.0, x_i[-1] + 10.0, 101):
                best = (lines[after, b] + slopes[after, b] * (x - x_i)).max()
                found = _line_envelope(
                    x, after, b, (centre, 1, work_centre, work_scale, offsets, lines, slopes, hull, breaks)
                )
                assert found == pytest.approx(best, abs=1e-12), (after, b, x)
