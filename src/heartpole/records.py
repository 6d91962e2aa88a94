"""What every training backend shares: the Stable-Baselines3 model it saves, the files of a run, the run's
evaluation, and its line in a summary with the aggregates across seeds.

Stable-Baselines3 in this process (`heartpole.training`) and PPO compiled in JAX
(`heartpole.jax.ppo`) write the same files through these helpers, so that
``heartpole evaluate``, ``heartpole plot`` and [`load_policy`][heartpole.policies.load_policy] read them
alike. A run's configuration is a `TrainConfig` (typed ``Any`` here: this
module sits below the training backends). Stable-Baselines3 and PyTorch are imported only by the functions
that need them.
"""

from __future__ import annotations

import csv
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from heartpole import files, solved
from heartpole.policies import CURVE_COLUMNS, MODEL_FORMAT, MODEL_NAME, SIDECAR_NAME, load_policy
from heartpole.registry import env_dynamics, solved_bar
from heartpole.stats import bootstrap_interval, fixed, interquartile_mean

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.vec_env import VecEnv

EVALUATION_FILE = "evaluation.json"
SUMMARY_FILE = "summary.json"

# ------------------------------------------------------------------------------------------------------
# the Stable-Baselines3 model


@dataclass(frozen=True)
class LinearSchedule:
    """A learning rate falling linearly from ``initial`` to 0 over the run: SB3 calls it with the share of
    the run left after the rollout it is about to learn from (``anneal_learning_rate`` in the
    hyperparameters; the JAX trainer follows the same schedule)."""

    initial: float

    def __call__(self, progress_remaining: float) -> float:
        """The learning rate with ``progress_remaining`` (1 at the start, 0 at the end) of the run left."""
        return self.initial * max(progress_remaining, 0.0)


def normalize_env(venv: VecEnv, *, observations: bool, rewards: bool, gamma: float) -> VecEnv:
    """``venv`` wrapped in SB3's ``VecNormalize`` when observations or rewards are normalised, else itself."""
    if not (observations or rewards):
        return venv
    from stable_baselines3.common.vec_env import VecNormalize

    return VecNormalize(venv, norm_obs=observations, norm_reward=rewards, gamma=gamma)


def sb3_model(config: Any, venv: VecEnv) -> BaseAlgorithm:
    """The SB3 model of ``config`` (its algorithm, network, hyperparameters and seed) on ``venv``.

    ``anneal_learning_rate`` becomes a [`LinearSchedule`][heartpole.records.LinearSchedule], and a PPO
    minibatch is capped at the rollout's size. Its logger writes no files.
    """
    import stable_baselines3 as sb3

    algorithm = {"ppo": sb3.PPO, "a2c": sb3.A2C, "dqn": sb3.DQN}[config.algo]
    hyperparameters = dict(config.hyperparameters)
    if hyperparameters.pop("anneal_learning_rate", False):
        hyperparameters["learning_rate"] = LinearSchedule(float(hyperparameters.get("learning_rate", 3e-4)))
    if config.algo == "ppo" and "batch_size" in hyperparameters:  # a minibatch cannot exceed the rollout
        rollout = int(hyperparameters.get("n_steps", 2048)) * config.n_envs
        hyperparameters["batch_size"] = min(int(hyperparameters["batch_size"]), rollout)
    model = algorithm(
        "MlpPolicy",
        venv,
        policy_kwargs={"net_arch": list(config.net_arch)},
        seed=config.seed,
        device="cpu",
        verbose=0,
        **hyperparameters,
    )
    # A logger of its own, writing nowhere: SB3's default makes an empty SB3-<timestamp>/ folder in the system's
    # temporary folder at every learn() call and leaves it there.
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def versions(**extra: str) -> dict[str, str]:
    """The versions a run's ``heartpole.json`` records: HeartPole's, SB3's, PyTorch's, Gymnasium's, NumPy's,
    and ``extra`` (the JAX trainer adds JAX's)."""
    import stable_baselines3
    import torch

    from heartpole import __version__

    return {
        "heartpole": __version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "gymnasium": gym.__version__,
        "numpy": np.__version__,
        **extra,
    }


# ------------------------------------------------------------------------------------------------------
# a run's files and evaluation


def write_curve(path: Path, rows: Sequence[Mapping[str, float]]) -> None:
    """Write the learning curve as CSV with `CURVE_COLUMNS` (into a run's
    staging folder, which is moved into place whole)."""
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=CURVE_COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({key: row[key] for key in CURVE_COLUMNS})


def run_description(config: Any) -> dict[str, Any]:
    """What every backend's ``heartpole.json`` says first: its format, the run's algorithm, env (id and keyword
    arguments: what ``heartpole evaluate`` and the other commands play the model on, see
    [`heartpole.policies.trained_env`][heartpole.policies.trained_env]), seed, steps, preset, policy class and
    whole configuration."""
    return {
        "format": MODEL_FORMAT,
        "algo": config.algo,
        "env_id": config.env_id,
        "env_kwargs": dict(config.env_kwargs),
        "seed": config.seed,
        "timesteps": config.timesteps,
        "preset": config.preset,
        "policy": "MlpPolicy",
        "config": config.to_dict(),
    }


def evaluate_saved(
    config: Any,
    folder: Path,
    sidecar: Mapping[str, Any],
    *,
    eval_episodes: int,
    eval_seed: int,
    progress: bool,
    final_folder: Path,
) -> tuple[dict[str, Any], float]:
    """Write ``sidecar`` as ``folder/heartpole.json``, evaluate the model saved in ``folder`` as ``heartpole
    evaluate`` would (loaded back from the files by [`load_policy`][heartpole.policies.load_policy], named
    by its path in ``final_folder``) and write ``evaluation.json``.

    Returns:
        The evaluation as [`EvaluationResult.to_dict`][heartpole.results.EvaluationResult.to_dict] gives it,
        and the seconds it took.
    """
    from heartpole.evaluation import evaluate

    started = time.perf_counter()
    files.write_json(folder / SIDECAR_NAME, sidecar)
    policy = load_policy(str(folder / MODEL_NAME), config.env_id, env_kwargs=dict(config.env_kwargs))
    policy.name = str(final_folder / MODEL_NAME)  # type: ignore[attr-defined]
    result = evaluate(policy, config.env_id, episodes=eval_episodes, seed=eval_seed,
                      env_kwargs=dict(config.env_kwargs), progress=progress)  # fmt: skip
    evaluation = result.to_dict()
    files.write_json(folder / EVALUATION_FILE, evaluation)
    return evaluation, time.perf_counter() - started


# ------------------------------------------------------------------------------------------------------
# summaries and the solved bar


def env_solved_bar(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The solved bar of ``env_id`` (`solved_bar`) as a JSON-safe dict."""
    bar = solved_bar(env_dynamics(env_id, env_kwargs))
    return {"heart_attacks_per_episode_at_most": bar.heart_attacks_at_most, "score_at_least": bar.score_at_least}


def meets_bar(evaluation: Mapping[str, Any], bar: Mapping[str, Any]) -> bool:
    """Whether an evaluation's heart attacks and score meet ``bar`` (from
    [`env_solved_bar`][heartpole.records.env_solved_bar])."""
    return solved.meets_bar(
        evaluation["heart_attacks_per_episode"], evaluation["score"],
        bar["heart_attacks_per_episode_at_most"], bar["score_at_least"],
    )  # fmt: skip


def run_summary(
    config: Any, evaluation: Mapping[str, Any], train_seconds: float, wall: float, cpu: float | None = None
) -> dict[str, Any]:
    """One run's line in a summary: seed, evaluation figures, whether it is solved, timings (``cpu``: the
    CPU time of the process that trained and evaluated it, all its threads, where measured).

    Solved means a regret whose 95% upper bound is at most
    [`SOLVED_REGRET`][heartpole.solved.SOLVED_REGRET] where the optimum is known
    ([`heartpole.optimum`][heartpole.optimum]), and the env's heart-attack and score bar elsewhere. Under a
    finite cohort of ``people`` it is the **oracle** regret's 95% upper bound against the same
    [`SOLVED_REGRET`][heartpole.solved.SOLVED_REGRET] (each episode against its own person's optimum: the same
    quantity on the same scale as v0's regret, where one env's heart-attack and score bars would hold every
    person to one person's floor); ``oracle_regret`` and ``oracle_regret_ci95`` are in the line then.
    """
    oracle = evaluation.get("oracle_regret")
    if oracle is not None:
        by_oracle = solved.regret_solved(float(evaluation["oracle_regret_ci95"][1]))
        line = _summary_line(config, evaluation, train_seconds, wall, cpu, solved_by=None)
        return line | {
            "oracle_regret": oracle,
            "oracle_regret_ci95": evaluation["oracle_regret_ci95"],
            "solved": bool(by_oracle),
            "solved_bar": {"oracle_regret_at_most": solved.SOLVED_REGRET},
        }
    return _summary_line(config, evaluation, train_seconds, wall, cpu, solved_by=evaluation.get("solved"))


def _summary_line(
    config: Any, evaluation: Mapping[str, Any], train_seconds: float, wall: float, cpu: float | None,
    solved_by: bool | None,
) -> dict[str, Any]:  # fmt: skip
    """[`run_summary`][heartpole.records.run_summary]'s line, solved by regret (``solved_by``) or the env's bar."""
    if solved_by is None:
        bar = env_solved_bar(config.env_id, config.env_kwargs)
        solved_by = meets_bar(evaluation, bar)
    else:
        bar = {"regret_at_most": solved.SOLVED_REGRET}
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
        "solved": solved_by,
        "solved_bar": bar,
        "train_seconds": round(train_seconds, 2),
        "wall_seconds": round(wall, 2),
    } | ({} if cpu is None else {"cpu_seconds": round(cpu, 2)})


def seeds_summary(
    config: Any,
    seeds: Sequence[int],
    runs: Sequence[Mapping[str, Any]],
    *,
    eval_episodes: int,
    eval_seed: int,
) -> dict[str, Any]:
    """The content of ``summary.json`` for ``runs`` (each a [`run_summary`][heartpole.records.run_summary])
    of ``config`` over ``seeds``."""
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


AGGREGATED = ("mean_return", "expected_return", "oracle_regret", "heart_attacks_per_episode", "score", "wall_seconds")
"""The figures a many-seed summary aggregates over its seeds."""


def aggregate(runs: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """For each figure of [`AGGREGATED`][heartpole.records.AGGREGATED]: IQM, 95% bootstrap interval of the IQM,
    mean, min and max."""
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
    ("oracle_regret", "oracle regret", 4),
    ("wall_seconds", "wall time (s)", 0),
)


def aggregate_figures(aggregate_: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(label, "iqm [low, high]")`` for each figure of an [`aggregate`][heartpole.records.aggregate] result,
    for tables and text; ``"iqm (one seed: no interval)"`` for one seed, where an interval across seeds has no
    meaning (its bootstrap would print a zero width)."""
    figures = []
    one_seed = aggregate_.get("seeds", 2) < 2  # a bootstrap over one seed has zero width: no interval
    for key, label, digits in AGGREGATE_LABELS:
        if key in aggregate_:
            item = aggregate_[key]
            low, high = item["iqm_ci95"]
            interval = "(one seed: no interval)" if one_seed else f"[{fixed(low, digits)}, {fixed(high, digits)}]"
            figures.append((label, f"{fixed(item['iqm'], digits)} {interval}"))
    return figures
