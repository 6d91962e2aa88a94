"""heartpole.jax with measurement=: the Sensor's own reading traced by JAX; the state itself unchanged.

Statistical tolerances as tests/test_measurement.py's: over 40,000 readings the noise's sample standard
deviation is within 3% of the spec's (its relative standard error is 0.35%) and its mean within 5 standard
errors of 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

jax = pytest.importorskip("jax", reason="heartpole.jax needs the 'jax' extra: pip install 'heartpole[jax]'")
import jax.numpy as jnp  # noqa: E402

from heartpole.jax import make  # noqa: E402
from heartpole.measurement import Measurement  # noqa: E402
from heartpole.model import ALERTNESS, HYPERTENSION, TIME_ELAPSED  # noqa: E402

COFFEE, SLEEP = 1, 3
N = 40_000


def test_noise_has_the_given_sd_on_measured_columns_only() -> None:
    measurement = Measurement({"alertness": 0.3, "hypertension": 0.05})
    env, params = make("HeartPole-v0", measurement=measurement)
    keys = jax.random.split(jax.random.key(0), N)
    obs, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    obs, states, *_ = jax.jit(jax.vmap(env.step, in_axes=(0, 0, None, None)))(keys, states, COFFEE, params)
    errors = np.asarray(obs, np.float64) - np.stack(states.variables, -1).astype(np.float64)
    for column, sd in ((ALERTNESS, 0.3), (HYPERTENSION, 0.05)):
        assert abs(errors[:, column].std(ddof=1) / sd - 1) < 0.03
        assert abs(errors[:, column].mean()) < 5 * sd / math.sqrt(N)
    np.testing.assert_array_equal(errors[:, 2:], 0.0)  # not measured: exact
    assert obs.shape == (N, 6)  # measured every half-hour: no age column


def test_the_state_is_unchanged_and_readings_are_the_sensors() -> None:
    """With the same keys the true states equal the unmeasured env's bit for bit; each observation is
    Sensor.read (NumPy, float64) of the truth with the noise drawn from the step key folded with 1."""
    measurement = Measurement({"alertness": 0.2, "intoxication": 0.01}, every=3)
    env, params = make("HeartPole-v0", people="default", measurement=measurement)
    plain, _ = make("HeartPole-v0", people="default")
    sensor = env.sensor
    key = jax.random.key(4)
    obs, state = env.reset(key, params)
    _, plain_state = plain.reset(key, params)
    step, plain_step = jax.jit(env.step_env), jax.jit(plain.step_env)
    for t, step_key in enumerate(jax.random.split(jax.random.key(5), 30)):
        action = (COFFEE, 2, SLEEP)[t % 3] if t % 7 == 0 else COFFEE
        before, before_time = np.asarray(state.seen, np.float64), float(state.variables[TIME_ELAPSED])
        before_age = float(state.age)
        obs, state, *_ = step(step_key, state, action, params)
        _, plain_state, *_ = plain_step(step_key, plain_state, action, params)
        np.testing.assert_array_equal(state.variables, plain_state.variables)
        noise = np.asarray(jax.random.normal(jax.random.fold_in(step_key, 1), (1, 2), jnp.float32), np.float64)
        passed = np.array([float(state.variables[TIME_ELAPSED]) - before_time])
        true = np.asarray(state.variables, np.float64)[None]
        seen, age = sensor.read(true, before[None], np.array([before_age]), passed, noise, np)
        np.testing.assert_allclose(obs, sensor.observation(seen, age)[0], rtol=1e-6, atol=1e-6)


def test_measured_every_k_half_hours_carried_forward_with_their_age() -> None:
    """every=4 with coffee (one half-hour a step): ages 1, 2, 3, 0, ...; a sleep (17 half-hours) measures."""
    env, params = make("HeartPole-v0", measurement=Measurement({"alertness": 0.5}, every=4))
    space = env.observation_space(params)
    assert space.shape == (7,) and space.low[ALERTNESS] == -np.inf and space.high[ALERTNESS] == np.inf
    assert (space.low[6], space.high[6]) == (0.0, 4.0) and space.low[HYPERTENSION] == 0.0
    obs, state = env.reset(jax.random.key(0), params)
    assert float(obs[6]) == 0.0 and float(obs[ALERTNESS]) != float(state.variables[ALERTNESS])
    step = jax.jit(env.step)
    for t, want in enumerate([1, 2, 3, 0, 0, 1, 2]):
        carried = float(obs[ALERTNESS])
        obs, state, *_ = step(jax.random.key(t + 1), state, SLEEP if t == 4 else COFFEE, params)
        assert float(obs[6]) == want and bool(space.contains(obs))
        np.testing.assert_array_equal(obs[1:6], state.variables[1:])
        if want:
            assert float(obs[ALERTNESS]) == carried
        else:
            assert float(obs[ALERTNESS]) != carried


def test_traits_follow_the_age_and_bad_measurements_are_refused() -> None:
    env, params = make("HeartPole-v0", people="default", observe_traits=True,
                       measurement=Measurement({"alertness": 0.1}, every=2))  # fmt: skip
    obs, state = env.reset(jax.random.key(0), params)
    assert obs.shape == (12,) and env.observation_space(params).shape == (12,)
    np.testing.assert_array_equal(obs[7:], env.person_values(state))
    assert state.person_values.shape == (0,)  # a cohort's person is carried as their index alone
    with pytest.raises(TypeError, match="measurement must be a heartpole.measurement.Measurement, its JSON"):
        make("HeartPole-v0", measurement={"alertness": 0.1})
    with pytest.raises(ValueError, match=r"unknown variables \['thc'\]"):
        make("HeartPole-v0", measurement=Measurement({"thc": 0.1}))
