"""heartpole.measurement: noisy readings, measured on schedule, carried forward with their age.

Statistical tolerances: over 40,000 readings the noise's sample standard deviation is within 3% of the
spec's (its relative standard error is 1 / sqrt(2n) = 0.35%, so 3% is over 8 of them) and its mean within 5
standard errors of 0.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from heartpole.measurement import Measurement
from heartpole.parameters import V0_VARIABLES, variable_names

NAMES = variable_names(V0_VARIABLES)
N = 40_000


def true_observations(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.0, 5.0, size=(n, len(NAMES)))


def test_noise_has_the_given_sd_on_measured_columns_only() -> None:
    sensor = Measurement({"alertness": 0.3, "hypertension": 0.05}).sensor(NAMES)
    true = true_observations(N)
    seen, age = sensor.reset(true, np.random.default_rng(1))
    errors = seen - true
    for column, sd in ((0, 0.3), (1, 0.05)):
        assert abs(errors[:, column].std(ddof=1) / sd - 1) < 0.03
        assert abs(errors[:, column].mean()) < 5 * sd / math.sqrt(N)
    assert abs(np.corrcoef(errors[:, 0], errors[:, 1])[0, 1]) < 5 / math.sqrt(N)  # independent readings
    np.testing.assert_array_equal(seen[:, 2:], true[:, 2:])  # not measured: exact
    np.testing.assert_array_equal(age, np.zeros(N))


def test_readings_are_carried_forward_with_their_exact_age() -> None:
    """every=4: measured at reset and at the first step 4 or more half-hours after the last reading."""
    sensor = Measurement({"alertness": 0.5, "intoxication": 0.0}, every=4).sensor(NAMES)
    rng = np.random.default_rng(2)
    passed = [1, 1, 1, 1, 17, 1, 2, 1, 3]  # a sleep passes 17 half-hours at once
    expected_age = [1, 2, 3, 0, 0, 1, 3, 0, 3]
    seen, age = sensor.reset(true_observations(5, seed=0), rng)
    for step, (half_hours, want) in enumerate(zip(passed, expected_age)):
        true = true_observations(5, seed=step + 1)
        before = seen
        seen, age = sensor.step(true, seen, age, np.full(5, float(half_hours)), rng)
        np.testing.assert_array_equal(age, np.full(5, float(want)))
        np.testing.assert_array_equal(seen[:, 1], true[:, 1])  # hypertension: not measured, always true
        np.testing.assert_array_equal(seen[:, 3:], true[:, 3:])
        if want == 0:  # a fresh reading: alertness noisy, intoxication exact (sd 0)
            assert np.all(seen[:, 0] != true[:, 0])
            np.testing.assert_array_equal(seen[:, 2], true[:, 2])
        else:  # carried forward exactly
            np.testing.assert_array_equal(seen[:, [0, 2]], before[:, [0, 2]])


def test_each_env_keeps_its_own_schedule_and_inf_measures_now() -> None:
    sensor = Measurement({"alertness": 0.1}, every=3).sensor(NAMES)
    rng = np.random.default_rng(3)
    true = true_observations(3)
    seen, age = sensor.step(true, true, np.array([0.0, 2.0, 1.0]), np.array([1.0, 1.0, np.inf]), rng)
    np.testing.assert_array_equal(age, [1.0, 0.0, 0.0])
    assert seen[0, 0] == true[0, 0] and seen[1, 0] != true[1, 0] and seen[2, 0] != true[2, 0]


def test_draws_are_reproducible_and_do_not_depend_on_the_schedule() -> None:
    true = true_observations(100)
    outputs = []
    for every in (1, 1, 5):
        rng = np.random.default_rng(4)
        sensor = Measurement({"alertness": 0.2}, every=every).sensor(NAMES)
        seen, age = sensor.reset(true, rng)
        seen, age = sensor.step(true, seen, age, np.ones(100), rng)
        outputs.append((seen, rng.random()))
    np.testing.assert_array_equal(outputs[0][0], outputs[1][0])
    assert outputs[0][1] == outputs[1][1] == outputs[2][1]  # the same number of draws whatever was measured


def test_observation_and_space() -> None:
    low = np.array([v.low for v in V0_VARIABLES], dtype=np.float32)
    high = np.array([v.high for v in V0_VARIABLES], dtype=np.float32)
    sensor = Measurement({"hypertension": 0.5, "intoxication": 0.0}, every=4).sensor(NAMES)
    space_low, space_high = sensor.space(low, high)
    assert space_low.shape == (7,) and space_low.dtype == np.float32
    assert space_low[1] == -np.inf and space_low[2] == 0.0  # noise may read below the floor; sd 0 may not
    assert (space_low[6], space_high[6]) == (0.0, 4.0)
    np.testing.assert_array_equal(space_low[[0, 2, 3, 4, 5]], low[[0, 2, 3, 4, 5]])
    box = gym.spaces.Box(space_low, space_high, dtype=np.float32)
    rng = np.random.default_rng(5)
    true = np.zeros((200, 6))  # hypertension 0: noise reads below it half the time
    seen, age = sensor.reset(true, rng)
    for _ in range(6):
        seen, age = sensor.step(true, seen, age, np.ones(200), rng)
        obs = sensor.observation(seen, age)
        assert obs.shape == (200, 7) and obs.dtype == np.float32
        assert all(box.contains(row) for row in obs)
    assert (seen[:, 1] < 0).any()
    every_step = Measurement({"alertness": 0.1}).sensor(NAMES)
    assert not every_step.has_age and every_step.space(low, high)[0].shape == (6,)
    assert every_step.observation(*every_step.reset(true, rng)).shape == (200, 6)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Measurement({}), "noise must map at least one variable name"),
        (lambda: Measurement(0.1), "noise must map"),
        (lambda: Measurement({1: 0.1}), "noise's keys must be variable names"),
        (lambda: Measurement({"alertness": -0.1}), r"noise\['alertness'\] \(a standard deviation\) must be"),
        (lambda: Measurement({"alertness": math.nan}), r"finite number in \[0.0, inf\]"),
        (lambda: Measurement({"alertness": True}), r"finite number in \[0.0, inf\]"),
        (lambda: Measurement({"alertness": 0.1}, every=0), "every must be an integer >= 1, got 0"),
        (lambda: Measurement({"alertness": 0.1}, every=1.5), "every must be an integer >= 1"),
        (
            lambda: Measurement({"mood": 0.1}).sensor(NAMES),
            r"unknown variables \['mood'\]; the env observes \['alertness'",
        ),
        (
            lambda: Measurement({"alertness": 0.1}).sensor(NAMES).reset(np.zeros((2, 5)), np.random.default_rng()),
            r"shape \(n, 6\), got \(2, 5\)",
        ),
    ],
)
def test_bad_measurements_are_refused_clearly(make: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make()


def test_to_dict() -> None:
    assert Measurement({"alertness": 0.2}, every=4).to_dict() == {"noise": {"alertness": 0.2}, "every": 4}
