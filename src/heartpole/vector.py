"""HeartPole as a native NumPy vector env: many people, one array operation per formula."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from heartpole import kernel
from heartpole import render as rendering
from heartpole.actions import Action
from heartpole.env import build_dynamics, check_render_mode, episode_length, observation_space
from heartpole.model import Variable, check_integer

INFO_KEYS = ("action", "heart_attack", "heart_attack_risk", "productivity", "score")
"""The keys of a step's ``info`` (each with its ``_key`` mask)."""


class HeartPoleVectorEnv(VectorEnv):
    """``num_envs`` independent HeartPole episodes stepped together, with the single env's dynamics.

    The same compiled step as :class:`heartpole.HeartPole` (:func:`heartpole.kernel.step_envs`) runs
    over a ``(num_variables, num_envs)`` float32 state, in place. Each env's random numbers are keyed by
    one 64-bit draw from ``self.np_random`` at ``reset``, in env order, and counted from there on (through
    autoresets too): env 0 after ``reset(seed=s)`` follows ``HeartPole().reset(seed=s)`` bit for bit.
    Keyword arguments are the single env's.

    Spaces are batched: observations ``(num_envs, 6)`` float32, actions ``MultiDiscrete([4] * num_envs)``.
    Observations are fresh copies in column-major (Fortran) order, as ``CartPoleVectorEnv``'s are: each
    variable is contiguous; ``np.ascontiguousarray(obs)`` gives rows. ``info`` holds arrays of
    ``num_envs`` values (:data:`INFO_KEYS`: ``action``, the index of the action taken, where the single env
    gives its name; ``heart_attack``, ``heart_attack_risk``, ``productivity``, ``score``), with
    Gymnasium's ``_key`` masks (one shared mask array: every key is present for every env).

    Every episode starts at ``reset`` and is truncated after ``max_steps`` decisions, so all envs' episodes
    end together. Autoreset: by default Gymnasium's ``NEXT_STEP`` mode: the call to ``step`` after the
    episodes ended starts new ones, ignoring the actions, and returns the first observations with reward 0,
    ``truncated=False`` and an empty ``info`` (as ``reset`` does). With
    ``autoreset_mode=AutoresetMode.SAME_STEP`` the envs restart within the step that ends them; the last
    observations and infos are then in ``info["final_obs"]`` and ``info["final_info"]`` (the mode
    Stable-Baselines3's VecEnv expects).

    Invalid actions (wrong shape, not integers, out of range) raise ``ValueError`` and change nothing.

    Episode length: ``max_steps``, or Gymnasium's name for it, ``max_episode_steps`` (which
    ``gymnasium.make_vec`` passes from the registered spec); when both are given ``max_steps`` wins, and
    ``env.spec.max_episode_steps`` reports the length the env truncates at.

    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 8, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        heart_attack_proclivity: float = 0.5,
        max_steps: int | None = None,
        render_mode: str | None = None,
        *,
        actions: Sequence[Action] | None = None,
        variables: Sequence[Variable] | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
        **model_params: Any,
    ) -> None:
        check_integer("num_envs", num_envs, 1)
        check_render_mode(render_mode, self.metadata["render_modes"])
        modes = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
        if autoreset_mode not in modes and autoreset_mode not in [m.value for m in modes]:
            raise ValueError(f"autoreset_mode must be one of {[m.value for m in modes]}, got {autoreset_mode!r}")
        max_steps = episode_length(max_steps, max_episode_steps, max_steps_wins=True)
        self.dynamics = build_dynamics(
            heart_attack_proclivity, max_steps, actions, variables, model_params, "HeartPoleVectorEnv.__init__"
        )
        self.num_envs = int(num_envs)
        self.max_steps = int(max_steps)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "autoreset_mode": AutoresetMode(autoreset_mode)}
        self.single_action_space = spaces.Discrete(len(self.dynamics.actions))
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = observation_space(self.dynamics)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._envs = np.zeros((len(self.dynamics.variables), self.num_envs), dtype=np.float32)  # the states
        self._rng = np.zeros((3, self.num_envs), dtype=np.uint32)
        self._started = False
        self._steps = 0  # every env's episode starts at reset and lasts max_steps: they end together
        self._ended = False  # NEXT_STEP autoreset: the episodes ended on the last step
        self._last_actions = np.full(self.num_envs, -1)
        self._last_attacks = np.zeros(self.num_envs, dtype=bool)
        self._heart_attacks = np.zeros(self.num_envs, dtype=np.int64)

    @property
    def spec(self) -> EnvSpec | None:
        """The spec ``gymnasium.make_vec`` made this env from, its ``max_episode_steps`` this env's ``max_steps``."""
        return self.__dict__.get("_spec")

    @spec.setter
    def spec(self, spec: EnvSpec | None) -> None:
        # make_vec passes the registered max_episode_steps along with the caller's max_steps, which wins;
        # a max_episode_steps the caller gave that disagrees with both is refused.
        if spec is not None:
            given = spec.kwargs.get("max_episode_steps", self.max_steps)
            if given not in (self.max_steps, spec.max_episode_steps):
                raise ValueError(
                    f"max_steps={self.max_steps} and max_episode_steps={given} disagree; they are the same "
                    "number (the episode length), so give one of them"
                )
            spec = copy.copy(spec)
            spec.kwargs = {**spec.kwargs, "max_episode_steps": self.max_steps}
            spec.max_episode_steps = self.max_steps
        self.__dict__["_spec"] = spec

    @property
    def state(self) -> np.ndarray:
        """The current states, ``(num_variables, num_envs)`` float32 (a copy)."""
        if not self._started:
            raise ResetNeeded("call reset() before reading the state of HeartPoleVectorEnv")
        return self._envs.copy()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every env afresh (fact 0, then waking up). ``options`` is accepted and unused."""
        super().reset(seed=seed)
        self._rng[:] = kernel.generator_states(self.np_random, self.num_envs)
        self._started = True
        self._restart()
        return self._observations(), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its action; see the class docstring for autoreset and ``info``."""
        action = self._validate(actions)
        if not self._started:
            raise ResetNeeded("call reset() before step() in HeartPoleVectorEnv")
        n = self.num_envs
        if self._ended:  # NEXT_STEP autoreset: every env starts afresh, ignoring its action
            self._restart()
            nothing = np.zeros(n, dtype=bool)
            return self._observations(), np.zeros(n, dtype=np.float32), nothing, nothing.copy(), {}
        results = kernel.new_results(n)  # fresh: they go out as they are
        kernel.step_envs(self._envs, results, action, self._rng, self.dynamics.packed, self.dynamics.layout)
        reward, worked, risk, attack, new_score = results
        self._steps += 1
        ended = self._steps >= self.max_steps
        truncated, terminated = np.full(n, ended), np.zeros(n, dtype=bool)
        present = np.ones(n, dtype=bool)  # one mask for all keys: every key is present for every env
        info: dict[str, Any] = {}
        for key, value in zip(INFO_KEYS, (action, attack, risk, worked, new_score)):
            info[key], info["_" + key] = value, present
        if self.render_mode is not None:  # copies: `action` and `attack` go out in info
            self._last_actions, self._last_attacks = action.astype(np.int64), attack.copy()
            self._heart_attacks += attack
        obs = self._observations()
        if ended and self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP:
            info["final_obs"], info["_final_obs"] = obs, truncated.copy()
            info["final_info"] = {key: value for key, value in info.items() if not key.startswith(("final", "_final"))}
            info["_final_info"] = truncated.copy()
            self._restart()
            obs = self._observations()
        else:
            self._ended = ended
        return obs, reward, terminated, truncated, info

    def render(self) -> tuple[np.ndarray, ...] | None:
        """With ``render_mode="rgb_array"``: one RGB frame per env, drawing its current state."""
        if self.render_mode is None or not self._started:
            return None
        names = self.dynamics.names
        frames = []
        for i in range(self.num_envs):
            last = int(self._last_actions[i])
            frames.append(
                rendering.draw_frame(
                    dict(zip(names, self._envs[:, i].tolist())),
                    action=self.dynamics.actions[last].name if last >= 0 else None,
                    heart_attack=bool(self._last_attacks[i]),
                    heart_attacks=int(self._heart_attacks[i]),
                    step=self._steps,
                    max_steps=self.max_steps,
                )
            )
        return tuple(frames)

    # ----------------------------------------------------------------------------------------------------
    def _observations(self) -> np.ndarray:
        """A copy of the state as ``(num_envs, num_variables)``, column-major like ``CartPoleVectorEnv``'s."""
        return self._envs.copy().T

    def _restart(self) -> None:
        """Start every env afresh; their random numbers go on from their counters."""
        everyone = np.ones(self.num_envs, dtype=bool)
        kernel.reset_envs(self._envs, self._rng, everyone, self.dynamics.packed, self.dynamics.layout)
        self._steps, self._ended = 0, False
        self._last_actions[:], self._last_attacks[:], self._heart_attacks[:] = -1, False, 0  # for rendering

    def _validate(self, actions: Any) -> np.ndarray:
        """The actions as the kernel's index array (a copy), or ``ValueError`` naming what is wrong and what
        is accepted."""
        n, num_actions = self.num_envs, len(self.dynamics.actions)
        expected = f"an integer array of shape ({n},) with values in 0..{num_actions - 1}"
        array = np.asarray(actions)
        if array.shape != (n,):
            raise ValueError(f"HeartPoleVectorEnv.step expects {expected}; got shape {array.shape}")
        if array.dtype.kind not in "iu":
            raise ValueError(f"HeartPoleVectorEnv.step expects {expected}; got dtype {array.dtype}")
        unsigned = array.view(array.dtype.str.replace("i", "u"))  # negative values become huge ones
        if n and unsigned.max() >= num_actions:
            raise ValueError(
                f"HeartPoleVectorEnv.step expects {expected}; got values from {array.min()} to {array.max()}"
            )
        return array.astype(kernel.ACTION_DTYPE)
