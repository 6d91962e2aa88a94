"""``heartpole train --backend jax``: PPO trained in JAX (`heartpole.jax.ppo`), saved as
``heartpole train`` saves Stable-Baselines3's runs, evaluated and summarised.

The trained weights are saved as an SB3 ``model.zip`` plus ``vecnormalize.pkl``, so that
[`heartpole.load_policy`][heartpole.policies.load_policy], ``heartpole evaluate`` and the plots read them
unchanged; the other files, the evaluation and the summaries are the ones every backend writes
([`heartpole.records`][heartpole.records]). It needs the ``train`` extra as well (Stable-Baselines3 and
PyTorch, for the saved format).
"""

from __future__ import annotations

import io
import os
import threading
import time
import zipfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, cast

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np

from heartpole import files, records
from heartpole.jax.evaluation import evaluate_batch
from heartpole.jax.ppo import (
    PPOSettings,
    Runner,
    RunningStats,
    Trained,
    learning_curve,
    policy_and_value,
    train_compiled,
)
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


class Weights(NamedTuple):
    """What a trained seed saves: its network and the running statistics of its observations and returns (the
    fields of a [`Runner`][heartpole.jax.ppo.Runner] that `SB3Writer` writes)."""

    network: dict[str, Any]
    obs_stats: RunningStats
    return_stats: RunningStats


HOST_CHUNK = 256
"""Seeds copied from the JAX device to the host at a time (`on_host`): a seed's learning-curve metrics are
about 5 MB with the default preset, so a chunk bounds the host memory at about 1.3 GB."""


def on_host(trained: Trained) -> Iterator[tuple[Weights, list[dict[str, float]]]]:
    """Each seed's `Weights` and learning-curve rows, in seed order, copied from the device ``HOST_CHUNK`` seeds
    at a time: picking one seed out of device arrays is a device operation for each array of each seed (for
    4,096 seeds on a GPU, minutes), out of host arrays a NumPy view."""
    runners = trained.runners
    stacked = (Weights(runners.network, runners.obs_stats, runners.return_stats), trained.ended)
    count = len(jax.tree_util.tree_leaves(stacked)[0])
    for first in range(0, count, HOST_CHUNK):
        weights, ended = jax.device_get(_rows(stacked, slice(first, first + HOST_CHUNK)))
        for i in range(min(HOST_CHUNK, count - first)):
            yield _rows(weights, i), learning_curve(_rows(ended, i), trained.settings)


def _rows(tree: Any, index: int | slice) -> Any:
    """Every array of ``tree`` indexed along its first axis (the seeds') by ``index``."""
    return jax.tree_util.tree_map(lambda x: x[index], tree)


POLICY_ENTRY = "policy.pth"
"""The entry of SB3's ``model.zip`` that holds the policy's weights (``torch.save`` of its ``state_dict``)."""


class SB3Writer:
    """Writes seeds' trained networks and statistics as ``heartpole train`` saves SB3's runs: ``model.zip`` (an
    SB3 PPO ``MlpPolicy`` with these weights), ``vecnormalize.pkl`` and ``vecnormalize.json`` (the running
    statistics, pickled for SB3 and as plain JSON for loading without unpickling). One SB3 model
    and env serve every seed (building them is most of the cost), so a seed's files take a few milliseconds of
    copying and writing. Use it as a context manager: it closes the env."""

    def __init__(self, config: Any) -> None:
        self.config = config
        self.model, self.venv = sb3_ppo(config)
        self._archive: list[tuple[zipfile.ZipInfo, bytes]] | None = None

    def __enter__(self) -> SB3Writer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.venv.close()

    def write(self, runner: Weights | Runner, folder: Path) -> None:
        """Save ``runner``'s network and statistics (a `Weights`, or a whole
        [`Runner`][heartpole.jax.ppo.Runner]) into ``folder``."""
        import torch
        from stable_baselines3.common.vec_env import VecNormalize

        model, venv = self.model, self.venv
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
        model.num_timesteps = PPOSettings.from_config(self.config).num_updates * self.config.n_envs * model.n_steps  # type: ignore[attr-defined]
        if isinstance(venv, VecNormalize):
            # what SB3 records of a model trained under VecNormalize (the raw last observations): loading reads its
            # presence as "expects normalised observations" and warns when no statistics come with the model
            shape = (int(self.config.n_envs), *(venv.observation_space.shape or ()))
            model._last_original_obs = np.zeros(shape, dtype=np.float32)
        self._save_model(folder / MODEL_NAME)
        if isinstance(venv, VecNormalize):
            obs_rms = cast("RunningMeanStd", venv.obs_rms)  # a dict only for dict observations
            for stats, ours in ((obs_rms, runner.obs_stats), (venv.ret_rms, runner.return_stats)):
                stats.mean = np.asarray(ours.mean, dtype=np.float64).reshape(stats.mean.shape)
                stats.var = np.asarray(ours.var, dtype=np.float64).reshape(stats.var.shape)
                stats.count = float(ours.count)
            venv.training = False
            venv.save(str(folder / VECNORMALIZE_NAME))
            save_statistics(venv, folder / VECNORMALIZE_JSON_NAME)

    def _save_model(self, path: Path) -> None:
        """What ``self.model.save(path)`` writes, made from the first seed's archive: everything SB3 saves but
        the policy's weights (the model's attributes as JSON, the untouched optimiser, the versions) is the same
        for every seed, and serialising it was most of a seed's writing; each archive gets its own
        `POLICY_ENTRY`, written as SB3 writes it."""
        import torch

        if self._archive is None:
            buffer = io.BytesIO()
            self.model.save(buffer)
            with zipfile.ZipFile(buffer) as archive:
                self._archive = [(info, archive.read(info)) for info in archive.infolist()]
        weights = io.BytesIO()
        torch.save(self.model.policy.state_dict(), weights)
        path.parent.mkdir(parents=True, exist_ok=True)  # as SB3's save does
        with zipfile.ZipFile(path, "w") as archive:
            for info, data in self._archive:
                archive.writestr(info, weights.getvalue() if info.filename == POLICY_ENTRY else data)


def export_sb3(config: Any, runner: Weights | Runner, folder: Path) -> None:
    """Save one seed's trained network and statistics as ``heartpole train`` saves SB3's (`SB3Writer`)."""
    with SB3Writer(config) as writer:
        writer.write(runner, folder)


def network_policy(settings: PPOSettings) -> Callable[[tuple[Any, RunningStats], jax.Array], jax.Array]:
    """``act((network, obs_stats), obs) -> actions``: a trained network's deterministic actions (the most likely,
    as SB3's ``predict(deterministic=True)``), on observations normalised as in training."""

    def act(weights: tuple[Any, RunningStats], obs: jax.Array) -> jax.Array:
        network, stats = weights
        if settings.normalize_observations:
            obs = jnp.clip((obs - stats.mean) / jnp.sqrt(stats.var + 1e-8), -settings.clip_obs, settings.clip_obs)
        logits, _ = policy_and_value(network, obs)
        return jnp.argmax(logits, axis=-1).astype(jnp.int32)

    return act


def evaluate_trained(
    config: Any, trained: Trained, names: Sequence[str], eval_episodes: int, eval_seed: int
) -> list[dict[str, Any]]:
    """Every seed of ``trained`` evaluated as ``heartpole evaluate`` evaluates a model (the same estimator, episodes
    and JSON), all in one compiled call on the JAX device ([`evaluate_batch`][heartpole.jax.evaluation.evaluate_batch]),
    each result named as in ``names``."""
    runners = trained.runners
    results = evaluate_batch(
        network_policy(trained.settings),
        (runners.network, runners.obs_stats),
        config.env_id,
        eval_episodes,
        eval_seed,
        env_kwargs=dict(config.env_kwargs),
        names=list(names),
    )
    return [result.to_dict() for result in results]


def _write_seed(
    config: Any, writer: SB3Writer, runner: Weights, curve: list[dict[str, float]], folder: Path,
    evaluation: dict[str, Any], timings: dict[str, float],
) -> dict[str, Any]:  # fmt: skip
    """Write one seed's files into ``folder`` (the model, its statistics, the curve, ``heartpole.json`` and its
    ``evaluation.json``) and return its line of the summary ([`run_summary`][heartpole.records.run_summary])."""
    started = time.perf_counter()
    folder.mkdir(parents=True, exist_ok=True)
    writer.write(runner, folder)
    records.write_curve(folder / CURVE_NAME, curve)
    files.write_json(folder / records.EVALUATION_FILE, evaluation)
    sidecar = {
        **records.run_description(config),
        "backend": "jax",
        **_statistics_record(folder),
        **{key: round(value, 2) for key, value in timings.items()},
        "versions": records.versions(jax=jax.__version__),
    }
    own = time.perf_counter() - started
    wall = timings["compile_seconds"] + timings["train_seconds"] + timings["eval_seconds"] + own
    sidecar.update(write_seconds=round(own, 3), wall_seconds=round(wall, 2))
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
    places = [(folder, final) if single else (folder / f"seed_{seed}", final / f"seed_{seed}") for seed in seeds]
    started = time.perf_counter()
    evaluations = evaluate_trained(config, trained, [str(f / MODEL_NAME) for _, f in places], eval_episodes, eval_seed)
    timings = trained.timings | {"eval_seconds": time.perf_counter() - started}
    runs: list[dict[str, Any]] = []
    with SB3Writer(config) as writer:
        for i, (seed, (runner, curve)) in enumerate(zip(seeds, on_host(trained))):
            result = _write_seed(replace(config, seed=seed), writer, runner, curve, places[i][0], evaluations[i],
                                 timings)  # fmt: skip
            runs.append(result)
            if on_run is not None:
                on_run(result)
    if single:
        return runs[0]
    summary = records.seeds_summary(config, seeds, runs, eval_episodes=eval_episodes, eval_seed=eval_seed)
    summary |= {"backend": "jax", **{key: round(value, 2) for key, value in timings.items()}}
    files.write_json(folder / records.SUMMARY_FILE, summary)
    return summary
