"""Off-policy estimators against known values: exact on-policy identities, a tabular chain, HeartPole itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from heartpole.offline.behaviour import EpsilonGreedy
from heartpole.offline.ope import (
    LinearFQE,
    estimate_all,
    importance_weights,
    target_probabilities,
)
from heartpole.offline.trajectories import Trajectories, collect
from heartpole.offline.truth import true_value
from heartpole.policies import ExpertPolicy, RandomPolicy, ReferencePolicy

SHORT = {"max_steps": 5}


def by_name(estimates):
    return {e.estimator: e for e in estimates}


def test_on_policy_weights_are_one_and_is_is_the_monte_carlo_mean():
    behaviour = EpsilonGreedy(ReferencePolicy(), 0.0, 4, rng=1)
    data = collect(behaviour, 30, seeds=(3,))
    target = target_probabilities(ReferencePolicy(), data)
    assert np.array_equal(importance_weights(target, data), np.ones_like(data.rewards))
    estimates = by_name(estimate_all(data, ReferencePolicy(), 0.95))
    monte_carlo = data.returns(0.95).mean()
    assert estimates["PDIS"].value == pytest.approx(monte_carlo, abs=1e-9)
    assert estimates["WPDIS"].value == pytest.approx(monte_carlo, abs=1e-9)
    # a deterministic target on its own data: V(s_t) = Q(s_t, a_t), so DR's corrections cancel whatever Q is
    assert estimates["DR"].value == pytest.approx(monte_carlo, abs=1e-9)


def test_on_policy_stochastic_target_weights_are_one():
    data = collect(EpsilonGreedy(RandomPolicy(rng=0), 0.0, 4, rng=1), 20, seeds=(3,))
    weights = importance_weights(target_probabilities(RandomPolicy(), data), data)
    assert np.allclose(weights, 1.0)
    assert by_name(estimate_all(data, RandomPolicy(), 0.9))["PDIS"].value == pytest.approx(data.returns(0.9).mean())


def chain(episodes: int, seed: int, steps: int = 3) -> Trajectories:
    """A deterministic chain: state s in 0..2, action 1 moves on, reward s + a; the uniform behaviour."""
    rng = np.random.default_rng(seed)
    obs = np.zeros((episodes, steps + 1, 6), dtype=np.float32)
    actions = rng.integers(0, 2, (episodes, steps))
    rewards = np.zeros((episodes, steps))
    state = np.zeros(episodes)
    for t in range(steps):
        obs[:, t, 0], obs[:, t, 1] = state, t
        rewards[:, t] = state + actions[:, t]
        state = np.minimum(state + actions[:, t], 2)
    obs[:, steps, 0], obs[:, steps, 1] = state, steps
    zeros = np.zeros((episodes, steps + 1), dtype=np.float32)
    return Trajectories(
        observations=obs,
        actions=actions,
        rewards=rewards,
        action_probabilities=np.full((episodes, steps + 1, 2), 0.5),
        heart_attack_risk=zeros,
        productivity=zeros,
        heart_attack=zeros.astype(bool),
        score=zeros,
    )


def tabular(obs: np.ndarray) -> np.ndarray:
    """The constant, then one-hot (time, state) features: Q is exactly representable."""
    index = (obs[:, 1] * 3 + obs[:, 0]).astype(int)
    out = np.zeros((len(obs), 13))
    out[:, 0] = 1.0
    out[np.arange(len(obs)), 1 + index] = 1.0
    return out


class AlwaysMove:
    name = "move"

    def __call__(self, obs):
        return np.ones(len(obs), dtype=np.int64)


def test_tabular_chain_fqe_and_dr_are_exact_and_is_is_unbiased():
    gamma = 0.9
    truth = 1 + 2 * gamma + 3 * gamma**2  # s = 0, 1, 2 moving every step: rewards 1, 2, 3
    data = chain(4000, seed=0)
    estimates = by_name(estimate_all(data, AlwaysMove(), gamma, ridge=1e-12, featurize=tabular))
    assert estimates["FQE"].value == pytest.approx(truth, abs=1e-6)
    assert estimates["DR"].value == pytest.approx(truth, abs=1e-6)  # exact Q, deterministic chain: no variance
    low, high = estimates["PDIS"].ci95
    half = (high - low) / 2
    assert abs(estimates["PDIS"].value - truth) < 2.1 * half  # 4 standard errors
    assert estimates["WPDIS"].value == pytest.approx(truth, abs=2.1 * half)


def test_fqe_fit_is_required():
    with pytest.raises(RuntimeError, match="fit"):
        LinearFQE(0.9).q_values(np.zeros((1, 6), dtype=np.float32))


def test_gamma_is_checked():
    with pytest.raises(ValueError, match="gamma"):
        estimate_all(chain(2, 0), AlwaysMove(), 1.5)


@pytest.mark.slow
def test_off_policy_estimates_match_the_truth_on_a_short_heartpole():
    """Uniform behaviour, expert target, 5-step episodes: PDIS and DR unbiased within 4 standard errors."""
    gamma = 0.9
    data = collect(EpsilonGreedy(RandomPolicy(rng=1), 0.0, 4, rng=2), 20_000, seeds=(5,), env_kwargs=SHORT)
    truth = true_value(ExpertPolicy(), gamma, 20_000, env_kwargs=SHORT, seed=7)
    truth_se = (truth.value_ci95[1] - truth.value_ci95[0]) / (2 * 1.96)
    estimates = by_name(estimate_all(data, ExpertPolicy(), gamma, expected_rewards=True))
    for name in ("PDIS", "DR"):
        estimate = estimates[name]
        se = (estimate.ci95[1] - estimate.ci95[0]) / (2 * 1.96)
        assert abs(estimate.value - truth.value) < 4 * math.hypot(se, truth_se), name
    pdis_se = (estimates["PDIS"].ci95[1] - estimates["PDIS"].ci95[0]) / (2 * 1.96)
    assert abs(estimates["WPDIS"].value - truth.value) < 4 * math.hypot(pdis_se, truth_se)
    assert abs(estimates["FQE"].value - truth.value) < 0.25 * abs(truth.value)  # a linear model: close, biased


@pytest.mark.parametrize("epsilon", [True, "0.5", -0.1, 1.5, float("nan")])
def test_a_behaviour_epsilon_must_be_a_number_in_0_1(epsilon: object) -> None:
    """The rule for a number (not a bool, not a string: ``float("0.5")`` would have let one through)."""
    with pytest.raises(ValueError, match=r"epsilon must be a finite number in \[0.0, 1.0\], got"):
        EpsilonGreedy(ExpertPolicy(), epsilon, 4)
