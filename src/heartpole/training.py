"""Stable-Baselines3 glue: the VecEnv adapter, the training reward, presets, training runs, multi-seed IQMs.

This module needs the optional ``train`` extra (``pip install 'heartpole[train]'``: Stable-Baselines3,
PyTorch, tqdm); ``import heartpole`` never imports it. Its parts:

* :class:`HeartPoleSB3VecEnv` puts HeartPole's native vector env behind SB3's ``VecEnv`` interface, so
  PPO, A2C and DQN step all envs with one array operation. Episodes end by truncation only, reported as
  ``TimeLimit.truncated=True`` with the last observation in ``info["terminal_observation"]``, so SB3
  bootstraps through the time limit; each ended episode's ``info["episode"]`` holds its true return
  (``"r"``), length (``"l"``), heart attacks and final score, read by SB3's logger like ``Monitor``'s.
* :class:`TrainingReward` is the reward the agent learns from: the env's own reward, or the
  *shaped* reward of the default preset (see below). Evaluation always uses the env's true return.
* :class:`TrainConfig` and :data:`PRESETS`: the ``default`` preset (PPO that solves HeartPole-v0) and the
  ``tutorial`` preset (the tutorial's DQN with ``net_arch=[16, 16]`` and SB3's default hyperparameters).
* :func:`train_run` trains one seed and writes ``model.zip``, ``vecnormalize.pkl`` (when observations are
  normalised), ``heartpole.json``, ``learning_curve.csv`` and ``evaluation.json`` (2,000 episodes of
  :func:`heartpole.evaluation.evaluate` on the saved files); :func:`train_seeds` trains several seeds and
  summarises them with the interquartile mean and a bootstrap interval (rliable's recommendation).

Why naive training fails on HeartPole, and what the default does about it
--------------------------------------------------------------------------
An episode's return is its final score (``work_done / time_elapsed``, about 0.33 at best) minus 100 per
heart attack. Two things bury the score under noise:

1. *The heart-attack coin.* Even a policy that never drinks suffers ~1.24 attacks an episode (the risk
   floor ``0.5 * sigmoid(-6)`` per step), a standard deviation of ~110 per episode against a score signal of
   ~0.3. The default replaces the realised ``-100 x attack`` by ``-100 x (heart_attack_risk - floor)``:
   given the state, the attack is a coin flipped with probability ``info["heart_attack_risk"]``, so the
   expected penalty is the same for every policy (the attack itself still happens in the dynamics and
   resets blood pressure), the constant floor changes no ranking, and the coin's noise is gone.
2. *The telescoping score.* The env's score reward is the change of ``work_done / time_elapsed``; written
   out it is ``(productivity - score_before x half_hours) / time_elapsed``: a half-hour's work minus the
   running score per half-hour spent, shrunk by the time elapsed, so that late steps weigh ~1/2000 of early
   ones. The default undoes the shrinkage and fixes the running score at a rate ``score_rate``:
   ``(productivity - score_rate x half_hours) / horizon``. Its sum, ``(work - rate x time) / horizon``, is
   Dinkelbach's linearisation of the ratio ``work / time``: with ``rate`` at the best achievable score,
   maximising it maximises the score, and near that optimum it equals ``score - rate`` for episodes of
   ``horizon`` half-hours. ``horizon`` (2,000: 1,000 decisions plus ~60 sleeps of 16) keeps the score part
   in the same units as the risk part, so the trade-off between work and heart attacks is the env's.

Both changes make the reward a function of the state and action only, stationary in time, so a discount
of 0.95 suffices (a coffee's blood pressure fades by 0.97 a half-hour; a day lasts ~17 decisions), and
PPO's bootstrapping through the time limit is exact. Rewards are normalised by VecNormalize, whose
running statistics are kept over a window (``reward_stats_window`` samples) rather than the whole run:
early on the agent drinks and the risk penalty is large; once it stops drinking, what is left are the
small differences between sleep times, and statistics remembering the drinking phase would shrink them
to nothing.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NoReturn, cast

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole.model import TIME_ELAPSED, heart_attack_risk
from heartpole.policies import (  # the run's file names and the algorithms, each defined once, there
    CURVE_COLUMNS,
    CURVE_NAME,
    MODEL_NAME,
    SB3_ALGORITHMS,
    SIDECAR_NAME,
    VECNORMALIZE_NAME,
)
from heartpole.stats import bootstrap_interval, interquartile_mean

if TYPE_CHECKING:
    from tqdm import tqdm

    from heartpole.vector import HeartPoleVectorEnv

TRAIN_EXTRA = "pip install 'heartpole[train]'"
"""How to install what training needs (Stable-Baselines3 with PyTorch, tqdm)."""

try:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import VecEnv, VecNormalize
    from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn
except ImportError as error:  # pragma: no cover - `heartpole train` checks for the modules first
    raise ImportError(f"heartpole.training needs Stable-Baselines3 and PyTorch: {TRAIN_EXTRA}") from error

EVALUATION_FILE = "evaluation.json"
SUMMARY_FILE = "summary.json"

SOLVED_HEART_ATTACKS = 1.30
"""Issue 3's bar for HeartPole-v0: at most this many heart attacks per episode over 2,000 evaluation
episodes ..."""
SOLVED_SCORE = 0.30
"""... and at least this final productivity score. Other envs have their own bar,
:func:`heartpole.registry.solved_bar`, which gives these two for v0."""
RATE_SHARE_OF_BEST = 0.98
"""The shaped reward's default rate as a share of the env's best known score: 0.32 for v0 (its tuned value),
0.68 for v1."""


# ------------------------------------------------------------------------------------------------------
# the training reward


@dataclass(frozen=True)
class TrainingReward:
    """The reward an agent is trained on. Evaluation always uses the env's own return.

    Attributes:
        expected_risk: replace the realised ``-penalty x heart_attack`` by
            ``-penalty x (heart_attack_risk - risk at zero blood pressure)``: the same expectation for every
            policy (up to a constant per step), without the coin's noise.
        score_rate: ``None`` keeps the env's score reward (the change of ``work_done / time_elapsed``); a
            number ``rate`` uses ``(productivity - rate x half_hours_passed) / horizon`` instead; ``"auto"``
            uses the running work per half-hour of the policy being trained as the rate (an exponential
            average over about ``rate_window`` steps of all envs together), for variants whose best score
            is unknown.
        rate_window: the averaging window of ``score_rate="auto"``, in vector steps.
        horizon: half-hours of a typical episode, the scale of the score part when ``score_rate`` is set.
    """

    expected_risk: bool = False
    score_rate: float | Literal["auto"] | None = None
    rate_window: float = 2000.0
    horizon: float = 2000.0

    def __post_init__(self) -> None:
        rate = self.score_rate
        number = isinstance(rate, (int, float)) and not isinstance(rate, bool) and math.isfinite(rate)
        if rate is not None and rate != "auto" and not number:
            raise ValueError(f"score_rate must be a finite number, 'auto' or None, got {rate!r}")
        if not (math.isfinite(self.rate_window) and self.rate_window >= 1):
            raise ValueError(f"rate_window must be a number >= 1, got {self.rate_window!r}")
        if not (math.isfinite(self.horizon) and self.horizon > 0):
            raise ValueError(f"horizon must be a positive number, got {self.horizon!r}")

    @property
    def is_env_reward(self) -> bool:
        """Whether this is exactly the env's reward."""
        return not self.expected_risk and self.score_rate is None

    def describe(self) -> str:
        """One line for humans."""
        if self.is_env_reward:
            return "the env's reward (score change - 100 x heart attack)"
        score = (
            "score change"
            if self.score_rate is None
            else f"(productivity - {self.score_rate} x half-hours) / {self.horizon:g}"
        )
        risk = "100 x (heart-attack risk - floor)" if self.expected_risk else "100 x heart attack"
        return f"{score} - {risk}"


ENV_REWARD = TrainingReward()
SHAPED_REWARD = TrainingReward(expected_risk=True, score_rate=0.32, horizon=2000.0)


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
            variant from :func:`heartpole.register_variant`).
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
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        from heartpole.policies import quiet_version_warnings

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
        self.risk_floor = float(heart_attack_risk(0.0, params.heart_attack_proclivity))
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
        """Remember the actions (one integer per env) for :meth:`step_wait`."""
        self._actions = np.asarray(actions).reshape(self.num_envs)  # the vector env validates the values

    def step_wait(self) -> VecEnvStepReturn:
        """Step all envs: ``(observations, training rewards, dones, infos)``; see the class docstring."""
        if self._obs is None or self._actions is None:
            raise RuntimeError("call reset() and step_async() before step_wait()")
        before = self._obs
        obs, env_reward, terminated, truncated, info = self.vector_env.step(self._actions)
        self._actions = None
        done = terminated | truncated
        after = np.where(done[:, None], info["final_obs"], obs) if done.any() else obs
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
        """The reward of :attr:`reward` for one step, from the env's reward, observations and ``info``.

        ``before`` and ``after`` are the observations around the step (``after`` is the last observation
        of an episode that just ended); their ``time_elapsed`` difference is the half-hours the step took.
        With ``score_rate="auto"`` each call also folds the step's work and half-hours into the running rate.
        """
        env_reward = np.asarray(env_reward, dtype=np.float64)
        if self.reward.is_env_reward:
            return env_reward
        attack = np.asarray(info["heart_attack"], dtype=np.float64)
        if self.reward.score_rate is None:
            score_part = env_reward + self.penalty * attack
        else:
            half_hours = after[:, TIME_ELAPSED].astype(np.float64) - before[:, TIME_ELAPSED]
            worked = np.asarray(info["productivity"], dtype=np.float64)
            rate = self._rate if self.reward.score_rate == "auto" else self.reward.score_rate
            score_part = (worked - rate * half_hours) / self.reward.horizon
            if self.reward.score_rate == "auto":
                decay = 1.0 - 1.0 / self.reward.rate_window
                self._work = decay * self._work + worked.sum()
                self._time = decay * self._time + half_hours.sum()
                self._rate = self._work / self._time
        if self.reward.expected_risk:
            risk = np.asarray(info["heart_attack_risk"], dtype=np.float64)
            return score_part - self.penalty * (risk - self.risk_floor)
        return score_part - self.penalty * attack

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
    if normalize_observations or normalize_rewards:
        venv = VecNormalize(venv, norm_obs=normalize_observations, norm_reward=normalize_rewards, gamma=gamma)
    return venv


# ------------------------------------------------------------------------------------------------------
# callbacks


class RewardStatsWindow(BaseCallback):
    """Keep VecNormalize's reward statistics to about the last ``window`` samples.

    ``VecNormalize`` divides rewards by the standard deviation of discounted returns seen so far, weighing
    the whole run alike. Capping the sample count makes the statistics an exponential moving estimate that
    follows the current policy (whose returns shrink by orders of magnitude once it stops drinking).
    """

    def __init__(self, normalizer: VecNormalize, window: float) -> None:
        super().__init__()
        if not window > 0:
            raise ValueError(f"window must be positive, got {window!r}")
        self.normalizer, self.window = normalizer, float(window)

    def _on_step(self) -> bool:
        rms = self.normalizer.ret_rms
        if rms.count > self.window:
            rms.count = self.window
        return True


class LearningCurve(BaseCallback):
    """Collect training episodes' true return, heart attacks and final score into rows of a learning curve.

    A row is written each time at least ``episodes_per_row`` episodes have ended since the last row (and at
    the end of training for any left over); it holds the timestep and the means over those episodes.
    """

    def __init__(self, episodes_per_row: int = 16) -> None:
        super().__init__()
        self.episodes_per_row = max(1, int(episodes_per_row))
        self.rows: list[dict[str, float]] = []
        self._pending: list[dict[str, Any]] = []

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", ()):
            episode = info.get("episode")
            if episode is not None and "heart_attacks" in episode:
                self._pending.append(episode)
        if len(self._pending) >= self.episodes_per_row:
            self._flush()
        return True

    def _on_training_end(self) -> None:
        self._flush()

    def _flush(self) -> None:
        if not self._pending:
            return
        self.rows.append(
            {
                "timesteps": int(self.num_timesteps),
                "mean_return": float(np.mean([e["r"] for e in self._pending])),
                "heart_attacks": float(np.mean([e["heart_attacks"] for e in self._pending])),
                "score": float(np.mean([e["score"] for e in self._pending])),
            }
        )
        self._pending = []


class ProgressBar(BaseCallback):
    """A tqdm progress bar over the timesteps (shown when stderr is a terminal, or when ``force`` is set)."""

    def __init__(self, total: int, description: str = "training", force: bool = False) -> None:
        super().__init__()
        self.total, self.description, self.force = int(total), description, force
        self._bar: tqdm[NoReturn] | None = None

    def _on_training_start(self) -> None:
        from tqdm import tqdm

        disable = False if self.force or os.environ.get("HEARTPOLE_PROGRESS") == "1" else None
        self._bar = tqdm(total=self.total, desc=self.description, unit="step", unit_scale=True, disable=disable)

    def _on_step(self) -> bool:
        if self._bar is not None:
            self._bar.update(min(self.training_env.num_envs, self.total - self._bar.n))
        return True

    def _on_training_end(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


# ------------------------------------------------------------------------------------------------------
# configurations and presets


@dataclass(frozen=True)
class TrainConfig:
    """Everything a training run depends on; :func:`train_run` records it in ``heartpole.json``.

    Attributes:
        algo: ``"ppo"``, ``"a2c"`` or ``"dqn"``.
        preset: the preset it came from (informative).
        env_id: the HeartPole id to train on.
        timesteps: env steps to train for (all envs together).
        n_envs: episodes stepped side by side by the adapter.
        seed: seeds the model (PyTorch, NumPy) and the env.
        net_arch: hidden layer sizes of the MLP (actor and critic each, or the Q-network).
        hyperparameters: keyword arguments of the SB3 algorithm (``gamma``, ``learning_rate``, ...).
        reward: the training reward.
        normalize_observations, normalize_rewards: use ``VecNormalize`` for observations / rewards.
        reward_stats_window: cap of VecNormalize's reward-statistics sample count (``None``: no cap).
        env_kwargs: the env's keyword arguments.
    """

    algo: str = "ppo"
    preset: str = "default"
    env_id: str = "HeartPole-v0"
    timesteps: int = 400_000
    n_envs: int = 16
    seed: int = 0
    net_arch: tuple[int, ...] = (64, 64)
    hyperparameters: Mapping[str, Any] = field(default_factory=dict)
    reward: TrainingReward = SHAPED_REWARD
    normalize_observations: bool = True
    normalize_rewards: bool = True
    reward_stats_window: float | None = 100_000
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.algo not in SB3_ALGORITHMS:
            raise ValueError(f"unknown algorithm {self.algo!r}; choose one of {', '.join(SB3_ALGORITHMS)}")
        for name in ("timesteps", "n_envs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be a whole number >= 1, got {value!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed must be a whole number >= 0, got {self.seed!r}")
        if not self.net_arch or any(int(n) < 1 for n in self.net_arch):
            raise ValueError(f"net_arch must list positive layer sizes, got {self.net_arch!r}")

    @property
    def gamma(self) -> float:
        """The discount factor (SB3's default 0.99 unless the hyperparameters set one)."""
        return float(self.hyperparameters.get("gamma", 0.99))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe."""
        out = asdict(self)
        out["net_arch"] = list(self.net_arch)
        out["hyperparameters"] = dict(self.hyperparameters)
        out["env_kwargs"] = dict(self.env_kwargs)
        out["reward"] = {**asdict(self.reward), "description": self.reward.describe()}
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TrainConfig:
        """The inverse of :meth:`to_dict` (``reward["description"]`` is ignored); unknown keys raise ValueError."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown configuration keys {unknown}; known: {', '.join(sorted(known))}")
        values = dict(data)
        if "reward" in values:
            reward = {k: v for k, v in dict(values["reward"]).items() if k != "description"}
            values["reward"] = TrainingReward(**reward)
        if "net_arch" in values:
            values["net_arch"] = tuple(int(n) for n in values["net_arch"])
        for key in ("hyperparameters", "env_kwargs"):
            if key in values:
                values[key] = dict(values[key])
        return cls(**values)


DEFAULT_HYPERPARAMETERS: Mapping[str, Mapping[str, Any]] = {
    # PPO: 16 envs x 128 steps per update, big minibatches (few gradient steps, fast on 2 cores), a
    # discount matching the reward's time scales, and an entropy bonus so the policy keeps trying to
    # stay awake while it learns that sleeping at once undoes the drinking it is unlearning.
    "ppo": {
        "n_steps": 128,
        "batch_size": 512,
        "n_epochs": 10,
        "learning_rate": 3e-4,
        "gamma": 0.95,
        "gae_lambda": 0.95,
        "clip_range": 0.2,
        "ent_coef": 0.01,
    },
    "a2c": {
        "n_steps": 16,
        "learning_rate": 7e-4,
        "gamma": 0.95,
        "gae_lambda": 0.95,
        "ent_coef": 0.01,
    },
    "dqn": {
        "learning_rate": 2.5e-4,
        "buffer_size": 200_000,
        "learning_starts": 10_000,
        "batch_size": 256,
        "gamma": 0.95,
        "train_freq": 1,
        "gradient_steps": 1,
        "target_update_interval": 2_000,
        "exploration_fraction": 0.2,
        "exploration_final_eps": 0.01,
    },
}

PRESETS = ("default", "tutorial")
PRESET_HELP = {
    "default": "the settings that solve HeartPole-v0: shaped reward, VecNormalize, 16 envs, tuned PPO",
    "tutorial": "the tutorial's setup: SB3 defaults, net_arch [16, 16], the env's own reward, one env",
}
DEFAULT_ALGO = {"default": "ppo", "tutorial": "dqn"}
DEFAULT_TIMESTEPS = {"default": 400_000, "tutorial": 500_000}


def preset_config(
    preset: str = "default", algo: str | None = None, *, score_rate: float | str = "best", **overrides: Any
) -> TrainConfig:
    """The :class:`TrainConfig` of ``preset`` for ``algo`` (default: the preset's own), with ``overrides``.

    ``default`` trains on the shaped reward with VecNormalize and 16 envs, with the hyperparameters of
    :data:`DEFAULT_HYPERPARAMETERS`; PPO is the one that solves HeartPole-v0. ``tutorial`` is the
    tutorial's run: SB3's default hyperparameters, ``net_arch=[16, 16]``, the env's reward, no
    normalisation, one env and 500,000 timesteps (DQN unless ``algo`` says otherwise).

    ``score_rate`` is the shaped reward's rate (default preset only): ``"best"`` (default) is
    :data:`RATE_SHARE_OF_BEST` of the trained env's best known score (0.32 for v0, 0.68 for v1; see
    :func:`heartpole.registry.best_known_rate`), or ``"auto"`` where none is known; ``"auto"`` estimates
    it while training; a number fixes it.

    Raises:
        ValueError: an unknown preset or algorithm, or a bad override.
    """
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; choose one of {', '.join(PRESETS)}")
    algo = DEFAULT_ALGO[preset] if algo is None else algo
    if algo not in SB3_ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of {', '.join(SB3_ALGORITHMS)}")
    if preset == "tutorial":
        if score_rate != "best":
            raise ValueError("the tutorial preset trains on the env's own reward, which has no score rate")
        base = TrainConfig(
            algo=algo,
            preset=preset,
            timesteps=DEFAULT_TIMESTEPS[preset],
            n_envs=1,
            net_arch=(16, 16),
            hyperparameters={},
            reward=ENV_REWARD,
            normalize_observations=False,
            normalize_rewards=False,
            reward_stats_window=None,
        )
        return replace(base, **overrides)
    base = TrainConfig(algo=algo, preset=preset, hyperparameters=dict(DEFAULT_HYPERPARAMETERS[algo]))
    config = replace(base, **overrides)
    if "reward" not in overrides:
        rate = shaped_reward_rate(config.env_id, config.env_kwargs, score_rate)
        config = replace(config, reward=replace(SHAPED_REWARD, score_rate=rate))
    return config


def shaped_reward_rate(
    env_id: str, env_kwargs: Mapping[str, Any], score_rate: float | str = "best"
) -> float | Literal["auto"]:
    """The shaped reward's rate for ``env_id``: see :func:`preset_config`'s ``score_rate``."""
    from heartpole.policies import env_dynamics
    from heartpole.registry import best_known_rate

    if score_rate == "auto":
        return "auto"
    if score_rate == "best":
        best = best_known_rate(env_dynamics(env_id, env_kwargs))
        return "auto" if best is None else round(RATE_SHARE_OF_BEST * best, 2)
    number = isinstance(score_rate, (int, float)) and not isinstance(score_rate, bool) and math.isfinite(score_rate)
    if not number:
        raise ValueError(f"score_rate must be 'best', 'auto' or a finite number, got {score_rate!r}")
    return float(score_rate)


def env_solved_bar(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The solved bar of ``env_id`` (:func:`heartpole.registry.solved_bar`) as a JSON-safe dict."""
    from heartpole.policies import env_dynamics
    from heartpole.registry import solved_bar

    bar = solved_bar(env_dynamics(env_id, env_kwargs))
    return {"heart_attacks_per_episode_at_most": bar.heart_attacks_at_most, "score_at_least": bar.score_at_least}


def meets_bar(evaluation: Mapping[str, Any], bar: Mapping[str, Any]) -> bool:
    """Whether an evaluation's heart attacks and score meet ``bar`` (from :func:`env_solved_bar`)."""
    score_ok = bar["score_at_least"] is None or evaluation["score"] >= bar["score_at_least"]
    return bool(evaluation["heart_attacks_per_episode"] <= bar["heart_attacks_per_episode_at_most"] and score_ok)


PRESET_FORMAT = "heartpole-preset/1"
"""The ``format`` field of a preset file (:func:`save_preset`)."""


def save_preset(config: TrainConfig, path: str | os.PathLike[str], **notes: Any) -> Path:
    """Write ``config`` (all but its seed) as a JSON preset file that ``heartpole train --preset FILE`` reads.

    ``notes`` (e.g. where the configuration came from) are stored under ``"notes"`` and ignored on loading.
    The file is written to a temporary name and moved into place.
    """
    path = Path(path)
    data = {"format": PRESET_FORMAT, "config": {k: v for k, v in config.to_dict().items() if k != "seed"}}
    if notes:
        data["notes"] = notes
    staging = path.with_name(f".{path.name}.partial")
    _write_json(staging, data)
    os.replace(staging, path)
    return path


def load_preset(path: str | os.PathLike[str]) -> TrainConfig:
    """The :class:`TrainConfig` of a preset file written by :func:`save_preset` (seed 0).

    Raises:
        ValueError: the file is not JSON, not a preset file, or holds a bad configuration.
        OSError: the file cannot be read.
    """
    try:
        data = json.loads(Path(path).read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"preset file {path} is not JSON: {error}") from None
    if not isinstance(data, dict) or data.get("format") != PRESET_FORMAT or not isinstance(data.get("config"), dict):
        raise ValueError(f"{path} is not a preset file (expected a JSON object with format {PRESET_FORMAT!r})")
    try:
        return TrainConfig.from_dict(data["config"])
    except TypeError as error:
        raise ValueError(f"preset file {path}: {error}") from None


# ------------------------------------------------------------------------------------------------------
# training


@dataclass
class TrainedModel:
    """What :func:`train_model` returns: the model, its VecNormalize (or ``None``), curve and timing."""

    model: BaseAlgorithm
    normalizer: VecNormalize | None
    curve: list[dict[str, float]]
    seconds: float


def build_model(config: TrainConfig) -> tuple[BaseAlgorithm, VecEnv]:
    """The SB3 model of ``config`` on a freshly made, seeded adapter (``VecNormalize``-wrapped if asked)."""
    import stable_baselines3 as sb3

    env = make_vec_env(
        config.env_id,
        config.n_envs,
        seed=config.seed,
        reward=config.reward,
        normalize_observations=config.normalize_observations,
        normalize_rewards=config.normalize_rewards,
        gamma=config.gamma,
        env_kwargs=config.env_kwargs,
    )
    algorithm = {"ppo": sb3.PPO, "a2c": sb3.A2C, "dqn": sb3.DQN}[config.algo]
    hyperparameters = dict(config.hyperparameters)
    if config.algo == "ppo" and "batch_size" in hyperparameters:  # a minibatch cannot exceed the rollout
        rollout = int(hyperparameters.get("n_steps", 2048)) * config.n_envs
        hyperparameters["batch_size"] = min(int(hyperparameters["batch_size"]), rollout)
    model = algorithm(
        "MlpPolicy",
        env,
        policy_kwargs={"net_arch": list(config.net_arch)},
        seed=config.seed,
        device="cpu",
        verbose=0,
        **hyperparameters,
    )
    return model, env


def train_model(config: TrainConfig, *, progress: bool = False, description: str | None = None) -> TrainedModel:
    """Train ``config``'s model for ``config.timesteps`` steps; nothing is written to disk."""
    model, env = build_model(config)
    normalizer = env if isinstance(env, VecNormalize) else None
    curve = LearningCurve()
    callbacks: list[BaseCallback] = [curve]
    if normalizer is not None and config.normalize_rewards and config.reward_stats_window is not None:
        callbacks.insert(0, RewardStatsWindow(normalizer, config.reward_stats_window))
    if progress:
        callbacks.append(ProgressBar(config.timesteps, description or f"training {config.algo} seed {config.seed}"))
    started = time.perf_counter()
    model.learn(total_timesteps=config.timesteps, callback=callbacks)
    seconds = time.perf_counter() - started
    if normalizer is not None:
        normalizer.training = False
    return TrainedModel(model, normalizer, curve.rows, seconds)


def train_run(
    config: TrainConfig,
    folder: str | os.PathLike[str],
    *,
    eval_episodes: int = 2000,
    eval_seed: int = 0,
    progress: bool = False,
    final_folder: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Train one seed and write its files into ``folder`` (created if missing); return its summary.

    Files: ``model.zip``, ``vecnormalize.pkl`` (when observations or rewards are normalised),
    ``heartpole.json`` (the configuration, timings and versions), ``learning_curve.csv`` and
    ``evaluation.json`` (:func:`heartpole.evaluation.evaluate` of the saved model over ``eval_episodes``
    episodes with ``eval_seed``, loaded back from the files by :func:`heartpole.policies.load_policy`, as
    ``heartpole evaluate`` does). ``final_folder`` is where the files will end up if ``folder`` is a
    staging folder (see :func:`staged_output`); the evaluation names the model by that path.
    """
    from heartpole.evaluation import evaluate
    from heartpole.policies import load_policy

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    trained = train_model(config, progress=progress)
    trained.model.save(folder / MODEL_NAME)
    if trained.normalizer is not None:
        trained.normalizer.save(str(folder / VECNORMALIZE_NAME))
    write_curve(folder / CURVE_NAME, trained.curve)
    from heartpole.policies import file_sha256

    sidecar: dict[str, Any] = {
        "algo": config.algo,
        "env_id": config.env_id,
        "seed": config.seed,
        "timesteps": config.timesteps,
        "preset": config.preset,
        "policy": "MlpPolicy",
        "config": config.to_dict(),
        "model": MODEL_NAME,
        "model_sha256": file_sha256(folder / MODEL_NAME),
        # the statistics saved with this model: load_policy applies these and no others
        "vecnormalize": VECNORMALIZE_NAME if trained.normalizer is not None else None,
        "vecnormalize_sha256": file_sha256(folder / VECNORMALIZE_NAME) if trained.normalizer is not None else None,
        "train_seconds": round(trained.seconds, 2),
        "versions": _versions(),
    }
    _write_json(folder / SIDECAR_NAME, sidecar)
    eval_started = time.perf_counter()
    policy = load_policy(str(folder / MODEL_NAME), config.env_id, env_kwargs=dict(config.env_kwargs))
    policy.name = str(Path(final_folder if final_folder is not None else folder) / MODEL_NAME)  # type: ignore[attr-defined]
    result = evaluate(
        policy,
        config.env_id,
        episodes=eval_episodes,
        seed=eval_seed,
        env_kwargs=dict(config.env_kwargs),
        progress=progress,
    )
    evaluation = result.to_dict()
    _write_json(folder / EVALUATION_FILE, evaluation)
    eval_seconds = time.perf_counter() - eval_started
    sidecar.update(eval_seconds=round(eval_seconds, 2), wall_seconds=round(time.perf_counter() - started, 2))
    _write_json(folder / SIDECAR_NAME, sidecar)
    return run_summary(config, evaluation, trained.seconds, sidecar["wall_seconds"])


def run_summary(
    config: TrainConfig, evaluation: Mapping[str, Any], train_seconds: float, wall: float
) -> dict[str, Any]:
    """One run's line in a summary: seed, evaluation figures, whether it is solved, timings.

    Solved means a regret whose 95% upper bound is at most :data:`heartpole.evaluation.SOLVED_REGRET` where
    the optimum is known (:mod:`heartpole.optimum`), and the env's heart-attack and score bar elsewhere.
    """
    from heartpole.evaluation import SOLVED_REGRET

    bar = env_solved_bar(config.env_id, config.env_kwargs)
    by_regret = evaluation.get("solved")
    return {
        "seed": config.seed,
        "mean_return": evaluation["mean_return"],
        "ci95": evaluation["ci95"],
        "expected_return": evaluation["expected_return"],
        "expected_ci95": evaluation["expected_ci95"],
        "heart_attacks_per_episode": evaluation["heart_attacks_per_episode"],
        "score": evaluation["score"],
        "drinks_per_episode": evaluation["drinks_per_episode"],
        "sleeps_per_episode": evaluation["sleeps_per_episode"],
        "regret": evaluation.get("regret"),
        "regret_ci95": evaluation.get("regret_ci95"),
        "solved": meets_bar(evaluation, bar) if by_regret is None else by_regret,
        "solved_bar": bar if by_regret is None else {"regret_at_most": SOLVED_REGRET},
        "train_seconds": round(train_seconds, 2),
        "wall_seconds": round(wall, 2),
    }


def train_seeds(
    config: TrainConfig,
    seeds: Sequence[int],
    folder: str | os.PathLike[str],
    *,
    eval_episodes: int = 2000,
    eval_seed: int = 0,
    progress: bool = False,
    on_run: Callable[[dict[str, Any]], None] | None = None,
    final_folder: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Train ``config`` once per seed into ``folder/seed_<s>/`` and write ``folder/summary.json``.

    The summary lists every seed's figures and aggregates them across seeds with the interquartile mean
    and a 95% percentile-bootstrap interval over seeds (:func:`aggregate`), and counts the seeds that meet
    the solved bar. ``on_run`` is called with each seed's summary as soon as it is done; ``final_folder``
    is as for :func:`train_run`.
    """
    if not seeds:
        raise ValueError("give at least one seed")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be distinct, got {list(seeds)}")
    folder = Path(folder)
    runs = []
    for seed in seeds:
        run = train_run(
            replace(config, seed=int(seed)),
            folder / f"seed_{seed}",
            eval_episodes=eval_episodes,
            eval_seed=eval_seed,
            progress=progress,
            final_folder=Path(final_folder) / f"seed_{seed}" if final_folder is not None else None,
        )
        runs.append(run)
        if on_run is not None:
            on_run(run)
    summary = seeds_summary(config, seeds, runs, eval_episodes=eval_episodes, eval_seed=eval_seed)
    _write_json(folder / SUMMARY_FILE, summary)
    return summary


def seeds_summary(
    config: TrainConfig,
    seeds: Sequence[int],
    runs: Sequence[Mapping[str, Any]],
    *,
    eval_episodes: int,
    eval_seed: int,
) -> dict[str, Any]:
    """The content of ``summary.json`` for ``runs`` (:func:`train_run` results) of ``config`` over ``seeds``."""
    return {
        "config": replace(config, seed=int(seeds[0])).to_dict() | {"seed": None},
        "seeds": [int(s) for s in seeds],
        "eval_episodes": eval_episodes,
        "eval_seed": eval_seed,
        "runs": list(runs),
        "aggregate": aggregate(runs),
        "solved_bar": runs[0]["solved_bar"] if runs else env_solved_bar(config.env_id, config.env_kwargs),
        "solved_seeds": sum(run["solved"] for run in runs),
    }


# ------------------------------------------------------------------------------------------------------
# aggregates across seeds

AGGREGATED = ("mean_return", "expected_return", "heart_attacks_per_episode", "score", "wall_seconds")


def aggregate(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """For each figure of :data:`AGGREGATED`: IQM, 95% bootstrap interval of the IQM, mean, min and max."""
    out: dict[str, Any] = {"seeds": len(runs), "method": "interquartile mean over seeds, 95% percentile bootstrap"}
    for key in AGGREGATED:
        values = [float(run[key]) for run in runs if run.get(key) is not None]
        if not values:
            continue
        out[key] = {
            "iqm": float(interquartile_mean(values)),
            "iqm_ci95": list(bootstrap_interval(values)),
            "mean": float(np.mean(values)),
            "min": float(np.min(values)),
            "max": float(np.max(values)),
        }
    return out


AGGREGATE_LABELS: tuple[tuple[str, str, int], ...] = (
    ("heart_attacks_per_episode", "heart attacks/episode", 3),
    ("score", "score", 4),
    ("mean_return", "return", 2),
    ("expected_return", "expected-risk return", 3),
    ("wall_seconds", "wall time (s)", 0),
)


def aggregate_figures(aggregate_: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(label, "iqm [low, high]")`` for each figure of an :func:`aggregate` result, for tables and text."""
    figures = []
    for key, label, digits in AGGREGATE_LABELS:
        if key in aggregate_:
            item = aggregate_[key]
            low, high = item["iqm_ci95"]
            figures.append((label, f"{item['iqm']:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"))
    return figures


# ------------------------------------------------------------------------------------------------------
# output folders and files


def check_output_folder(out: str | os.PathLike[str], force: bool = False) -> Path:
    """Check that training may write to ``out``, before any training starts; return it as a ``Path``.

    ``out`` may be missing or an empty folder. An existing non-empty folder needs ``force``, and even then
    it must be a folder ``heartpole train`` wrote (it holds ``heartpole.json`` or ``summary.json``):
    ``--force`` never deletes anything else.

    Raises:
        FileExistsError: ``out`` is a file, or a non-empty folder without ``force``.
        PermissionError: ``force`` on a folder that ``heartpole train`` did not write.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"--out {out} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise FileExistsError(f"--out {out} exists and is not empty; pass --force to replace it")
        if not ((out / SIDECAR_NAME).is_file() or (out / SUMMARY_FILE).is_file()):
            raise PermissionError(
                f"--out {out} was not written by 'heartpole train' (no {SIDECAR_NAME} or {SUMMARY_FILE}); "
                "refusing to replace it even with --force"
            )
    return out


@contextmanager
def staged_output(out: str | os.PathLike[str], force: bool = False) -> Iterator[Path]:
    """Write into a temporary folder beside ``out``; move it to ``out`` only if the block succeeds.

    On any error or interruption the temporary folder is removed and ``out`` is left as it was, so a
    failed run never leaves half its files. With ``force``, a previous run in ``out`` is replaced.
    """
    out = check_output_folder(out, force)
    created = [p for p in [out.parent, *out.parent.parents] if not p.exists()]
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        os.chmod(staging, 0o777 & ~_umask())  # mkdtemp makes folders private; give the usual permissions
        yield staging
        check_output_folder(out, force)
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".old", dir=out.parent))
            os.replace(out, old / out.name)
            os.replace(staging, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        for folder in created:  # nearest first; only folders this call made and left empty
            try:
                folder.rmdir()
            except OSError:
                break
        raise


def _umask() -> int:
    current = os.umask(0)
    os.umask(current)
    return current


def write_curve(path: Path, rows: Sequence[Mapping[str, float]]) -> None:
    """Write the learning curve as CSV with :data:`CURVE_COLUMNS`."""
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=CURVE_COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({key: row[key] for key in CURVE_COLUMNS})


def read_curve(path: str | os.PathLike[str]) -> list[dict[str, float]]:
    """Read a learning curve written by :func:`write_curve`."""
    with Path(path).open(newline="") as handle:
        return [{key: float(row[key]) for key in CURVE_COLUMNS} for row in csv.DictReader(handle)]


def _write_json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")


def _versions() -> dict[str, str]:
    import stable_baselines3
    import torch

    return {
        "heartpole": heartpole.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "gymnasium": gym.__version__,
        "numpy": np.__version__,
    }
