"""Every dataset carries the env it was recorded on: its Minari ``env_spec`` and ``eval_env`` make that env
again (people, observed traits, measurement, v1, a variant's parameters), with the data's spaces."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("minari")

import heartpole  # noqa: E402
from heartpole.cli import main  # noqa: E402
from heartpole.measurement import Measurement  # noqa: E402
from heartpole.offline.recorded import ENTRY_POINT, recorded_spec  # noqa: E402
from heartpole.people import People  # noqa: E402
from heartpole.vector import HeartPoleVectorEnv  # noqa: E402

MEASUREMENT = {"noise": {"alertness": 0.2, "hypertension": 0.1}, "every": 4}
RECORD = ["dataset", "--policy", "expert", "--epsilon", "0.1", "--episodes", "3"]


@pytest.fixture(autouse=True)
def minari_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    return tmp_path


def test_a_spec_carries_the_people_the_traits_and_the_measurement_as_json() -> None:
    spec = recorded_spec(
        "HeartPole-v0", {"people": "default", "observe_traits": True, "measurement": Measurement(**MEASUREMENT)}
    )
    assert spec.entry_point == ENTRY_POINT and spec.id == "HeartPole-v0" and spec.max_episode_steps == 1000
    assert spec.kwargs == {
        "env_id": "HeartPole-v0",
        "people": People.default().to_dict(),
        "observe_traits": True,
        "measurement": MEASUREMENT,
    }
    again = gym.envs.registration.EnvSpec.from_json(spec.to_json())  # as Minari stores and reads it
    env = gym.make(again)
    assert env.observation_space.shape == (6 + 5 + 1,)  # the state, Ada's five traits, the measurement's age
    assert env.unwrapped.people == People.default()
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    env.close()


def test_a_spec_keeps_a_variants_parameters_and_makes_its_native_vector_env() -> None:
    heartpole.register_variant("RecordedPole-v0", max_steps=40, replace=True)
    spec = recorded_spec("RecordedPole-v0", {"heart_attack_proclivity": 0.7})
    assert spec.max_episode_steps == 40
    env = gym.make(spec)
    assert env.unwrapped.heart_attack_proclivity == 0.7 and env.unwrapped.max_steps == 40
    env.close()
    vec = gym.make_vec(spec, 3, vectorization_mode="vector_entry_point")
    assert isinstance(vec.unwrapped, HeartPoleVectorEnv) and vec.num_envs == 3
    vec.close()


def test_a_spec_of_an_episode_length_given_as_max_episode_steps_recovers_that_length() -> None:
    """The env recovered was one of 1,000 steps: ``recorded_env`` unwrapped the ``TimeLimit`` that
    ``gymnasium.make`` gave ``max_episode_steps`` to, and the env kept the registered length."""
    spec = recorded_spec("HeartPole-v0", {"max_episode_steps": 500})
    assert spec.max_episode_steps == 500 and spec.kwargs == {"env_id": "HeartPole-v0", "max_steps": 500}
    env = gym.make(gym.envs.registration.EnvSpec.from_json(spec.to_json()))
    assert env.unwrapped.max_steps == env.spec.max_episode_steps == 500
    env.close()
    vec = gym.make_vec(spec, 2, vectorization_mode="vector_entry_point")
    assert vec.unwrapped.max_steps == vec.spec.max_episode_steps == 500
    vec.close()


def test_a_spec_refuses_what_it_cannot_store_or_make() -> None:
    with pytest.raises(ValueError, match="NoSuchPole-v0"):
        recorded_spec("NoSuchPole-v0")
    with pytest.raises(TypeError, match="colour"):
        recorded_spec("HeartPole-v0", {"colour": "red"})
    with pytest.raises(ValueError, match="JSON"):
        recorded_spec("HeartPole-v0", {"heart_attack_proclivity": np.float64(0.5), "max_steps": np.int64(9)})


def recorded(arguments: list[str]) -> list[str]:
    """Record with ``heartpole`` + ``arguments``; the ids of the datasets it wrote."""
    assert main(arguments) == 0
    from heartpole.offline.datasets import local_dataset_ids

    return local_dataset_ids()


def check_recovers_its_env(dataset_id: str, expected_kwargs: dict[str, Any]) -> None:
    """Both of the dataset's envs are its own: the spec's kwargs, the spaces equal to the data's, an episode
    of the recorded length, the population and the measurement of the metadata."""
    import minari

    dataset = minari.load_dataset(dataset_id)
    metadata = dataset.storage.metadata
    episode = next(dataset.iterate_episodes())
    assert dataset.spec.env_spec is not None
    assert {k: v for k, v in dataset.spec.env_spec.kwargs.items() if k != "env_id"} == expected_kwargs
    assert dataset.observation_space.shape == episode.observations.shape[1:]
    for eval_env in (False, True):
        env = dataset.recover_environment(eval_env=eval_env)
        assert env.spec is not None and env.spec.id == metadata["env_id"]
        assert env.observation_space == dataset.observation_space and env.action_space == dataset.action_space
        people = env.unwrapped.people
        assert (people.to_dict() if people is not None else None) == metadata.get("people")
        obs, _ = env.reset(seed=0)
        assert obs.shape == episode.observations.shape[1:] and env.observation_space.contains(obs)
        steps = 1
        while not any(env.step(0)[2:4]):
            steps += 1
        assert steps == len(episode.actions)
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize(
    "arguments, expected",
    [
        ([], {}),
        (["--people", "default"], {"people": People.default().to_dict()}),
        (["--people", "default", "--observe-traits"], {"people": People.default().to_dict(), "observe_traits": True}),
        (["--measurement", json.dumps(MEASUREMENT)], {"measurement": MEASUREMENT}),
        (["--env", "HeartPole-v1"], {}),
    ],
    ids=["plain", "people", "observe-traits", "measurement", "v1"],
)
def test_every_recorded_dataset_recovers_its_env(arguments: list[str], expected: dict[str, Any]) -> None:
    (dataset_id,) = recorded([*RECORD, *arguments])
    check_recovers_its_env(dataset_id, expected)


@pytest.mark.slow
def test_the_standard_collection_recovers_its_env() -> None:
    ids = recorded(["dataset", "--standard", "--episodes", "2"])
    assert len(ids) == 6
    for dataset_id in ids:
        check_recovers_its_env(dataset_id, {})


@pytest.mark.parametrize(
    "value, message",
    [("alertness=0.2", "must be a JSON object"), ('{"noise": {"alertness": -1}}', "a standard deviation")],
)
def test_measurement_on_the_command_line_is_checked(
    value: str, message: str, capsys: pytest.CaptureFixture[str], minari_folder: Path
) -> None:
    with pytest.raises(SystemExit) as stopped:
        main([*RECORD, "--measurement", value])
    assert stopped.value.code == 2
    error = capsys.readouterr().err
    assert "--measurement" in error and message in error and repr(value) in error
    assert main(["dataset", "--standard", "--measurement", json.dumps(MEASUREMENT)]) == 2
    assert not any(minari_folder.iterdir())


@pytest.mark.slow
def test_a_variants_dataset_recovers_its_env_where_the_variant_is_registered() -> None:
    """A user's variant (its actions are objects, which Minari could not store) is stored by id, like any
    registered env; recovering it makes the variant, with its fifth action and its episode length."""
    from heartpole.offline.datasets import record_dataset

    tea = heartpole.Action("drink_tea", effects={"alertness": (0.0, 0.5)})
    heartpole.register_variant("RecordedTeaPole-v0", [*heartpole.V0_ACTIONS, tea], max_steps=30, replace=True)
    dataset = record_dataset("random", 0.0, 3, env_id="RecordedTeaPole-v0")
    assert dataset.spec.env_spec is not None and dataset.spec.env_spec.kwargs == {"env_id": "RecordedTeaPole-v0"}
    check_recovers_its_env(dataset.spec.dataset_id, {})
    assert dataset.recover_environment().unwrapped.actions[4].name == "drink_tea"
