"""Stable-Baselines3 glue: the VecEnv adapter, the training reward, presets, training runs, multi-seed IQMs.

This package needs the optional ``train`` extra (``pip install 'heartpole[train]'``: Stable-Baselines3,
PyTorch); ``import heartpole`` never imports it. Its parts, each a module of its own (``adapter``,
``reward``, ``presets``, ``callbacks``, ``runs``, ``outputs``), all importable from here, with the run
records every training backend shares ([`heartpole.records`][heartpole.records]: the files, the evaluation
of the saved model, the summaries):

* [`HeartPoleSB3VecEnv`][heartpole.training.adapter.HeartPoleSB3VecEnv] puts HeartPole's native vector env behind SB3's
  ``VecEnv`` interface, so PPO, A2C and DQN step all envs with one array operation. Episodes end by truncation only,
  reported as ``TimeLimit.truncated=True`` with the last observation in ``info["terminal_observation"]``, so SB3
  bootstraps through the time limit; each ended episode's ``info["episode"]`` holds its true return (``"r"``), length
  (``"l"``), heart attacks and final score, read by SB3's logger like ``Monitor``'s.
* [`TrainingReward`][heartpole.training.reward.TrainingReward] is the reward the agent learns from: the env's own
  reward, or the *shaped* reward of the default preset (see below). Evaluation always uses the env's true return.
* [`TrainConfig`][heartpole.training.presets.TrainConfig] and [`PRESETS`][heartpole.training.presets.PRESETS]: the
  ``default`` preset (PPO that solves HeartPole-v0) and the ``tutorial`` preset (the tutorial's DQN with ``net_arch=[16,
  16]`` and SB3's default hyperparameters).
* [`train_run`][heartpole.training.runs.train_run] trains one seed and writes ``model.zip``, ``vecnormalize.pkl`` and
  ``vecnormalize.json`` (when observations or rewards are normalised), ``heartpole.json``, ``learning_curve.csv`` and
  ``evaluation.json`` (2,000 episodes of [`heartpole.evaluation.evaluate`][heartpole.evaluation.evaluate] on the saved
  files);
  [`train_seeds`][heartpole.training.runs.train_seeds] trains several seeds and summarises them with the interquartile
  mean and a bootstrap interval (rliable's recommendation).

Picking a backend (Stable-Baselines3 here, Ray Tune trials, or PPO compiled in JAX) is not this package's
work but the launcher's, one layer up: [`heartpole.launch.train`][heartpole.launch.train] is what
``heartpole train`` runs.

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

import importlib.util

TRAIN_EXTRA = "pip install 'heartpole[train]'"
"""How to install what training needs (Stable-Baselines3 with PyTorch)."""
if importlib.util.find_spec("stable_baselines3") is None or importlib.util.find_spec("torch") is None:
    raise ImportError(f"heartpole.training needs Stable-Baselines3 and PyTorch: {TRAIN_EXTRA}")

# ruff: noqa: E402 - the parts are imported after the check above, so a missing extra says what to install

from heartpole.records import (
    AGGREGATE_LABELS,
    AGGREGATED,
    EVALUATION_FILE,
    SUMMARY_FILE,
    aggregate,
    aggregate_figures,
    cpu_total,
    env_solved_bar,
    meets_bar,
    run_description,
    run_summary,
    seeds_summary,
    write_curve,
)
from heartpole.training.adapter import HeartPoleSB3VecEnv, make_vec_env
from heartpole.training.callbacks import LearningCurve, ProgressBar, RewardStatsWindow
from heartpole.training.outputs import check_output_folder, staged_output
from heartpole.training.presets import (
    BACKENDS,
    DEFAULT_ALGO,
    DEFAULT_HYPERPARAMETERS,
    DEFAULT_TIMESTEPS,
    JAX_PPO_HYPERPARAMETERS,
    JAX_PPO_TIMESTEPS,
    PRESET_FORMAT,
    PRESET_HELP,
    PRESETS,
    RATE_SHARE_OF_BEST,
    SOLVED_HEART_ATTACKS,
    SOLVED_SCORE,
    Backend,
    ScoreRate,
    TrainConfig,
    load_preset,
    preset_config,
    save_preset,
    shaped_reward_rate,
)
from heartpole.training.reward import ENV_REWARD, SHAPED_REWARD, TrainingReward
from heartpole.training.runs import (
    RunCallback,
    TrainedModel,
    build_model,
    train_model,
    train_run,
    train_seeds,
)

__all__ = [
    "check_output_folder",
    "staged_output",
    "write_curve",
    "TrainingReward",
    "ENV_REWARD",
    "SHAPED_REWARD",
    "EVALUATION_FILE",
    "SUMMARY_FILE",
    "SOLVED_HEART_ATTACKS",
    "SOLVED_SCORE",
    "RATE_SHARE_OF_BEST",
    "TrainConfig",
    "ScoreRate",
    "DEFAULT_HYPERPARAMETERS",
    "PRESETS",
    "PRESET_HELP",
    "DEFAULT_ALGO",
    "DEFAULT_TIMESTEPS",
    "JAX_PPO_HYPERPARAMETERS",
    "JAX_PPO_TIMESTEPS",
    "preset_config",
    "shaped_reward_rate",
    "env_solved_bar",
    "meets_bar",
    "PRESET_FORMAT",
    "save_preset",
    "load_preset",
    "HeartPoleSB3VecEnv",
    "make_vec_env",
    "RewardStatsWindow",
    "LearningCurve",
    "ProgressBar",
    "TrainedModel",
    "build_model",
    "train_model",
    "train_run",
    "run_description",
    "run_summary",
    "train_seeds",
    "seeds_summary",
    "AGGREGATED",
    "aggregate",
    "cpu_total",
    "AGGREGATE_LABELS",
    "aggregate_figures",
    "RunCallback",
    "Backend",
    "BACKENDS",
    "TRAIN_EXTRA",
]
