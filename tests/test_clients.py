"""The client matrix: HeartPole, unmodified, in the libraries users plug it into, each used as its own docs show.

Gymnasium (its env checker, every vectorization mode in every autoreset mode, common wrappers),
Stable-Baselines3 (its env checker, ``make_vec_env``, a short PPO run), RL Zoo3 (its train and enjoy entry
points), TorchRL (``GymEnv`` and ``GymWrapper`` with ``check_env_specs`` and rollouts), Minari
(``DataCollector`` with infos, ``recover_environment``) and d3rlpy (``get_minari``, an offline learner,
``EnvironmentEvaluator``). Every run is tiny: these tests check that the pieces
fit, not that anything learns. The clients come with HeartPole's ``test`` extra; each is imported inside its
tests, so the default suite, which deselects these slow tests, never loads them.

Processes that a client starts (an async vector env, ``SubprocVecEnv``, TorchRL's ``num_envs``) are new
Python processes that never imported ``heartpole``: there the env is named ``"heartpole:HeartPole-v0"``,
Gymnasium's form that imports the module first, as users must name it too.
"""

from __future__ import annotations

import csv
import multiprocessing
import os
import subprocess
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import heartpole
from heartpole.model import TIME_ELAPSED, TIME_SINCE_SLEPT, WORK_DONE

pytestmark = pytest.mark.slow
ID = "HeartPole-v0"
IMPORTING_ID = "heartpole:HeartPole-v0"  # for processes that have not imported heartpole
MODES = ("sync", "async", "vector_entry_point")
AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)
EPISODE = 3  # the vector runs' episode length: several episode ends in a few steps


def make_vec(
    mode: str, autoreset_mode: AutoresetMode, num_envs: int = 3, length: int = EPISODE
) -> gym.vector.VectorEnv:
    """``gymnasium.make_vec`` as Gymnasium documents it for ``mode``: the autoreset mode goes to the vectorizer
    (``vector_kwargs``) in sync and async mode, to the env itself in vector_entry_point mode.

    Async workers are spawned, the strictest start method (the default on macOS and Windows): everything
    must pickle and import in a fresh process.
    """
    if mode == "vector_entry_point":
        return gym.make_vec(ID, num_envs, vectorization_mode=mode, autoreset_mode=autoreset_mode, max_steps=length)
    vector_kwargs: dict[str, Any] = {"autoreset_mode": autoreset_mode}
    if mode == "async":
        vector_kwargs["context"] = "spawn"
    return gym.make_vec(
        ID, num_envs, vectorization_mode=mode, vector_kwargs=vector_kwargs, max_steps=length, max_episode_steps=length
    )


# ------------------------------------------------------------------------------------------------ Gymnasium
@pytest.mark.parametrize("env_id", [ID, "HeartPole-v1"])
@pytest.mark.parametrize("render_mode", [None, "ansi", "rgb_array"])
def test_gymnasium_env_checker_passes_without_warnings(env_id: str, render_mode: str | None) -> None:
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", r".*The environment HeartPole-v0 is out of date", DeprecationWarning)
        check_env(gym.make(env_id, render_mode=render_mode).unwrapped)


def describe(info: dict[str, Any]) -> dict[str, Any]:
    """What a client can rely on in a vector env's ``info``: every key, the masks, each array's kind of values
    (integer, float, bool, object) and, where its mask is set, the values of an integer array (action
    indices, episode lengths); never the random numbers, nor values where the mask is unset (unspecified)."""
    out: dict[str, Any] = {}
    for key, value in sorted(info.items()):
        mask = np.asarray(info.get("_" + key, []), dtype=bool)
        if isinstance(value, dict):
            out[key] = describe(value)
        elif key == "final_obs":  # an object array in sync and async mode
            out[key] = [np.asarray(value[i])[[TIME_SINCE_SLEPT, TIME_ELAPSED]].tolist() for i in np.flatnonzero(mask)]
        else:
            array = np.asarray(value)
            values = None
            if key.startswith("_"):
                values = array.tolist()
            elif array.dtype.kind in "iu":
                values = array[mask].tolist() if mask.shape == array.shape else array.tolist()
            out[key] = (array.dtype.kind, values)
    return out


def drive(env: gym.vector.VectorEnv, autoreset_mode: AutoresetMode, steps: int = 3 * EPISODE + 2) -> list[Any]:
    """Step ``env`` across several episode ends as Gymnasium prescribes for ``autoreset_mode``, with fixed
    actions (sleep included), and return the trace: each call's clock columns (time since slept and time
    elapsed: set by the actions alone), dones and :func:`describe` of its info.

    In DISABLED mode the caller resets ended envs with ``options={"reset_mask": ...}``; env 0 is also
    restarted after the first step, so that its episodes end a step after the others'.
    """
    obs, info = env.reset(seed=0)
    trace: list[Any] = [("reset", obs[:, [TIME_SINCE_SLEPT, TIME_ELAPSED]].tolist(), describe(info))]
    for t in range(steps):
        actions = (np.arange(env.num_envs) + t) % 4
        obs, _, terminated, truncated, info = env.step(actions)
        clock = obs[:, [TIME_SINCE_SLEPT, TIME_ELAPSED]].tolist()
        trace.append(("step", clock, terminated.tolist(), truncated.tolist(), describe(info)))
        if autoreset_mode == AutoresetMode.DISABLED:
            done = terminated | truncated
            done[0] |= t == 0
            if done.any():
                obs, info = env.reset(options={"reset_mask": done})
                trace.append(
                    ("reset", done.tolist(), obs[:, [TIME_SINCE_SLEPT, TIME_ELAPSED]].tolist(), describe(info))
                )
    return trace


@pytest.mark.parametrize("autoreset_mode", AUTORESET_MODES, ids=lambda m: m.name)
def test_every_vectorization_mode_behaves_as_gymnasiums_own_sync_vector_env(autoreset_mode: AutoresetMode) -> None:
    """Async mode and HeartPole's native vector env against Gymnasium's SyncVectorEnv over the single env: the
    same dones, clocks, info keys, masks and kinds of values, inside Gymnasium's RecordEpisodeStatistics.

    Not in DISABLED mode: there Gymnasium 1.4's own vectorizers take ``reset_mask`` out of the caller's
    ``options`` before RecordEpisodeStatistics looks for it, which then restarts every env's statistics.
    """
    wrapped = autoreset_mode != AutoresetMode.DISABLED
    traces = {}
    for mode in MODES:
        env = make_vec(mode, autoreset_mode)
        if wrapped:
            env = gym.wrappers.vector.RecordEpisodeStatistics(env)
        traces[mode] = drive(env, autoreset_mode)
        env.close()
    reference = traces["sync"]
    ends = [entry for entry in reference if entry[0] == "step" and any(entry[3])]
    assert len(ends) >= 3, "the run must cross several episode ends"
    if wrapped:
        assert all(entry[4]["episode"]["l"][1] == [EPISODE if done else 0 for done in entry[3]] for entry in ends)
    if autoreset_mode == AutoresetMode.SAME_STEP:
        assert all(entry[4]["_final_obs"][1] == entry[3] for entry in ends)
    for mode in ("async", "vector_entry_point"):
        assert len(traces[mode]) == len(reference), f"{mode}: {len(traces[mode])} calls, sync: {len(reference)}"
        for call, (got, expected) in enumerate(zip(traces[mode], reference)):
            assert got == expected, f"{mode} differs from sync at call {call}:\n{mode}: {got}\nsync: {expected}"


def test_gymnasium_wrappers_record_video_and_episode_statistics(tmp_path: Path) -> None:
    env = gym.make(ID, render_mode="rgb_array", max_steps=10, max_episode_steps=10)
    videos = tmp_path / "videos"
    env = gym.wrappers.RecordVideo(env, str(videos), episode_trigger=lambda episode: episode == 0, disable_logger=True)
    env = gym.wrappers.RecordEpisodeStatistics(env)
    env = gym.wrappers.NormalizeObservation(env)
    env.action_space.seed(0)
    for episode in range(2):
        env.reset(seed=episode)
        rewards = []
        while True:
            _, reward, terminated, truncated, info = env.step(env.action_space.sample())
            rewards.append(reward)
            if terminated or truncated:
                break
        assert info["episode"]["l"] == 10 and info["episode"]["r"] == pytest.approx(sum(rewards), abs=1e-5)
    env.close()
    assert [path.suffix for path in videos.iterdir()] == [".mp4"]


# ------------------------------------------------------------------------------------------ Stable-Baselines3
def test_stable_baselines3_checker_make_vec_env_and_ppo(tmp_path: Path) -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import SubprocVecEnv

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", r".*The environment HeartPole-v0 is out of date", DeprecationWarning)
        for env_id in (ID, "HeartPole-v1"):
            check_env(gym.make(env_id))
    length = 64
    lengths = {"max_steps": length, "max_episode_steps": length}
    for env_id, vec_env_cls in ((ID, None), (IMPORTING_ID, SubprocVecEnv)):
        venv = make_vec_env(env_id, n_envs=2, seed=0, env_kwargs=lengths, vec_env_cls=vec_env_cls)
        model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
        model.learn(total_timesteps=256)
        assert [episode["l"] for episode in model.ep_info_buffer] == [length] * 4  # two envs, two episodes each
        venv.close()
    model.save(tmp_path / "model")
    loaded = PPO.load(tmp_path / "model", device="cpu")
    episode_rewards, episode_lengths = evaluate_policy(
        loaded, make_vec_env(ID, n_envs=2, seed=1, env_kwargs=lengths), n_eval_episodes=4, return_episode_rewards=True
    )
    assert episode_lengths == [length] * 4 and np.isfinite(episode_rewards).all()


# ------------------------------------------------------------------------------------------------- RL Zoo3
def test_rl_zoo3_trains_and_enjoys_heartpole_from_its_command_line(tmp_path: Path) -> None:
    """``python -m rl_zoo3.train`` with ``--gym-packages heartpole``: PPO with the Zoo's default
    hyperparameters (HeartPole has no entry of its own in its hyperparams/ppo.yml), a smaller rollout, and
    its evaluation callback; then ``python -m rl_zoo3.enjoy`` runs the saved agent for an episode."""
    from stable_baselines3 import PPO

    zoo = ["--algo", "ppo", "--env", ID, "--gym-packages", "heartpole", "-f", str(tmp_path), "--seed", "0"]
    train = [*zoo, "-n", "2048", "--eval-freq", "1024", "--eval-episodes", "1", "--device", "cpu"]
    train += ["-params", "n_steps:512", "batch_size:128", "n_epochs:1"]
    run_zoo("rl_zoo3.train", train)
    run = tmp_path / "ppo" / f"{ID}_1"
    assert PPO.load(run / f"{ID}.zip", device="cpu").num_timesteps == 2048
    with open(run / "0.monitor.csv") as file:
        next(file)  # Monitor's JSON header line
        assert [int(row["l"]) for row in csv.DictReader(file)] == [1000, 1000]
    assert np.load(run / "evaluations.npz")["ep_lengths"].tolist() == [[1000], [1000]]
    enjoyed = run_zoo("rl_zoo3.enjoy", [*zoo, "-n", "1000", "--no-render", "--device", "cpu"])
    assert "Episode Length 1000" in enjoyed


def run_zoo(module: str, args: list[str]) -> str:
    """Run ``python -m module args``; its output, or a failure showing the end of its output."""
    result = subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, f"{module} failed:\n{result.stdout[-2000:]}\n{result.stderr[-4000:]}"
    return result.stdout


# ------------------------------------------------------------------------------------------------- TorchRL
@pytest.fixture(scope="module")
def torchrl_envs() -> Iterator[Any]:
    """``torchrl.envs``. Importing TorchRL sets multiprocessing's start method to spawn for the whole process:
    so it is for these tests, and the tests after this module get back the start method they had."""
    before = multiprocessing.get_start_method(allow_none=True)
    import torchrl.envs

    yield torchrl.envs
    multiprocessing.set_start_method(before, force=True)


def test_torchrl_gym_env_single(torchrl_envs: Any) -> None:
    """TorchRL passes ``frameskip`` to every env and drops it on Python's TypeError for an unexpected keyword."""
    import torch
    from torchrl.envs.utils import check_env_specs

    env = torchrl_envs.GymEnv(ID)
    assert isinstance(env._env.unwrapped, heartpole.HeartPole)
    check_env_specs(env)
    rollout = env.rollout(50)
    assert rollout.batch_size == (50,) and rollout["next", "observation"].shape == (50, 6)
    assert (rollout["next", "observation"][:, TIME_ELAPSED] >= torch.arange(1, 51)).all()
    env.close()


def test_torchrl_gym_env_num_envs(torchrl_envs: Any) -> None:
    """TorchRL runs ``num_envs`` copies in Gymnasium's AsyncVectorEnv in its default NEXT_STEP autoreset mode.

    TorchRL 0.14 then shows the episode-ending step's next observation as zeros (CartPole-v1's too), so the
    rollout is checked for its dones, the fresh episodes after them and the env's infos.
    """
    from torchrl.envs.utils import check_env_specs

    length = 4
    env = torchrl_envs.GymEnv(IMPORTING_ID, num_envs=4, max_steps=length, max_episode_steps=length)
    check_env_specs(env)
    rollout = env.rollout(3 * length, break_when_any_done=False)
    assert rollout.batch_size == (4, 3 * length) and rollout["next", "observation"].shape == (4, 3 * length, 6)
    truncated = rollout["next", "truncated"].squeeze(-1)
    ends = [length - 1, 2 * length - 1, 3 * length - 1]
    assert truncated[:, ends].all() and truncated.sum() == 4 * len(ends)
    assert (rollout["observation"][:, [length, 2 * length], 1:] == 0).all()  # fresh: awake, everything else 0
    assert set(single_step_info()) <= set(rollout["next"].keys())
    env.close()


@pytest.mark.parametrize("mode", MODES)
def test_torchrl_gym_wrapper_over_a_same_step_vector_env_keeps_infos(torchrl_envs: Any, mode: str) -> None:
    """A rollout crossing two episode ends: the step that ends an episode shows its last observation and
    infos, the next step starts afresh, and the env's infos reach the rollout."""
    import torch
    from torchrl.envs.utils import check_env_specs

    length = 5
    env = torchrl_envs.GymWrapper(make_vec(mode, AutoresetMode.SAME_STEP, length=length))
    check_env_specs(env)
    rollout = env.rollout(2 * length + 2, break_when_any_done=False)
    assert rollout.batch_size == (3, 2 * length + 2)
    truncated = rollout["next", "truncated"].squeeze(-1)
    ends = [length - 1, 2 * length - 1]
    assert truncated[:, ends].all() and truncated.sum() == 3 * len(ends)
    assert (rollout["next", "observation"][:, ends, TIME_ELAPSED] >= length).all()  # the ended episodes' last states
    assert (rollout["observation"][:, [length, 2 * length], TIME_ELAPSED] == 0).all()  # the next episodes' first
    step_keys = set(single_step_info())
    assert step_keys <= set(rollout["next"].keys()), f"infos lost: {sorted(step_keys - set(rollout['next'].keys()))}"
    observation = rollout["next", "observation"]
    torch.testing.assert_close(
        rollout["next", "score"].reshape(observation.shape[:2]).float(),
        observation[..., WORK_DONE] / observation[..., TIME_ELAPSED],
        rtol=1e-5,
        atol=1e-6,
    )
    env.close()


def single_step_info() -> dict[str, Any]:
    """The info of one step of a fresh single env."""
    env = gym.make(ID)
    env.reset(seed=0)
    return env.step(0)[4]


# -------------------------------------------------------------------------------------------------- Minari
def test_minari_data_collector_records_infos_and_recovers_the_env(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    import minari
    from minari import DataCollector

    length, episodes = 20, 3
    env = DataCollector(gym.make(ID, max_steps=length, max_episode_steps=length), record_infos=True)
    env.action_space.seed(0)
    for seed in range(episodes):
        env.reset(seed=seed)
        while not any(env.step(env.action_space.sample())[2:4]):
            pass
    env.create_dataset(
        "heartpole/v0/datacollector-v0",
        eval_env=gym.make(ID, max_steps=2 * length, max_episode_steps=2 * length),
        description=f"{episodes} episodes of {length} uniformly random actions, recorded by HeartPole's tests",
        algorithm_name="uniformly random",
        author="HeartPole's tests",
        author_email="tests@example.org",
        code_permalink="https://example.org/heartpole",
    )
    env.close()
    dataset = minari.load_dataset("heartpole/v0/datacollector-v0")
    assert dataset.total_episodes == episodes and dataset.total_steps == episodes * length
    keys = set(single_step_info())
    for episode in dataset.iterate_episodes():
        assert set(episode.infos) == keys
        assert all(len(values) == length + 1 and values.dtype.kind in "biuf" for values in episode.infos.values())
        observations = episode.observations
        np.testing.assert_allclose(
            episode.infos["score"][1:], observations[1:, WORK_DONE] / observations[1:, TIME_ELAPSED], rtol=1e-5
        )
    for eval_env, episode_length in ((False, length), (True, 2 * length)):
        recovered = dataset.recover_environment(eval_env=eval_env)
        assert recovered.spec is not None and recovered.spec.id == ID
        recovered.reset(seed=0)
        steps = 1
        while not any(recovered.step(0)[2:4]):
            steps += 1
        assert steps == episode_length
        recovered.close()


def test_a_heartpole_people_dataset_recovers_its_env_in_minari(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The command line's dataset, as Minari's docs load it: its env is the one it was recorded on (the 24
    people, their traits observed), with the data's spaces, for ``recover_environment`` and ``eval_env``. This
    is what d3rlpy's ``get_minari`` and ``EnvironmentEvaluator`` rely on (and the next test runs them)."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    command = [sys.executable, "-m", "heartpole", "dataset", "--policy", "expert", "--epsilon", "0.1", "--episodes",
               "5", "--people", "default", "--observe-traits"]  # fmt: skip
    subprocess.run(command, check=True, capture_output=True)
    import minari

    dataset = minari.load_dataset("heartpole/v0/expert-eps10-people-default-traits-v0")
    observations = next(dataset.iterate_episodes()).observations
    assert dataset.observation_space.shape == observations.shape[1:] == (11,)
    assert dataset.spec.env_spec is not None and dataset.spec.env_spec.kwargs["observe_traits"] is True
    for eval_env in (False, True):
        env = dataset.recover_environment(eval_env=eval_env)
        assert env.observation_space == dataset.observation_space
        assert len(env.unwrapped.people.cohort) == 24
        obs, _ = env.reset(seed=0)
        weights = np.ones((observations.shape[1], 4))  # a learner's first layer, shaped by the data
        action = int(np.argmax(obs @ weights))
        env.step(action)
        env.close()


def test_d3rlpy_trains_and_evaluates_on_a_people_dataset_with_traits(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The issue's d3rlpy case, as d3rlpy's docs use a Minari dataset: ``get_minari`` (which recovers the env),
    a discrete offline learner (CQL) and ``EnvironmentEvaluator`` on the recovered env. On a dataset without its
    env this crashed with ``mat1 and mat2 shapes cannot be multiplied (1x6 and 11x256)``."""
    d3rlpy = pytest.importorskip("d3rlpy")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    command = [sys.executable, "-m", "heartpole", "dataset", "--policy", "expert", "--epsilon", "0.1", "--episodes",
               "3", "--people", "default", "--observe-traits"]  # fmt: skip
    subprocess.run(command, check=True, capture_output=True)
    dataset, env = d3rlpy.datasets.get_minari("heartpole/v0/expert-eps10-people-default-traits-v0")
    assert env.observation_space.shape == dataset.episodes[0].observations.shape[1:] == (11,)
    learner = d3rlpy.algos.DiscreteCQLConfig(batch_size=32).create(device="cpu:0")
    evaluator = d3rlpy.metrics.EnvironmentEvaluator(env, n_trials=1)
    learner.fit(dataset, n_steps=20, n_steps_per_epoch=20, evaluators={"environment": evaluator},
                show_progress=False, save_interval=1000, experiment_name=str(tmp_path / "d3rlpy"))  # fmt: skip
    assert np.isfinite(evaluator(learner, dataset))


# ------------------------------------------------------------------------------ the v0 warning, as users silence it
V0_SCRIPT = """\
import functools
import gymnasium as gym

if __name__ == "__main__":
    gym.make("heartpole:HeartPole-v0").close()
    workers = [functools.partial(gym.make, "heartpole:HeartPole-v0")] * 3
    env = gym.vector.AsyncVectorEnv(workers, context="spawn")
    env.reset(seed=0)
    env.close()
"""
USER_FILTER = (
    'import warnings\nwarnings.filterwarnings("ignore", ".*HeartPole-v0 is out of date", DeprecationWarning)\n'
)


@pytest.mark.parametrize(
    "options, environment, prelude, shown",
    [
        ([], {}, "", 0),  # unasked: import heartpole ignores it, in the main process and each of the three workers
        (["-W", "default::DeprecationWarning"], {}, "", 4),  # asked for: each process shows it
        (["-W", "ignore::DeprecationWarning"], {}, "", 0),
        ([], {"PYTHONWARNINGS": "ignore::DeprecationWarning"}, "", 0),
        ([], {}, USER_FILTER, 0),  # before `import gymnasium`; spawned workers run it too, as they import the script
    ],
    ids=["unasked", "-W default", "-W", "PYTHONWARNINGS", "filter-before-import-gymnasium"],
)
def test_the_v0_warning_obeys_the_users_filters_in_workers_too(
    tmp_path: Path, options: list[str], environment: dict[str, str], prelude: str, shown: int
) -> None:
    script = tmp_path / "v0.py"
    script.write_text(prelude + V0_SCRIPT)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"} | environment
    done = subprocess.run([sys.executable, *options, str(script)], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stderr.count("HeartPole-v0 is out of date") == shown, done.stderr[-2000:]


def test_an_error_filter_for_deprecations_turns_the_v0_warning_into_an_error() -> None:
    code = 'import gymnasium as gym, heartpole; gym.make("HeartPole-v0")'
    done = subprocess.run(
        [sys.executable, "-W", "error::DeprecationWarning", "-c", code], capture_output=True, text=True
    )
    assert done.returncode == 1 and "DeprecationWarning" in done.stderr and "HeartPole-v0 is out of date" in done.stderr
