"""The env a dataset was recorded on, as Minari stores it: an ``EnvSpec`` that makes it again.

Minari keeps a dataset's env as a Gymnasium ``EnvSpec`` written to JSON (``dataset.spec.env_spec``), and
``dataset.recover_environment()`` is ``gymnasium.make`` of it. A registered id alone would make the plain env:
without the dataset's people, its observed traits or its measurement, and with an observation space unlike the
data's. So every dataset HeartPole records carries [`recorded_spec`][heartpole.offline.recorded.recorded_spec]:
the id and ``reward_threshold`` of the registered spec, the episode length as ``max_episode_steps``, and as kwargs
the env id and the keyword arguments the episodes were run with, in JSON (a population as
[`People.to_dict`][heartpole.people.People.to_dict] writes it, a measurement as
[`Measurement.to_dict`][heartpole.measurement.Measurement.to_dict] does, a ``max_episode_steps`` as the env's
``max_steps``, the argument ``gymnasium.make`` gives the env itself). Its entry points,
[`recorded_env`][heartpole.offline.recorded.recorded_env] and
[`recorded_vector_env`][heartpole.offline.recorded.recorded_vector_env], turn them back into objects and make the
registered env with them, so ``recover_environment()`` (and ``eval_env=True``) gives that env, whose spaces are
the data's, and ``gymnasium.make_vec`` of the spec its native vector env. A variant of the user's own must be
registered (its ``register_variant`` run) before its dataset's env is recovered, as before ``gymnasium.make``.

>>> import gymnasium as gym
>>> import heartpole
>>> spec = recorded_spec("HeartPole-v0", {"people": "default", "observe_traits": True})
>>> spec.id, spec.max_episode_steps, sorted(spec.kwargs)
('HeartPole-v0', 1000, ['env_id', 'observe_traits', 'people'])
>>> env = gym.make(spec)
>>> env.observation_space.shape, len(env.unwrapped.people.cohort)
((11,), 24)
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
from gymnasium.envs.registration import EnvSpec

from heartpole.measurement import Measurement
from heartpole.offline.population import measurement_metadata, people_from_dict, people_metadata
from heartpole.people import People
from heartpole.registry import check_heartpole_id, env_dynamics, heartpole_ids, quiet_version_warnings

ENTRY_POINT = "heartpole.offline.recorded:recorded_env"
"""The single env's entry point of a dataset's spec."""
VECTOR_ENTRY_POINT = "heartpole.offline.recorded:recorded_vector_env"
"""The native vector env's entry point of a dataset's spec."""


def recorded_spec(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> EnvSpec:
    """The spec of env ``env_id`` made with ``env_kwargs``, in the JSON that Minari stores.

    Args:
        env_id: a registered HeartPole env id.
        env_kwargs: the keyword arguments of ``gymnasium.make(env_id, ...)``: ``people`` (a
            [`People`][heartpole.people.People], a name or its ``to_dict()``), ``observe_traits``, ``measurement``
            (a [`Measurement`][heartpole.measurement.Measurement] or its ``to_dict()``) and the env's parameters
            (``max_steps``, ``heart_attack_proclivity``, ...), which must be JSON values.

    Raises:
        ValueError: an unknown env, a bad value, or a keyword argument whose value is not JSON.
        TypeError: a keyword argument the env does not take.
    """
    kwargs = _json_kwargs(env_kwargs or {})
    dynamics = env_dynamics(env_id, _objects(kwargs))  # checks the id and every value now, not at recovery
    if "max_episode_steps" in kwargs:  # make would give it to a TimeLimit only, which recorded_env unwraps
        del kwargs["max_episode_steps"]
        kwargs["max_steps"] = int(dynamics.params.max_steps)
    registered = gym.spec(env_id)
    spec = EnvSpec(
        id=env_id,
        entry_point=ENTRY_POINT,
        vector_entry_point=VECTOR_ENTRY_POINT,
        reward_threshold=registered.reward_threshold,
        max_episode_steps=int(dynamics.params.max_steps),
        kwargs={"env_id": env_id, **kwargs},
    )
    try:
        spec.to_json()
    except (TypeError, ValueError) as error:
        raise ValueError(f"env {env_id!r}: its keyword arguments must be JSON values to be stored ({error})") from None
    return spec


def recorded_spaces(spec: EnvSpec) -> tuple[gym.spaces.Space[Any], gym.spaces.Space[Any]]:
    """The observation and action spaces of the env ``spec`` makes: the spaces of a dataset recorded on it."""
    env = gym.make(spec)
    try:
        return env.observation_space, env.action_space
    finally:
        env.close()


def minari_env_options(spec: EnvSpec) -> dict[str, Any]:
    """The env arguments of ``minari.create_dataset_from_buffers`` for data recorded on ``spec``'s env: the spec
    as ``env`` and ``eval_env``, and its spaces (Minari would otherwise make them from the spec itself)."""
    observation_space, action_space = recorded_spaces(spec)
    return {"env": spec, "eval_env": spec, "observation_space": observation_space, "action_space": action_space}


def recorded_metadata(env_id: str, env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """A dataset's metadata about its env: ``env_id``, ``max_steps``, ``action_names``, ``observation_names`` (the
    state's; the traits and a measurement's age follow), and the people and the measurement, if any."""
    dynamics = env_dynamics(env_id, _objects(_json_kwargs(env_kwargs)))
    return {
        "env_id": env_id,
        "max_steps": int(dynamics.params.max_steps),
        "action_names": [a.name for a in dynamics.actions],
        "observation_names": list(dynamics.names),
        **people_metadata(env_kwargs),
        **measurement_metadata(env_kwargs),
    }


def recorded_env(env_id: str, **kwargs: Any) -> gym.Env[Any, Any]:
    """Gymnasium's entry point of a dataset's spec: the registered env ``env_id`` made with ``kwargs``, their
    JSON descriptions turned back into a population and a measurement (``gymnasium.make`` of the spec adds the
    time limit and the checks). ``env_id`` must be a HeartPole id (it comes from a dataset's file)."""
    check_heartpole_id(env_id, "a dataset's env spec")
    with quiet_version_warnings():
        return gym.make(env_id, **_objects(kwargs)).unwrapped


def recorded_vector_env(env_id: str, num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv[Any, Any, Any]:
    """Gymnasium's vector entry point of a dataset's spec: ``num_envs`` envs of ``env_id`` on its native vector
    env, made with ``kwargs`` as [`recorded_env`][heartpole.offline.recorded.recorded_env] makes one."""
    check_heartpole_id(env_id, "a dataset's env spec")
    with quiet_version_warnings():
        return gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point", **_objects(kwargs))


def check_dataset_env(metadata_path: str | Path) -> None:
    """Check a dataset's ``metadata.json`` before Minari reads it: its ``env_id`` and the id of its env specs
    (``env_spec``, ``eval_env_spec``) must be HeartPole ids, and the specs' entry points HeartPole's, without
    wrappers, so that neither loading the dataset nor ``recover_environment()`` imports another module.

    Raises:
        ValueError: naming the file and what in it is refused.
    """
    source = f"dataset metadata {metadata_path}"
    try:
        metadata = json.loads(Path(metadata_path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{source} cannot be read ({' '.join(str(error).split())})") from None
    if not isinstance(metadata, dict):
        raise ValueError(f"{source} is not a JSON object")
    check_heartpole_id(metadata.get("env_id", "HeartPole-v0"), source)
    ids = heartpole_ids()
    entry_points = {ENTRY_POINT, *(gym.registry[i].entry_point for i in ids)}
    vector_entry_points = {None, VECTOR_ENTRY_POINT, *(gym.registry[i].vector_entry_point for i in ids)}
    for key in ("env_spec", "eval_env_spec"):
        text = metadata.get(key)
        if text is None:
            continue
        try:
            spec = json.loads(text) if isinstance(text, str) else None
        except json.JSONDecodeError:
            spec = None
        if not isinstance(spec, dict):
            raise ValueError(f"{source}: {key} is not an env spec in JSON")
        check_heartpole_id(spec.get("id"), f"{source} ({key})")
        kwargs = spec.get("kwargs")
        if isinstance(kwargs, dict) and "env_id" in kwargs:
            check_heartpole_id(kwargs["env_id"], f"{source} ({key} kwargs)")
        if spec.get("entry_point") not in entry_points or spec.get("vector_entry_point") not in vector_entry_points:
            raise ValueError(
                f"{source}: {key} names entry points {spec.get('entry_point')!r} and {spec.get('vector_entry_point')!r}"
                f", not HeartPole's ({ENTRY_POINT!r}); nothing was imported"
            )
        if spec.get("additional_wrappers"):
            raise ValueError(
                f"{source}: {key} adds wrappers, which HeartPole's datasets never do; nothing was imported"
            )


def _json_kwargs(env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """``env_kwargs`` with the population and the measurement as their JSON descriptions."""
    kwargs = dict(env_kwargs)
    people = kwargs.get("people")
    if people is not None and not isinstance(people, Mapping):
        kwargs["people"] = People.resolve(people).to_dict()  # type: ignore[union-attr]
    measurement = kwargs.get("measurement")
    if isinstance(measurement, Measurement):
        kwargs["measurement"] = measurement.to_dict()
    return kwargs


def _objects(kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """``kwargs`` with a JSON population and measurement as the objects the env takes."""
    out = dict(kwargs)
    if isinstance(out.get("people"), Mapping):
        out["people"] = people_from_dict(out["people"])
    if isinstance(out.get("measurement"), Mapping):
        out["measurement"] = Measurement.resolve(out["measurement"])
    return out


__all__ = [
    "ENTRY_POINT",
    "VECTOR_ENTRY_POINT",
    "check_dataset_env",
    "minari_env_options",
    "recorded_metadata",
    "recorded_env",
    "recorded_spaces",
    "recorded_spec",
    "recorded_vector_env",
]
