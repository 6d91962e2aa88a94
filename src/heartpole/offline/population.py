"""Datasets and off-policy evaluation over a population of people (see the page "People differ").

A dataset recorded with ``people`` ([`record_dataset`][heartpole.offline.datasets.record_dataset]'s ``people=``)
stores each episode's person in its infos (``person`` and ``traits``, the reset's ``info["person"]`` and
``info["traits"]``, repeated at every observation as Minari's infos are per observation) and the population in its
metadata (``people``: [`People.to_dict`][heartpole.people.People.to_dict]; ``observe_traits``).
[`dataset_env_kwargs`][heartpole.offline.population.dataset_env_kwargs] makes the env's keyword arguments again
from that metadata, so off-policy evaluation measures the truth over the same population:
[`people_truth_fields`][heartpole.offline.population.people_truth_fields] adds, for a finite cohort, the evaluated
policy's oracle regret (each person's optimum, solved once and cached).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import numpy as np

from heartpole.measurement import Measurement
from heartpole.offline.trajectories import Trajectories
from heartpole.people import People, Person, Uniform, Value


def people_kwargs(people: People | str | None, observe_traits: bool = False) -> dict[str, Any]:
    """The env keyword arguments of ``people`` and ``observe_traits`` (empty without people).

    Raises:
        ValueError: ``observe_traits`` without ``people``, or an unknown population name.
        TypeError: a ``people`` that is not a [`People`][heartpole.people.People], a name or ``None``.
    """
    resolved = People.resolve(people)
    if resolved is None:
        if observe_traits:
            raise ValueError("observe_traits=True needs people (the traits are the person's)")
        return {}
    return {"people": resolved, "observe_traits": True} if observe_traits else {"people": resolved}


def people_suffix(people: People | str | None, observe_traits: bool = False) -> str:
    """What a dataset's default name adds for its population: ``-people-default`` for ``people="default"``
    (``-people`` for a [`People`][heartpole.people.People] value), then ``-traits`` with ``observe_traits``; empty
    without people, so a dataset with people never takes the id of one without."""
    if people is None:
        return ""
    named = f"-people-{people}" if isinstance(people, str) else "-people"
    return named + ("-traits" if observe_traits else "")


def people_metadata(env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """A dataset's metadata about its population: ``people`` (``People.to_dict()``) and ``observe_traits``;
    empty without people."""
    people = env_kwargs.get("people")
    if people is None:
        return {}
    return {"people": People.resolve(people).to_dict(), "observe_traits": bool(env_kwargs.get("observe_traits"))}  # type: ignore[union-attr]


def measurement_kwargs(measurement: Measurement | None) -> dict[str, Any]:
    """The env keyword argument of ``measurement`` (empty without one).

    Raises:
        TypeError: a ``measurement`` that is neither a [`Measurement`][heartpole.measurement.Measurement] nor
            ``None``.
    """
    if measurement is None:
        return {}
    if not isinstance(measurement, Measurement):
        raise TypeError(f"measurement must be a heartpole.Measurement or None, got {measurement!r}")
    return {"measurement": measurement}


def measurement_suffix(measurement: Measurement | None) -> str:
    """What a dataset's default name adds for a measurement: ``-measured`` (empty without one), so a dataset of
    measured observations never takes the id of one of the state itself."""
    return "" if measurement is None else "-measured"


def measurement_metadata(env_kwargs: Mapping[str, Any]) -> dict[str, Any]:
    """A dataset's metadata about its measurement: ``measurement``
    ([`Measurement.to_dict`][heartpole.measurement.Measurement.to_dict]); empty without one."""
    measurement = env_kwargs.get("measurement")
    return {} if measurement is None else {"measurement": measurement.to_dict()}


def people_from_dict(spec: Mapping[str, Any]) -> People:
    """The population [`People.to_dict`][heartpole.people.People.to_dict] described.

    Raises:
        ValueError: a description that is neither a ``cohort`` nor ``fields``.
    """
    if "cohort" in spec:
        return People(cohort=[Person(p["name"], **{k: _value(v) for k, v in p.items() if k != "name"})
                              for p in spec["cohort"]])  # fmt: skip
    if "fields" in spec:
        fields: dict[str, Any] = {
            field: Uniform(*value["uniform"]) if isinstance(value, Mapping) else _value(value)
            for field, value in spec["fields"].items()
        }
        return People(**fields)
    raise ValueError(f"a population's description has 'cohort' or 'fields', got keys {sorted(spec)}")


def dataset_env_kwargs(metadata: Mapping[str, Any]) -> dict[str, Any]:
    """The env keyword arguments of a dataset's metadata: the env's parameters its env spec records
    (``max_steps``, ``heart_attack_proclivity``, ...), its ``people`` and ``observe_traits``, and its
    ``measurement`` (empty for a dataset recorded on the env's defaults without them)."""
    spec, measured = metadata.get("people"), metadata.get("measurement")
    kwargs = people_kwargs(people_from_dict(spec), bool(metadata.get("observe_traits", False))) if spec else {}
    return {**_env_params(metadata), **kwargs, **({"measurement": Measurement(**measured)} if measured else {})}


def _env_params(metadata: Mapping[str, Any]) -> dict[str, Any]:
    """The env's parameters in the keyword arguments of a dataset's env spec (Minari's ``env_spec``, JSON text),
    without the env id, people and measurement (read from their own metadata); empty where there are none."""
    try:
        kwargs = json.loads(metadata["env_spec"])["kwargs"]
    except (KeyError, TypeError, ValueError):
        return {}
    if not isinstance(kwargs, dict):
        return {}
    return {k: v for k, v in kwargs.items() if k not in ("env_id", "people", "observe_traits", "measurement")}


def people_truth_fields(
    policy: Any, episodes: int, env_id: str, seed: int, env_kwargs: Mapping[str, Any]
) -> dict[str, Any]:
    """The per-person truth of an OPE report beyond the true value: for a finite cohort, ``policy``'s oracle
    regret over ``episodes`` episodes (undiscounted, HeartPole's return, as
    [`evaluate`][heartpole.evaluation.evaluate] reports it) with its interval; for a distribution, why there
    is none; nothing without people."""
    people = env_kwargs.get("people")
    if people is None:
        return {}
    if not People.resolve(people).finite:  # type: ignore[union-attr]
        from heartpole.truth import people_truth

        return {"no_oracle_regret_reason": people_truth(env_id, env_kwargs)}  # a sentence: no episodes to run
    from heartpole.evaluation import evaluate

    result = evaluate(policy, env_id, episodes, seed, env_kwargs=env_kwargs)
    reason = result.no_oracle_regret_reason
    if reason:
        return {"no_oracle_regret_reason": reason}
    return {"oracle_regret": float(result.oracle_regret), "oracle_regret_ci95": tuple(result.oracle_regret_ci95)}


def person_infos(trajectories: Trajectories, i: int) -> dict[str, np.ndarray]:
    """Episode ``i``'s person and traits, repeated at each of its ``T + 1`` observations (none without people)."""
    if trajectories.person is None or trajectories.traits is None:
        return {}
    rows = trajectories.steps + 1
    return {
        "person": np.full(rows, trajectories.person[i], dtype=np.int64),
        "traits": np.tile(trajectories.traits[i], (rows, 1)),
    }


def people_reference_scores(env_id: str, env_kwargs: Mapping[str, Any], episodes: int) -> tuple[float, float]:
    """Minari's reference scores under people: random's and the expert's expected returns over the population
    (expected-risk estimates; one optimum is no one's in particular, and the people's optima are not solved
    for a dataset)."""
    from heartpole.offline.truth import true_value

    scores = (true_value(p, 1.0, episodes, env_id, 0, env_kwargs=dict(env_kwargs)) for p in ("random", "expert"))
    low, high = (float(score.expected_return) for score in scores)
    return low, high


def _value(value: Any) -> Value:
    """A JSON value of a field: a pair comes back as a tuple."""
    return tuple(value) if isinstance(value, list) else value
