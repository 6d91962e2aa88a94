"""Whole episodes on the native vector env: the one loop that evaluation, true values and datasets run.

```python
with vector_env("HeartPole-v0", {}, num_envs=100) as env:
    for step in episode_steps(env, reset_seed=0, choose=policy_actions(act, "expert", env)):
        returns += step.rewards
```

[`vector_env`][heartpole.rollout.vector_env] makes (and closes) the native vector env of an id;
[`episode_steps`][heartpole.rollout.episode_steps] resets it once and yields each of its ``max_steps``
steps, every env of it at the same step, and checks at the end that every episode ended there.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import numpy as np

from heartpole.dynamics import Dynamics
from heartpole.policies import Policy, act_batch, quiet_version_warnings

if TYPE_CHECKING:
    from gymnasium.vector import VectorEnv

    from heartpole.vector import HeartPoleVectorEnv

Choose = Callable[[np.ndarray, int], np.ndarray]
"""``choose(observations, t) -> actions``: the actions of every env at step ``t`` (0 to ``max_steps - 1``)."""


class EpisodeStep(NamedTuple):
    """One step of every env: the actions taken and what the env returned for them."""

    t: int
    actions: np.ndarray
    observations: np.ndarray
    rewards: np.ndarray
    info: dict[str, Any]


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
    observations, _ = env.reset(seed=reset_seed)
    truncated = np.zeros(env.num_envs, dtype=bool)
    for t in range(max_steps):
        actions = choose(observations, t)
        observations, rewards, _, truncated, info = env.step(actions)
        yield EpisodeStep(t, actions, observations, rewards, info)
    if not np.all(truncated):
        raise RuntimeError(f"episodes did not end after max_steps={max_steps} steps")


def check_actions(actions: object, size: int, num_actions: int, name: str) -> np.ndarray:
    """``actions`` as an index array, or ``ValueError`` naming the policy, what it returned and what is accepted."""
    array = np.asarray(actions)
    expected = f"expected {size} integer actions in 0..{num_actions - 1}"
    if array.shape != (size,):
        raise ValueError(f"policy {name!r} returned shape {array.shape} for {size} observations; {expected}")
    if array.dtype.kind not in "iu":
        raise ValueError(f"policy {name!r} returned {array.dtype} actions; {expected}")
    if size and (array.min() < 0 or array.max() >= num_actions):
        raise ValueError(f"policy {name!r} returned actions {array.min()}..{array.max()}; {expected}")
    return array.astype(np.intp, copy=False)


def policy_actions(act: Policy, name: str, env: VectorEnv) -> Choose:
    """``choose`` for [`episode_steps`][heartpole.rollout.episode_steps]: ``act``'s actions, checked, with the
    decisions left passed to a policy that needs them (every env of ``env`` is at the same step)."""
    base = base_env(env)
    size, max_steps, num_actions = base.num_envs, int(base.max_steps), len(base.dynamics.actions)

    def choose(observations: np.ndarray, t: int) -> np.ndarray:
        left = np.full(size, max_steps - t, dtype=np.int64)
        return check_actions(act_batch(act, observations, left), size, num_actions, name)

    return choose
