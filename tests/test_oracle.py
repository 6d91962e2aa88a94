"""heartpole.policies.oracle: the policy that knows each episode's person and acts optimally for them."""

from __future__ import annotations

import numpy as np
import pytest

from heartpole.optimum import PeopleOptimum, solve_people
from heartpole.people import People, Uniform
from heartpole.policies import (
    BUILTIN_POLICIES,
    OptimalPolicy,
    OraclePolicy,
    act_batch,
    available_builtins,
    load_policy,
    make_policy,
    oracle_policy,
)
from tests.people_cohorts import TRIO

pytestmark = pytest.mark.slow  # a cohort of people solved and their loop compiled: minutes in all


@pytest.fixture(scope="module")
def trio() -> PeopleOptimum:
    return solve_people(TRIO)


def _observations(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    obs = np.zeros((n, 6), dtype=np.float32)
    obs[:, 0] = rng.uniform(-0.5, 2.0, n)  # alertness
    obs[:, 3] = rng.integers(0, 60, n)  # time since slept
    left = rng.integers(1, 1001, n)
    done = 1000 - left
    obs[:, 4] = done + 16 * np.round(done / 17 + rng.integers(-2, 3, n))  # time elapsed: about a sleep a day
    obs[:, 5] = done * rng.uniform(0.6, 0.7, n)  # work done (the optimum reads both)
    return obs, left, rng.integers(0, len(TRIO.cohort), n)


def test_the_oracle_acts_as_each_persons_optimal_policy(trio: PeopleOptimum) -> None:
    obs, left, person = _observations(30_000)
    oracle = OraclePolicy(None, trio)
    actions = act_batch(oracle, obs, left, person)
    for index, solution in enumerate(trio.solutions):
        mine = person == index
        expected = OptimalPolicy(None, solution)(obs[mine], left[mine])
        np.testing.assert_array_equal(actions[mine], expected)
    assert 0.05 < (actions == 3).mean() < 0.95  # both actions are taken
    # and the people differ: one person's rule for everyone takes other actions
    assert not np.array_equal(actions, act_batch(oracle, obs, left, np.zeros_like(person)))


def test_the_oracle_is_a_builtin_that_needs_the_person(trio: PeopleOptimum) -> None:
    assert BUILTIN_POLICIES["oracle"] is OraclePolicy
    policy = oracle_policy(env_kwargs={"people": TRIO}, optimum=trio)
    assert policy.name == "oracle" and policy.needs_person and policy.needs_decisions_left
    obs, left, _ = _observations(5)
    with pytest.raises(ValueError, match="needs each episode's person"):
        act_batch(policy, obs, left)  # a loop without people
    with pytest.raises(ValueError, match="needs the decisions left and each env's person"):
        policy(obs, left)


def test_the_oracle_needs_a_finite_cohort() -> None:
    with pytest.raises(ValueError, match="finite cohort.*was given no people"):
        oracle_policy("HeartPole-v0", {})
    spread = People(sleep_half_hours=Uniform(12, 20))
    with pytest.raises(ValueError, match="finite cohort.*was given a distribution of people"):
        oracle_policy("HeartPole-v0", {"people": spread})
    with pytest.raises(ValueError, match="oracle policy acts optimally for each person of a finite cohort"):
        make_policy("oracle")
    with pytest.raises(ValueError, match="finite cohort"):
        load_policy("oracle")


def test_the_oracle_refuses_a_person_outside_its_cohort(trio: PeopleOptimum) -> None:
    obs, left, _ = _observations(3)
    oracle = OraclePolicy(None, trio)
    with pytest.raises(ValueError, match=r"3 people of its cohort \(indices 0..2\), got person indices -1..-1"):
        oracle(obs, left, person=np.full(3, -1))
    with pytest.raises(ValueError, match="got person indices 0..3"):
        oracle(obs, left, person=np.array([0, 1, 3]))


def test_oracle_is_offered_only_with_a_finite_cohort() -> None:
    assert "oracle" not in available_builtins("HeartPole-v0")
    assert "oracle" not in available_builtins("HeartPole-v0", {"people": People(decay_rate=Uniform(0.93, 0.97))})
    assert available_builtins("HeartPole-v0", {"people": TRIO})[-2:] == ["optimal", "oracle"]


def test_the_jax_oracle_plays_the_numpy_oracles_episodes(trio: PeopleOptimum) -> None:
    """The JAX ``oracle`` calls the NumPy one (the history-aware optimum decides in float64): the same episodes as
    the NumPy evaluator's, but for the few that float32 rounding of the env's ``exp`` moves (as ``optimal``'s)."""
    pytest.importorskip("jax")
    from heartpole.evaluation import evaluate
    from heartpole.jax.evaluation import evaluate as jax_evaluate
    from tests.test_jax_evaluation import same_episodes

    kwargs = {"people": TRIO, "max_steps": 1000}
    numpy = evaluate("oracle", episodes=300, seed=3, env_kwargs=kwargs)
    device = jax_evaluate("oracle", episodes=300, seed=3, env_kwargs=kwargs)
    assert same_episodes(numpy, device) >= 0.99
    assert abs(numpy.oracle_regret - device.oracle_regret) < 1e-4
