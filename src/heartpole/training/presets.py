"""Training configurations: [`TrainConfig`][heartpole.training.presets.TrainConfig], the presets, preset files and
the solved bars."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal, TypeAlias

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole import files
from heartpole.parameters import Params, check_integer, is_number
from heartpole.policies import (  # the run's file names and the algorithms, each defined once, there
    SB3_ALGORITHMS,
)
from heartpole.records import env_solved_bar as env_solved_bar  # the bars every backend's summary reports
from heartpole.records import meets_bar as meets_bar
from heartpole.registry import check_heartpole_id
from heartpole.solved import V0_HEART_ATTACKS_AT_MOST, V0_SCORE_AT_LEAST
from heartpole.training.checks import check_config, check_net_arch
from heartpole.training.reward import ENV_REWARD, SHAPED_REWARD, TrainingReward

SOLVED_HEART_ATTACKS = V0_HEART_ATTACKS_AT_MOST
"""HeartPole-v0's heart-attack bar ([`heartpole.solved`][heartpole.solved] defines it)."""
SOLVED_SCORE = V0_SCORE_AT_LEAST
"""HeartPole-v0's score bar ([`heartpole.solved`][heartpole.solved] defines it)."""
ScoreRate: TypeAlias = Literal["best", "auto"] | float
"""How a preset sets the shaped reward's rate: ``"best"``
([`RATE_SHARE_OF_BEST`][heartpole.training.presets.RATE_SHARE_OF_BEST] of the env's best known score), ``"auto"``
(estimated while training) or the rate itself. See [`preset_config`][heartpole.training.presets.preset_config]."""
MAX_TRAINING_SEED = 2**32 - 1
"""The largest seed training takes: NumPy's legacy seeding (which Stable-Baselines3's ``set_random_seed`` calls)
takes 0 to 2**32 - 1."""
RATE_SHARE_OF_BEST = 0.98
"""The shaped reward's default rate as a share of the env's best known score: 0.32 for v0 (its tuned value),
0.68 for v1."""


# ------------------------------------------------------------------------------------------------------
# configurations and presets


@dataclass(frozen=True)
class TrainConfig:
    """Everything a training run depends on; `train_run` records it in ``heartpole.json``.

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
            check_integer(name, getattr(self, name), 1)
        if check_integer("seed", self.seed, 0) > MAX_TRAINING_SEED:
            raise ValueError(f"seed must be at most {MAX_TRAINING_SEED} (2**32 - 1, NumPy's seeding), got {self.seed}")
        check_net_arch(self.net_arch)

    @property
    def gamma(self) -> float:
        """The discount factor (SB3's default 0.99 unless the hyperparameters set one)."""
        return float(self.hyperparameters.get("gamma", 0.99))

    @property
    def heart_attack_penalty(self) -> float:
        """The env's heart-attack penalty: ``env_kwargs``' if set, else the registered variant's, else v0's (read
        without building the env, so that a configuration ``check_config`` would refuse still describes itself;
        NaN where the value is not a number, or the id is not registered and ``env_kwargs`` give none)."""
        import gymnasium as gym

        spec = gym.registry.get(self.env_id)  # gym.spec raises on an id this process has not registered
        default = math.nan if spec is None else spec.kwargs.get("heart_attack_penalty", Params.heart_attack_penalty)
        value = self.env_kwargs.get("heart_attack_penalty", default)
        return float(value) if is_number(value) else math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe."""
        out = asdict(self)
        out["net_arch"] = list(self.net_arch)
        out["hyperparameters"] = dict(self.hyperparameters)
        out["env_kwargs"] = dict(self.env_kwargs)
        out["reward"] = {**asdict(self.reward), "description": self.reward.describe(self.heart_attack_penalty)}
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TrainConfig:
        """The inverse of [`to_dict`][heartpole.training.presets.TrainConfig.to_dict] (``reward["description"]`` is
        ignored); unknown keys and values of the wrong kind raise ValueError naming the key."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown configuration keys {unknown}; known: {', '.join(sorted(known))}")
        values = dict(data)
        for key in ("reward", "hyperparameters", "env_kwargs"):
            if key in values and not isinstance(values[key], Mapping):
                raise ValueError(f"{key} must be an object (a JSON {{...}}), got {values[key]!r}")
            if key in values:
                values[key] = dict(values[key])
        if "reward" in values:
            reward = {k: v for k, v in values["reward"].items() if k != "description"}
            accepted = [f.name for f in fields(TrainingReward)]
            unknown = sorted(set(reward) - set(accepted))
            if unknown:
                raise ValueError(f"reward has no {', '.join(map(repr, unknown))}; it takes {accepted}")
            try:
                values["reward"] = TrainingReward(**reward)
            except ValueError as error:
                raise ValueError(f"reward.{error}") from None
        if "net_arch" in values:
            values["net_arch"] = check_net_arch(values["net_arch"])
        return cls(**values)


DEFAULT_HYPERPARAMETERS: Mapping[str, Mapping[str, Any]] = {
    # PPO: 16 envs x 128 steps per update, big minibatches (few gradient steps, fast on 2 cores), a
    # discount matching the reward's time scales, and an entropy bonus so the policy keeps trying to
    # stay awake while it learns that sleeping at once undoes the drinking it is unlearning. The learning
    # rate starts at 6e-4 and falls linearly to 0 (SB3's schedule): seeds 0-19 all met the regret bar
    # (worst 0.0095) where a constant 3e-4 met it with 17 of 20 (seeds 0, 6, 10 at 0.011-0.014), same
    # steps, same time (issue 34).
    "ppo": {
        "n_steps": 128,
        "batch_size": 512,
        "n_epochs": 10,
        "learning_rate": 6e-4,
        "anneal_learning_rate": True,
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
"""Each algorithm's hyperparameters when no preset gives them (the comments say why each was chosen)."""

PRESETS = ("default", "tutorial")
"""The presets `heartpole train --preset` offers ([`PRESET_HELP`][heartpole.training.presets.PRESET_HELP])."""
PRESET_HELP = {
    "default": "the settings that solve HeartPole-v0: shaped reward, VecNormalize, 16 envs, tuned PPO",
    "tutorial": "the tutorial's setup: SB3 defaults, net_arch [16, 16], the env's own reward, one env",
}
"""What each preset is, for `heartpole train --help`."""
DEFAULT_ALGO = {"default": "ppo", "tutorial": "dqn"}
DEFAULT_TIMESTEPS = {"default": 400_000, "tutorial": 500_000}
Backend: TypeAlias = Literal["sb3", "jax"]
"""``"sb3"``: Stable-Baselines3 (PyTorch); ``"jax"``: [`heartpole.jax.ppo`][heartpole.jax.ppo], the whole run
compiled."""
BACKENDS: tuple[Backend, ...] = ("sb3", "jax")
"""Where ``heartpole train`` runs: Stable-Baselines3, or PPO compiled with JAX
([`heartpole.jax.ppo`][heartpole.jax.ppo])."""
JAX_PPO_HYPERPARAMETERS: Mapping[str, Any] = {
    # The default preset's PPO with minibatches of 256 instead of 512: twice the gradient steps per env
    # step for the same arithmetic, which matters here because the JAX trainer's time goes into the
    # gradient steps, not into the env. Measured with 10 seeds (benchmarks/jax_presets.py): it met the
    # regret bar with 10 of 10 seeds at 250,000 steps, where the default met it with 8 of 10 (10 of 10 at
    # 400,000). Fewer epochs or an annealed learning rate (half the arithmetic) fell short at 250-300k.
    **DEFAULT_HYPERPARAMETERS["ppo"],
    "batch_size": 256,
    # constant: what the 10 and 20 seeds above were measured with (issue 34: 19 of 20; 18 of 20 on issue 31's draws)
    "learning_rate": 3e-4,
    "anneal_learning_rate": False,
}
"""The default preset's PPO hyperparameters with ``--backend jax``."""
JAX_PPO_TIMESTEPS = 250_000
"""The default preset's timesteps with ``--backend jax``."""


def preset_config(
    preset: str = "default",
    algo: str | None = None,
    *,
    score_rate: ScoreRate = "best",
    backend: str = "sb3",
    **overrides: Any,
) -> TrainConfig:
    """The [`TrainConfig`][heartpole.training.presets.TrainConfig] of ``preset`` for ``algo`` (default: the preset's
    own), with ``overrides``.

    ``default`` trains on the shaped reward with VecNormalize and 16 envs, with the hyperparameters of
    [`DEFAULT_HYPERPARAMETERS`][heartpole.training.presets.DEFAULT_HYPERPARAMETERS]; PPO is the one that solves
    HeartPole-v0. ``tutorial`` is the tutorial's run: SB3's default hyperparameters, ``net_arch=[16, 16]``, the env's
    reward, no normalisation, one env and 500,000 timesteps (DQN unless ``algo`` says otherwise).

    ``score_rate`` is the shaped reward's rate (default preset only): ``"best"`` (default) is
    [`RATE_SHARE_OF_BEST`][heartpole.training.presets.RATE_SHARE_OF_BEST] of the trained env's best known score (0.32
    for v0, 0.68 for v1; see [`heartpole.registry.best_known_rate`][heartpole.rates.best_known_rate]), or ``"auto"``
    where none is known; ``"auto"`` estimates it while training; a number fixes it.

    ``backend="jax"`` gives the default preset's PPO as ``heartpole train --backend jax`` runs it:
    [`JAX_PPO_HYPERPARAMETERS`][heartpole.training.presets.JAX_PPO_HYPERPARAMETERS] for
    [`JAX_PPO_TIMESTEPS`][heartpole.training.presets.JAX_PPO_TIMESTEPS] steps.

    Raises:
        ValueError: an unknown preset, algorithm or backend, or a bad override.

    >>> config = preset_config("tutorial")
    >>> config.algo, config.net_arch, config.n_envs, config.reward.is_env_reward
    ('dqn', (16, 16), 1, True)
    >>> preset_config(env_id="HeartPole-v1").reward.score_rate  # 98% of v1's best known score
    0.68
    """
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
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
    if backend == "jax" and algo == "ppo":
        base = replace(base, timesteps=JAX_PPO_TIMESTEPS, hyperparameters=dict(JAX_PPO_HYPERPARAMETERS))
    config = replace(base, **overrides)
    if "reward" not in overrides:
        rate = shaped_reward_rate(config.env_id, config.env_kwargs, score_rate)
        config = replace(config, reward=replace(SHAPED_REWARD, score_rate=rate))
    return config


def shaped_reward_rate(
    env_id: str, env_kwargs: Mapping[str, Any], score_rate: ScoreRate = "best"
) -> float | Literal["auto"]:
    """The shaped reward's rate for ``env_id``: see [`preset_config`][heartpole.training.presets.preset_config]'s
    ``score_rate``."""
    from heartpole.registry import best_known_rate, env_dynamics

    if score_rate == "auto":
        return "auto"
    if score_rate == "best":
        best = best_known_rate(env_dynamics(env_id, env_kwargs))
        return "auto" if best is None else round(RATE_SHARE_OF_BEST * best, 2)
    if not (is_number(score_rate) and math.isfinite(score_rate)):
        raise ValueError(f"score_rate must be 'best', 'auto' or a finite number, got {score_rate!r}")
    return float(score_rate)


PRESET_FORMAT = "heartpole-preset/1"
"""The ``format`` field of a preset file ([`save_preset`][heartpole.training.presets.save_preset])."""


def save_preset(config: TrainConfig, path: str | os.PathLike[str], **notes: Any) -> Path:
    """Write ``config`` (all but its seed) as a JSON preset file that ``heartpole train --preset FILE`` reads.

    ``notes`` (e.g. where the configuration came from) are stored under ``"notes"`` and ignored on loading.
    The file is written to a temporary name and moved into place.
    """
    data = {"format": PRESET_FORMAT, "config": {k: v for k, v in config.to_dict().items() if k != "seed"}}
    if notes:
        data["notes"] = notes
    return files.write_json(path, data)


def load_preset(path: str | os.PathLike[str]) -> TrainConfig:
    """The [`TrainConfig`][heartpole.training.presets.TrainConfig] of a preset file written by
    [`save_preset`][heartpole.training.presets.save_preset] (seed 0).

    Every key is checked ([`heartpole.training.checks.check_config`][heartpole.training.checks.check_config]) before
    the configuration is returned.

    Raises:
        ValueError: the file is not JSON, not a preset file, or holds a bad configuration (an ``env_id`` that is
            not a HeartPole id is refused before anything imports or makes it): the message names the file, the
            key, its value and what is accepted.
        OSError: the file cannot be read.
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"preset file {path} is not JSON text: {error}") from None
    found = data.get("format") if isinstance(data, dict) else None
    if isinstance(found, str) and found.startswith("heartpole-preset/") and found != PRESET_FORMAT:
        raise ValueError(f"preset file {path} has format {found!r}, made by another version of HeartPole; this one "
                         f"reads {PRESET_FORMAT!r}")  # fmt: skip
    if not isinstance(data, dict) or found != PRESET_FORMAT or not isinstance(data.get("config"), dict):
        raise ValueError(f"{path} is not a preset file (expected a JSON object with format {PRESET_FORMAT!r})")
    check_heartpole_id(data["config"].get("env_id", TrainConfig.env_id), f"preset file {path}")
    try:
        config = TrainConfig.from_dict(data["config"])
        check_config(config)
    except (TypeError, ValueError) as error:
        raise ValueError(f"preset file {path}: {error}") from None
    return config
