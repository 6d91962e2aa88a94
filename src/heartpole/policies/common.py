"""What every policy shares: the types, the batch of observations, the default dynamics, a policy's name,
how loops call a policy, and the names of the files a training run saves."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Protocol

import numpy as np
import numpy.typing as npt

from heartpole.dynamics import Dynamics

Observations = np.ndarray
"""A batch of observations, ``(n, obs_dim)`` float32 (one row per env, in observation order)."""
Actions = np.ndarray
"""A batch of actions, ``(n,)`` integers in ``0 .. num_actions - 1``."""
DecisionsLeft = int | np.ndarray | None
"""The decisions left in each env's episode (a number for all, ``(n,)`` integers, or ``None``: unknown)."""
PersonIndex = np.ndarray | None
"""The cohort index of each env's person (``(n,)`` integers, ``info["person"]``), or ``None``: unknown."""
Policy = Callable[[Observations], Actions]
"""A policy: observations ``(n, obs_dim)`` float32 -> integer actions ``(n,)``."""


class Predictor(Protocol):
    """What `ModelPolicy` needs of a model: Stable-Baselines3's
    ``predict``."""

    def predict(self, observation: np.ndarray, /, *, deterministic: bool = ...) -> tuple[np.ndarray, object]:
        """The actions for ``observation`` and the next recurrent state (``None`` without one)."""
        ...


SB3_ALGORITHMS = ("ppo", "a2c", "dqn")
"""The Stable-Baselines3 algorithms HeartPole trains and loads."""
OFF_POLICY_ALGORITHMS = frozenset({"dqn"})
"""Those of [`SB3_ALGORITHMS`][heartpole.policies.common.SB3_ALGORITHMS] that learn from a replay buffer: SB3 keeps
their last raw observations (``_last_original_obs``) whatever the env, where the on-policy ones keep them only
under ``VecNormalize``."""
# The files a training run writes in its folder (every training backend writes them; loading and plots read them).
MODEL_NAME = "model.zip"
SIDECAR_NAME = "heartpole.json"
MODEL_FORMAT = "heartpole-model/1"
"""The ``format`` of the ``heartpole.json`` in a trained model's folder (written by every training backend); one
without the field, written before it existed, is read as this version."""
VECNORMALIZE_NAME = "vecnormalize.pkl"
VECNORMALIZE_JSON_NAME = "vecnormalize.json"  # the same statistics as plain JSON, read without unpickling
CURVE_NAME = "learning_curve.csv"
CURVE_COLUMNS = ("timesteps", "mean_return", "heart_attacks", "score")
"""The columns of a learning curve: after each evaluation, its timestep and the mean return, heart
attacks and score of the episodes finished since the last one."""


def check_model_format(sidecar: object, record: object) -> None:
    """``ValueError`` naming ``sidecar`` (a ``heartpole.json``) when its ``record`` (the JSON read from it) says
    another ``format`` than [`MODEL_FORMAT`][heartpole.policies.common.MODEL_FORMAT]: a later HeartPole's model,
    whose fields this one would misread."""
    found = record.get("format", MODEL_FORMAT) if isinstance(record, dict) else MODEL_FORMAT
    if found != MODEL_FORMAT:
        raise ValueError(f"{sidecar}: format {found!r}, and this HeartPole reads {MODEL_FORMAT!r} only (or a record "
                         "without a format, from before it had one)")  # fmt: skip


def observation_batch(obs: npt.ArrayLike) -> np.ndarray:
    """``obs`` as an array, checked to be a batch ``(n, obs_dim)``.

    Raises:
        ValueError: ``obs`` is not two-dimensional.
    """
    array = np.asarray(obs)
    if array.ndim != 2:
        raise ValueError(f"a policy takes a batch of observations of shape (n, obs_dim), got shape {array.shape}")
    return array


@functools.lru_cache(maxsize=1)
def default_dynamics() -> Dynamics:
    """HeartPole-v0's dynamics, which a policy acts in when given none (built once)."""
    return Dynamics()


def policy_name(policy: object) -> str:
    """A display name: the policy's ``name`` attribute, its ``__name__``, or its class name."""
    for attribute in ("name", "__name__"):
        value = getattr(policy, attribute, None)
        if isinstance(value, str) and value:
            return value
    return type(policy).__name__


def act_batch(policy: Policy, obs: Observations, decisions_left: DecisionsLeft, person: PersonIndex = None) -> Actions:
    """``policy``'s actions for ``obs``, passing ``decisions_left`` to a policy that ``needs_decisions_left``
    (second argument) and ``person=`` to one that ``needs_person``.

    Raises:
        ValueError: a policy that needs the person, called without it (an env without ``people``).
    """
    args: tuple[DecisionsLeft, ...] = (decisions_left,) if getattr(policy, "needs_decisions_left", False) else ()
    if not getattr(policy, "needs_person", False):
        return policy(obs, *args)
    if person is None:
        raise ValueError(
            f"policy {policy_name(policy)!r} needs each episode's person (info['person']): run it in an env "
            "made with people= (a finite cohort, such as 'default')"
        )
    return policy(obs, *args, person=person)  # type: ignore[call-arg]
