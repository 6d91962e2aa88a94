"""Training runs: one seed's model, files and evaluation; several seeds and their interquartile mean."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, TypeAlias

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole import files
from heartpole.policies import CURVE_NAME, MODEL_NAME, SIDECAR_NAME, VECNORMALIZE_JSON_NAME, VECNORMALIZE_NAME
from heartpole.policies.saved import file_sha256
from heartpole.policies.untrusted import save_statistics
from heartpole.records import (
    SUMMARY_FILE,
    LinearSchedule,
    evaluate_saved,
    run_description,
    run_summary,
    sb3_model,
    seeds_summary,
    versions,
    write_curve,
)
from heartpole.training.adapter import make_vec_env
from heartpole.training.callbacks import LearningCurve, ProgressBar, RewardStatsWindow
from heartpole.training.presets import TrainConfig

__all__ = ["RunCallback", "TrainedModel", "LinearSchedule", "build_model", "train_model", "train_run", "train_seeds"]

RunCallback: TypeAlias = Callable[[dict[str, Any]], None]
"""Called with each seed's summary ([`run_summary`][heartpole.records.run_summary]) as it finishes."""

# ------------------------------------------------------------------------------------------------------
# training


@dataclass
class TrainedModel:
    """What [`train_model`][heartpole.training.runs.train_model] returns: the model, its VecNormalize (or ``None``),
    curve and timing."""

    model: BaseAlgorithm
    normalizer: VecNormalize | None
    curve: list[dict[str, float]]
    seconds: float


def build_model(config: TrainConfig) -> tuple[BaseAlgorithm, VecEnv]:
    """The SB3 model of ``config`` on a freshly made, seeded adapter (``VecNormalize``-wrapped if asked)."""
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
    return sb3_model(config, env), env


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

    Files: ``model.zip``, ``vecnormalize.pkl`` and ``vecnormalize.json`` (the same statistics as plain JSON,
    which loading reads without unpickling; when observations or rewards are normalised),
    ``heartpole.json`` (the configuration, timings and versions), ``learning_curve.csv`` and
    ``evaluation.json`` ([`heartpole.evaluation.evaluate`][heartpole.evaluation.evaluate] of the saved model over
    ``eval_episodes`` episodes with ``eval_seed``, loaded back from the files by
    [`heartpole.policies.load_policy`][heartpole.policies.load_policy], as ``heartpole evaluate`` does).
    ``final_folder`` is where the files will end up if ``folder`` is a staging folder (see `staged_output`); the
    evaluation names the model by that path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    started, cpu_started = time.perf_counter(), time.process_time()
    trained = train_model(config, progress=progress)
    trained.model.save(folder / MODEL_NAME)
    if trained.normalizer is not None:
        trained.normalizer.save(str(folder / VECNORMALIZE_NAME))
        save_statistics(trained.normalizer, folder / VECNORMALIZE_JSON_NAME)
    write_curve(folder / CURVE_NAME, trained.curve)
    sidecar: dict[str, Any] = {
        **run_description(config),
        "model": MODEL_NAME,
        "model_sha256": file_sha256(folder / MODEL_NAME),
        # the statistics saved with this model: load_policy applies these and no others
        "vecnormalize": VECNORMALIZE_NAME if trained.normalizer is not None else None,
        "vecnormalize_sha256": file_sha256(folder / VECNORMALIZE_NAME) if trained.normalizer is not None else None,
        # the same statistics as plain JSON: what load_policy reads (the pickle is for SB3's VecNormalize.load)
        "vecnormalize_json": VECNORMALIZE_JSON_NAME if trained.normalizer is not None else None,
        "vecnormalize_json_sha256": (
            file_sha256(folder / VECNORMALIZE_JSON_NAME) if trained.normalizer is not None else None
        ),
        "train_seconds": round(trained.seconds, 2),
        "versions": versions(),
    }
    evaluation, eval_seconds = evaluate_saved(
        config, folder, sidecar, eval_episodes=eval_episodes, eval_seed=eval_seed, progress=progress,
        final_folder=Path(final_folder if final_folder is not None else folder),
    )  # fmt: skip
    sidecar.update(
        eval_seconds=round(eval_seconds, 2),
        wall_seconds=round(time.perf_counter() - started, 2),
        cpu_seconds=round(time.process_time() - cpu_started, 2),
    )
    files.write_json(folder / SIDECAR_NAME, sidecar)
    return run_summary(config, evaluation, trained.seconds, sidecar["wall_seconds"], sidecar["cpu_seconds"])


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

    The summary lists every seed's figures and aggregates them across seeds with the interquartile mean and a 95%
    percentile-bootstrap interval over seeds ([`aggregate`][heartpole.records.aggregate]), and counts the seeds that
    meet the solved bar. ``on_run`` is called with each seed's summary as soon as it is done; ``final_folder`` is as for
    [`train_run`][heartpole.training.runs.train_run].
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
