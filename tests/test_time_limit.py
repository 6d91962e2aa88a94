"""The env is its own time limit: ``max_steps`` sets the episode length through ``gymnasium.make`` and ``make_vec``,
and ``env.spec.max_episode_steps`` reports it (heartpole.time_limit)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import heartpole
from heartpole.registry import MO_ID, V0_ID, V1_ID


def episode_steps(env: gym.Env, limit: int = 3000) -> int:
    """The number of steps of the episode after ``reset``, up to ``limit``."""
    env.reset(seed=0)
    for step in range(1, limit + 1):
        *_, terminated, truncated, _ = env.step(0)
        if terminated or truncated:
            return step
    return -1


def vector_episode_steps(env: gym.vector.VectorEnv, limit: int = 3000) -> int:
    """The step at which the first episode of every env of ``env`` ends, all at once, up to ``limit``."""
    env.reset(seed=0)
    actions = np.zeros(env.num_envs, dtype=np.int64)
    for step in range(1, limit + 1):
        *_, terminated, truncated, _ = env.step(actions)
        ended = terminated | truncated
        if ended.any():
            return step if ended.all() else -step
    return -1


@pytest.mark.parametrize("env_id", [V0_ID, V1_ID, MO_ID])
def test_the_registered_spec_declares_the_length_as_the_envs_own_max_steps(env_id: str) -> None:
    spec = gym.spec(env_id)
    assert spec.max_episode_steps is None and spec.kwargs["max_steps"] == 1000
    env = gym.make(env_id)
    assert not _time_limits(env)  # no second limit around the env's own
    assert env.spec.max_episode_steps == env.unwrapped.spec.max_episode_steps == env.unwrapped.max_steps == 1000
    env.close()


# (make's keyword arguments, the episode's length, env.spec.max_episode_steps, the env's own max_steps)
CASES = [
    ({"max_steps": 1500}, 1500, 1500, 1500),
    ({"max_steps": 500}, 500, 500, 500),
    ({"max_steps": 1500, "max_episode_steps": 1500}, 1500, 1500, 1500),
    ({"max_episode_steps": 500}, 500, 500, 1000),  # make's TimeLimit shortens the env's 1,000-step episodes
    # make gives max_episode_steps to its TimeLimit only: it cannot lengthen the env's episodes, and Gymnasium's
    # TimeLimit reports its own number as env.spec's (docs/conventions.md); the env's spec says what it does
    ({"max_episode_steps": 1500}, 1000, 1500, 1000),
]


@pytest.mark.parametrize(("kwargs", "length", "spec_steps", "max_steps"), CASES, ids=str)
def test_make_gives_the_length_and_the_spec_reports_it(kwargs: dict, length: int, spec_steps: int, max_steps: int):
    env = gym.make(V0_ID, **kwargs)
    assert episode_steps(env) == length
    assert env.spec.max_episode_steps == spec_steps
    assert env.unwrapped.max_steps == env.unwrapped.spec.max_episode_steps == max_steps
    assert env.unwrapped.spec.kwargs["max_steps"] == max_steps and "max_episode_steps" not in env.unwrapped.spec.kwargs
    env.close()


@pytest.mark.parametrize(("kwargs", "length"), [({"max_steps": 1500}, 1500), ({"max_episode_steps": 500}, 500)])
def test_make_of_the_envs_spec_makes_an_env_of_the_same_length(kwargs: dict, length: int) -> None:
    first = gym.make(V0_ID, **kwargs)
    again = gym.make(gym.envs.registration.EnvSpec.from_json(first.spec.to_json()))  # as Minari stores it
    assert episode_steps(again) == length and again.spec.max_episode_steps == length
    first.close()
    again.close()


def test_a_variants_length_is_its_max_steps_and_make_can_change_it() -> None:
    spec = heartpole.register_variant("LimitPole-v0", max_steps=300, replace=True)
    try:
        assert spec.max_episode_steps is None and spec.kwargs["max_steps"] == 300
        env = gym.make("LimitPole-v0")
        assert episode_steps(env) == 300 and env.spec.max_episode_steps == 300
        longer = gym.make("LimitPole-v0", max_steps=600)
        assert episode_steps(longer) == 600 and longer.spec.max_episode_steps == 600
    finally:
        gym.registry.pop("LimitPole-v0", None)
        heartpole.registry._variants.discard("LimitPole-v0")


def test_the_multi_objective_env_takes_max_steps() -> None:
    env = gym.make(MO_ID, max_steps=1500)
    assert episode_steps(env) == 1500 and env.spec.max_episode_steps == env.unwrapped.max_steps == 1500
    mo_gym = pytest.importorskip("mo_gymnasium")
    assert episode_steps(mo_gym.make(MO_ID, max_steps=1200)) == 1200


@pytest.mark.parametrize("mode", ["sync", "vector_entry_point"])
def test_make_vec_gives_the_length(mode: str) -> None:
    env = gym.make_vec(V0_ID, num_envs=2, vectorization_mode=mode, max_steps=1500)
    assert vector_episode_steps(env) == 1500
    single = env.unwrapped.envs[0] if mode == "sync" else env.unwrapped
    assert single.spec.max_episode_steps == 1500
    env.close()


def test_a_time_limit_shortens_the_vector_envs_episodes_and_cannot_lengthen_them() -> None:
    env = gym.make_vec(V0_ID, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=500)
    assert vector_episode_steps(env) == 500 and env.spec.max_episode_steps == 500
    again = gym.make_vec(env.spec)  # its spec says max_steps=500
    assert vector_episode_steps(again) == 500
    with pytest.raises(ValueError, match=r"max_episode_steps=1500 is above max_steps=1000.*with max_steps=1500"):
        gym.make_vec(V0_ID, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=1500)


def test_the_env_built_directly_takes_a_time_limit_that_shortens_it() -> None:
    assert episode_steps(heartpole.HeartPole(max_episode_steps=7)) == 7
    assert episode_steps(heartpole.HeartPole(max_steps=9, max_episode_steps=5)) == 5
    with pytest.raises(ValueError, match=r"max_episode_steps=9 is above max_steps=5"):
        heartpole.HeartPole(max_steps=5, max_episode_steps=9)


@pytest.mark.parametrize("value", ["5", 0, True, 2.5])
def test_a_bad_time_limit_is_refused_by_its_name(value: object) -> None:
    for kwargs in ({}, {"max_steps": 9}):
        with pytest.raises(ValueError, match=rf"^max_episode_steps must be an integer in \[1, .*got {value!r}"):
            heartpole.HeartPole(max_episode_steps=value, **kwargs)


def _time_limits(env: gym.Env) -> list[int]:
    limits = []
    while isinstance(env, gym.Wrapper):
        if isinstance(env, gym.wrappers.TimeLimit):
            limits.append(env._max_episode_steps)
        env = env.env
    return limits


def test_a_spec_taken_from_an_env_keeps_its_time_limit_as_docs_conventions_says() -> None:
    """docs/conventions.md: a taken spec has ``max_episode_steps``, so a longer ``max_steps`` alone ends at the spec's
    length (Gymnasium's ``TimeLimit``); with ``max_episode_steps`` too, or from the id, the episodes are longer."""
    spec = gym.make(V0_ID, max_steps=30).spec
    assert episode_steps(gym.make(spec, max_steps=60)) == 30
    assert episode_steps(gym.make(spec, max_steps=60, max_episode_steps=60)) == 60
    assert episode_steps(gym.make(spec.id, max_steps=60)) == 60
    assert vector_episode_steps(gym.make_vec(spec, 2, max_steps=60, max_episode_steps=60)) == 60


def test_the_optimum_check_s_progress_counts_the_steps_the_episodes_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """A variant's max_steps, and a max_episode_steps below max_steps, are the length: the bar counted 1,000 a
    variant's episode and max_steps where max_episode_steps shortened it."""
    import argparse

    from heartpole import progress
    from heartpole.cli import optimum

    totals: list[int] = []
    real = progress.progress
    monkeypatch.setattr(progress, "progress", lambda total, text: (totals.append(total), real(total, text))[1])
    heartpole.register_variant("CheckPole-v0", heartpole.V0_ACTIONS, max_steps=20, replace=True)
    args = argparse.Namespace(env="CheckPole-v0", check=2, seed=0)
    optimum._check(args, {}, ("expert",))
    optimum._check(
        argparse.Namespace(env=V0_ID, check=2, seed=0), {"max_steps": 30, "max_episode_steps": 10}, ("expert",)
    )
    assert totals == [2 * 20, 2 * 10]
