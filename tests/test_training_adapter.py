"""Training with Stable-Baselines3: the VecEnv adapter (HeartPoleSB3VecEnv) as SB3's tools see it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from stable_baselines3.common.monitor import Monitor  # noqa: E402

from heartpole import training  # noqa: E402
from heartpole.model import TIME_ELAPSED, WORK_DONE  # noqa: E402
from heartpole.training import (  # noqa: E402
    SHAPED_REWARD,
    HeartPoleSB3VecEnv,
)

torch.set_num_threads(1)
pytestmark = pytest.mark.filterwarnings("ignore:.*is out of date.*:DeprecationWarning")


def step_episode(venv: HeartPoleSB3VecEnv, actions: np.ndarray, steps: int) -> list[tuple]:
    out = []
    for _ in range(steps):
        venv.step_async(actions)
        out.append(venv.step_wait())
    return out


# ------------------------------------------------------------------------------------------------------
# the adapter


def test_adapter_reports_truncation_terminal_observation_and_episode_statistics() -> None:
    venv = HeartPoleSB3VecEnv(num_envs=3, env_kwargs={"max_steps": 7})
    venv.seed(5)
    obs = venv.reset()
    assert obs.shape == (3, 6) and obs.dtype == np.float32 and (obs[:, TIME_ELAPSED] == 0).all()
    actions = np.array([0, 1, 3])
    results = step_episode(venv, actions, 7)
    for _, rewards, dones, infos in results[:-1]:
        assert rewards.shape == (3,) and not dones.any()
        assert all("terminal_observation" not in info and "episode" not in info for info in infos)
        assert all({"heart_attack", "heart_attack_risk", "productivity", "score"} <= set(info) for info in infos)
    obs, _, dones, infos = results[-1]
    assert dones.all()
    returns = np.sum([r for _, r, _, _ in results], axis=0)
    for i, info in enumerate(infos):
        assert info["TimeLimit.truncated"] is True
        terminal = info["terminal_observation"]
        assert terminal.shape == (6,) and terminal[TIME_ELAPSED] >= 7  # the last state, not the reset one
        episode = info["episode"]
        assert episode["l"] == 7
        assert episode["r"] == pytest.approx(returns[i], abs=1e-4)  # the env's reward, summed
        assert episode["score"] == pytest.approx(terminal[WORK_DONE] / terminal[TIME_ELAPSED], rel=1e-5)
        assert episode["r"] == pytest.approx(episode["score"] - 100 * episode["heart_attacks"], abs=1e-3)
    assert (obs[:, TIME_ELAPSED] == 0).all()  # reset within the step, as SB3 expects
    _, _, dones, infos = step_episode(venv, actions, 1)[0]
    assert not dones.any() and "episode" not in infos[0]


def test_adapter_is_reproducible_from_its_seed() -> None:
    def run(seed: int) -> list[bytes]:
        venv = HeartPoleSB3VecEnv(num_envs=4, reward=SHAPED_REWARD)
        venv.seed(seed)
        frames = [venv.reset().tobytes()]
        actions = np.random.default_rng(0).integers(0, 4, (50, 4))
        for a in actions:
            obs, reward, _, _ = venv.step(a)
            frames += [obs.tobytes(), reward.tobytes()]
        return frames

    assert run(3) == run(3)
    assert run(3) != run(4)


def test_adapter_answers_vecenv_queries() -> None:
    venv = HeartPoleSB3VecEnv(num_envs=2)
    assert venv.get_attr("max_steps") == [1000, 1000]
    assert venv.get_attr("max_steps", indices=1) == [1000]
    assert venv.env_is_wrapped(gym.Wrapper) == [False, False]
    assert venv.env_is_wrapped(Monitor) == [True, True]  # it reports episodes as Monitor does
    assert venv.render_mode is None
    with pytest.raises(IndexError, match="out of range for 2 envs"):
        venv.get_attr("max_steps", indices=[5])
    venv.close()


class _AlwaysCoffee:
    """A stand-in model for SB3's evaluate_policy: drinks coffee in every env."""

    def predict(self, obs, state=None, episode_start=None, deterministic=False):
        return np.ones(len(obs), dtype=np.int64), state


@pytest.mark.parametrize("normalized", [False, True])
def test_sb3_evaluate_policy_sees_the_envs_true_return(normalized: bool) -> None:
    from stable_baselines3.common.evaluation import evaluate_policy

    venv = training.make_vec_env(
        n_envs=4, seed=3, reward=SHAPED_REWARD, env_kwargs={"max_steps": 30}, normalize_rewards=normalized
    )
    returns, lengths = evaluate_policy(_AlwaysCoffee(), venv, n_eval_episodes=8, return_episode_rewards=True)
    assert lengths == [30] * 8
    # the same episodes, stepped by hand: the env's own rewards summed, and the shaped ones
    env = HeartPoleSB3VecEnv(num_envs=4, reward=SHAPED_REWARD, env_kwargs={"max_steps": 30})
    env.seed(3)
    env.reset()
    shaped = np.zeros(4)
    for _ in range(30):
        _, reward, _, infos = env.step(np.ones(4, dtype=np.int64))
        shaped += reward
    true = np.array([info["episode"]["r"] for info in infos])
    assert np.allclose(sorted(returns[:4]), sorted(true))
    assert not np.allclose(sorted(returns[:4]), sorted(shaped))


def test_adapter_env_method_calls_nothing_for_no_indices() -> None:
    venv = HeartPoleSB3VecEnv(num_envs=2)
    venv.reset()
    venv.step(np.array([1, 1]))
    assert venv.env_method("reset", indices=[]) == []
    assert venv.vector_env.unwrapped.state[TIME_ELAPSED].tolist() == [1.0, 1.0]  # not reset: still mid-episode
    assert len(venv.env_method("reset", seed=0, indices=[0, 1])) == 2


@pytest.mark.parametrize("actions", [np.array([0.7, 1.2]), np.array([True, False])], ids=["float", "bool"])
def test_adapter_passes_bad_actions_on_to_the_env_which_rejects_them(actions: np.ndarray) -> None:
    venv = HeartPoleSB3VecEnv(num_envs=2)
    venv.reset()
    before = venv.vector_env.unwrapped.state
    venv.step_async(actions)
    with pytest.raises(ValueError, match="integer array"):
        venv.step_wait()
    np.testing.assert_array_equal(venv.vector_env.unwrapped.state, before)


def test_vecmonitor_and_sb3_logger_read_the_episodes() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    # SB3 warns that the adapter already reports episodes as Monitor does (VecMonitor is not needed)
    with pytest.warns(UserWarning, match="already wrapped with a `Monitor`"):
        venv = VecMonitor(HeartPoleSB3VecEnv(num_envs=2, env_kwargs={"max_steps": 50}))
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(256)  # two rollouts of 64 steps x 2 envs: 128 steps per env, two episodes each
    assert len(model.ep_info_buffer) == 4
    assert all(info["l"] == 50 for info in model.ep_info_buffer)
