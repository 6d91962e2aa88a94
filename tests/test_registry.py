"""Registration: episode lengths and solved bars in every spec, reserved ids, no global filters (the time limit
through make and make_vec: test_time_limit.py)."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import heartpole
from heartpole.registry import BUILTIN_REWARD_THRESHOLDS, env_dynamics, solved_bar


@pytest.fixture
def variant():
    made: list[str] = []

    def define(env_id: str, **kwargs):
        spec = heartpole.register_variant(env_id, **kwargs)
        made.append(env_id)
        return spec

    yield define
    for env_id in made:
        gym.registry.pop(env_id, None)
        heartpole.registry._variants.discard(env_id)


def vec(env_id: str, **kwargs) -> gym.vector.VectorEnv:
    return gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)


def steps_to_truncation(env: gym.Env, limit: int = 100) -> int:
    env.reset(seed=0)
    for step in range(1, limit + 1):
        *_, truncated, _ = env.step(0)
        if truncated:
            return step
    return -1


@pytest.mark.parametrize("env_id", ["HeartPole-v0", "HeartPole-v1"])
def test_builtin_specs_carry_the_episode_length_and_solved_bar(env_id: str) -> None:
    spec = gym.spec(env_id)
    assert spec.kwargs["max_steps"] == 1000 and isinstance(spec.kwargs["max_steps"], int)
    # the written-out thresholds are what solved_bar computes from the dynamics
    computed = solved_bar(env_dynamics(env_id)).reward_threshold
    assert spec.reward_threshold == BUILTIN_REWARD_THRESHOLDS[env_id] == computed
    env = gym.make(env_id)
    assert env.spec.max_episode_steps == env.unwrapped.max_steps == 1000
    env.close()


def test_v0_bar_is_issue_3s() -> None:
    bar = solved_bar(env_dynamics("HeartPole-v0"))
    assert (bar.heart_attacks_at_most, bar.score_at_least) == (1.30, 0.30)
    assert bar.reward_threshold == pytest.approx(0.30 - 100 * 1.30)


def test_variant_spec_takes_its_own_length_and_bar(variant) -> None:
    spec = variant("ShortPole-v0", max_steps=40, heart_attack_proclivity=0.0)
    assert spec.kwargs["max_steps"] == 40
    bar = solved_bar(env_dynamics("ShortPole-v0"))
    assert bar.heart_attacks_at_most == 0.0  # no risk at all: no heart attack is acceptable
    assert spec.reward_threshold == bar.reward_threshold == bar.score_at_least
    env = gym.make("ShortPole-v0")
    assert env.spec.max_episode_steps == env.unwrapped.max_steps == 40
    assert steps_to_truncation(env) == 40
    assert vec("ShortPole-v0").unwrapped.max_steps == 40


def test_variant_without_sleep_has_an_attacks_only_bar(variant) -> None:
    spec = variant("AwakePole-v0", actions=[heartpole.V0_ACTIONS[0], heartpole.V0_ACTIONS[1]])
    bar = solved_bar(env_dynamics("AwakePole-v0"))
    assert bar.score_at_least is None
    assert spec.reward_threshold == pytest.approx(-100 * bar.heart_attacks_at_most)


@pytest.mark.parametrize("kwargs", [{"max_steps": 7}, {"max_episode_steps": 7}])
def test_vector_env_takes_either_name_and_its_spec_agrees(kwargs: dict) -> None:
    env = vec("HeartPole-v0", **kwargs)
    assert env.unwrapped.max_steps == env.spec.max_episode_steps == 7
    env.reset(seed=0)
    for _ in range(6):
        *_, truncated, _ = env.step(np.zeros(2, dtype=np.int64))
        assert not truncated.any()
    assert env.step(np.zeros(2, dtype=np.int64))[3].all()


def test_vector_env_takes_a_time_limit_below_its_length_and_refuses_one_above() -> None:
    assert vec("HeartPole-v0", max_steps=9, max_episode_steps=5).unwrapped.max_steps == 5
    with pytest.raises(ValueError, match="max_episode_steps=9 is above max_steps=5"):
        vec("HeartPole-v0", max_steps=5, max_episode_steps=9)


def test_single_env_takes_either_name_and_refuses_a_time_limit_above_its_length() -> None:
    assert steps_to_truncation(heartpole.HeartPole(max_episode_steps=7)) == 7
    assert steps_to_truncation(heartpole.HeartPoleV1(max_episode_steps=7)) == 7
    with pytest.raises(ValueError, match="max_episode_steps=9 is above max_steps=5"):
        heartpole.HeartPole(max_steps=5, max_episode_steps=9)


def test_make_with_both_names_agrees_everywhere() -> None:
    env = gym.make("HeartPole-v0", max_steps=9, max_episode_steps=9)
    assert env.spec.max_episode_steps == env.unwrapped.max_steps == 9
    assert steps_to_truncation(env) == 9


def test_a_variants_length_is_given_as_max_steps() -> None:
    with pytest.raises(TypeError, match=r"episode length is max_steps .*pass max_steps=40"):
        heartpole.register_variant("LongPole-v0", max_episode_steps=40)
    assert "LongPole-v0" not in gym.registry


@pytest.mark.parametrize("env_id", ["HeartPole-v2", "HeartPole-v10"])
def test_heartpoles_own_names_are_reserved(env_id: str) -> None:
    with pytest.raises(ValueError, match="reserved for HeartPole's own versions"):
        heartpole.register_variant(env_id)
    assert env_id not in gym.registry


def test_import_adds_one_warning_filter_for_the_v0_notice_alone() -> None:
    """``import heartpole`` changes none of the filters there are and adds one: ignore Gymnasium's "HeartPole-v0 is
    out of date" from its registration module."""
    code = (
        "import re, warnings, gymnasium\n"
        "before = list(warnings.filters)\n"
        "import heartpole, heartpole.policies, heartpole.evaluation\n"
        "added = [f for f in warnings.filters if f not in before]\n"
        "assert [f for f in warnings.filters if f in before] == before\n"
        "[(action, message, category, module, line)] = added\n"
        "assert (action, category, module.pattern, line) == ('ignore', DeprecationWarning, "
        "re.escape('gymnasium.envs.registration'), 0), added\n"
        "assert message.match('\\x1b[33mWARN: The environment HeartPole-v0 is out of date.')\n"
        "assert not message.match('\\x1b[33mWARN: The environment CartPole-v0 is out of date.')\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("how", ["gym.make('HeartPole-v0')", "gym.make('heartpole:HeartPole-v0')"])
def test_a_first_make_of_v0_prints_no_warning(how: str) -> None:
    code = f"import gymnasium as gym\nimport heartpole\n{how}.close()\ngym.make('CartPole-v0').close()\n"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "HeartPole" not in done.stderr and "CartPole-v0 is out of date" in done.stderr, done.stderr
