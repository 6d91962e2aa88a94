"""Minari datasets: round trip, propensities, metadata, atomic writes, bad input. All in a tmp folder."""

from __future__ import annotations

import json
import math
import time

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("minari")
import minari  # noqa: E402

from heartpole.offline.behaviour import EpsilonGreedy, Mixture, action_probabilities  # noqa: E402
from heartpole.offline.datasets import (  # noqa: E402
    STANDARD_DATASETS,
    default_dataset_id,
    load_local,
    load_trajectories,
    local_dataset_ids,
    record_dataset,
    record_standard,
)
from heartpole.policies import ExpertPolicy, RandomPolicy, ReferencePolicy  # noqa: E402

SHORT_ID = "heartpole/short/test-v0"


@pytest.fixture(autouse=True)
def minari_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    return tmp_path


def leftovers(folder):
    return [p.name for p in folder.rglob(".heartpole-*")]


def test_round_trip(minari_folder):
    dataset = record_dataset("reference", 0.2, episodes=12, seed=1)
    assert dataset.spec.dataset_id == "heartpole/v0/reference-eps20-v0" == default_dataset_id("reference-eps20")
    loaded = minari.load_dataset("heartpole/v0/reference-eps20-v0")
    env = loaded.recover_environment()
    assert loaded.total_episodes == 12 and loaded.total_steps == 12 * 1000
    assert loaded.observation_space == env.observation_space and loaded.action_space == env.action_space
    assert isinstance(env.unwrapped, gym.Env) and hasattr(env.unwrapped, "dynamics")
    episode = next(loaded.iterate_episodes())
    assert episode.observations.shape == (1001, 6) and episode.actions.shape == (1000,)
    assert episode.truncations[-1] and not episode.terminations.any()
    probs = episode.infos["action_probabilities"]
    assert probs.shape == (1001, 4) and np.allclose(probs.sum(axis=1), 1.0)
    expected = 0.8 * action_probabilities(ReferencePolicy(), episode.observations, 4) + 0.05
    assert np.allclose(probs, expected)
    for key in ("heart_attack_risk", "productivity", "heart_attack", "score"):
        assert episode.infos[key].shape == (1001,)
    assert np.all(episode.infos["heart_attack_risk"][1:] > 0) and episode.infos["heart_attack_risk"][0] == 0
    meta = loaded.storage.metadata
    assert meta["behaviour_policy"] == "reference" and meta["epsilon"] == 0.2 and meta["seed"] == 1
    assert meta["ref_min_score"] < meta["ref_max_score"] < -123
    for key in ("author", "algorithm_name", "description", "eval_env_spec"):
        assert meta.get(key)
    # No address that is not the project's own: it has none (pypi.org/project/heartpole is another package).
    assert "author_email" not in meta and "code_permalink" not in meta
    assert "pypi.org" not in json.dumps(meta, default=str)
    assert local_dataset_ids() == ["heartpole/v0/reference-eps20-v0"]
    assert leftovers(minari_folder) == []


def test_actions_follow_the_propensities():
    """The share of actions equal to the reference's is 0.8 + 0.2 / 4 = 0.85, within 4 standard errors."""
    data = load_trajectories(record_dataset("reference", 0.2, episodes=10, seed=2).spec.dataset_id)
    greedy = ReferencePolicy()(data.observations[:, :-1].reshape(-1, 6)).reshape(data.actions.shape)
    share = (greedy == data.actions).mean()
    assert abs(share - 0.85) < 4 * math.sqrt(0.85 * 0.15 / data.actions.size)
    assert np.allclose(data.propensities, np.where(greedy == data.actions, 0.85, 0.05))


def test_mixture_and_callables():
    mixed = record_dataset(["random", "expert"], 0.0, episodes=3, dataset_id=SHORT_ID)
    data = load_trajectories(mixed.spec.dataset_id)
    obs = data.observations[0]
    expected = 0.5 * 0.25 + 0.5 * action_probabilities(ExpertPolicy(), obs, 4)
    assert np.allclose(data.action_probabilities[0], expected)
    assert mixed.storage.metadata["behaviour_components"] == ["random", "expert"]


def test_existing_dataset_needs_force():
    record_dataset("expert", 0.1, episodes=2)
    with pytest.raises(FileExistsError, match="--force"):
        record_dataset("expert", 0.1, episodes=3)
    record_dataset("expert", 0.1, episodes=3, force=True)
    assert load_local("heartpole/v0/expert-eps10-v0").total_episodes == 3


def test_a_failure_while_writing_leaves_nothing(minari_folder, monkeypatch):
    original = minari.create_dataset_from_buffers

    def fail_after_writing(*args, **kwargs):
        original(*args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(minari, "create_dataset_from_buffers", fail_after_writing)
    with pytest.raises(KeyboardInterrupt):
        record_dataset("expert", 0.1, episodes=2)
    assert local_dataset_ids() == [] and leftovers(minari_folder) == []


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"policy": "expert", "epsilon": 1.5}, ValueError, "epsilon"),
        ({"policy": "expert", "epsilon": -0.1}, ValueError, "epsilon"),
        ({"policy": "nobody"}, ValueError, "unknown policy"),
        ({"policy": "expert", "env_id": "Nope-v0"}, ValueError, "Nope"),
        ({"policy": lambda obs: np.full(len(obs), 7)}, ValueError, "returned actions 7..7"),
        ({"policy": lambda obs: np.zeros(len(obs))}, ValueError, "float64"),
        ({"policy": RandomPolicy().__call__}, ValueError, "acts at random"),
        ({"policy": "expert", "dataset_id": "no version"}, ValueError, "name-vN"),
        ({"policy": "expert", "dataset_id": "x/y-v0"}, ValueError, "name-vN"),
    ],
)
def test_bad_input_writes_nothing(minari_folder, kwargs, error, message):
    with pytest.raises(error, match=message):
        record_dataset(episodes=2, **kwargs)
    assert local_dataset_ids() == [] and leftovers(minari_folder) == []


def test_unknown_dataset_never_downloads():
    with pytest.raises(ValueError, match="unknown dataset id"):
        load_local("D4RL/door/human-v2")


def test_standard_collection_checks_every_id_first():
    record_dataset("random", 0.0, episodes=2)
    with pytest.raises(FileExistsError, match="random-v0"):
        record_standard(episodes=2)
    assert local_dataset_ids() == ["heartpole/v0/random-v0"]
    ids = record_standard(episodes=2, force=True, specs=STANDARD_DATASETS[:2])
    assert ids == ["heartpole/v0/random-v0", "heartpole/v0/reference-eps5-v0"]


def test_epsilon_greedy_probabilities():
    behaviour = EpsilonGreedy(ExpertPolicy(), 0.4, 4)
    obs = np.zeros((3, 6), dtype=np.float32)
    probs = behaviour.action_probabilities(obs)
    assert np.allclose(probs.sum(axis=1), 1) and probs.max() == pytest.approx(0.7)
    assert Mixture([ExpertPolicy(), ReferencePolicy()], 4).action_probabilities(obs).shape == (3, 4)


@pytest.mark.slow
def test_a_thousand_episodes_in_under_a_minute():
    started = time.perf_counter()
    dataset = record_dataset("reference", 0.2, episodes=1000)
    seconds = time.perf_counter() - started
    assert dataset.total_steps == 1_000_000
    assert seconds < 60, f"recording 1,000 x 1,000 steps took {seconds:.1f} s"


@pytest.mark.filterwarnings("ignore::UserWarning")  # Minari's notes on metadata this test leaves out
def test_a_dataset_without_propensities_is_refused():
    from minari.data_collector import EpisodeBuffer

    buffer = EpisodeBuffer(
        observations=np.zeros((3, 6), dtype=np.float32),
        actions=np.zeros(2, dtype=np.int64),
        rewards=np.zeros(2),
        terminations=np.zeros(2, dtype=bool),
        truncations=np.array([False, True]),
    )
    minari.create_dataset_from_buffers("other/plain-v0", [buffer], env="HeartPole-v0", algorithm_name="x")
    with pytest.raises(ValueError, match="lacks the infos"):
        load_trajectories("other/plain-v0")


def test_chunks_are_written_one_after_another():
    dataset = record_dataset("expert", 0.3, episodes=7, num_envs=3, seed=4)
    assert dataset.total_episodes == 7 and dataset.total_steps == 7000
    data = load_trajectories(dataset.spec.dataset_id)
    assert len({tuple(obs) for obs in data.observations[:, 0]}) == 7  # every episode its own waking
