"""The expected-risk correction and the shaped training reward: one formula for NumPy and JAX."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from heartpole.model import heart_attack_risk
from heartpole.parameters import Params
from heartpole.rewards import expected_risk, risk_floor, training_reward

PENALTY = Params.heart_attack_penalty


def step_values(n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    risk = rng.uniform(0.0, 0.05, n)
    return {
        "env_reward": rng.normal(0.0, 0.01, n) - PENALTY * (rng.random(n) < risk),
        "heart_attack": (rng.random(n) < risk).astype(np.float64),
        "risk": risk,
        "productivity": rng.uniform(0.0, 1.0, n),
        "half_hours": rng.integers(1, 17, n).astype(np.float64),
    }


def test_each_use_of_the_correction_is_the_formula_it_replaced_bit_for_bit() -> None:
    v = step_values(10_000, 0)
    coin, risk, reward = v["heart_attack"], v["risk"], v["env_reward"]
    # a step: the realized charge given back, the expected one taken
    assert np.array_equal(expected_risk(reward, risk, PENALTY, coin), reward + PENALTY * (coin - risk))
    # an episode: final score less the summed risks
    assert np.array_equal(expected_risk(reward, risk, PENALTY), reward - PENALTY * risk)
    floor = risk_floor(0.5)
    assert floor == float(heart_attack_risk(0.0, 0.5))
    assert np.array_equal(expected_risk(reward, risk, PENALTY, floor), reward - PENALTY * (risk - floor))


def test_the_expected_risk_reward_keeps_the_realized_mean() -> None:
    """Statistical: over 200,000 steps the corrected and realized rewards differ in mean by less than 4
    standard errors of their difference (a martingale: same expectation)."""
    v = step_values(200_000, 1)
    rng = np.random.default_rng(2)
    coin = (rng.random(len(v["risk"])) < v["risk"]).astype(np.float64)
    realized = v["productivity"] - PENALTY * coin
    expected = expected_risk(realized, v["risk"], PENALTY, coin)
    difference = realized - expected
    assert abs(difference.mean()) < 4 * difference.std(ddof=1) / np.sqrt(len(difference))
    assert expected.std() < realized.std() / 10  # the coin's noise is gone


@pytest.mark.parametrize(("expected", "score_rate"), list(itertools.product([False, True], [None, 0.32])))
def test_the_training_reward_is_its_parts(expected: bool, score_rate: float | None) -> None:
    v = step_values(1000, 3)
    floor = risk_floor(0.5)
    reward = training_reward(
        v["env_reward"], v["heart_attack"], v["risk"], v["productivity"], v["half_hours"],
        penalty=PENALTY, floor=floor, expected=expected, score_rate=score_rate, horizon=2000.0,
    )  # fmt: skip
    if score_rate is None:
        score = v["env_reward"] + PENALTY * v["heart_attack"]
    else:
        score = (v["productivity"] - score_rate * v["half_hours"]) / 2000.0
    charge = PENALTY * (v["risk"] - floor) if expected else PENALTY * v["heart_attack"]
    np.testing.assert_allclose(reward, score - charge, rtol=0, atol=1e-12)
    if not expected and score_rate is None:
        assert np.allclose(reward, v["env_reward"], rtol=0, atol=1e-12)  # exactly the env's reward


@pytest.mark.parametrize(("expected", "score_rate"), list(itertools.product([False, True], [None, 0.32])))
def test_jax_arrays_get_the_same_reward_in_float32(expected: bool, score_rate: float | None) -> None:
    jnp = pytest.importorskip("jax.numpy")
    v = step_values(1000, 4)
    floor = np.float32(risk_floor(0.5))
    options = {"penalty": PENALTY, "floor": floor, "expected": expected, "score_rate": score_rate, "horizon": 2000.0}
    names = ("env_reward", "heart_attack", "risk", "productivity", "half_hours")
    in_numpy = training_reward(*(v[k].astype(np.float32) for k in names), **options)
    in_jax = training_reward(*(jnp.asarray(v[k], dtype=jnp.float32) for k in names), **options)
    assert in_jax.dtype == jnp.float32 and in_numpy.dtype == np.float32
    np.testing.assert_allclose(np.asarray(in_jax), in_numpy, rtol=1e-6, atol=1e-6)
