"""The optimum over every policy (heartpole.optimum.whole): brute force on a tiny instance, bounds, the policy."""

from __future__ import annotations

import numpy as np
import pytest

from heartpole import model
from heartpole.dynamics import Dynamics, step_tables
from heartpole.model import TIME_ELAPSED, WORK_DONE, Params
from heartpole.optimum.sleep import solve_params
from heartpole.optimum.whole import solve_history
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
