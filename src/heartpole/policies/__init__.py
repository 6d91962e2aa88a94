"""Built-in HeartPole policies: plain callables from a batch of observations to a batch of actions.

A policy is anything with the signature of [`Policy`][heartpole.policies.Policy]: it takes observations of shape ``(n,
obs_dim)`` (float32, in the env's variable order: alertness, hypertension, intoxication, time_since_slept, time_elapsed,
work_done, then any variant's extras) and returns ``n`` integer action indices. Write your own the same way and pass it
to [`heartpole.evaluate`][heartpole.evaluation.evaluate]::

    import numpy as np
    import heartpole

    def nap_when_tired(obs: np.ndarray) -> np.ndarray:
        return np.where(obs[:, 0] < 0.5, 3, 0)  # 3 is v0's "sleep"

    print(heartpole.evaluate(nap_when_tired, episodes=2000, seed=0).expected_return)

Policies carry no hidden state between calls: whatever they need (the phase of a daily cycle, say) they read from the
observation, so one policy object serves any number of envs and any episode boundary. Each built-in looks its action
indices up by name in the env's [`Dynamics`][heartpole.dynamics.Dynamics], so it keeps working in variants whose action
set is larger than v0's.

Decisions left. A policy may also ask for the number of decisions left in each env's episode, which the observation does
not show (``time_elapsed`` mixes work and sleep): a policy with a true attribute ``needs_decisions_left`` is called as
``policy(obs, decisions_left)`` with an integer array ``(n,)``, ``max_steps`` on the first decision and 1 on the last.
Every loop in this package that runs policies ([`heartpole.evaluate`][heartpole.evaluation.evaluate] and friends,
``heartpole record``, ``heartpole plot episode``) calls them through [`act_batch`][heartpole.policies.act_batch], which
passes it; other loops must pass it too (the env counts decisions: ``env.unwrapped.max_steps`` minus the steps taken
since reset).

Built-ins ([`BUILTIN_POLICIES`][heartpole.policies.BUILTIN_POLICIES]): ``random``, ``nothing``, ``coffee``,
``reference``, ``expert``, ``optimal`` (the solved optimum of [`heartpole.optimum`][heartpole.optimum], which needs
the decisions left) and ``oracle`` (in an env with a finite cohort of ``people``: each episode's person's own optimum).

The person. A policy with a true attribute ``needs_person`` is also called with ``person=``, the cohort index of each
env's person (``info["person"]`` of an env made with ``people=``): [`act_batch`][heartpole.policies.act_batch] passes
it as it passes the decisions left, and refuses such a policy without it.

[`load_policy`][heartpole.policies.load_policy] turns a built-in name or the path of a Stable-Baselines3 model saved
by ``heartpole train`` (or by the JAX trainer, which saves the same files) into a [`Policy`][heartpole.policies.Policy].

The package's modules: ``common`` (the types, the file names of a training run,
[`act_batch`][heartpole.policies.act_batch]), ``builtins`` (the built-in policies), ``oracle`` (the ``oracle``
policy), ``saved`` (models saved by ``heartpole train``, loaded with Stable-Baselines3, which is imported only when a
model is loaded), ``untrusted`` (reading those files without running code from them). Everything is importable from
here.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from heartpole.dynamics import Dynamics
from heartpole.policies.builtins import (
    BUILTIN_POLICIES,
    ConstantPolicy,
    ExpertPolicy,
    HistoryOptimalPolicy,
    OptimalPolicy,
    RandomPolicy,
    ReferencePolicy,
    available_builtins,
    coffee_policy,
    make_policy,
    nothing_policy,
)
from heartpole.policies.common import (
    CURVE_COLUMNS,
    CURVE_NAME,
    MODEL_FORMAT,
    MODEL_NAME,
    SB3_ALGORITHMS,
    SIDECAR_NAME,
    VECNORMALIZE_JSON_NAME,
    VECNORMALIZE_NAME,
    Actions,
    DecisionsLeft,
    Observations,
    PersonIndex,
    Policy,
    Predictor,
    act_batch,
    default_dynamics,
    observation_batch,
    policy_name,
)
from heartpole.policies.oracle import OraclePolicy, oracle_policy
from heartpole.rates import expert_rate
from heartpole.registry import env_dynamics, quiet_version_warnings

__all__ = [
    "Policy",
    "Observations",
    "Actions",
    "DecisionsLeft",
    "PersonIndex",
    "Predictor",
    "SB3_ALGORITHMS",
    "MODEL_NAME",
    "MODEL_FORMAT",
    "SIDECAR_NAME",
    "VECNORMALIZE_NAME",
    "VECNORMALIZE_JSON_NAME",
    "CURVE_NAME",
    "CURVE_COLUMNS",
    "observation_batch",
    "default_dynamics",
    "policy_name",
    "act_batch",
    "RandomPolicy",
    "ConstantPolicy",
    "nothing_policy",
    "coffee_policy",
    "ReferencePolicy",
    "ExpertPolicy",
    "expert_rate",
    "HistoryOptimalPolicy",
    "OptimalPolicy",
    "OraclePolicy",
    "oracle_policy",
    "BUILTIN_POLICIES",
    "available_builtins",
    "make_policy",
    "load_policy",
    "env_dynamics",
    "quiet_version_warnings",
]


def load_policy(
    spec: str,
    env_id: str = "HeartPole-v0",
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    rng: np.random.Generator | int | None = None,
    trust_pickles: bool = False,
    dynamics: Dynamics | None = None,
) -> Policy:
    """A built-in policy by name, or a Stable-Baselines3 model (a ``.zip`` saved by ``heartpole train``).

    For a model, the algorithm is read from a ``heartpole.json`` beside the zip (``{"algo": "ppo"}``) or
    else from the policy class recorded in the zip. Observations are normalised only with the
    ``VecNormalize`` statistics that ``heartpole.json`` records as saved with this model (see
    `recorded_normalizer`); the returned policy's
    ``normalizer_path`` names them. The model then acts deterministically.

    Loading runs no code from the files: the network is rebuilt from its recorded architecture, its weights
    read by PyTorch's weights-only reader and the statistics from plain JSON or a restricted unpickler (see
    [`heartpole.policies.untrusted`][heartpole.policies.untrusted]). A file those cannot read is refused
    with [`UnsafeFileError`][heartpole.policies.untrusted.UnsafeFileError] unless ``trust_pickles``.

    Args:
        spec: a name in [`BUILTIN_POLICIES`][heartpole.policies.BUILTIN_POLICIES] or a path to a model ``.zip``.
        env_id: the env the policy will act in (its action names and spaces).
        env_kwargs: keyword arguments of that env (a variant's parameters).
        rng: generator or seed of the ``random`` policy.
        trust_pickles: read a model file by unpickling (Stable-Baselines3's ``load``, ``pickle``) where the
            safe readers refuse it. Unpickling can run any code the file's author chose: only for files you
            trust.
        dynamics: the env's [`Dynamics`][heartpole.dynamics.Dynamics], where the caller resolved ``env_id`` and
            ``env_kwargs`` already (default: resolved here, by
            [`env_dynamics`][heartpole.registry.env_dynamics]).

    Raises:
        ValueError: unknown name, or a file that is not a usable model for this env
            ([`UnsafeFileError`][heartpole.policies.untrusted.UnsafeFileError], a subclass: one that only
            unpickling could read).
        FileNotFoundError: a path that does not exist.

    A policy maps a batch of observations to a batch of action indices:

    >>> import numpy as np
    >>> policy = load_policy("coffee")
    >>> policy(np.zeros((3, 6), dtype=np.float32))
    array([1, 1, 1])
    """
    if dynamics is None:
        dynamics = env_dynamics(env_id, env_kwargs)
    if spec == "oracle":
        return oracle_policy(env_id, env_kwargs, dynamics)
    if spec == "optimal":  # solved here, so that a refusal names this env, not v0
        from heartpole.optimum import optimum_for

        return OptimalPolicy(dynamics, optimum_for(dynamics, env_id, env_kwargs))
    if spec in BUILTIN_POLICIES:
        return make_policy(spec, dynamics, rng)
    if not _looks_like_path(spec):
        raise ValueError(
            f"unknown policy {spec!r}; built-in policies are {', '.join(BUILTIN_POLICIES)}, "
            "or give the path of a model .zip saved by 'heartpole train'"
        )
    from heartpole.policies.saved import load_model_policy  # imports Stable-Baselines3 when it loads

    return load_model_policy(spec, dynamics, _observation_shape(env_id, env_kwargs), trust_pickles=trust_pickles)


def _observation_shape(env_id: str, env_kwargs: Mapping[str, Any] | None) -> tuple[int, ...]:
    """The observation shape of ``env_id`` made with ``env_kwargs`` (wider than its variables with
    ``observe_traits`` or ``measurement``)."""
    import gymnasium as gym

    with quiet_version_warnings():
        env = gym.make(env_id, **dict(env_kwargs or {}))
    shape = tuple(env.observation_space.shape or ())
    env.close()
    return shape


def _looks_like_path(spec: str) -> bool:
    return bool(spec) and (spec.endswith(".zip") or "/" in spec or "\\" in spec or Path(spec).exists())
