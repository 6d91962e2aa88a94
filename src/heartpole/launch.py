"""Where a training run runs: Stable-Baselines3 in this process, SB3 seeds as Ray Tune trials, or PPO in JAX.

[`train`][heartpole.launch.train] is what ``heartpole train`` calls once its arguments are checked: it stages
the output folder (nothing is left half written), trains one seed or several on the chosen backend, and returns
the run's summary (one seed: `train_run`'s; several:
`train_seeds`'s). Every backend writes the same files
([`heartpole.records`][heartpole.records]), so ``heartpole evaluate`` and ``heartpole plot`` read them alike.
This module sits above the backends it picks from (`heartpole.training`,
`heartpole.jax`, `heartpole.scale`); none of them imports it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from heartpole.registry import env_dynamics
from heartpole.training import RunCallback, TrainConfig, check_output_folder, staged_output, train_run, train_seeds
from heartpole.training.checks import check_config
from heartpole.training.presets import BACKENDS, Backend

__all__ = ["BACKENDS", "Backend", "check_run", "default_out", "train"]


def default_out(config: TrainConfig, backend: Backend = "sb3") -> str:
    """``runs/<algo>`` for the default preset, ``runs/<preset>-<algo>`` for the others (``-jax`` appended
    for the jax backend).

    >>> from heartpole.training import preset_config
    >>> default_out(preset_config("tutorial")), default_out(preset_config(), "jax")
    ('runs/tutorial-dqn', 'runs/ppo-jax')
    """
    preset = os.path.splitext(os.path.basename(config.preset))[0]
    out = f"runs/{config.algo}" if preset == "default" else f"runs/{preset}-{config.algo}"
    return out + ("-jax" if backend == "jax" else "")


def check_run(config: TrainConfig, out: str | os.PathLike[str], backend: Backend = "sb3", force: bool = False) -> Path:
    """Check, before any training, that ``config`` can train on ``backend`` and write to ``out``.

    Returns:
        ``out`` as a ``Path``.

    Raises:
        ValueError: an unknown env id, a bad configuration (see
            [`heartpole.training.checks.check_config`][heartpole.training.checks.check_config]), or settings the
            backend cannot run.
        OSError: ``out`` may not be written (see `check_output_folder`).
    """
    env_dynamics(config.env_id)
    check_config(config)
    if backend == "jax":
        from heartpole.jax.ppo import PPOSettings

        PPOSettings.from_config(config)
    return check_output_folder(out, force)


def train(
    config: TrainConfig,
    out: str | os.PathLike[str],
    *,
    seeds: Sequence[int] | None = None,
    backend: Backend = "sb3",
    ray: bool = False,
    address: str | None = None,
    cpus_per_trial: int = 1,
    force: bool = False,
    eval_episodes: int = 2000,
    eval_seed: int = 0,
    progress: bool = True,
    on_run: RunCallback | None = None,
    on_compiled: Callable[[float], None] | None = None,
) -> dict[str, Any]:
    """Train ``config`` (``config.seed``, or each of ``seeds``) into ``out`` and return the summary.

    The files are written into a staging folder beside ``out`` and moved into place when every seed is
    done (see `staged_output`); ``force`` replaces an earlier run there.

    Args:
        config: what to train.
        out: the output folder.
        seeds: train each of these into ``out/seed_<s>/`` and aggregate them; ``None``: one run of
            ``config.seed`` into ``out`` itself.
        backend: ``"sb3"`` or ``"jax"`` (see [`Backend`][heartpole.training.Backend]).
        ray: run the seeds as Ray Tune trials (sb3 backend, ``seeds`` given), on the cluster at ``address``
            (``None``: Ray on this machine) with ``cpus_per_trial`` CPUs each; see
            `train_seeds_ray`.
        eval_episodes: episodes of the evaluation of each saved model.
        eval_seed: the seed of that evaluation.
        progress: show a progress bar.
        on_run: called with each seed's summary as it finishes (with ``seeds``).
        on_compiled: jax backend: called with the compile time in seconds before training starts.

    Raises:
        ValueError: ``ray`` without ``seeds`` or with the jax backend.
        heartpole.scale.AllTrialsFailedError: with ``ray``, when every seed failed (nothing is written).
        ConnectionError: with ``ray``, when the cluster at ``address`` cannot be reached.
    """
    if ray and (seeds is None or backend != "sb3"):
        raise ValueError("ray runs the seeds of an sb3 run as Ray Tune trials: give seeds and the sb3 backend")
    import torch

    # Small networks train fastest on one thread; more threads only contend on a shared machine.
    torch.set_num_threads(1)
    with staged_output(out, force) as staging:
        if backend == "jax":
            from heartpole.jax.export import train_seeds as train_jax

            return train_jax(config, seeds, staging, eval_episodes=eval_episodes, eval_seed=eval_seed,
                             progress=progress, final_folder=out, on_compiled=on_compiled,
                             on_run=None if seeds is None else on_run)  # fmt: skip
        if seeds is None:
            return train_run(config, staging, eval_episodes=eval_episodes, eval_seed=eval_seed, progress=progress,
                             final_folder=out)  # fmt: skip
        if ray:
            from heartpole.scale import train_seeds_ray

            return train_seeds_ray(config, seeds, staging, eval_episodes=eval_episodes, eval_seed=eval_seed,
                                   address=address, cpus_per_trial=cpus_per_trial, final_folder=out,
                                   on_run=on_run)  # fmt: skip
        return train_seeds(config, seeds, staging, eval_episodes=eval_episodes, eval_seed=eval_seed,
                           progress=progress, final_folder=out, on_run=on_run)  # fmt: skip
