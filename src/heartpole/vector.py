"""HeartPole as a native NumPy vector env: many people, one array operation per formula."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from heartpole import kernel
from heartpole import render as rendering
from heartpole.actions import Action
from heartpole.env import build_dynamics, check_render_mode, observation_space
from heartpole.model import Variable


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
    ``num_envs`` values (``action``, the index of the action taken or -1 where an env was restarted;
    ``heart_attack``, ``heart_attack_risk``, ``productivity``, ``score``), with Gymnasium's ``_key``
    masks (one shared mask array: every key is present for the same envs).

    Autoreset: by default Gymnasium's ``NEXT_STEP`` mode. An env whose episode was truncated is reset by
    the *next* call to ``step``, which ignores its action and returns its first observation with reward 0
    and ``truncated=False``. With ``autoreset_mode=AutoresetMode.SAME_STEP`` the env is reset within the
    step that ends it; its last observation and info are then in ``info["final_obs"]`` and
    ``info["final_info"]`` (the mode Stable-Baselines3's VecEnv expects).

    Invalid actions (wrong shape, not integers, out of range) raise ``ValueError`` and change nothing.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 8, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        heart_attack_proclivity: float = 0.5,
        max_steps: int = 1000,
        render_mode: str | None = None,
        *,
        actions: Sequence[Action] | None = None,
        variables: Sequence[Variable] | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **model_params: Any,
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        check_render_mode(render_mode, self.metadata["render_modes"])
        modes = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
        if AutoresetMode(autoreset_mode) not in modes:
            raise ValueError(f"autoreset_mode must be one of {[m.value for m in modes]}, got {autoreset_mode!r}")
        self.dynamics = build_dynamics(heart_attack_proclivity, max_steps, actions, variables, model_params)
        self.num_envs = int(num_envs)
        self.max_steps = int(max_steps)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "autoreset_mode": AutoresetMode(autoreset_mode)}
        self.single_action_space = spaces.Discrete(len(self.dynamics.actions))
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = observation_space(self.dynamics)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        n = len(self.dynamics.variables)
        self._envs = np.zeros((n + len(kernel.OUTPUTS), self.num_envs), dtype=np.float32)  # states, then results
        self._rng = np.zeros((3, self.num_envs), dtype=np.uint32)
        self._started = False
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._last_actions = np.full(self.num_envs, -1)
        self._last_attacks = np.zeros(self.num_envs, dtype=bool)
        self._heart_attacks = np.zeros(self.num_envs, dtype=np.int64)

    @property
    def state(self) -> np.ndarray:
        """The current states, ``(num_variables, num_envs)`` float32 (a copy)."""
        if not self._started:
            raise ResetNeeded("call reset() before reading the state of HeartPoleVectorEnv")
        return self._states().copy()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every env afresh (fact 0, then waking up). ``options`` is accepted and unused."""
        super().reset(seed=seed)
        self._rng[:] = kernel.generator_states(self.np_random, self.num_envs)
        self._started = True
        self._restart(np.ones(self.num_envs, dtype=bool))
        self._steps[:] = 0
        self._needs_reset[:] = False
        self._forget_last_steps(np.ones(self.num_envs, dtype=bool))
        return self._observations(), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its action; see the class docstring for autoreset and ``info``."""
        action = self._validate(actions)
        if not self._started:
            raise ResetNeeded("call reset() before step() in HeartPoleVectorEnv")
        kernel.step_envs(self._envs, action, self._rng, self.dynamics.packed, self.dynamics.layout)
        reward, worked, risk, attack, new_score = self._envs[len(self.dynamics.variables) :].copy()
        attack = attack > 0.5
        self._steps += 1
        truncated = self._steps >= self.max_steps
        terminated = np.zeros(self.num_envs, dtype=bool)
        info = {"action": action.copy(), "heart_attack": attack, "heart_attack_risk": risk, "productivity": worked,
                "score": new_score}
        if self._needs_reset.any():  # NEXT_STEP autoreset: these envs start afresh and ignore their action
            restart = self._needs_reset
            self._restart(restart)
            reward[restart], truncated[restart], attack[restart] = 0.0, False, False
            info["action"][restart] = -1
            info = self._masked(info, ~restart)
        else:
            info = self._masked(info, None)
        if self.render_mode is not None:  # copies: the caller owns `action`, and `attack` goes out in info
            self._last_actions, self._last_attacks = info["action"].copy(), attack.copy()
            self._heart_attacks += attack
        obs = self._observations()
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP:
            if truncated.any():
                info["final_obs"] = np.where(truncated[:, None], obs, np.nan).astype(np.float32)
                info["_final_obs"] = truncated.copy()
                info["final_info"] = {k: v for k, v in info.items() if not k.startswith(("final", "_final"))}
                info["_final_info"] = truncated.copy()
                self._restart(truncated)
                obs = self._observations()
        else:
            self._needs_reset = truncated.copy()
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
                    dict(zip(names, self._states()[:, i].tolist())),
                    action=self.dynamics.actions[last].name if last >= 0 else None,
                    heart_attack=bool(self._last_attacks[i]),
                    heart_attacks=int(self._heart_attacks[i]),
                    step=int(self._steps[i]),
                    max_steps=self.max_steps,
                )
            )
        return tuple(frames)

    # ----------------------------------------------------------------------------------------------------
    def _observations(self) -> np.ndarray:
        """A copy of the state as ``(num_envs, num_variables)``, column-major like ``CartPoleVectorEnv``'s."""
        return self._states().copy().T

    def _states(self) -> np.ndarray:
        """The states, ``(num_variables, num_envs)``: a view of the rows of ``_envs`` that hold them."""
        return self._envs[: len(self.dynamics.variables)]

    def _restart(self, which: np.ndarray) -> None:
        """Start the envs in ``which`` (a mask) afresh; their random numbers go on from their counters."""
        kernel.reset_envs(self._envs, self._rng, which, self.dynamics.packed, self.dynamics.layout)
        self._steps[which] = 0
        self._forget_last_steps(which)

    def _forget_last_steps(self, which: np.ndarray) -> None:
        """Rendering's memory of the envs in ``which`` (a mask): no last action, no heart attacks yet."""
        self._last_actions[which] = -1
        self._last_attacks[which] = False
        self._heart_attacks[which] = 0

    @staticmethod
    def _masked(info: dict[str, Any], mask: np.ndarray | None) -> dict[str, Any]:
        out: dict[str, Any] = {}
        present = np.ones(len(next(iter(info.values()))), dtype=bool) if mask is None else mask.copy()
        for key, value in info.items():
            out[key] = value
            out["_" + key] = present  # one mask for all keys: every key is present for the same envs
        return out

    def _validate(self, actions: Any) -> np.ndarray:
        """The actions as an index array, or ``ValueError`` naming what is wrong and what is accepted."""
        n, num_actions = self.num_envs, len(self.dynamics.actions)
        expected = f"an integer array of shape ({n},) with values in 0..{num_actions - 1}"
        array = np.asarray(actions)
        if array.shape != (n,):
            raise ValueError(f"HeartPoleVectorEnv.step expects {expected}; got shape {array.shape}")
        if array.dtype.kind not in "iu":
            raise ValueError(f"HeartPoleVectorEnv.step expects {expected}; got dtype {array.dtype}")
        index = array.astype(np.intp, copy=False)
        if n and index.view(np.uintp).max() >= num_actions:  # negative indices wrap around to huge ones
            raise ValueError(
                f"HeartPoleVectorEnv.step expects {expected}; got values from {array.min()} to {array.max()}"
            )
        return index
