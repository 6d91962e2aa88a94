"""PPO in JAX, in the style of PureJaxRL: rollout, advantages and updates in one jitted function, seeds vmapped.

It is Stable-Baselines3's PPO as ``heartpole train`` configures it, step for step: separate actor and
critic MLPs with tanh (SB3's ``MlpPolicy``, orthogonal initialisation), Adam (eps 1e-5) with the
gradient's global norm clipped, GAE, per-minibatch advantage normalisation, the clipped surrogate, an
entropy bonus; VecNormalize's running observation and discounted-return statistics (the latter capped at
``reward_stats_window`` samples, as
[`heartpole.training.RewardStatsWindow`][heartpole.training.callbacks.RewardStatsWindow]); the training reward of
[`heartpole.training.TrainingReward`][heartpole.training.reward.TrainingReward]; and bootstrapping through the time
limit from the value of the episode's last observation (``info["final_observation"]``), as SB3 does for
``TimeLimit.truncated``.

`train_compiled` trains several seeds in one compiled call;
`heartpole.jax.export` saves them as ``heartpole train`` saves SB3's runs, evaluates
and summarises them.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple, cast

import jax
import jax.numpy as jnp
import numpy as np

from heartpole.jax.env import EnvParams, HeartPoleJax
from heartpole.model import TIME_ELAPSED
from heartpole.progress import Progress
from heartpole.rewards import risk_floor, training_reward

CACHE_DIR_VARIABLE = "HEARTPOLE_JAX_CACHE"
"""Environment variable naming the persistent compilation cache's folder (default: the user's cache)."""


def enable_compilation_cache(folder: str | os.PathLike[str] | None = None) -> Path | None:
    """Keep compiled code on disk across runs (JAX's persistent compilation cache); return its folder.

    Default: ``$HEARTPOLE_JAX_CACHE``, else ``$XDG_CACHE_HOME/heartpole/jax`` (``~/.cache/heartpole/jax``).
    Where that folder cannot be made (no writable home), JAX compiles in memory: one warning, and ``None``.
    """
    if folder is None:
        folder = (
            os.environ.get(CACHE_DIR_VARIABLE)
            or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "heartpole" / "jax"
        )
    path = Path(folder)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        warnings.warn(
            f"JAX compiles in memory, again in every run: cannot make its cache folder ({error}). "
            f"Set {CACHE_DIR_VARIABLE} to a writable folder to keep compiled code.",
            RuntimeWarning,
            stacklevel=2,
        )
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path


# ------------------------------------------------------------------------------------------------------
# the settings


@dataclass(frozen=True)
class PPOSettings:
    """The numbers of one PPO run (a [`heartpole.training.TrainConfig`][heartpole.training.presets.TrainConfig] with
    ``algo="ppo"`` gives them)."""

    timesteps: int = 400_000
    n_envs: int = 16
    n_steps: int = 128
    batch_size: int = 512
    n_epochs: int = 10
    learning_rate: float = 3e-4
    anneal_learning_rate: bool = False
    gamma: float = 0.95
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.01
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    net_arch: tuple[int, ...] = (64, 64)
    normalize_observations: bool = True
    normalize_rewards: bool = True
    reward_stats_window: float | None = 100_000
    clip_obs: float = 10.0
    clip_reward: float = 10.0
    expected_risk: bool = True
    score_rate: float | None = 0.32
    horizon: float = 2000.0

    @classmethod
    def from_config(cls, config: Any) -> PPOSettings:
        """The settings of a [`heartpole.training.TrainConfig`][heartpole.training.presets.TrainConfig] (PPO only; SB3's
        defaults fill gaps).

        Raises:
            ValueError: another algorithm, ``score_rate="auto"``, or hyperparameters this PPO does not have.
        """
        if config.algo != "ppo":
            raise ValueError(f"the jax backend trains PPO only, not {config.algo!r} (use the default preset)")
        if config.reward.score_rate == "auto":
            raise ValueError("the jax backend does not support score_rate='auto'; give a number")
        known = {"n_steps", "batch_size", "n_epochs", "learning_rate", "gamma", "gae_lambda", "clip_range",
                 "ent_coef", "vf_coef", "max_grad_norm", "anneal_learning_rate"}  # fmt: skip
        unknown = sorted(set(config.hyperparameters) - known)
        if unknown:
            raise ValueError(f"the jax backend's PPO has no hyperparameter(s) {unknown}; it has {sorted(known)}")
        settings = cls(
            timesteps=int(config.timesteps),
            n_envs=int(config.n_envs),
            net_arch=tuple(int(n) for n in config.net_arch),
            normalize_observations=config.normalize_observations,
            normalize_rewards=config.normalize_rewards,
            reward_stats_window=config.reward_stats_window,
            expected_risk=config.reward.expected_risk,
            score_rate=config.reward.score_rate,
            horizon=config.reward.horizon,
            **{key: type(getattr(cls, key))(value) for key, value in config.hyperparameters.items()},
        )
        return replace(settings, batch_size=min(settings.batch_size, settings.rollout))

    @property
    def rollout(self) -> int:
        """Env steps per update (all envs together)."""
        return self.n_envs * self.n_steps

    @property
    def num_updates(self) -> int:
        """Updates in the run: as SB3, enough rollouts to reach ``timesteps``."""
        return math.ceil(self.timesteps / self.rollout)


# ------------------------------------------------------------------------------------------------------
# the network, the optimiser and the running statistics


def init_network(key: jax.Array, obs_dim: int, num_actions: int, net_arch: Sequence[int]) -> dict[str, Any]:
    """Actor and critic MLPs as SB3's ``MlpPolicy`` makes them: tanh layers, orthogonal weights with gain
    sqrt(2), the policy head 0.01 and the value head 1, zero biases. Weights are ``(inputs, outputs)``."""

    def mlp(key: jax.Array, head: int, head_gain: float) -> list[tuple[jax.Array, jax.Array]]:
        sizes = [obs_dim, *net_arch, head]
        gains = [math.sqrt(2.0)] * len(net_arch) + [head_gain]
        keys = jax.random.split(key, len(gains))
        return [
            (orthogonal(k, (n_in, n_out), gain), jnp.zeros(n_out, jnp.float32))
            for k, n_in, n_out, gain in zip(keys, sizes[:-1], sizes[1:], gains)
        ]

    actor_key, critic_key = jax.random.split(key)
    return {"actor": mlp(actor_key, num_actions, 0.01), "critic": mlp(critic_key, 1, 1.0)}


def orthogonal(key: jax.Array, shape: tuple[int, int], gain: float) -> jax.Array:
    """A random orthogonal ``float32`` matrix times ``gain`` (``jax.nn.initializers.orthogonal``), made one
    matrix at a time when ``vmap``-ed over keys.

    Batched, jaxlib's CPU QR splits the batch into tasks on XLA's thread pool and waits for them on a
    thread of that same pool; when every thread of the pool waits so (two QRs at once on a 2-core machine),
    none is left to run the tasks and the process hangs for ever. One matrix at a time, QR runs inline."""

    def one(key: jax.Array) -> jax.Array:
        return jax.nn.initializers.orthogonal(gain)(key, shape, jnp.float32)

    one_at_a_time: Callable[[jax.Array], jax.Array] = jax.custom_batching.sequential_vmap(one)
    return one_at_a_time(key)


def forward(layers: list[tuple[jax.Array, jax.Array]], x: jax.Array) -> jax.Array:
    """An MLP with tanh between layers."""
    for weight, bias in layers[:-1]:
        x = jnp.tanh(x @ weight + bias)
    weight, bias = layers[-1]
    return x @ weight + bias


def policy_and_value(network: dict[str, Any], obs: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Action logits and the value of (normalised) observations."""
    return forward(network["actor"], obs), forward(network["critic"], obs)[..., 0]


class Adam(NamedTuple):
    """Adam's moments and step count (PyTorch's Adam, as SB3 uses it)."""

    mean: Any
    square: Any
    count: jax.Array  # type: ignore[assignment]  # the field shadows tuple.count


def adam_init(params: Any) -> Adam:
    """Zero moments for ``params``."""
    zeros = jax.tree_util.tree_map(jnp.zeros_like, params)
    return Adam(zeros, zeros, jnp.int32(0))


def adam_step(params: Any, grads: Any, state: Adam, lr: float | jax.Array, max_norm: float) -> tuple[Any, Adam]:
    """Clip ``grads`` to global norm ``max_norm``, then one Adam step (betas 0.9, 0.999; eps 1e-5)."""
    norm = jnp.sqrt(sum(jnp.sum(g**2) for g in jax.tree_util.tree_leaves(grads)))
    grads = jax.tree_util.tree_map(lambda g: g * jnp.minimum(1.0, max_norm / (norm + 1e-6)), grads)
    count = state.count + 1
    mean = jax.tree_util.tree_map(lambda m, g: 0.9 * m + 0.1 * g, state.mean, grads)
    square = jax.tree_util.tree_map(lambda v, g: 0.999 * v + 0.001 * g**2, state.square, grads)
    fix1, fix2 = 1.0 - 0.9**count, 1.0 - 0.999**count
    params = jax.tree_util.tree_map(
        lambda p, m, v: p - lr * (m / fix1) / (jnp.sqrt(v / fix2) + 1e-5), params, mean, square
    )
    return params, Adam(mean, square, count)


class RunningStats(NamedTuple):
    """A running mean and variance, as SB3's ``RunningMeanStd`` (which starts with count 1e-4)."""

    mean: jax.Array
    var: jax.Array
    count: jax.Array  # type: ignore[assignment]  # the field shadows tuple.count

    @classmethod
    def start(cls, shape: tuple[int, ...]) -> RunningStats:
        """Mean 0, variance 1, count 1e-4."""
        return cls(jnp.zeros(shape, jnp.float32), jnp.ones(shape, jnp.float32), jnp.float32(1e-4))

    def update(self, batch: jax.Array) -> RunningStats:
        """Fold in a batch (first axis), with Chan et al.'s parallel formula."""
        batch_mean, batch_var, n = batch.mean(0), batch.var(0), batch.shape[0]
        delta, total = batch_mean - self.mean, self.count + n
        mean = self.mean + delta * n / total
        m2 = self.var * self.count + batch_var * n + delta**2 * self.count * n / total
        return RunningStats(mean, m2 / total, total)


# ------------------------------------------------------------------------------------------------------
# training


class Runner(NamedTuple):
    """Everything that a training run carries from one update to the next."""

    network: dict[str, Any]
    adam: Adam
    env_state: Any
    obs: jax.Array
    obs_stats: RunningStats
    return_stats: RunningStats
    discounted: jax.Array
    episode_return: jax.Array
    episode_attacks: jax.Array
    key: jax.Array


def make_train(env: HeartPoleJax, params: EnvParams, s: PPOSettings) -> Callable[[jax.Array], tuple[Runner, Any]]:
    """``train(key) -> (runner, metrics)``: a whole PPO run as one pure function, to ``jit`` and ``vmap``.

    ``metrics`` holds, per update and env step, whether an episode ended there and its true return, heart
    attacks and final score (for the learning curve).
    """
    start, run = make_parts(env, params, s, s.num_updates)
    return lambda key: run(start(key))


def make_parts(
    env: HeartPoleJax, params: EnvParams, s: PPOSettings, updates: int
) -> tuple[Callable[[jax.Array], Runner], Callable[[Runner], tuple[Runner, Any]]]:
    """``start(key) -> runner`` and ``run(runner) -> (runner, metrics)`` doing ``updates`` updates: a run
    in pieces, so that the host can show progress between them (see [`make_train`][heartpole.jax.ppo.make_train])."""
    n_envs, obs_dim = s.n_envs, env.observation_space(params).shape[0]  # the traits too with observe_traits
    penalty = params.heart_attack_penalty
    floor = np.float32(risk_floor(float(params.heart_attack_proclivity)))
    minibatches = s.rollout // s.batch_size
    step_envs = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def normalize(obs: jax.Array, stats: RunningStats) -> jax.Array:
        if not s.normalize_observations:
            return obs
        return jnp.clip((obs - stats.mean) / jnp.sqrt(stats.var + 1e-8), -s.clip_obs, s.clip_obs)

    def shaped_reward(env_reward: jax.Array, before: jax.Array, info: dict[str, jax.Array]) -> jax.Array:
        # heartpole.training.TrainingReward, as HeartPoleSB3VecEnv.training_reward computes it
        half_hours = info["final_observation"][:, TIME_ELAPSED] - before[:, TIME_ELAPSED]
        attack = info["heart_attack"].astype(jnp.float32)
        return cast("jax.Array", training_reward(
            env_reward, attack, info["heart_attack_risk"], info["productivity"], half_hours, penalty=penalty,
            floor=floor, expected=s.expected_risk, score_rate=s.score_rate, horizon=s.horizon,
        ))  # fmt: skip

    def env_step(runner: Runner, _: Any) -> tuple[Runner, tuple[tuple[jax.Array, ...], tuple[jax.Array, ...]]]:
        key, action_key, step_key = jax.random.split(runner.key, 3)
        seen = normalize(runner.obs, runner.obs_stats)
        logits, value = policy_and_value(runner.network, seen)
        action = jax.random.categorical(action_key, logits)
        log_prob = jax.nn.log_softmax(logits)[jnp.arange(n_envs), action]
        obs, env_state, env_reward, terminated, truncated, info = step_envs(
            jax.random.split(step_key, n_envs), runner.env_state, action, params
        )
        done = terminated | truncated
        reward = shaped_reward(env_reward, runner.obs, info)
        obs_stats = runner.obs_stats.update(obs) if s.normalize_observations else runner.obs_stats
        return_stats, discounted = runner.return_stats, runner.discounted
        if s.normalize_rewards:
            discounted = discounted * s.gamma + reward
            return_stats = return_stats.update(discounted[:, None])
            if s.reward_stats_window is not None:
                return_stats = return_stats._replace(count=jnp.minimum(return_stats.count, s.reward_stats_window))
            reward = jnp.clip(reward / jnp.sqrt(return_stats.var[0] + 1e-8), -s.clip_reward, s.clip_reward)
            discounted = jnp.where(done, 0.0, discounted)
        # Truncation is not termination: bootstrap from the value of the episode's last observation.
        _, final_value = policy_and_value(runner.network, normalize(info["final_observation"], obs_stats))
        reward = reward + jnp.where(truncated & ~terminated, s.gamma * final_value, 0.0)
        episode_return = runner.episode_return + env_reward
        episode_attacks = runner.episode_attacks + info["heart_attack"]
        ended = (done, episode_return, episode_attacks, info["score"])
        runner = Runner(
            runner.network, runner.adam, env_state, obs, obs_stats, return_stats, discounted,
            jnp.where(done, 0.0, episode_return), jnp.where(done, 0, episode_attacks), key,
        )  # fmt: skip
        return runner, ((seen, action, log_prob, value, reward, done), ended)

    def advantages(values: jax.Array, rewards: jax.Array, dones: jax.Array, last: jax.Array) -> jax.Array:
        def back(carry: tuple[jax.Array, jax.Array], t: tuple[jax.Array, ...]) -> tuple[Any, jax.Array]:
            gae, next_value = carry
            value, reward, done = t
            live = 1.0 - done.astype(jnp.float32)
            delta = reward + s.gamma * next_value * live - value
            gae = delta + s.gamma * s.gae_lambda * live * gae
            return (gae, value), gae

        _, out = jax.lax.scan(back, (jnp.zeros_like(last), last), (values, rewards, dones), reverse=True)
        return out

    def loss(network: dict[str, Any], batch: tuple[jax.Array, ...]) -> jax.Array:
        obs, action, old_log_prob, advantage, target = batch
        logits, value = policy_and_value(network, obs)
        log_probs = jax.nn.log_softmax(logits)
        log_prob = jnp.take_along_axis(log_probs, action[:, None], axis=1)[:, 0]
        advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
        ratio = jnp.exp(log_prob - old_log_prob)
        clipped = jnp.clip(ratio, 1.0 - s.clip_range, 1.0 + s.clip_range)
        policy_loss = -jnp.minimum(ratio * advantage, clipped * advantage).mean()
        value_loss = ((target - value) ** 2).mean()
        entropy = -(jnp.exp(log_probs) * log_probs).sum(-1).mean()
        return policy_loss + s.vf_coef * value_loss - s.ent_coef * entropy

    def learning_rate(steps_done: jax.Array) -> jax.Array | float:
        return learning_rate_at(s, steps_done // (s.n_epochs * minibatches))

    def update(runner: Runner, _: Any) -> tuple[Runner, Any]:
        runner, (transitions, ended) = jax.lax.scan(env_step, runner, None, s.n_steps)
        obs, action, log_prob, value, reward, done = transitions
        _, last_value = policy_and_value(runner.network, normalize(runner.obs, runner.obs_stats))
        advantage = advantages(value, reward, done, last_value)
        data = (obs, action, log_prob, advantage, advantage + value)
        data = jax.tree_util.tree_map(lambda x: x.reshape((s.rollout, *x.shape[2:])), data)

        def epoch(carry: tuple[Any, Adam, jax.Array], _: Any) -> tuple[Any, None]:
            network, adam, key = carry
            key, shuffle_key = jax.random.split(key)
            order = jax.random.permutation(shuffle_key, s.rollout)[: minibatches * s.batch_size]
            shuffled = jax.tree_util.tree_map(lambda x: x[order].reshape((minibatches, -1, *x.shape[1:])), data)

            def minibatch(carry: tuple[Any, Adam], batch: tuple[jax.Array, ...]) -> tuple[Any, None]:
                network, adam = carry
                grads = jax.grad(loss)(network, batch)
                return adam_step(network, grads, adam, learning_rate(adam.count), s.max_grad_norm), None

            (network, adam), _ = jax.lax.scan(minibatch, (network, adam), shuffled)
            return (network, adam, key), None

        key, epoch_key = jax.random.split(runner.key)
        (network, adam, _), _ = jax.lax.scan(epoch, (runner.network, runner.adam, epoch_key), None, s.n_epochs)
        return runner._replace(network=network, adam=adam, key=key), ended

    def start(key: jax.Array) -> Runner:
        key, network_key, reset_key = jax.random.split(key, 3)
        network = init_network(network_key, obs_dim, env.num_actions, s.net_arch)
        obs, env_state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(reset_key, n_envs), params)
        obs_stats = RunningStats.start((obs_dim,))
        obs_stats = obs_stats.update(obs) if s.normalize_observations else obs_stats
        runner = Runner(
            network, adam_init(network), env_state, obs, obs_stats, RunningStats.start((1,)),
            jnp.zeros(n_envs), jnp.zeros(n_envs), jnp.zeros(n_envs, jnp.int32), key,
        )  # fmt: skip
        return runner

    def run(runner: Runner) -> tuple[Runner, Any]:
        return jax.lax.scan(update, runner, None, updates)

    return start, run


def learning_rate_at(s: PPOSettings, update: jax.Array) -> jax.Array | float:
    """The learning rate of update ``update`` (0, 1, ...): constant, or with ``anneal_learning_rate`` SB3's
    linear schedule ([`heartpole.training.runs.LinearSchedule`][heartpole.records.LinearSchedule]), given the share
    of the run left once that update's rollout is collected."""
    if not s.anneal_learning_rate:
        return s.learning_rate
    collected = (update + 1).astype(jnp.float32) * s.rollout
    return s.learning_rate * jnp.maximum(1.0 - collected / s.timesteps, 0.0)


def chunk_size(updates: int, pieces: int = 20) -> int:
    """The largest divisor of ``updates`` that makes at least ``pieces`` pieces (1 if ``updates`` is prime)."""
    return max(d for d in range(1, max(1, updates // pieces) + 1) if updates % d == 0)


def learning_curve(ended: Any, settings: PPOSettings) -> list[dict[str, float]]:
    """One seed's learning-curve rows (the columns of `heartpole.training.CURVE_COLUMNS`): at each
    env step where episodes ended, their mean true return, heart attacks and final score."""
    done, returns, attacks, scores = (np.asarray(x).reshape(-1, settings.n_envs) for x in ended)
    rows = []
    for step in np.flatnonzero(done.any(axis=1)):
        mask = done[step]
        rows.append({
            "timesteps": int((step + 1) * settings.n_envs),
            "mean_return": float(returns[step][mask].mean()),
            "heart_attacks": float(attacks[step][mask].mean()),
            "score": float(scores[step][mask].mean()),
        })  # fmt: skip
    return rows


# ------------------------------------------------------------------------------------------------------
# training several seeds in one compiled call (heartpole.jax.export saves, evaluates and summarises them)


class Trained(NamedTuple):
    """What `train_compiled` returns: every seed's trained runner and
    learning-curve metrics (stacked along a first axis of seeds), the settings, and the timings."""

    runners: Runner
    ended: Any
    settings: PPOSettings
    timings: dict[str, float]


def train_compiled(
    config: Any,
    seeds: Sequence[int],
    *,
    progress: bool = False,
    on_compiled: Callable[[float], None] | None = None,
) -> Trained:
    """Train ``config`` (a `TrainConfig` of PPO) for every one of ``seeds``
    in one compiled, vmapped call; nothing is written.

    Timings: ``compile_seconds`` (tracing and compiling, or loading from the persistent cache) and
    ``train_seconds`` (the compiled calls, all seeds together) are kept apart. Training runs in about 20
    compiled pieces of whole updates, between which the progress bar moves. ``on_compiled`` is called
    with the compile time before training starts.
    """
    settings = PPOSettings.from_config(config)
    enable_compilation_cache()
    env = HeartPoleJax.from_id(config.env_id, **dict(config.env_kwargs))
    keys = jax.vmap(jax.random.key)(jnp.asarray(seeds, dtype=jnp.uint32))
    chunk = chunk_size(settings.num_updates)
    start, run = make_parts(env, env.default_params, settings, chunk)
    started = time.perf_counter()
    start = jax.jit(jax.vmap(start)).lower(keys).compile()
    runners = start(keys)
    run = jax.jit(jax.vmap(run)).lower(runners).compile()
    compile_seconds = time.perf_counter() - started
    if on_compiled is not None:
        on_compiled(compile_seconds)
    started = time.perf_counter()
    pieces = []
    with _progress_bar(settings.num_updates * settings.rollout * len(seeds), seeds, progress) as bar:
        for _ in range(settings.num_updates // chunk):
            runners, ended = jax.block_until_ready(run(runners))
            pieces.append(ended)
            bar.update(chunk * settings.rollout * len(seeds))
    ended = jax.tree_util.tree_map(lambda *xs: jnp.concatenate(xs, axis=1), *pieces)
    timings = {"compile_seconds": compile_seconds, "train_seconds": time.perf_counter() - started}
    return Trained(runners, ended, settings, timings)


def _progress_bar(total: int, seeds: Sequence[int], show: bool) -> Progress:
    """A bar over all seeds' env steps (shown where ``show`` and stderr is a terminal or HEARTPOLE_PROGRESS=1)."""
    name = f"training ppo (jax) seed{'s' if len(seeds) > 1 else ''} {','.join(map(str, seeds))}"
    return Progress(total, name, enabled=None if show else False, unit="step")
