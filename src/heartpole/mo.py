"""HeartPole with a vector reward, the way MO-Gymnasium's multi-objective envs give theirs: ``mo-heartpole-v0``.

HeartPole's scalar reward mixes two objectives at a fixed price: the change of the score (productivity) less
``heart_attack_penalty`` per heart attack (health). A multi-objective agent gets them apart instead:

* ``reward`` is a float32 vector of two: the step's change of ``work_done / time_elapsed`` (productivity; an
  episode's sum is its final score) and ``-1`` for a heart attack, else ``0`` (health; an episode's sum is minus its
  heart attacks). As in MO-Gymnasium, both are maximised.
* ``reward_space`` is a ``Box`` of those two, ``reward_dim`` is 2.
* [`pareto_front`][heartpole.mo.MOHeartPole.pareto_front] gives the known Pareto front: the productivity-risk
  frontier's ``(expected score, -expected heart attacks)`` ([`heartpole.optimum.frontier`][heartpole.optimum.frontier]).

Scalarised with the weights ``(1, heart_attack_penalty)`` (MO-Gymnasium's ``LinearReward``), the vector gives back
HeartPole's own reward: bit for bit with float32 weights, as the env computes it (the score change less the
penalty, rounded to float32); float64 weights compute the same difference without that last rounding.

``import heartpole`` registers the id; MO-Gymnasium itself (``pip install "heartpole[mo]"``) is needed only for its
wrappers and agents::

    import mo_gymnasium, heartpole
    env = mo_gymnasium.make("mo-heartpole-v0")
    obs, info = env.reset(seed=0)
    obs, vector, terminated, truncated, info = env.step(0)   # vector: [score change, -heart attack]
"""

from __future__ import annotations

import functools
import warnings
from typing import Any

import numpy as np
from gymnasium import spaces

from heartpole.env import HeartPole
from heartpole.model import score

REWARD_NAMES = ("productivity", "health")
"""The reward vector's entries, in order: the score's change, minus the heart attacks."""


class MOHeartPole(HeartPole):
    """HeartPole-v0 (any of its keyword arguments) with the vector reward ``(score change, -heart attack)``.

    Everything else (observations, actions, ``info``, episodes, seeds) is HeartPole's: the same seed gives the
    same episode as ``gymnasium.make("HeartPole-v0")``. See the module docstring.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._kwargs = {k: v for k, v in kwargs.items() if k not in ("render_mode", "heart_attack_penalty")}
        if args:  # HeartPole's positional arguments: heart_attack_proclivity, max_steps
            self._kwargs.update(zip(("heart_attack_proclivity", "max_steps"), args[:2]))
        self.reward_space = spaces.Box(
            low=np.array([-np.inf, -1.0], dtype=np.float32), high=np.array([np.inf, 0.0], dtype=np.float32)
        )
        """The reward vector's space: the score's change (unbounded), and -1 or 0."""
        self.reward_dim = 2
        """The number of objectives."""
        self._score = np.float32(0.0)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """HeartPole's ``reset``; the score the first step's change is measured from."""
        observation, info = super().reset(seed=seed, options=options)
        state = self.state
        self._score = np.float32(score(np.float32(state["work_done"]), np.float32(state["time_elapsed"])))
        return observation, info

    def step(self, action: Any) -> tuple[np.ndarray, np.ndarray, bool, bool, dict[str, Any]]:  # type: ignore[override]
        """HeartPole's ``step``, with the reward as the vector ``(score change, -heart attack)`` (float32)."""
        observation, _, terminated, truncated, info = super().step(action)
        new = np.float32(info["score"])
        change = new - self._score  # float32 arithmetic, as the step computed its reward's score part
        self._score = new
        reward = np.array([change, -1.0 if info["heart_attack"] else 0.0], dtype=np.float32)
        return observation, reward, terminated, truncated, info

    def pareto_front(self, gamma: float = 1.0) -> list[np.ndarray]:
        """The known Pareto front: the productivity-risk frontier's ``(expected final score, -expected heart attacks
        per episode)`` points for this env's parameters, none dominated (MO-Gymnasium's ``pareto_front``).

        Solved once per parameters (minutes the first time; the optimum's cache keeps each penalty's solution). Where
        a penalty is not solved (a solver refuses it) its point is left out, with a ``UserWarning`` naming the
        penalties. Where drinks may pay the point is the drinking solver's policy, a lower bound on the optimum (see
        [`heartpole.optimum.tradeoff`][heartpole.optimum.tradeoff]).

        Args:
            gamma: the discount; only 1.0 (the frontier is of whole episodes' score and heart attacks).

        Raises:
            ValueError: ``gamma`` other than 1.0.
            NotCoveredError: parameters the optimum does not cover (the reason says why).
        """
        if gamma != 1.0:
            raise ValueError(
                f"gamma={gamma!r}: HeartPole's Pareto front is undiscounted (the episode's final score and heart "
                "attacks); only gamma=1.0 is accepted"
            )
        front, missing = _front(tuple(sorted(self._kwargs.items(), key=lambda item: item[0])))
        if missing:
            warnings.warn(
                f"the Pareto front leaves out penalties {', '.join(f'{p:g}' for p in missing)}, where drinks may pay "
                "and no solver covers the optimum: the front shown is the part solved",
                UserWarning,
                stacklevel=2,
            )
        return [np.array(point, dtype=np.float64) for point in front]


@functools.lru_cache(maxsize=8)
def _front(kwargs: tuple[tuple[str, Any], ...]) -> tuple[list[tuple[float, float]], list[float]]:
    """The frontier's Pareto front for HeartPole-v0 with ``kwargs``, and the penalties left out."""
    from heartpole.optimum import tradeoff

    # the drinking solver looked up at each call, not bound at import: a test can stand in for it
    solved = tradeoff.frontier("HeartPole-v0", env_kwargs=dict(kwargs), drinking=tradeoff.package_drinking)
    return solved.pareto_front(), [penalty for penalty, _ in solved.missing]
