"""The one loop over whole episodes: the env it makes, the steps it yields, the actions it checks."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

import heartpole  # noqa: F401  (registers the envs)
from heartpole.policies import load_policy
from heartpole.rollout import base_env, check_actions, episode_steps, policy_actions, vector_env


def test_the_steps_are_the_envs_own_bit_for_bit() -> None:
    import gymnasium as gym

    expert = load_policy("expert", "HeartPole-v0")
    with vector_env("HeartPole-v0", {"max_steps": 30}, 5) as env:
        steps = list(episode_steps(env, 11, policy_actions(expert, "expert", env)))
    assert [step.t for step in steps] == list(range(30))
    manual = gym.make_vec("HeartPole-v0", num_envs=5, vectorization_mode="vector_entry_point", max_steps=30)
    obs, _ = manual.reset(seed=11)
    for step in steps:
        obs, reward, _, truncated, info = manual.step(expert(obs))
        assert np.array_equal(obs, step.observations) and np.array_equal(reward, step.rewards)
        assert np.array_equal(info["heart_attack_risk"], step.info["heart_attack_risk"])
    assert truncated.all()
    manual.close()


def test_a_policy_that_needs_it_is_told_the_decisions_left() -> None:
    seen: list[np.ndarray] = []

    def counting(obs: np.ndarray, decisions_left: np.ndarray) -> np.ndarray:
        seen.append(decisions_left.copy())
        return np.zeros(len(obs), dtype=np.int64)

    counting.needs_decisions_left = True  # type: ignore[attr-defined]
    with vector_env("HeartPole-v0", {"max_steps": 4}, 3) as env:
        for _ in episode_steps(env, 0, policy_actions(counting, "counting", env)):
            pass
    assert [left.tolist() for left in seen] == [[4] * 3, [3] * 3, [2] * 3, [1] * 3]


def test_bad_envs_are_refused_with_what_went_wrong() -> None:
    with pytest.raises(ValueError, match="cannot make a vector env for 'NoSuchPole-v0'"):
        with vector_env("NoSuchPole-v0", {}, 2):
            pass
    with pytest.raises(ValueError, match="'CartPole-v1' is not a HeartPole env"):
        with vector_env("CartPole-v1", {}, 2):
            pass


class NeverEnding:
    """A vector env whose episodes do not end when its ``max_steps`` says."""

    num_envs = 2

    def __init__(self) -> None:
        self.unwrapped = SimpleNamespace(max_steps=3)

    def reset(self, seed: int) -> tuple[np.ndarray, dict[str, Any]]:
        return np.zeros((2, 1)), {}

    def step(self, actions: np.ndarray) -> tuple[Any, ...]:
        return np.zeros((2, 1)), np.zeros(2), np.zeros(2, bool), np.array([True, False]), {}


def test_episodes_that_do_not_end_are_an_error_after_the_last_step() -> None:
    steps = episode_steps(NeverEnding(), 0, lambda obs, t: np.zeros(2, dtype=np.intp))  # type: ignore[arg-type]
    assert [next(steps).t for _ in range(3)] == [0, 1, 2]
    with pytest.raises(RuntimeError, match="did not end after max_steps=3 steps"):
        next(steps)


@pytest.mark.parametrize(
    ("actions", "message"),
    [
        (np.zeros(3, dtype=np.int64), r"returned shape \(3,\) for 2 observations; expected 2 integer actions in 0..3"),
        (np.zeros(2), "returned float64 actions"),
        (np.array([0, 4]), "returned actions 0..4"),
        (np.array([-1, 0]), "returned actions -1..0"),
    ],
)
def test_actions_are_checked(actions: np.ndarray, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        check_actions(actions, 2, 4, "mine")
    assert check_actions(np.array([0, 3], dtype=np.int32), 2, 4, "mine").dtype == np.intp


def test_the_base_env_is_under_the_wrappers() -> None:
    with vector_env("HeartPole-v0", {"max_steps": 2}, 1) as env:
        assert base_env(env).max_steps == 2
