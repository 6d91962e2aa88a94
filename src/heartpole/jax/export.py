"""``heartpole train --backend jax``: PPO trained in JAX (`heartpole.jax.ppo`), saved as
``heartpole train`` saves Stable-Baselines3's runs, evaluated and summarised.

The trained weights are saved as an SB3 ``model.zip`` plus ``vecnormalize.pkl`` and ``vecnormalize.json``, so that
[`heartpole.load_policy`][heartpole.policies.load_policy], ``heartpole evaluate`` and the plots read them
unchanged; the other files, the evaluation and the summaries are the ones every backend writes
([`heartpole.records`][heartpole.records]). It needs the ``train`` extra as well (Stable-Baselines3 and
PyTorch, for the saved format).
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import jax
import numpy as np

from heartpole import files, records
from heartpole.jax.ppo import PPOSettings, Runner, train_compiled
from heartpole.policies import CURVE_NAME, MODEL_NAME, SIDECAR_NAME, VECNORMALIZE_JSON_NAME, VECNORMALIZE_NAME
from heartpole.policies.saved import file_sha256
from heartpole.policies.untrusted import save_statistics
from heartpole.registry import quiet_version_warnings

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.running_mean_std import RunningMeanStd
    from stable_baselines3.common.vec_env import VecEnv


def sb3_ppo(config: Any) -> tuple[BaseAlgorithm, VecEnv]:
    """The SB3 PPO of ``config`` ([`sb3_model`][heartpole.records.sb3_model]) on ``config.n_envs`` copies of
    its env, ``VecNormalize``-wrapped as in training: the model whose weights and statistics the JAX
    trainer's are copied into."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    def make() -> gym.Env[Any, Any]:
        return gym.make(config.env_id, **dict(config.env_kwargs))

    with quiet_version_warnings():
        venv: VecEnv = DummyVecEnv([make] * int(config.n_envs))
    venv = records.normalize_env(venv, observations=config.normalize_observations,
                                 rewards=config.normalize_rewards, gamma=config.gamma)  # fmt: skip
    return records.sb3_model(config, venv), venv


def export_sb3(config: Any, runner: Runner, folder: Path) -> None:
    """Save one seed's trained network and statistics as ``heartpole train`` saves SB3's: ``model.zip``
    (an SB3 PPO ``MlpPolicy`` with these weights), ``vecnormalize.pkl`` and ``vecnormalize.json`` (the running
    statistics, pickled for SB3 and as plain JSON for loading without unpickling)."""
    import torch
    from stable_baselines3.common.vec_env import VecNormalize

    model, venv = sb3_ppo(config)
    try:
        state = model.policy.state_dict()
        for torch_name, layers in (("mlp_extractor.policy_net", "actor"), ("mlp_extractor.value_net", "critic")):
            for i, (weight, bias) in enumerate(runner.network[layers][:-1]):
                state[f"{torch_name}.{2 * i}.weight"] = torch.as_tensor(np.asarray(weight).T.copy())
                state[f"{torch_name}.{2 * i}.bias"] = torch.as_tensor(np.asarray(bias).copy())
        for torch_name, layers in (("action_net", "actor"), ("value_net", "critic")):
            weight, bias = runner.network[layers][-1]
            state[f"{torch_name}.weight"] = torch.as_tensor(np.asarray(weight).T.copy())
            state[f"{torch_name}.bias"] = torch.as_tensor(np.asarray(bias).copy())
        model.policy.load_state_dict(state)
        # sb3_ppo makes a PPO (typed as SB3's BaseAlgorithm, which has no n_steps)
        model.num_timesteps = PPOSettings.from_config(config).num_updates * config.n_envs * model.n_steps  # type: ignore[attr-defined]
        if isinstance(venv, VecNormalize):
            # what SB3 records of a model trained under VecNormalize (the raw last observations): loading reads its
            # presence as "expects normalised observations" and warns when no statistics come with the model
            shape = (int(config.n_envs), *(venv.observation_space.shape or ()))
            model._last_original_obs = np.zeros(shape, dtype=np.float32)
        model.save(folder / MODEL_NAME)
        if isinstance(venv, VecNormalize):
            obs_rms = cast("RunningMeanStd", venv.obs_rms)  # a dict only for dict observations
            for stats, ours in ((obs_rms, runner.obs_stats), (venv.ret_rms, runner.return_stats)):
                stats.mean = np.asarray(ours.mean, dtype=np.float64).reshape(stats.mean.shape)
                stats.var = np.asarray(ours.var, dtype=np.float64).reshape(stats.var.shape)
                stats.count = float(ours.count)
            venv.training = False
            venv.save(str(folder / VECNORMALIZE_NAME))
            save_statistics(venv, folder / VECNORMALIZE_JSON_NAME)
    finally:
        venv.close()


def _seed_result(
    config: Any, runner: Runner, curve: list[dict[str, float]], folder: Path, timings: dict[str, float],
    eval_episodes: int, eval_seed: int, progress: bool, final_folder: Path,
) -> dict[str, Any]:  # fmt: skip
    """Write one seed's files into ``folder``, evaluate the saved model as ``heartpole evaluate`` would,
    and return its line of the summary ([`run_summary`][heartpole.records.run_summary])."""
    started = time.perf_counter()
    folder.mkdir(parents=True, exist_ok=True)
    export_sb3(config, runner, folder)
    records.write_curve(folder / CURVE_NAME, curve)
    sidecar = {
        **records.run_description(config),
        "backend": "jax",
        **_statistics_record(folder),
        **{key: round(value, 2) for key, value in timings.items()},
        "versions": records.versions(jax=jax.__version__),
    }
    evaluation, _ = records.evaluate_saved(config, folder, sidecar, eval_episodes=eval_episodes, eval_seed=eval_seed,
                                           progress=progress, final_folder=final_folder)  # fmt: skip
    own = time.perf_counter() - started
    wall = timings["compile_seconds"] + timings["train_seconds"] + own
    sidecar.update(eval_seconds=round(own, 2), wall_seconds=round(wall, 2))
    files.write_json(folder / SIDECAR_NAME, sidecar)
    return records.run_summary(config, evaluation, timings["train_seconds"], wall) | {
        "compile_seconds": round(timings["compile_seconds"], 2)
    }


def _statistics_record(folder: Path) -> dict[str, str | None]:
    """``heartpole.json``'s record of the statistics saved in ``folder`` (``None`` where there are none), each
    file with its SHA-256, as ``heartpole train`` records them."""
    record: dict[str, str | None] = {}
    for key, name in (("vecnormalize", VECNORMALIZE_NAME), ("vecnormalize_json", VECNORMALIZE_JSON_NAME)):
        saved = (folder / name).is_file()
        record[key] = name if saved else None
        record[f"{key}_sha256"] = file_sha256(folder / name) if saved else None
    return record


def _warm_up(env_id: str, env_kwargs: dict[str, Any]) -> threading.Thread:
    """Start, on a thread beside training (which runs compiled code without the GIL), what saving and
    evaluating the seeds will wait for otherwise: PyTorch's lazily imported compiler (every
    ``torch.optim`` optimiser imports it, and SB3's models build one), the NumPy env's compiled kernels
    and the optimum the regret is measured against. Errors are left for the real work to raise."""

    def work() -> None:
        try:
            import torch._dynamo  # noqa: F401

            from heartpole.evaluation import evaluate

            evaluate("nothing", env_id, episodes=2, env_kwargs=env_kwargs)
        except Exception:  # noqa: BLE001, S110 - the same work runs again afterwards and reports its errors
            pass

    thread = threading.Thread(target=work, name="heartpole-warm-up", daemon=True)
    thread.start()
    return thread


def train_seeds(
    config: Any,
    seeds: Sequence[int] | None,
    folder: str | os.PathLike[str],
    *,
    eval_episodes: int = 2000,
    eval_seed: int = 0,
    progress: bool = False,
    on_run: Callable[[dict[str, Any]], None] | None = None,
    final_folder: str | os.PathLike[str] | None = None,
    on_compiled: Callable[[float], None] | None = None,
) -> dict[str, Any]:
    """Train ``config`` (PPO) for every seed in one compiled, vmapped call, then evaluate each seed.

    With ``seeds=None`` one run of ``config.seed`` is written into ``folder`` itself and its summary
    returned (as `heartpole.training.train_run`); otherwise each seed goes to
    ``folder/seed_<s>/`` and ``folder/summary.json`` aggregates them (as
    `heartpole.training.train_seeds`). Training and its timings are
    `train_compiled`'s; ``on_compiled`` is called with the compile time
    before training starts.
    """
    single = seeds is None
    seeds = [int(config.seed)] if seeds is None else [int(seed) for seed in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"give distinct seeds, got {list(seeds)}")
    folder, final = Path(folder), Path(final_folder if final_folder is not None else folder)
    warm_ups: list[threading.Thread] = []

    def compiled(seconds: float) -> None:
        if on_compiled is not None:
            on_compiled(seconds)
        warm_ups.append(_warm_up(config.env_id, dict(config.env_kwargs)))

    trained = train_compiled(config, seeds, progress=progress, on_compiled=compiled)
    for thread in warm_ups:
        thread.join()
    timings = trained.timings
    runs: list[dict[str, Any]] = []
    for i, seed in enumerate(seeds):
        runner, curve = trained.seed(i)
        where = (folder, final) if single else (folder / f"seed_{seed}", final / f"seed_{seed}")
        result = _seed_result(replace(config, seed=seed), runner, curve, where[0], timings, eval_episodes, eval_seed,
                              progress, where[1])  # fmt: skip
        runs.append(result)
        if on_run is not None:
            on_run(result)
    if single:
        return runs[0]
    summary = records.seeds_summary(config, seeds, runs, eval_episodes=eval_episodes, eval_seed=eval_seed)
    summary |= {"backend": "jax", **{key: round(value, 2) for key, value in timings.items()}}
    files.write_json(folder / records.SUMMARY_FILE, summary)
    return summary
