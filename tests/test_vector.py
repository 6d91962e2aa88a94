"""HeartPoleVectorEnv: Gymnasium's vector conventions, autoreset, reproducibility and bad input.

That its dynamics equal the single env's in distribution is tested in test_faithfulness.py.
"""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import heartpole


def make(num_envs: int = 4, **kwargs) -> heartpole.HeartPoleVectorEnv:
    return gym.make_vec("HeartPole-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def test_batched_spaces_and_shapes() -> None:
    env = make(5, max_steps=20, heart_attack_proclivity=0.2)
    assert env.single_action_space == gym.spaces.Discrete(4)
    assert env.action_space == gym.spaces.MultiDiscrete([4] * 5)
    assert env.observation_space.shape == (5, 6) and env.observation_space.dtype == np.float32
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.dynamics.params.heart_attack_proclivity == 0.2 and env.max_steps == 20
    obs, info = env.reset(seed=0)
    assert obs.shape == (5, 6) and obs.dtype == np.float32 and obs in env.observation_space
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert reward.shape == terminated.shape == truncated.shape == (5,) and reward.dtype == np.float32
    for key in ("heart_attack", "heart_attack_risk", "productivity", "score"):
        assert info[key].shape == (5,) and info["_" + key].all()


def test_reset_seed_reproduces_and_envs_are_independent() -> None:
    actions = np.random.default_rng(0).integers(0, 4, (50, 8))

    def run(seed: int) -> list[bytes]:
        env = make(8)
        out = [env.reset(seed=seed)[0].tobytes()]
        out += [env.step(a)[0].tobytes() for a in actions]
        return out

    assert run(3) == run(3)
    assert run(3) != run(4)
    obs, _ = make(8).reset(seed=3)
    assert len(set(obs[:, 0].tolist())) == 8  # each env wakes up with its own alertness


def test_next_step_autoreset_restarts_an_env_on_the_step_after_truncation() -> None:
    env = make(3, max_steps=3)
    env.reset(seed=1)
    for _ in range(2):
        assert not env.step(np.array([1, 2, 0]))[3].any()
    obs, reward, terminated, truncated, _ = env.step(np.array([1, 2, 0]))
    assert truncated.all() and not terminated.any() and obs[:, 4].min() >= 3
    obs, reward, terminated, truncated, info = env.step(np.array([3, 3, 3]))  # actions ignored
    assert not truncated.any() and (reward == 0).all() and info == {}  # as reset() gives
    assert (obs[:, 1:] == 0).all() and ((obs[:, 0] >= 0.7) & (obs[:, 0] <= 1.3)).all()
    obs, *_ = env.step(np.array([0, 0, 0]))
    assert (obs[:, 4] == 1).all()


def test_same_step_autoreset_reports_the_final_observation() -> None:
    env = heartpole.HeartPoleVectorEnv(2, max_steps=2, autoreset_mode=AutoresetMode.SAME_STEP)
    assert env.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    env.reset(seed=2)
    env.step(np.array([0, 0]))
    obs, _, _, truncated, info = env.step(np.array([0, 1]))
    assert truncated.all() and info["_final_obs"].all()
    assert (info["final_obs"][:, 4] == 2).all()  # two half-hours worked
    assert (obs[:, 4] == 0).all()  # already the next episode
    assert info["final_info"]["score"].shape == (2,)
    np.testing.assert_array_equal(info["final_info"]["action"], [0, 1])


def test_info_has_the_single_envs_keys_with_action_indices() -> None:
    env = make(3)
    env.reset(seed=0)
    info = env.step(np.array([2, 0, 3]))[4]
    single = heartpole.HeartPole()
    single.reset(seed=0)
    assert {k for k in info if not k.startswith("_")} == set(single.step(2)[4])
    np.testing.assert_array_equal(info["action"], [2, 0, 3])
    assert all(info["_" + k].all() for k in info if not k.startswith("_"))


BAD_ACTIONS = [
    (np.array([0, 1, 2]), "shape"),
    (np.array([[0, 1, 2, 3]]), "shape"),
    (np.array([0.0, 1.0, 2.0, 3.0]), "dtype"),
    (np.array([0, 1, 2, 4]), "values"),
    (np.array([0, -1, 2, 3]), "values"),
    (["a", "b", "c", "d"], "dtype"),
    (3, "shape"),
]


@pytest.mark.parametrize("actions, what", BAD_ACTIONS, ids=[w + str(i) for i, (_, w) in enumerate(BAD_ACTIONS)])
def test_bad_action_batches_raise_and_change_nothing(actions, what: str) -> None:
    env = make(4)
    env.reset(seed=5)
    env.step(np.array([1, 1, 2, 3]))
    untouched = copy.deepcopy(env)
    with pytest.raises(ValueError, match=f"integer array of shape \\(4,\\) with values in 0..3; got {what}"):
        env.step(actions)
    np.testing.assert_array_equal(env.state, untouched.state)
    good = np.array([0, 1, 2, 3])
    assert env.step(good)[0].tobytes() == untouched.step(good)[0].tobytes()


def test_step_before_reset_and_bad_construction() -> None:
    with pytest.raises(gym.error.ResetNeeded):
        heartpole.HeartPoleVectorEnv(2).step(np.array([0, 0]))
    with pytest.raises(ValueError, match="num_envs"):
        heartpole.HeartPoleVectorEnv(0)
    with pytest.raises(ValueError, match="autoreset_mode"):
        heartpole.HeartPoleVectorEnv(2, autoreset_mode=AutoresetMode.DISABLED)
    with pytest.raises(ValueError, match="max_steps"):
        heartpole.HeartPoleVectorEnv(2, max_steps=0)


def test_observations_are_copies_in_cartpoles_column_major_layout() -> None:
    env = make(5)
    obs, _ = env.reset(seed=0)
    for _ in range(2):
        np.testing.assert_array_equal(obs, env.state.T)
        assert obs.shape == (5, 6) and obs.dtype == np.float32 and obs.flags.f_contiguous
        assert env.observation_space.contains(obs)
        obs[:] = 99.0  # the caller owns its observations
        assert not np.any(env.state == 99.0)
        obs = env.step(np.array([0, 1, 2, 3, 1]))[0]


def test_step_and_reset_leave_the_callers_actions_and_returned_info_alone() -> None:
    env = make(4, max_steps=3, render_mode="rgb_array", heart_attack_proclivity=1.0)
    always_sleep = np.full(4, 3, dtype=np.intp)  # the dtype the env works in: no conversion copies it
    infos = []
    for episode in range(2):
        env.reset(seed=episode)
        for _ in range(3):
            infos.append(env.step(always_sleep)[4])
    assert always_sleep.tolist() == [3, 3, 3, 3]
    kept = [info["heart_attack"].copy() for info in infos]
    env.reset(seed=5)
    assert all((info["heart_attack"] == k).all() for info, k in zip(infos, kept))
    env.step(always_sleep)
    always_sleep[:] = 9  # the caller reuses its array; the env's frames must not read it
    assert len(env.render()) == 4


def test_same_step_autoreset_forgets_the_ended_episode_for_rendering(monkeypatch) -> None:
    drawn = []
    monkeypatch.setattr(heartpole.vector.rendering, "draw_frame", lambda state, **kw: drawn.append(kw))
    env = heartpole.HeartPoleVectorEnv(
        1, max_steps=2, render_mode="rgb_array", autoreset_mode=AutoresetMode.SAME_STEP, heart_attack_proclivity=1.0
    )
    env.reset(seed=0)
    env.step(np.array([2]))
    env.render()
    assert drawn[-1]["action"] == "drink_beer" and drawn[-1]["step"] == 1
    *_, truncated, _ = env.step(np.array([2]))  # ends the episode; the env restarts within the step
    assert truncated[0]
    env.render()
    assert drawn[-1] == {**drawn[-1], "action": None, "heart_attack": False, "heart_attacks": 0, "step": 0}
