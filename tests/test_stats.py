"""heartpole.stats: Student-t intervals, the interquartile mean and its bootstrap interval, against known values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from heartpole import stats
from heartpole.stats import confidence_interval, standard_error, t_quantile_975


@pytest.mark.parametrize(
    ("dof", "quantile"),
    [(1, 12.7062), (4, 2.7764), (9, 2.2622), (10, 2.2281), (19, 2.0930), (30, 2.0423), (100, 1.9840), (10**6, 1.9600)],
)
def test_t_quantile_matches_tables(dof: int, quantile: float) -> None:
    assert t_quantile_975(dof) == pytest.approx(quantile, abs=1e-4)


def test_interval_edge_cases() -> None:
    assert all(math.isnan(x) for x in confidence_interval(np.array([3.0])))
    assert confidence_interval(np.full(10, 2.5)) == (2.5, 2.5)
    low, high = confidence_interval(np.array([1.0, 2.0, 3.0]))
    assert (low + high) / 2 == pytest.approx(2.0) and high - low == pytest.approx(2 * 4.3027 / math.sqrt(3))
    assert math.isnan(standard_error(np.array([1.0])))


def coverage(samples: np.ndarray, mean: float) -> float:
    hits = [low <= mean <= high for low, high in map(confidence_interval, samples)]
    return float(np.mean(hits))


def test_interval_covers_95_percent_of_small_normal_samples() -> None:
    """n = 5: the t interval covers 95%; a normal-quantile interval would cover only ~88%."""
    rng = np.random.default_rng(2024)
    reps = 4000
    rate = coverage(rng.normal(3.0, 2.0, (reps, 5)), 3.0)
    assert abs(rate - 0.95) < 4 * math.sqrt(0.95 * 0.05 / reps)


def test_interval_covers_95_percent_of_heart_attack_returns() -> None:
    """A population like HeartPole's returns: score - 100 x Poisson(1.236) heart attacks, 200 episodes."""
    rng = np.random.default_rng(7)
    reps = 4000
    samples = 0.33 - 100.0 * rng.poisson(1.236, (reps, 200))
    rate = coverage(samples, 0.33 - 123.6)
    assert abs(rate - 0.95) < 4 * math.sqrt(0.95 * 0.05 / reps)


def test_interquartile_mean_is_rliables() -> None:
    assert stats.interquartile_mean([5, 1, 3, 2, 4]) == pytest.approx(3.0)  # cuts 1 each side of 5
    assert stats.interquartile_mean([1, 2, 3, 4, 5, 6, 7, 100]) == pytest.approx(4.5)  # cuts 2 each side
    assert stats.interquartile_mean([1, 2, 9]) == pytest.approx(4.0)  # fewer than 4: the mean
    values = np.random.default_rng(0).normal(size=(3, 12))
    rows = stats.interquartile_mean(values, axis=1)
    assert rows == pytest.approx([np.sort(v)[3:9].mean() for v in values])


def test_bootstrap_interval_is_deterministic_and_brackets_the_iqm() -> None:
    values = [0.31, 0.32, 0.325, 0.30, 0.10]
    interval = stats.bootstrap_interval(values)
    assert interval == stats.bootstrap_interval(values)
    assert interval[0] <= stats.interquartile_mean(values) <= interval[1]
    assert stats.bootstrap_interval([2.0, 2.0, 2.0]) == (2.0, 2.0)
