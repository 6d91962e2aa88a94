"""gymnax's older five-value step for libraries written against it, such as rejax: `LegacyStep`.

gymnax 1.0's ``step`` returns ``(obs, state, reward, terminated, truncated, info)``, and so does
[`HeartPoleJax`][heartpole.jax.env.HeartPoleJax]. Libraries written for gymnax before 1.0 unpack five values,
``(obs, state, reward, done, info)``: rejax 0.1.3 fails on the six with ``ValueError: too many values to unpack
(expected 5)`` (``rejax/evaluate.py``, ``obs, env_state, reward, done, _ = env.step(...)``). gymnax's own
``LegacyStepAPIWrapper`` gives the five values but cannot be deep-copied (its ``__getattr__`` asks the wrapped env
for ``_env`` before ``_env`` is set: ``RecursionError``), and rejax's ``PPO.create`` deep-copies its config, the env
with it. `LegacyStep` is that wrapper, deep-copyable and without gymnax.

Train rejax's PPO on HeartPole (docs/rejax.md):

    import jax
    from rejax import PPO
    from heartpole.jax import LegacyStep, make

    env, params = make("HeartPole-v0")
    algo = PPO.create(env=LegacyStep(env), env_params=params, total_timesteps=100_000)
    train_state, (lengths, returns) = jax.jit(algo.train)(jax.random.key(0))
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from heartpole.jax.env import EnvParams, EnvState, HeartPoleJax


class LegacyStep:
    """``env`` with gymnax's older five-value ``step``: ``(obs, state, reward, done, info)``, ``done`` being
    ``terminated or truncated`` (gymnax's ``LegacyStepAPIWrapper``'s ``done``).

    Everything else is ``env``'s (`reset`, ``action_space``, ``observation_space``, ``default_params``,
    ``step_env``, ...), and the wrapper deep-copies (rejax's ``PPO.create`` deep-copies the env it is given).

    HeartPole's episodes never terminate; they are truncated after ``params.max_steps_in_episode`` decisions.
    A learner that reads ``done`` as the end of the returns (rejax's GAE does) does not bootstrap through the time
    limit; ``info["truncated"]`` and ``info["final_observation"]`` (the observation the episode ended on) are
    there for one that does.

    Args:
        env: the JAX env (`heartpole.jax.make`'s, or any `HeartPoleJax`).

    Raises:
        TypeError: ``env`` has no six-value gymnax ``step`` (another `LegacyStep`, or not an env).

    >>> import jax
    >>> from heartpole.jax import make
    >>> env, params = make("HeartPole-v0")
    >>> legacy = LegacyStep(env)
    >>> obs, state = legacy.reset(jax.random.key(0), params)
    >>> obs, state, reward, done, info = legacy.step(jax.random.key(1), state, 2, params)
    >>> bool(done), legacy.action_space(params).n
    (False, 4)
    """

    def __init__(self, env: HeartPoleJax) -> None:
        if isinstance(env, LegacyStep) or not callable(getattr(env, "step", None)):
            raise TypeError(f"LegacyStep wraps a heartpole.jax env (HeartPoleJax, make()'s), got {env!r}")
        self.env = env

    def __getattr__(self, name: str) -> Any:
        # Only ever called for what the wrapper itself lacks. Before __init__ has run (copy.deepcopy makes the copy
        # first, then fills its __dict__) there is no env to ask: an AttributeError, never a recursion.
        if name.startswith("__") or "env" not in self.__dict__:
            raise AttributeError(name)
        return getattr(self.__dict__["env"], name)

    def __repr__(self) -> str:
        return f"LegacyStep({self.env!r})"

    def reset(self, key: jax.Array, params: EnvParams | None = None) -> tuple[jax.Array, EnvState]:
        """``env.reset``: ``(obs, state)``."""
        return self.env.reset(key, params)

    def step(
        self, key: jax.Array, state: EnvState, action: Any, params: EnvParams | None = None
    ) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, dict[str, jax.Array]]:
        """``env.step`` with ``terminated`` and ``truncated`` joined: ``(obs, state, reward, done, info)``; at the
        end of an episode ``obs`` and ``state`` are already the next episode's (``info["final_observation"]`` is
        the observation the episode ended on), as ``env.step``'s."""
        obs, state, reward, terminated, truncated, info = self.env.step(key, state, action, params)
        return obs, state, reward, jnp.logical_or(terminated, truncated), info
