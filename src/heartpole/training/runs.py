"""Training runs: one seed's model, files and evaluation; several seeds and their interquartile mean."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeAlias

import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole import files
from heartpole.policies import (  # the run's file names and the algorithms, each defined once, there
    CURVE_NAME,
    MODEL_NAME,
    SIDECAR_NAME,
    VECNORMALIZE_NAME,
)
from heartpole.stats import bootstrap_interval, interquartile_mean
from heartpole.training.adapter import make_vec_env
from heartpole.training.callbacks import LearningCurve, ProgressBar, RewardStatsWindow
from heartpole.training.outputs import EVALUATION_FILE, SUMMARY_FILE, _versions, write_curve
from heartpole.training.presets import TrainConfig, env_solved_bar, meets_bar

RunCallback: TypeAlias = Callable[[dict[str, Any]], None]
"""Called with each seed's summary (:func:`run_summary`) as it finishes."""

# ------------------------------------------------------------------------------------------------------
# training


@dataclass
class TrainedModel:
    """What :func:`train_model` returns: the model, its VecNormalize (or ``None``), curve and timing."""

    model: BaseAlgorithm
    normalizer: VecNormalize | None
    curve: list[dict[str, float]]
    seconds: float


@dataclass(frozen=True)
class LinearSchedule:
    """A learning rate falling linearly from ``initial`` to 0 over the run: SB3 calls it with the share of
    the run left after the rollout it is about to learn from (``anneal_learning_rate`` in the
    hyperparameters; the JAX trainer follows the same schedule)."""

    initial: float

    def __call__(self, progress_remaining: float) -> float:
        """The learning rate with ``progress_remaining`` (1 at the start, 0 at the end) of the run left."""
        return self.initial * max(progress_remaining, 0.0)


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
    if hyperparameters.pop("anneal_learning_rate", False):
        hyperparameters["learning_rate"] = LinearSchedule(float(hyperparameters.get("learning_rate", 3e-4)))
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
    started, cpu_started = time.perf_counter(), time.process_time()
    trained = train_model(config, progress=progress)
    trained.model.save(folder / MODEL_NAME)
    if trained.normalizer is not None:
        trained.normalizer.save(str(folder / VECNORMALIZE_NAME))
    write_curve(folder / CURVE_NAME, trained.curve)
    from heartpole.training.models import file_sha256

    sidecar: dict[str, Any] = {
        **run_description(config),
        "model": MODEL_NAME,
        "model_sha256": file_sha256(folder / MODEL_NAME),
        # the statistics saved with this model: load_policy applies these and no others
        "vecnormalize": VECNORMALIZE_NAME if trained.normalizer is not None else None,
        "vecnormalize_sha256": file_sha256(folder / VECNORMALIZE_NAME) if trained.normalizer is not None else None,
        "train_seconds": round(trained.seconds, 2),
        "versions": _versions(),
    }
    files.write_json(folder / SIDECAR_NAME, sidecar)
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
    files.write_json(folder / EVALUATION_FILE, evaluation)
    eval_seconds = time.perf_counter() - eval_started
    sidecar.update(
        eval_seconds=round(eval_seconds, 2),
        wall_seconds=round(time.perf_counter() - started, 2),
        cpu_seconds=round(time.process_time() - cpu_started, 2),
    )
    files.write_json(folder / SIDECAR_NAME, sidecar)
    return run_summary(config, evaluation, trained.seconds, sidecar["wall_seconds"], sidecar["cpu_seconds"])


def run_description(config: TrainConfig) -> dict[str, Any]:
    """What every backend's ``heartpole.json`` says first: the run's algorithm, env, seed, steps, preset,
    policy class and whole configuration."""
    return {
        "algo": config.algo,
        "env_id": config.env_id,
        "seed": config.seed,
        "timesteps": config.timesteps,
        "preset": config.preset,
        "policy": "MlpPolicy",
        "config": config.to_dict(),
    }


def run_summary(
    config: TrainConfig, evaluation: Mapping[str, Any], train_seconds: float, wall: float, cpu: float | None = None
) -> dict[str, Any]:
    """One run's line in a summary: seed, evaluation figures, whether it is solved, timings (``cpu``: the
    CPU time of the process that trained and evaluated it, all its threads, where measured).

    Solved means a regret whose 95% upper bound is at most [`SOLVED_REGRET`][heartpole.solved.SOLVED_REGRET] where
    the optimum is known (:mod:`heartpole.optimum`), and the env's heart-attack and score bar elsewhere.
    """
    from heartpole.solved import SOLVED_REGRET

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
    } | ({} if cpu is None else {"cpu_seconds": round(cpu, 2)})


def train_seeds(
    config: TrainConfig,
    seeds: Sequence[int],
    folder: str | os.PathLike[str],
    *,
    eval_episodes: int = 2000,
    eval_seed: int = 0,
    progress: bool = False,
    on_run: RunCallback | None = None,
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
    files.write_json(folder / SUMMARY_FILE, summary)
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
    } | cpu_total(runs)


def cpu_total(runs: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """``{"cpu_seconds": total}`` over ``runs`` when every run measured its CPU time, else ``{}``: the
    figure that says what a number of seeds costs, wherever and however side by side they ran."""
    if not runs or any(run.get("cpu_seconds") is None for run in runs):
        return {}
    return {"cpu_seconds": round(sum(float(run["cpu_seconds"]) for run in runs), 2)}


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
