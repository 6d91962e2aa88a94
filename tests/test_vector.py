"""HeartPoleVectorEnv: Gymnasium's vector conventions, autoreset, reproducibility and bad input.

That its dynamics equal the single env's in distribution is tested in test_faithfulness.py.
"""

from __future__ import annotations

import copy
import math
import platform
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import heartpole
from heartpole.vector import uniform_rows


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
    assert not truncated.any() and (reward == 0).all() and not info["heart_attack"].any()
    assert (obs[:, 1:] == 0).all() and ((obs[:, 0] >= 0.7) & (obs[:, 0] <= 1.3)).all()
    assert not info["_score"].any()
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


def test_vector_env_follows_one_env_of_the_single_dynamics_exactly_given_the_same_draws() -> None:
    """One source of truth: feeding the single-state and the batch paths the same uniforms gives the
    same states (up to float32 rounding)."""
    dynamics = heartpole.Dynamics()
    rng = np.random.default_rng(0)
    single = dynamics.initial_state(0.25)
    batch = dynamics.initial_state(np.array([0.25], dtype=np.float32))
    for action in rng.integers(0, 4, 300).tolist():
        uniforms = rng.random(dynamics.num_uniforms)
        dynamics.transition(single, action, uniforms.tolist())
        dynamics.transition(batch, np.array([action]), uniforms[:, None].astype(np.float32))
        np.testing.assert_allclose(batch[:, 0], single, rtol=2e-3, atol=2e-3)


def test_a_batch_of_many_envs_follows_the_single_path_env_by_env() -> None:
    """The batch path looks each env's action up in a table (a matrix product); with every action in one
    batch, each env must still follow the single path given its own draws."""
    dynamics = heartpole.Dynamics()
    rng = np.random.default_rng(1)
    n = 64
    wake = rng.random(n).astype(np.float32)
    batch = dynamics.initial_state(wake)
    singles = [dynamics.initial_state(float(w)) for w in wake]
    for _ in range(200):
        actions = rng.integers(0, 4, n)
        uniforms = rng.random((dynamics.num_uniforms, n)).astype(np.float32)
        reward, *_ = dynamics.transition(batch, actions, uniforms)
        for i, single in enumerate(singles):
            single_reward, *_ = dynamics.transition(single, int(actions[i]), uniforms[:, i].astype(float).tolist())
            assert reward[i] == pytest.approx(single_reward, abs=2e-3)
    np.testing.assert_allclose(batch, np.array(singles).T, rtol=2e-3, atol=2e-3)


def test_uniform_rows_are_uniform_independent_and_reproducible() -> None:
    """2 x 200,000 draws: the mean within 4.5 standard errors of 1/2, the Kolmogorov-Smirnov distance to
    U(0, 1) below its 1e-4 critical value, the rows uncorrelated (|r| < 4.5 / sqrt(n)), all values on
    the 23-bit grid in [0, 1), and the same seed giving the same draws."""
    n = 200_000
    rows = uniform_rows(np.random.default_rng(3), 2, n)
    again = uniform_rows(np.random.default_rng(3), 2, n)
    for row, same in zip(rows, again):
        assert row.dtype == np.float32 and row.shape == (n,)
        np.testing.assert_array_equal(row, same)
        assert 0.0 <= row.min() and row.max() < 1.0
        assert np.all(row * 2**23 == np.floor(row * 2**23))
        assert abs(row.mean() - 0.5) < 4.5 * math.sqrt(1 / 12 / n)
        ordered = np.sort(row.astype(np.float64))
        ks = max(np.max(np.arange(1, n + 1) / n - ordered), np.max(ordered - np.arange(n) / n))
        assert ks < 2.23 / math.sqrt(n)
    assert abs(np.corrcoef(rows[0], rows[1])[0, 1]) < 4.5 / math.sqrt(n)


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


FAULTS_PER_STEP = """
import resource, sys
import numpy as np
import heartpole.vector
if sys.argv[1] == "without":
    heartpole.vector.keep_step_memory = lambda num_bytes: None
env = heartpole.vector.HeartPoleVectorEnv(16384)
env.reset(seed=0)
actions = np.random.default_rng(0).integers(0, 4, size=16384)
for _ in range(5):
    env.step(actions)
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(40):
    env.step(actions)
print((resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 40)
"""


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="about glibc's malloc thresholds")
def test_steps_reuse_freed_memory_instead_of_page_faulting_it_back() -> None:
    # A fresh process: pytest's own process has long raised glibc's thresholds by freeing large arrays.
    # Without keep_step_memory a step at 16,384 envs page-faults about 140 times.
    faults = float(
        subprocess.run(
            [sys.executable, "-c", FAULTS_PER_STEP, "with"], check=True, capture_output=True, text=True
        ).stdout
    )
    assert faults < 20, f"{faults} page faults per step"


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


def test_uniform_rows_from_a_32_bit_bit_generator_are_uniform() -> None:
    # MT19937's raw draws carry 32 random bits: splitting them in two 32-bit halves would give zeros.
    rows = uniform_rows(np.random.Generator(np.random.MT19937(0)), 4, 50_000)
    for row in rows:
        assert row.dtype == np.float32
        assert abs(row.mean() - 0.5) < 5 * math.sqrt(1 / 12 / 50_000)  # 5 standard errors
        assert (row == 0.0).mean() < 0.001
