"""Whole episodes on the native vector env: the one loop that evaluation, true values and datasets run.

```python
with vector_env("HeartPole-v0", {}, num_envs=100) as env:
    for step in episode_steps(env, reset_seed=0, choose=policy_actions(act, "expert", env)):
        returns += step.rewards
```

[`vector_env`][heartpole.rollout.vector_env] makes (and closes) the native vector env of an id;
[`episode_steps`][heartpole.rollout.episode_steps] resets it once and yields each of its ``max_steps``
steps, every env of it at the same step, and checks at the end that every episode ended there. In an env
with ``people``, each step carries each episode's person (the cohort index the reset's ``info["person"]``
gave), and [`policy_actions`][heartpole.rollout.policy_actions] passes it to a policy that ``needs_person``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import numpy as np

from heartpole.dynamics import Dynamics
from heartpole.model import HYPERTENSION
from heartpole.policies import Policy, act_batch, quiet_version_warnings
from heartpole.rewards import exact_risk

if TYPE_CHECKING:
    from gymnasium.vector import VectorEnv

    from heartpole.vector import HeartPoleVectorEnv

Choose = Callable[[np.ndarray, int], np.ndarray]
"""``choose(observations, t) -> actions``: the actions of every env at step ``t`` (0 to ``max_steps - 1``).
A ``choose`` with a true ``needs_person`` attribute is called as ``choose(observations, t, person)``, ``person``
as in [`EpisodeStep`][heartpole.rollout.EpisodeStep]."""


class EpisodeStep(NamedTuple):
    """One step of every env: the actions taken and what the env returned for them."""

    t: int
    actions: np.ndarray
    observations: np.ndarray
    rewards: np.ndarray
    info: dict[str, Any]
    person: np.ndarray | None = None
    """``(n,)`` int64: each env's episode's person (cohort index, -1 for a distribution's); ``None`` without
    ``people``."""


ENV_BYTES = 1024
"""Bytes one env of a vector env takes with its step's results, counted generously: what a size given in envs
(``n_envs``, a truth's episodes run side by side) is checked against memory with."""


@contextmanager
def vector_env(env_id: str, env_kwargs: Mapping[str, Any], num_envs: int) -> Iterator[VectorEnv]:
    """The native vector env of ``env_id`` with ``num_envs`` envs, closed afterwards.

    Raises:
        ValueError: an unknown id, bad keyword arguments, or an env that is not HeartPole.
    """
    import gymnasium as gym

    try:
        with quiet_version_warnings():
            env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **env_kwargs)
    except gym.error.Error as error:
        raise ValueError(f"cannot make a vector env for {env_id!r}: {' '.join(str(error).split())}") from None
    try:
        if not isinstance(getattr(env.unwrapped, "dynamics", None), Dynamics):
            raise ValueError(f"{env_id!r} is not a HeartPole env")
        yield env
    finally:
        env.close()


def base_env(env: VectorEnv) -> HeartPoleVectorEnv:
    """The HeartPole vector env under ``env``'s wrappers."""
    return cast("HeartPoleVectorEnv", env.unwrapped)


def episode_steps(env: VectorEnv, reset_seed: int, choose: Choose) -> Iterator[EpisodeStep]:
    """Reset ``env`` with ``reset_seed`` and run every env of it for one whole episode, step by step.

    Raises:
        RuntimeError: if the episodes did not all end after ``max_steps`` steps (checked once the last step
            has been taken).
    """
    max_steps = int(base_env(env).max_steps)
    observations, reset_info = env.reset(seed=reset_seed)
    person = episode_people(reset_info)
    wants_person = getattr(choose, "needs_person", False)
    truncated = np.zeros(env.num_envs, dtype=bool)
    for t in range(max_steps):
        actions = choose(observations, t, person) if wants_person else choose(observations, t)  # type: ignore[call-arg]
        observations, rewards, _, truncated, info = env.step(actions)
        yield EpisodeStep(t, actions, observations, rewards, info, person)
    if not np.all(truncated):
        raise RuntimeError(f"episodes did not end after max_steps={max_steps} steps")


def step_risks(env: VectorEnv, info: Mapping[str, Any], proclivity: np.ndarray | None = None) -> np.ndarray:
    """Each env's heart-attack risk of the step ``env`` just took (``info`` its info), in float64 from the blood
    pressure it left ([`exact_risk`][heartpole.rewards.exact_risk]): what evaluation sums, where the float32
    ``info["heart_attack_risk"]`` would drift by 7e-6 of return over 1,000 steps. ``proclivity``: the envs'
    ``heart_attack_proclivity`` if already read (it changes only with a new person)."""
    base = base_env(env)
    proclivity = base.heart_attack_proclivity if proclivity is None else proclivity
    pressure = base.variable(base.dynamics.names[HYPERTENSION])
    return exact_risk(pressure, proclivity, info["heart_attack_risk"], info["heart_attack"])


def episode_people(info: Mapping[str, Any]) -> np.ndarray | None:
    """Each env's person from a reset's ``info`` (``info["person"]`` as int64), or ``None`` without people."""
    person = info.get("person")
    return None if person is None else np.asarray(person, dtype=np.int64).reshape(-1)


def invalid_actions(
    name: str,
    size: int,
    num_actions: int,
    *,
    shape: tuple[int, ...] | None = None,
    dtype: object = None,
    low: object = None,
    high: object = None,
) -> str:
    """The message that policy ``name``, given ``size`` observations, returned invalid actions: of ``shape`` (not
    ``(size,)``), else of ``dtype`` (not integers), else from ``low`` to ``high`` (not all in
    ``0..num_actions - 1``). Every evaluator's refusal (NumPy's [`check_actions`][heartpole.rollout.check_actions],
    [`heartpole.jax.evaluate`][heartpole.jax.evaluation.evaluate]'s) says it in these words."""
    expected = f"expected {size} integer actions in 0..{num_actions - 1}"
    if shape is not None:
        return f"policy {name!r} returned shape {shape} for {size} observations; {expected}"
    if dtype is not None:
        return f"policy {name!r} returned {dtype} actions; {expected}"
    return f"policy {name!r} returned actions {low}..{high}; {expected}"


def check_actions(actions: object, size: int, num_actions: int, name: str) -> np.ndarray:
    """``actions`` as an index array, or ``ValueError`` naming the policy, what it returned and what is accepted
    ([`invalid_actions`][heartpole.rollout.invalid_actions])."""
    array = np.asarray(actions)
    if array.shape != (size,):
        raise ValueError(invalid_actions(name, size, num_actions, shape=array.shape))
    if array.dtype.kind not in "iu":
        raise ValueError(invalid_actions(name, size, num_actions, dtype=array.dtype))
    if size and (array.min() < 0 or array.max() >= num_actions):
        raise ValueError(invalid_actions(name, size, num_actions, low=array.min(), high=array.max()))
    return array.astype(np.intp, copy=False)


def policy_actions(act: Policy, name: str, env: VectorEnv) -> Choose:
    """``choose`` for [`episode_steps`][heartpole.rollout.episode_steps]: ``act``'s actions, checked, with the
    decisions left passed to a policy that needs them (every env of ``env`` is at the same step) and each
    episode's person to a policy that ``needs_person``."""
    return _PolicyChoice(act, name, env)


class _PolicyChoice:
    """[`policy_actions`][heartpole.rollout.policy_actions]' ``choose``: it takes the person, for any policy."""

    needs_person = True

    def __init__(self, act: Policy, name: str, env: VectorEnv) -> None:
        base = base_env(env)
        self.act, self.name = act, name
        self.size, self.max_steps, self.num_actions = base.num_envs, int(base.max_steps), len(base.dynamics.actions)

    def __call__(self, observations: np.ndarray, t: int, person: np.ndarray | None = None) -> np.ndarray:
        left = np.full(self.size, self.max_steps - t, dtype=np.int64)
        actions = act_batch(self.act, observations, left, person)
        return check_actions(actions, self.size, self.num_actions, self.name)
