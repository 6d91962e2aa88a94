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

from heartpole import render as rendering
from heartpole.actions import Action
from heartpole.env import build_dynamics, check_render_mode, episode_length, observation_space
from heartpole.model import Variable


class HeartPoleVectorEnv(VectorEnv):
    """``num_envs`` independent HeartPole episodes stepped together, with the single env's dynamics.

    The same :class:`heartpole.dynamics.Dynamics` as :class:`heartpole.HeartPole` runs on a
    ``(num_variables, num_envs)`` float32 state, updated in place, with one row of float32 uniforms per
    random column drawn from ``self.np_random`` (23 random bits each; see :func:`uniform_rows`). Keyword
    arguments are the single env's.

    Spaces are batched: observations ``(num_envs, 6)`` float32, actions ``MultiDiscrete([4] * num_envs)``.
    Observations are fresh copies in column-major (Fortran) order, as ``CartPoleVectorEnv``'s are: each
    variable is contiguous; ``np.ascontiguousarray(obs)`` gives rows. ``info`` holds arrays of
    ``num_envs`` values (``heart_attack``, ``heart_attack_risk``, ``productivity``, ``score``), with
    Gymnasium's ``_key`` masks (one shared mask array: every key is present for the same envs).

    Autoreset: by default Gymnasium's ``NEXT_STEP`` mode. An env whose episode was truncated is reset by
    the *next* call to ``step``, which ignores its action and returns its first observation with reward 0
    and ``truncated=False``. With ``autoreset_mode=AutoresetMode.SAME_STEP`` the env is reset within the
    step that ends it; its last observation and info are then in ``info["final_obs"]`` and
    ``info["final_info"]`` (the mode Stable-Baselines3's VecEnv expects).

    Invalid actions (wrong shape, not integers, out of range) raise ``ValueError`` and change nothing.

    Episode length: ``max_steps``, or Gymnasium's name for it, ``max_episode_steps`` (which
    ``gymnasium.make_vec`` passes from the registered spec); when both are given ``max_steps`` wins, and
    ``env.spec.max_episode_steps`` reports the length the env truncates at.

    Memory: creating the env lets glibc's malloc keep up to 512 bytes per env of freed memory for reuse
    (see :func:`keep_step_memory`); without it every step page-faulted its fresh arrays back in.
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
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        check_render_mode(render_mode, self.metadata["render_modes"])
        modes = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
        if AutoresetMode(autoreset_mode) not in modes:
            raise ValueError(f"autoreset_mode must be one of {[m.value for m in modes]}, got {autoreset_mode!r}")
        max_steps = episode_length(max_steps, max_episode_steps, max_steps_wins=True)
        self.dynamics = build_dynamics(heart_attack_proclivity, max_steps, actions, variables, model_params)
        self.num_envs = int(num_envs)
        self.max_steps = int(max_steps)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "autoreset_mode": AutoresetMode(autoreset_mode)}
        self.single_action_space = spaces.Discrete(len(self.dynamics.actions))
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = observation_space(self.dynamics)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._state: np.ndarray | None = None
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._last_actions = np.full(self.num_envs, -1)
        self._last_attacks = np.zeros(self.num_envs, dtype=bool)
        self._heart_attacks = np.zeros(self.num_envs, dtype=np.int64)
        keep_step_memory(STEP_MEMORY_ROWS * 4 * self.num_envs)

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
        if self._state is None:
            raise ResetNeeded("call reset() before reading the state of HeartPoleVectorEnv")
        return self._state.copy()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every env afresh (fact 0, then waking up). ``options`` is accepted and unused."""
        super().reset(seed=seed)
        wake = self.np_random.random(self.num_envs, dtype=np.float32)
        self._state = self.dynamics.initial_state(wake)
        self._steps[:] = 0
        self._needs_reset[:] = False
        self._forget_last_steps(np.ones(self.num_envs, dtype=bool))
        return self._observations(), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its action; see the class docstring for autoreset and ``info``."""
        action = self._validate(actions)
        if self._state is None:
            raise ResetNeeded("call reset() before step() in HeartPoleVectorEnv")
        uniforms = uniform_rows(self.np_random, self.dynamics.num_uniforms, self.num_envs)
        reward, worked, risk, attack, new_score = self.dynamics.transition(self._state, action, uniforms)
        self._steps += 1
        truncated = self._steps >= self.max_steps
        terminated = np.zeros(self.num_envs, dtype=bool)
        info = {"heart_attack": attack, "heart_attack_risk": risk, "productivity": worked, "score": new_score}
        if self._needs_reset.any():  # NEXT_STEP autoreset: these envs start afresh and ignore their action
            restart = self._needs_reset
            self._restart(restart, uniforms[self.dynamics.wake_uniform])
            reward[restart], truncated[restart], attack[restart] = 0.0, False, False
            action = np.where(restart, -1, action)
            info = self._masked(info, ~restart)
        else:
            info = self._masked(info, None)
        if self.render_mode is not None:  # copies: the caller owns `action`, and `attack` goes out in info
            self._last_actions, self._last_attacks = action.copy(), attack.copy()
            self._heart_attacks += attack
        obs = self._observations()
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP:
            if truncated.any():
                info["final_obs"] = np.where(truncated[:, None], obs, np.nan).astype(np.float32)
                info["_final_obs"] = truncated.copy()
                info["final_info"] = {k: v for k, v in info.items() if not k.startswith(("final", "_final"))}
                info["_final_info"] = truncated.copy()
                self._restart(truncated, self.np_random.random(self.num_envs, dtype=np.float32))
                obs = self._observations()
        else:
            self._needs_reset = truncated.copy()
        return obs, reward, terminated, truncated, info

    def render(self) -> tuple[np.ndarray, ...] | None:
        """With ``render_mode="rgb_array"``: one RGB frame per env, drawing its current state."""
        if self.render_mode is None or self._state is None:
            return None
        names = self.dynamics.names
        frames = []
        for i in range(self.num_envs):
            last = int(self._last_actions[i])
            frames.append(
                rendering.draw_frame(
                    dict(zip(names, self._state[:, i].tolist())),
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
        assert self._state is not None
        return self._state.copy().T

    def _restart(self, which: np.ndarray, wake_uniforms: np.ndarray) -> None:
        assert self._state is not None
        self._state[:, which] = self.dynamics.initial_state(wake_uniforms[which])
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


# A step's arrays (state, draws, action table, temporaries, results) add up to about this many rows of
# num_envs float32 values.
STEP_MEMORY_ROWS = 64
# glibc raises its thresholds only for a freed block of at most 32 MiB, its header and page rounding included.
LARGEST_THRESHOLD = 2**25 - 2**12


def keep_step_memory(num_bytes: int) -> None:
    """Let glibc's malloc keep up to ``2 * num_bytes`` of freed memory instead of returning it to the OS.

    At start, glibc gives freed heap memory back to the OS as soon as more than 128 kB of it is free, so
    the fresh arrays of every step were page-faulted in again: about 140 page faults a step at 16,384 envs,
    a third of the step's time. Freeing one block that was allocated with ``mmap`` (here, an untouched
    ``np.empty`` of ``num_bytes``) raises glibc's mmap and trim thresholds to its size and twice that
    (mallopt(3), "dynamic mmap threshold"), as freeing any large array does in a program. glibc ignores
    blocks over 32 MiB, so the block is capped just below. Other allocators are not affected.
    """
    np.empty(min(num_bytes, LARGEST_THRESHOLD), dtype=np.uint8)  # allocated, freed, its pages never touched


DRAW_BLOCK_VALUES = 16384  # uniforms per draw: 64 kB of float32, below glibc's mmap threshold
# Bit generators whose random_raw() gives 64 random bits per value; any other takes Generator.random's path.
RAW_64_BIT = (np.random.PCG64, np.random.PCG64DXSM, np.random.SFC64, np.random.Philox)


def uniform_rows(rng: np.random.Generator, rows: int, num_envs: int) -> list[np.ndarray]:
    """``rows`` float32 arrays of ``num_envs`` uniforms in [0, 1), 23 random bits each, drawn from ``rng``.

    Each 64-bit draw of ``rng``'s bit generator gives two uniforms: the top 23 bits of a 32-bit half become
    the mantissa of a float in [1, 2), then 1 is subtracted (exact). This is about twice as fast as
    ``rng.random(dtype=np.float32)`` (24 bits), and the draws were the vector env's largest cost. Rows are
    drawn in blocks of at most 64 kB: blocks that small are recycled by the memory allocator instead of
    being page-faulted in afresh on every step. A bit generator not in :data:`RAW_64_BIT` (MT19937, or a
    third party's) gives its rows through ``rng.random(dtype=np.float32)`` instead.
    """
    per_block = max(1, DRAW_BLOCK_VALUES // num_envs)
    drawn: list[np.ndarray] = []
    for start in range(0, rows, per_block):
        count = min(per_block, rows - start)
        drawn.extend(_uniforms(rng, count * num_envs).reshape(count, num_envs))
    return drawn


def _uniforms(rng: np.random.Generator, n: int) -> np.ndarray:
    if type(rng.bit_generator) not in RAW_64_BIT:  # e.g. MT19937's raw draws have 32 random bits, not 64
        return rng.random(n, dtype=np.float32)
    bits = rng.bit_generator.random_raw((n + 1) // 2).view(np.uint32)[:n]
    bits >>= 9
    bits |= 0x3F800000  # the exponent of 1.0
    uniforms = bits.view(np.float32)
    uniforms -= 1.0
    return uniforms
