"""HeartPole's native vector env behind Stable-Baselines3's ``VecEnv`` interface."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole.model import TIME_ELAPSED
from heartpole.rewards import risk_floor, training_reward

if TYPE_CHECKING:
    from heartpole.vector import HeartPoleVectorEnv

from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from heartpole.parameters import check_integer
from heartpole.records import normalize_env
from heartpole.training.reward import ENV_REWARD, TrainingReward

# ------------------------------------------------------------------------------------------------------
# the adapter


class HeartPoleSB3VecEnv(VecEnv):
    """HeartPole's native vector env as a Stable-Baselines3 ``VecEnv``: all envs in one array step.

    The env is built with ``gymnasium.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point",
    autoreset_mode=SAME_STEP)``: an episode that ends is reset within the same step, as SB3 expects. For
    each env whose episode ended, ``infos[i]`` holds

    * ``"terminal_observation"``: the episode's last observation (Gymnasium's ``info["final_obs"]``);
    * ``"TimeLimit.truncated"``: ``True``, since HeartPole episodes end by the step limit only, so on-policy
      algorithms bootstrap from the last observation's value and DQN's replay buffer does not treat it
      as terminal;
    * ``"episode"``: ``{"r": return, "l": length, "t": seconds since creation, "heart_attacks": n,
      "score": final score}``, with the env's true return whatever the training reward, read by SB3's
      logger (``rollout/ep_rew_mean``) like the statistics of ``Monitor`` / ``VecMonitor``.

    Every step's ``infos[i]`` also holds the env's per-step values: ``heart_attack``,
    ``heart_attack_risk``, ``productivity`` and ``score``.

    The native env is one object with one generator: ``seed(s)`` (SB3 calls it with the model's seed)
    seeds it at the next ``reset``; ``get_attr``, ``set_attr`` and ``env_method`` reach the vector env
    itself, their results repeated once per index.

    Args:
        env_id: a HeartPole id with a native vector entry point (``HeartPole-v0``, ``HeartPole-v1``, or a
            variant from [`heartpole.register_variant`][heartpole.registry.register_variant]).
        num_envs: episodes stepped side by side.
        reward: the training reward (default: the env's own).
        env_kwargs: the env's keyword arguments (``max_steps``, ``heart_attack_proclivity``, ...).
    """

    def __init__(
        self,
        env_id: str = "HeartPole-v0",
        num_envs: int = 8,
        *,
        reward: TrainingReward = ENV_REWARD,
        env_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        check_integer("num_envs", num_envs, 1)
        from heartpole.registry import quiet_version_warnings

        self.env_id = env_id
        with quiet_version_warnings():  # training on v0 is deliberate
            self.vector_env = gym.make_vec(
                env_id,
                num_envs=int(num_envs),
                vectorization_mode="vector_entry_point",
                autoreset_mode=AutoresetMode.SAME_STEP,
                **dict(env_kwargs or {}),
            )
        base = cast("HeartPoleVectorEnv", self.vector_env.unwrapped)
        params = base.dynamics.params
        self.reward = reward
        self.penalty = float(params.heart_attack_penalty)
        self.risk_floor = risk_floor(params.heart_attack_proclivity)
        super().__init__(int(num_envs), self.vector_env.single_observation_space, self.vector_env.single_action_space)
        self._obs: np.ndarray | None = None
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(self.num_envs)
        self._attacks = np.zeros(self.num_envs, dtype=np.int64)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._created = time.perf_counter()
        self._work, self._time, self._rate = 0.0, 0.0, 0.0

    @property
    def rate(self) -> float | None:
        """The rate the score part charges per half-hour: fixed, the running estimate ("auto"), or None."""
        if self.reward.score_rate == "auto":
            return self._rate
        return None if self.reward.score_rate is None else float(self.reward.score_rate)

    # -- VecEnv ---------------------------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        """Start every env afresh, seeded by the last ``seed()`` call if any; return the observations."""
        obs, _ = self.vector_env.reset(seed=self._seeds[0])
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._obs = obs
        self._returns[:] = 0.0
        self._attacks[:] = 0
        self._lengths[:] = 0
        return obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        """Remember the actions (one integer per env) for
        [`step_wait`][heartpole.training.adapter.HeartPoleSB3VecEnv.step_wait]."""
        self._actions = np.asarray(actions).reshape(self.num_envs)  # the vector env validates the values

    def step_wait(self) -> VecEnvStepReturn:
        """Step all envs: ``(observations, training rewards, dones, infos)``; see the class docstring."""
        if self._obs is None or self._actions is None:
            raise RuntimeError("call reset() and step_async() before step_wait()")
        before = self._obs
        obs, env_reward, terminated, truncated, info = self.vector_env.step(self._actions)
        self._actions = None
        done = terminated | truncated
        after = obs
        if done.any():  # the ended episodes' last observations (final_obs holds None for the others)
            after = obs.copy()
            after[done] = np.stack(info["final_obs"][done])
        reward = self.training_reward(env_reward, before, after, info)
        self._returns += env_reward
        self._attacks += info["heart_attack"]
        self._lengths += 1
        attack, risk, worked, score = (info[k] for k in ("heart_attack", "heart_attack_risk", "productivity", "score"))
        infos: list[dict[str, Any]] = [
            {"heart_attack": bool(attack[i]), "heart_attack_risk": float(risk[i]), "productivity": float(worked[i]),
             "score": float(score[i])}
            for i in range(self.num_envs)
        ]  # fmt: skip
        if done.any():
            final_score = info["final_info"]["score"]
            elapsed = round(time.perf_counter() - self._created, 6)
            for i in np.flatnonzero(done):
                infos[i]["terminal_observation"] = info["final_obs"][i].copy()
                infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                infos[i]["episode"] = {
                    "r": float(self._returns[i]),
                    "l": int(self._lengths[i]),
                    "t": elapsed,
                    "heart_attacks": int(self._attacks[i]),
                    "score": float(final_score[i]),
                }
            self._returns[done], self._attacks[done], self._lengths[done] = 0.0, 0, 0
        self._obs = obs
        return obs.copy(), reward.astype(np.float32), done, infos

    def training_reward(
        self, env_reward: np.ndarray, before: np.ndarray, after: np.ndarray, info: Mapping[str, Any]
    ) -> np.ndarray:
        """The reward of `reward` for one step, from the env's reward, observations and ``info``.

        ``before`` and ``after`` are the observations around the step (``after`` is the last observation
        of an episode that just ended); their ``time_elapsed`` difference is the half-hours the step took.
        With ``score_rate="auto"`` each call also folds the step's work and half-hours into the running rate.
        """
        env_reward = np.asarray(env_reward, dtype=np.float64)
        if self.reward.is_env_reward:
            return env_reward
        half_hours = after[:, TIME_ELAPSED].astype(np.float64) - before[:, TIME_ELAPSED]
        worked = np.asarray(info["productivity"], dtype=np.float64)
        rate = self._rate if self.reward.score_rate == "auto" else self.reward.score_rate
        reward: np.ndarray = training_reward(
            env_reward,
            np.asarray(info["heart_attack"], dtype=np.float64),
            np.asarray(info["heart_attack_risk"], dtype=np.float64),
            worked,
            half_hours,
            penalty=self.penalty,
            floor=self.risk_floor,
            expected=self.reward.expected_risk,
            score_rate=rate,
            horizon=self.reward.horizon,
        )
        if self.reward.score_rate == "auto":
            decay = 1.0 - 1.0 / self.reward.rate_window
            self._work = decay * self._work + worked.sum()
            self._time = decay * self._time + half_hours.sum()
            self._rate = self._work / self._time
        return reward

    def close(self) -> None:
        """Close the native vector env."""
        self.vector_env.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The vector env's attribute ``attr_name``, once per index."""
        value = getattr(self.vector_env.unwrapped, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the vector env's attribute (it is shared by all indices)."""
        setattr(self.vector_env.unwrapped, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        """Call the vector env's method once; its result is repeated once per index."""
        chosen = self._indices(indices)
        if not chosen:
            return []
        result = getattr(self.vector_env.unwrapped, method_name)(*method_args, **kwargs)
        return [result for _ in chosen]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """``True`` for SB3's ``Monitor`` only: each env reports its episodes as ``Monitor`` would.

        SB3's ``evaluate_policy`` (and so ``EvalCallback``) reads ``info["episode"]["r"]``, the env's true
        return, only when it is told the envs are ``Monitor``-wrapped; otherwise it sums the rewards it is
        given, here the training reward. The native vector env wraps no single envs in anything else.
        """
        monitored = wrapper_class is Monitor
        return [monitored for _ in self._indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """One RGB frame per env when made with ``render_mode="rgb_array"``."""
        frames = self.vector_env.render()
        return list(cast("tuple[np.ndarray, ...]", frames)) if frames is not None else [None] * self.num_envs

    def _indices(self, indices: VecEnvIndices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        chosen = [int(indices)] if isinstance(indices, (int, np.integer)) else [int(i) for i in indices]
        for i in chosen:
            if not -self.num_envs <= i < self.num_envs:  # negative indices count from the end, as in a list
                raise IndexError(f"env index {i} is out of range for {self.num_envs} envs")
        return chosen


def make_vec_env(
    env_id: str = "HeartPole-v0",
    n_envs: int = 16,
    *,
    seed: int | None = None,
    reward: TrainingReward = ENV_REWARD,
    normalize_observations: bool = False,
    normalize_rewards: bool = False,
    gamma: float = 0.99,
    env_kwargs: Mapping[str, Any] | None = None,
) -> VecEnv:
    """The adapter, seeded, wrapped in ``VecNormalize`` when observations or rewards are normalised."""
    venv: VecEnv = HeartPoleSB3VecEnv(env_id, n_envs, reward=reward, env_kwargs=env_kwargs)
    if seed is not None:
        venv.seed(seed)
    return normalize_env(venv, observations=normalize_observations, rewards=normalize_rewards, gamma=gamma)
