"""The env a model was trained on, as its folder records it: ``heartpole train`` writes the env id and keyword
arguments into the ``heartpole.json`` beside ``model.zip``, and the commands that play a model
(``evaluate``, ``compare``, ``baselines``, ``record``, ``plot episode``, ``dataset``, ``ope``) read them here
so that a model plays the env it learned, not plain ``HeartPole-v0``.

Reading the record makes nothing and imports nothing: the env id must be one this process registered for
HeartPole (looked up in Gymnasium's registry as a plain key; ``gymnasium.make`` and ``gymnasium.spec`` would
import the module of an id such as ``"mod:Id"``), and the keyword arguments a JSON object.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym

from heartpole.policies.common import MODEL_NAME, SIDECAR_NAME, check_model_format


@dataclass(frozen=True)
class TrainedEnv:
    """The env a model folder records: ``env_id`` made with ``env_kwargs``, as written in ``source``."""

    env_id: str
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    source: Path = Path(SIDECAR_NAME)

    def describe(self) -> str:
        """``HeartPole-v0 with {'max_steps': 200}`` (the id alone without keyword arguments)."""
        return f"{self.env_id} with {self.env_kwargs}" if self.env_kwargs else self.env_id


def model_file(spec: str) -> str:
    """``spec``, or ``spec/model.zip`` when ``spec`` is a folder holding one (a ``heartpole train --out`` folder
    given in place of its model)."""
    folder = Path(spec)
    if spec and folder.is_dir() and (folder / MODEL_NAME).is_file():
        return str(folder / MODEL_NAME)
    return spec


def is_heartpole_id(env_id: object) -> bool:
    """Whether ``env_id`` is an env id registered in this process for a HeartPole env (its entry point in the
    ``heartpole`` package), found without making the env or importing anything."""
    if not isinstance(env_id, str) or env_id not in gym.registry:
        return False
    entry_point = gym.registry[env_id].entry_point
    return isinstance(entry_point, str) and entry_point.split(":")[0].split(".")[0] == "heartpole"


def trained_env(spec: str) -> TrainedEnv | None:
    """The env the ``heartpole.json`` beside the model ``spec`` (a ``.zip`` or its folder) records, or ``None``
    where there is none (a built-in policy's name, a model without ``heartpole.json``, a record of another
    model, a record without an env id).

    Raises:
        ValueError: a record that cannot be read, an env id that is not a registered HeartPole id, or keyword
            arguments that are not a JSON object.
    """
    path = Path(model_file(spec))
    sidecar = path.parent / SIDECAR_NAME
    if not spec or path.suffix != ".zip" or not sidecar.is_file():
        return None
    try:
        record = json.loads(sidecar.read_text())
    except (OSError, ValueError) as error:
        raise ValueError(f"{sidecar}: cannot read the env it records ({' '.join(str(error).split())})") from None
    check_model_format(sidecar, record)
    if not isinstance(record, dict) or record.get("model", path.name) != path.name or "env_id" not in record:
        return None
    env_id = record["env_id"]
    if not is_heartpole_id(env_id):
        ids = ", ".join(sorted(i for i in gym.registry if is_heartpole_id(i)))
        raise ValueError(f"{sidecar}: env_id {env_id!r} is not a registered HeartPole env id; HeartPole envs: {ids}")
    config = record.get("config")
    kwargs = record.get("env_kwargs", config.get("env_kwargs", {}) if isinstance(config, dict) else {})
    if not isinstance(kwargs, dict):
        raise ValueError(f"{sidecar}: env_kwargs must be a JSON object of keyword: value, got {kwargs!r}")
    return TrainedEnv(env_id, dict(kwargs), sidecar)
