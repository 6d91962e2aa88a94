"""One check of a training configuration before any training: every key, its value and what is accepted.

[`check_config`][heartpole.training.checks.check_config] refuses what would otherwise train silently wrong or fail
deep inside Stable-Baselines3 or PyTorch after minutes of work: an unknown hyperparameter, a learning rate that is
not a positive number, a discount above 1, a minibatch larger than the replay buffer, a network given as a
string, env keyword arguments the env refuses, a shaped-reward rate no policy could earn. Its message names the
key, the value and what is accepted; [`heartpole.training.load_preset`][heartpole.training.presets.load_preset]
puts the preset file's name before it, and ``heartpole train`` runs it on every configuration it trains.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from heartpole.parameters import is_number
from heartpole.paths import check_memory
from heartpole.rollout import ENV_BYTES


@dataclass(frozen=True)
class Rule:
    """What one hyperparameter accepts: a whole number, a number, or true/false, within bounds.

    Attributes:
        kind: ``"int"`` (a whole number, not a bool), ``"float"`` (a finite number) or ``"bool"``.
        low, high: the bounds (inclusive unless ``low_open``).
        low_open: the lower bound is excluded.
        none: ``None`` (JSON ``null``) is accepted too.
    """

    kind: str
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    none: bool = False

    def accepts(self, value: Any) -> bool:
        """Whether ``value`` is accepted."""
        if value is None:
            return self.none
        if self.kind == "bool":
            return isinstance(value, bool)
        if not is_number(value) or not math.isfinite(value):
            return False
        if self.kind == "int" and not isinstance(value, (int, np.integer)):  # 1e9 is a float in JSON: refused
            return False
        return (self.low < value if self.low_open else self.low <= value) and value <= self.high

    def describe(self) -> str:
        """What is accepted, in words: ``a whole number >= 1``, ``a number in (0, 1]``, ``true or false``."""
        if self.kind == "bool":
            text = "true or false"
        else:
            what = "a whole number" if self.kind == "int" else "a finite number"
            if math.isfinite(self.low) and math.isfinite(self.high):
                text = f"{what} in {'(' if self.low_open else '['}{self.low:g}, {self.high:g}]"
            elif math.isfinite(self.low):
                text = f"{what} {'>' if self.low_open else '>='} {self.low:g}"
            else:
                text = what
        return f"{text} or null" if self.none else text


_POSITIVE = Rule("float", 0.0, low_open=True)
_NON_NEGATIVE = Rule("float", 0.0)
_SHARE = Rule("float", 0.0, 1.0)
_DISCOUNT = Rule("float", 0.0, 1.0, low_open=True)
_COUNT = Rule("int", 1)
_FLAG = Rule("bool")
_SHARED = {
    "learning_rate": _POSITIVE,
    "gamma": _DISCOUNT,
    "max_grad_norm": _POSITIVE,
    "stats_window_size": _COUNT,
    "anneal_learning_rate": _FLAG,  # HeartPole's own: the learning rate falls linearly to 0
}
_ON_POLICY = {
    **_SHARED,
    "n_steps": _COUNT,
    "gae_lambda": _SHARE,
    "ent_coef": _NON_NEGATIVE,
    "vf_coef": _NON_NEGATIVE,
    "normalize_advantage": _FLAG,
}
HYPERPARAMETERS: Mapping[str, Mapping[str, Rule]] = {
    "ppo": {
        **_ON_POLICY,
        "batch_size": Rule("int", 2),  # SB3's PPO needs two samples per minibatch
        "n_epochs": _COUNT,
        "clip_range": _POSITIVE,
        "clip_range_vf": Rule("float", 0.0, low_open=True, none=True),
        "target_kl": Rule("float", 0.0, low_open=True, none=True),
    },
    "a2c": {**_ON_POLICY, "rms_prop_eps": _POSITIVE, "use_rms_prop": _FLAG},
    "dqn": {
        **_SHARED,
        "buffer_size": _COUNT,
        "learning_starts": Rule("int", 0),
        "batch_size": _COUNT,
        "tau": _DISCOUNT,
        "train_freq": _COUNT,
        "gradient_steps": Rule("int", -1),  # -1: as many as env steps (SB3); 0 is refused below
        "optimize_memory_usage": _FLAG,
        "n_steps": _COUNT,
        "target_update_interval": _COUNT,
        "exploration_fraction": _SHARE,
        "exploration_initial_eps": _SHARE,
        "exploration_final_eps": _SHARE,
    },
}
"""The hyperparameters a configuration may set for each algorithm, with what each accepts: Stable-Baselines3's
keyword arguments that a JSON file can hold (not its classes, devices, logging or ``policy_kwargs``: the network
is ``net_arch``), and ``anneal_learning_rate``."""

SB3_BUFFER_SIZE = 1_000_000
"""Stable-Baselines3's default DQN replay buffer, for a ``batch_size`` given without ``buffer_size``."""
SB3_N_STEPS = {"ppo": 2048, "a2c": 5}
"""Stable-Baselines3's default steps per env in a rollout, for PPO and A2C."""


@functools.lru_cache(maxsize=1)
def score_rate_ceiling() -> float:
    """The largest shaped-reward rate accepted: the most work one half-hour can bring (about 1.44). A rate above
    it charges every half-hour more than any policy can earn, so the agent learns from a reward that is negative
    whatever it does."""
    from heartpole.optimum.common import peak_productivity

    return math.floor(peak_productivity() * 100) / 100


def check_score_rate(name: str, rate: Any) -> None:
    """Refuse a shaped-reward rate outside (0, [`score_rate_ceiling`][heartpole.training.checks.score_rate_ceiling]]
    (``"auto"`` and ``None`` pass); ``name`` is what the message calls it (``--score-rate``, ``reward.score_rate``).

    Raises:
        ValueError: naming ``name``, the value and the accepted range.
    """
    if rate is None or rate == "auto":
        return
    ceiling = score_rate_ceiling()
    if not (is_number(rate) and math.isfinite(rate) and 0 < rate <= ceiling):
        raise ValueError(
            f"{name} must be 'best', 'auto' or a number in (0, {ceiling:g}] (work per half-hour; {ceiling:g} is the "
            f"most a half-hour can bring), got {rate!r}"
        )


def check_net_arch(net_arch: Any) -> tuple[int, ...]:
    """``net_arch`` as a tuple of layer sizes; ``ValueError`` unless it is a non-empty list of whole numbers >= 1
    (a string such as ``"64"`` is refused, not read as ``[6, 4]``; ``1.7`` is refused, not cut to ``1``; a
    number is a whole number when its type is an integer's: JSON's ``64.0`` is refused too)."""
    if isinstance(net_arch, (str, bytes, Mapping)) or not isinstance(net_arch, Sequence) or not net_arch:
        raise ValueError(f"net_arch must be a non-empty list of layer sizes (whole numbers >= 1), got {net_arch!r}")
    if not all(_COUNT.accepts(n) for n in net_arch):
        raise ValueError(f"net_arch must list layer sizes that are whole numbers >= 1, got {list(net_arch)!r}")
    return tuple(int(n) for n in net_arch)


def check_hyperparameters(algo: str, hyperparameters: Any) -> None:
    """Refuse hyperparameters ``algo`` does not have, and values outside what each accepts
    ([`HYPERPARAMETERS`][heartpole.training.checks.HYPERPARAMETERS]).

    Raises:
        ValueError: naming the hyperparameter, its value and what is accepted.
    """
    if not isinstance(hyperparameters, Mapping):
        raise ValueError(f"hyperparameters must be an object of name: value, got {hyperparameters!r}")
    rules = HYPERPARAMETERS.get(algo, {})
    unknown = sorted(set(hyperparameters) - set(rules))
    if unknown:
        raise ValueError(f"hyperparameters: {algo} has no {', '.join(map(repr, unknown))}; it takes {sorted(rules)}")
    for key, value in hyperparameters.items():
        rule = rules[key]
        if not rule.accepts(value) or (key == "gradient_steps" and value == 0):
            accepted = rule.describe() + (" (not 0; -1: one per env step)" if key == "gradient_steps" else "")
            raise ValueError(f"hyperparameters.{key} must be {accepted}, got {value!r}")
    if algo == "dqn":
        buffer = hyperparameters.get("buffer_size", SB3_BUFFER_SIZE)
        if hyperparameters.get("batch_size", 32) > buffer:
            raise ValueError(
                f"hyperparameters.batch_size ({hyperparameters['batch_size']!r}) must be at most the replay "
                f"buffer's size (buffer_size {buffer!r})"
            )


def check_config(config: Any) -> None:
    """Check a [`TrainConfig`][heartpole.training.presets.TrainConfig] before any training: its network, its
    hyperparameters, its reward's rate, its normalisation switches and its env (built once with its keyword
    arguments, so that a keyword the env does not take or a value it refuses is found now).

    Raises:
        ValueError: naming the key (``hyperparameters.learning_rate``, ``env_kwargs``, ...), the value and what
            is accepted.
    """
    import gymnasium as gym

    from heartpole.registry import env_dynamics, one_line, quiet_version_warnings

    check_net_arch(config.net_arch)
    check_hyperparameters(config.algo, config.hyperparameters)
    check_score_rate("reward.score_rate", config.reward.score_rate)
    for key in ("normalize_observations", "normalize_rewards"):
        if not isinstance(getattr(config, key), bool):
            raise ValueError(f"{key} must be true or false, got {getattr(config, key)!r}")
    window = config.reward_stats_window
    if window is not None and not Rule("float", 1.0).accepts(window):
        raise ValueError(f"reward_stats_window must be a number >= 1 or null, got {window!r}")
    if not isinstance(config.env_kwargs, Mapping):
        raise ValueError(f"env_kwargs must be an object of keyword: value, got {config.env_kwargs!r}")
    where = f"env_kwargs {dict(config.env_kwargs)!r}" if config.env_kwargs else f"env_id {config.env_id!r}"
    with warnings.catch_warnings():  # Gymnasium's warning about a render_mode the env refuses anyway, in words
        warnings.filterwarnings("ignore", message=".*initialised with render_mode", category=UserWarning)
        try:
            env_dynamics(config.env_id, config.env_kwargs)
        except (TypeError, ValueError) as error:
            raise ValueError(f"{where}: {error}") from None
        try:  # and the vector env that training steps, which refuses more (a render_mode other than rgb_array)
            with quiet_version_warnings():
                kwargs = dict(config.env_kwargs)
                venv = gym.make_vec(config.env_id, 1, vectorization_mode="vector_entry_point", **kwargs)
        except (TypeError, ValueError, gym.error.Error) as error:
            raise ValueError(f"{where}: the vector env training steps refuses them: {one_line(error)}") from None
    inputs = int(np.prod(venv.single_observation_space.shape or (1,)))
    actions = int(getattr(venv.single_action_space, "n", 1))
    venv.close()
    check_network_memory(config.net_arch, inputs, actions)
    check_buffer_memory(config, inputs)


BUFFER_NUMBERS_PER_STEP = 8
"""Float32 numbers a rollout buffer keeps per step besides the observation (action, reward, return, advantage,
value, log-probability, episode start), counted generously; a replay buffer keeps two observations a step."""


def check_buffer_memory(config: Any, inputs: int) -> int:
    """The bytes the envs and the rollout (PPO, A2C) or replay (DQN) buffer of ``config`` take, checked against
    half the machine's memory before anything is built: ``n_steps`` of ``10**12`` would ask for hundreds of TiB.

    Raises:
        ValueError: naming the hyperparameters, the memory they need and the memory there is.
    """
    hyperparameters = config.hyperparameters
    if config.algo == "dqn":
        steps = hyperparameters.get("buffer_size", SB3_BUFFER_SIZE)
        needed = steps * (2 * inputs + BUFFER_NUMBERS_PER_STEP) * 4
        what = f"buffer_size {steps:,}"
    else:
        steps = hyperparameters.get("n_steps", SB3_N_STEPS[config.algo]) * config.n_envs
        needed = steps * (inputs + BUFFER_NUMBERS_PER_STEP) * 4
        what = f"n_steps x n_envs = {steps:,} steps a rollout"
    needed += config.n_envs * ENV_BYTES
    check_memory(needed, f"training with {what} and n_envs {config.n_envs:,} (its buffer and envs)")
    return needed


NETWORK_BYTES_PER_PARAMETER = 2 * 4 * 4
"""Bytes a network's parameter costs in training, counted generously: two networks of ``net_arch`` (PPO's and
A2C's actor and critic, DQN's Q-network and its target), each parameter with its gradient and Adam's two
moments, all float32."""


def check_network_memory(net_arch: Sequence[int], inputs: int, actions: int) -> int:
    """The bytes the networks of ``net_arch`` (between ``inputs`` observations and ``actions`` outputs) take in
    training ([`NETWORK_BYTES_PER_PARAMETER`][heartpole.training.checks.NETWORK_BYTES_PER_PARAMETER] a parameter),
    checked against half the machine's physical memory before anything is built: a ``net_arch`` of
    ``[1000000000]`` would take all of it, and the machine with it.

    Raises:
        ValueError: naming ``net_arch``, the memory it needs and the memory there is.
    """
    sizes = [inputs, *net_arch, actions + 1]  # +1: the critic's value beside the actor's logits, generously
    parameters = sum(a * b + b for a, b in zip(sizes, sizes[1:]))
    needed = parameters * NETWORK_BYTES_PER_PARAMETER
    check_memory(needed, f"net_arch {list(net_arch)} has {parameters:,} parameters per network; training them")
    return needed


__all__ = [
    "HYPERPARAMETERS",
    "Rule",
    "check_config",
    "check_hyperparameters",
    "check_net_arch",
    "check_network_memory",
    "check_buffer_memory",
    "NETWORK_BYTES_PER_PARAMETER",
    "check_score_rate",
    "score_rate_ceiling",
]
