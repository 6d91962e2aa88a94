"""heartpole.optimum.history: a sleep rule that reads the work and time so far, measured against the optimum, which
sees them too (issue 42): it gains nothing beyond the optimum's margin."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from heartpole.optimum import optimum
from heartpole.optimum.history import history_gain

KAI = {"heart_attack_proclivity": 0.75, "decay_rate": 0.93, "sleep_half_hours": 19, "wake_alertness": (0.5, 1.1)}
"""The default cohort's Kai, among those who gain the most from the history (benchmarks/history_gain.py)."""
CLEO_400 = {
    "heart_attack_proclivity": 0.75,
    "decay_rate": 0.95,
    "sleep_half_hours": 19,
    "wake_alertness": (0.55, 1.35),
    "max_steps": 400,
}
"""The cohort's Cleo on 400-decision episodes, where the history gained 5.1e-5, above the old measured margin (3e-5)."""
GUS_300 = {
    "heart_attack_proclivity": 0.80,
    "decay_rate": 0.95,
    "sleep_half_hours": 14,
    "wake_alertness": (0.80, 1.50),
    "max_steps": 300,
}
"""The cohort's Gus on 300-decision episodes (the history gained 3.8e-5 there)."""


@pytest.mark.slow
@pytest.mark.parametrize(
    "env_kwargs",
    [{}, pytest.param(KAI, marks=pytest.mark.audit), GUS_300, CLEO_400],  # v0 stands for 1,000 decisions in CI
    ids=["v0", "Kai", "Gus-300", "Cleo-400"],
)
def test_the_history_rule_gains_nothing_beyond_the_margin_over_optimal(env_kwargs: dict[str, object]) -> None:
    """The history-aware rule against ``optimal`` (the history-aware optimum) on 40,000 paired episodes: its gain is
    not significantly above the margin, at 1,000 decisions and at the short horizons where the history is worth most
    (it gained 3.8e-5 to 5.1e-5 there over the sleep-timing policy), and the optimum's own score on these episodes
    matches its expected score within 4 standard errors (about 3e-4)."""
    solution = optimum("HeartPole-v0", env_kwargs)
    measured = history_gain(solution, episodes=40_000, seed=1)
    assert solution.history is not None
    assert measured.ci95[0] <= solution.margin < 2.5e-6, (measured, solution.margin)
    assert abs(measured.optimal_score - solution.expected_score) < 1e-3, measured  # the paired simulator is v0's


@pytest.mark.slow
def test_the_measurement_sees_a_gain_where_there_is_one() -> None:
    """Against a worse rule (the sleep-timing thresholds 0.05 too low: it stays awake too long) the history-aware
    rule's gain is far above the margin: the measurement is able to fail."""
    solution = optimum("HeartPole-v0")
    worse = dataclasses.replace(solution, thresholds=solution.thresholds - 0.05, history=None)
    measured = history_gain(worse, episodes=5_000, seed=1)
    assert measured.ci95[0] > 10 * solution.margin, measured


def test_history_gain_wants_a_solution() -> None:
    with pytest.raises(TypeError, match="OptimumSolution"):
        history_gain(np.zeros(3))  # type: ignore[arg-type]


def test_regret_intervals_are_widened_by_the_margin() -> None:
    """Evaluation's regret interval: the expected-risk interval reflected, widened by the margin: the grids' error and
    the history program's gap (what any policy may add to the played one)."""
    from heartpole.evaluation import evaluate

    solution = optimum("HeartPole-v0")
    result = evaluate("expert", episodes=20)
    low, high = result.expected_ci95
    expected = (solution.expected_return - high - solution.margin, solution.expected_return - low + solution.margin)
    assert result.regret_ci95 == pytest.approx(expected, abs=1e-12)
    assert solution.margin == solution.error_bound + solution.history_worth
    assert solution.history is not None and solution.history_worth == solution.history.gap
    assert 0 < solution.history.gap < 1e-6 and solution.error_bound < 2e-6
