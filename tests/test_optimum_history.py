"""heartpole.optimum.history: a sleep rule that reads the work and time so far, measured against the optimum."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from heartpole.optimum import optimum
from heartpole.optimum.common import HISTORY_GAIN
from heartpole.optimum.history import history_gain

KAI = {"heart_attack_proclivity": 0.75, "decay_rate": 0.93, "sleep_half_hours": 19, "wake_alertness": (0.5, 1.1)}
"""The default cohort's Kai, among those who gain the most from the history (benchmarks/history_gain.py)."""


@pytest.mark.slow
@pytest.mark.parametrize("env_kwargs", [{}, KAI], ids=["v0", "Kai"])
def test_what_the_history_gains_is_within_the_margin_the_regrets_are_widened_by(env_kwargs: dict[str, object]) -> None:
    """The history-aware rule against ``optimal`` on paired episodes: its gain is not significantly above
    `HISTORY_GAIN`, and the optimum's own score on these episodes matches its exact expected score."""
    solution = optimum("HeartPole-v0", env_kwargs)
    measured = history_gain(solution, episodes=40_000, seed=1)
    assert measured.ci95[0] <= HISTORY_GAIN, measured
    assert solution.margin == solution.error_bound + HISTORY_GAIN
    assert abs(measured.optimal_score - solution.expected_score) < 1e-3, measured  # the paired simulator is v0's


@pytest.mark.slow
def test_the_measurement_sees_a_gain_where_there_is_one() -> None:
    """Against a worse rule (the optimum's thresholds 0.05 too low: it stays awake too long) the history-aware
    rule's gain is far above `HISTORY_GAIN`: the measurement is able to fail."""
    solution = optimum("HeartPole-v0")
    worse = dataclasses.replace(solution, thresholds=solution.thresholds - 0.05)
    measured = history_gain(worse, episodes=5_000, seed=1)
    assert measured.ci95[0] > 10 * HISTORY_GAIN, measured


def test_history_gain_wants_a_solution() -> None:
    with pytest.raises(TypeError, match="OptimumSolution"):
        history_gain(np.zeros(3))  # type: ignore[arg-type]


def test_regret_intervals_are_widened_by_the_margin() -> None:
    """Evaluation's regret interval: the expected-risk interval reflected, widened by the grid's error and the
    history's measured worth."""
    from heartpole.evaluation import evaluate

    solution = optimum("HeartPole-v0")
    result = evaluate("expert", episodes=20)
    low, high = result.expected_ci95
    expected = (solution.expected_return - high - solution.margin, solution.expected_return - low + solution.margin)
    assert result.regret_ci95 == pytest.approx(expected, abs=1e-12)
    assert solution.margin > HISTORY_GAIN > solution.error_bound
