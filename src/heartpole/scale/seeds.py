"""The seeds of ``heartpole train --ray``: one Ray Tune trial per seed, the same files and summary as one
after another."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from ray import tune

from heartpole import files, training
from heartpole.scale.trials import AllTrialsFailedError, TrialsBar, failure, fit, ray_session, run_config


def _seed_trial(
    params: Mapping[str, Any],
    *,
    config: training.TrainConfig,
    folder: str,
    eval_episodes: int,
    eval_seed: int,
    final_folder: str | None,
    threads: int,
) -> None:
    """A Ray Tune trial: `train_run` for ``params["seed"]``, reported to Tune."""
    import torch

    torch.set_num_threads(threads)
    seed = int(params["seed"])
    run = training.train_run(
        replace(config, seed=seed),
        Path(folder) / f"seed_{seed}",
        eval_episodes=eval_episodes,
        eval_seed=eval_seed,
        final_folder=Path(final_folder) / f"seed_{seed}" if final_folder is not None else None,
    )
    # Tune flattens nested metrics (intervals, the solved bar): the whole summary travels as JSON beside the
    # plain numbers the progress bar reads.
    numbers = {key: value for key, value in run.items() if isinstance(value, (int, float, bool))}
    tune.report({**numbers, "run": json.dumps(run, allow_nan=False)})


def _run_of(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """A trial's reported metrics back as [`run_summary`][heartpole.records.run_summary]'s dict."""
    run: dict[str, Any] = json.loads(metrics["run"])
    return run


def train_seeds_ray(
    config: training.TrainConfig,
    seeds: Sequence[int],
    folder: str | os.PathLike[str],
    *,
    eval_episodes: int = 2000,
    eval_seed: int = 0,
    address: str | None = None,
    num_cpus: int | None = None,
    cpus_per_trial: int = 1,
    final_folder: str | os.PathLike[str] | None = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """`heartpole.training.train_seeds` with each seed a Ray Tune trial;
    same files, same summary.

    ``folder`` is made absolute (trials run in Ray's own working directories, and on a cluster it must
    be a path every node shares). Each trial gets ``cpus_per_trial`` CPUs and as many PyTorch threads;
    with one (the default, and what ``heartpole train`` uses) a seed's results equal the sequential run's.
    ``summary.json`` lists failed seeds under ``"failed"``, and the aggregate is over the seeds that ran.

    Raises:
        AllTrialsFailedError: every seed failed (nothing is aggregated or written).
        KeyboardInterrupt: a signal (Ctrl-C, SIGTERM, SIGHUP) stopped the trials; Tune stops them first.
    """
    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"give distinct seeds, got {seeds}")
    if cpus_per_trial < 1:
        raise ValueError(f"cpus_per_trial must be >= 1, got {cpus_per_trial}")
    folder = Path(folder).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    trainable = tune.with_resources(
        tune.with_parameters(
            _seed_trial,
            config=config,
            folder=str(folder),
            eval_episodes=eval_episodes,
            eval_seed=eval_seed,
            final_folder=None if final_folder is None else str(final_folder),
            threads=cpus_per_trial,
        ),
        {"cpu": cpus_per_trial},
    )
    bar = TrialsBar(len(seeds), "seeds", "expected_return", None if on_run is None else lambda m: on_run(_run_of(m)))
    with tempfile.TemporaryDirectory(prefix="heartpole-tune-") as storage, ray_session(address, num_cpus):
        tuner = tune.Tuner(
            trainable,
            param_space={"seed": tune.grid_search(seeds)},
            run_config=run_config(Path(storage), "seeds", bar),
        )
        grid = fit(tuner, bar)
        runs, failures = {}, []
        for result in grid:
            if result.error is None and "expected_return" not in (result.metrics or {}):
                raise files.interruption()  # Tune stopped the trial before it finished: a signal
            seed = int((result.config or {})["seed"])
            if result.error is not None:
                failures.append(failure(result, f"seed {seed}"))
            else:
                runs[seed] = _run_of(result.metrics or {})
    if not runs:
        raise AllTrialsFailedError(failures)
    summary = training.seeds_summary(
        config, seeds, [runs[s] for s in seeds if s in runs], eval_episodes=eval_episodes, eval_seed=eval_seed
    )
    if failures:
        summary["failed"] = [f.to_dict() for f in sorted(failures, key=lambda f: seeds.index(int(f.label[5:])))]
    files.write_json(folder / training.SUMMARY_FILE, summary)
    return summary
