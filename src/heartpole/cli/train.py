"""``heartpole train``: train an agent with Stable-Baselines3 on the native vector env, then evaluate it.

The work is done by :mod:`heartpole.training` (imported only when the command runs, so the rest of the
command line works without the optional ``train`` extra); this module parses, checks and prints.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import types
from typing import Any, NoReturn

from heartpole.cli.common import CommandError, format_table

ORDER = 20

ALGORITHMS = ("ppo", "a2c", "dqn")
PRESETS = ("default", "tutorial")
MAX_SEEDS = 100
TRAINING_MODULES = ("stable_baselines3", "torch", "tqdm")

DESCRIPTION = """\
Train an agent on HeartPole with Stable-Baselines3 on the native vector env, with a progress bar, and
write to --out: model.zip, vecnormalize.pkl (observation/reward normalisation, when used),
heartpole.json (the configuration), learning_curve.csv (timesteps, mean_return, heart_attacks, score)
and evaluation.json (2,000 evaluation episodes of the saved model). With --seeds, one folder per seed
(seed_<s>/) and summary.json with the interquartile mean across seeds and its bootstrap interval.

Presets:
  default   PPO on a variance-reduced, rate-shaped reward with VecNormalize on 16 envs, 400,000 steps:
            solves HeartPole-v0 (heart attacks <= 1.30 per episode, score >= 0.30) in 1-2 minutes
  tutorial  the tutorial's setup: DQN, MlpPolicy, net_arch [16, 16], SB3's default hyperparameters,
            the env's own reward, one env, 500,000 steps
"""

EPILOG = """\
examples:
  heartpole train --out runs/ppo                       # the default: PPO that solves HeartPole-v0
  heartpole train --preset tutorial --out runs/tutorial
  heartpole train --seeds 0-4 --out runs/ppo-seeds     # five seeds, IQM with a bootstrap interval
  heartpole evaluate --policy runs/ppo/model.zip       # evaluate the trained model again
  heartpole train --backend jax --seeds 0-4 --out runs/ppo-jax   # PPO in JAX, five seeds in one compiled call

--backend jax (needs the 'jax' extra too) trains the same PPO on the same reward with JAX: the whole run
is one compiled function and the seeds run side by side (vmapped); compiled code is cached on disk, so
later runs skip most of the compile time. It saves the same files (an SB3 model.zip with the trained
weights), so heartpole evaluate and heartpole plot read them alike.
"""
BACKENDS = ("sb3", "jax")


def register(subparsers: Any) -> None:
    """Add the ``train`` subcommand."""
    parser = subparsers.add_parser(
        "train",
        help="train an agent with Stable-Baselines3 (needs the 'train' extra)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.error = types.MethodType(_one_line_error, parser)  # type: ignore[method-assign]
    parser.add_argument("--algo", metavar="ALGO", help="ppo, a2c or dqn (default: the preset's: ppo, or dqn)")
    parser.add_argument("--preset", default="default", metavar="NAME", help="default or tutorial (default: default)")
    parser.add_argument("--env", default="HeartPole-v0", metavar="ID", help="env id (default: HeartPole-v0)")
    parser.add_argument("--timesteps", metavar="N", help="env steps to train for (default: the preset's)")
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument("--seed", default="0", metavar="S", help="seed of the model and the env (default 0)")
    seeds.add_argument("--seeds", metavar="LIST", help="train several seeds, e.g. 0-4 or 0,3,7, and aggregate them")
    parser.add_argument("--n-envs", metavar="K", help="envs stepped side by side (default: the preset's, 16 or 1)")
    parser.add_argument("--out", metavar="DIR", help="output folder (default: runs/<algo> or runs/tutorial-<algo>)")
    parser.add_argument("--force", action="store_true", help="replace an earlier run in --out")
    parser.add_argument("--eval-episodes", default="2000", metavar="N", help="evaluation episodes (default 2000)")
    parser.add_argument("--eval-seed", default="0", metavar="S", help="evaluation seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print the results as one JSON object")
    parser.add_argument("--backend", default="sb3", metavar="NAME",
                        help="sb3 (Stable-Baselines3, default) or jax (PPO compiled with JAX, seeds vmapped)")
    parser.set_defaults(handler=run_train)


def _one_line_error(parser: argparse.ArgumentParser, message: str) -> NoReturn:
    """Argument errors of ``heartpole train`` as one line on stderr, exit code 2 (no usage block)."""
    print(f"heartpole train: error: {message} (see heartpole train --help)", file=sys.stderr)
    raise SystemExit(2)


# ------------------------------------------------------------------------------------------------------
# parsing


def whole_number(name: str, text: str | None, minimum: int) -> int | None:
    """``text`` as an integer >= ``minimum`` (``None`` stays ``None``); else a one-line :class:`CommandError`."""
    if text is None:
        return None
    try:
        value = int(str(text).replace("_", ""))
    except ValueError:
        raise CommandError(f"{name} must be a whole number >= {minimum}, got {text!r}") from None
    if value < minimum:
        raise CommandError(f"{name} must be a whole number >= {minimum}, got {value}")
    return value


def parse_seeds(text: str) -> list[int]:
    """Seeds from ``"0-4"``, ``"0,3,7"`` or a mix (``"0-2,9"``): distinct whole numbers >= 0, in order given.

    Raises:
        CommandError: anything else, repeated seeds, or more than :data:`MAX_SEEDS` seeds.
    """
    seeds: list[int] = []
    for part in text.split(","):
        part = part.strip()
        low, dash, high = part.partition("-")
        try:
            first = int(low)
            last = int(high) if dash else first
        except ValueError:
            raise CommandError(f"--seeds takes a list like 0-4 or 0,3,7, got {text!r}") from None
        if first < 0 or last < first:
            raise CommandError(f"--seeds takes ranges low-high with 0 <= low <= high, got {part!r}")
        if last - first + len(seeds) >= MAX_SEEDS:
            raise CommandError(f"--seeds: at most {MAX_SEEDS} seeds, got {text!r}")
        seeds.extend(range(first, last + 1))
    if len(set(seeds)) != len(seeds):
        raise CommandError(f"--seeds lists a seed twice: {text!r}")
    return seeds


def build_config(args: argparse.Namespace) -> Any:
    """The :class:`heartpole.training.TrainConfig` of the parsed arguments; bad values raise CommandError."""
    from heartpole.training import preset_config

    if args.preset not in PRESETS:
        raise CommandError(f"unknown preset {args.preset!r}; choose one of {', '.join(PRESETS)}")
    if args.algo is not None and args.algo.lower() not in ALGORITHMS:
        raise CommandError(f"unknown algorithm {args.algo!r}; choose one of {', '.join(ALGORITHMS)}")
    overrides: dict[str, Any] = {"env_id": args.env}
    timesteps = whole_number("--timesteps", args.timesteps, 1)
    n_envs = whole_number("--n-envs", args.n_envs, 1)
    if timesteps is not None:
        overrides["timesteps"] = timesteps
    if n_envs is not None:
        overrides["n_envs"] = n_envs
    overrides["seed"] = whole_number("--seed", args.seed, 0)
    try:
        return preset_config(args.preset, args.algo.lower() if args.algo else None, **overrides)
    except ValueError as error:
        raise CommandError(str(error)) from None


def default_out(config: Any, backend: str = "sb3") -> str:
    """``runs/<algo>`` for the default preset, ``runs/<preset>-<algo>`` for the others (``-jax`` appended
    for the jax backend)."""
    out = f"runs/{config.algo}" if config.preset == "default" else f"runs/{config.preset}-{config.algo}"
    return out + ("-jax" if backend == "jax" else "")


# ------------------------------------------------------------------------------------------------------
# the handler


def run_train(args: argparse.Namespace) -> int:
    """``heartpole train``: check everything, train (one seed or several), print the evaluation."""
    _require_training_extra()
    if args.backend not in BACKENDS:
        raise CommandError(f"unknown backend {args.backend!r}; choose one of {', '.join(BACKENDS)}")
    if args.backend == "jax" and importlib.util.find_spec("jax") is None:
        raise CommandError("--backend jax needs JAX, which this Python cannot import: pip install 'heartpole[jax]'")
    import torch

    from heartpole import training
    from heartpole.policies import env_dynamics

    config = build_config(args)
    seeds = parse_seeds(args.seeds) if args.seeds is not None else None
    episodes = whole_number("--eval-episodes", args.eval_episodes, 2)
    eval_seed = whole_number("--eval-seed", args.eval_seed, 0)
    try:
        env_dynamics(config.env_id)
        if config.timesteps < config.n_envs:
            raise ValueError(f"--timesteps ({config.timesteps}) must be at least --n-envs ({config.n_envs})")
        if args.backend == "jax":
            from heartpole.jax.ppo import PPOSettings

            PPOSettings.from_config(config)
        out = training.check_output_folder(args.out or default_out(config, args.backend), args.force)
    except (ValueError, OSError) as error:
        raise CommandError(" ".join(str(error).split())) from None
    # Small networks train fastest on one thread; more threads only contend on a shared machine.
    torch.set_num_threads(1)
    if not args.json:
        _announce(config, seeds, out, args.backend)
    try:
        with training.staged_output(out, args.force) as staging:
            if args.backend == "jax":
                result = _train_jax(args, config, seeds, staging, out, episodes, eval_seed)
            elif seeds is None:
                result: dict[str, Any] = training.train_run(
                    config, staging, eval_episodes=episodes, eval_seed=eval_seed, progress=True, final_folder=out
                )
            else:
                result = training.train_seeds(
                    config,
                    seeds,
                    staging,
                    eval_episodes=episodes,
                    eval_seed=eval_seed,
                    progress=True,
                    final_folder=out,
                    on_run=None if args.json else lambda run: print(format_run(run), flush=True),
                )
    except OSError as error:
        raise CommandError(f"cannot write {out}: {error.strerror or error}") from None
    if args.json:
        print(json.dumps({"out": str(out), **result}))
    elif seeds is None:
        print(format_run(result))
        print(f"wrote {out}/: model.zip, heartpole.json, learning_curve.csv, evaluation.json"
              + (", vecnormalize.pkl" if (out / training.VECNORMALIZE_FILE).exists() else ""))  # fmt: skip
    else:
        print(format_summary(result))
        print(f"wrote {out}/seed_<s>/ for seeds {args.seeds} and {out}/{training.SUMMARY_FILE}")
    return 0


def _train_jax(
    args: argparse.Namespace, config: Any, seeds: list[int] | None, staging: Any, out: Any, episodes: int,
    eval_seed: int,
) -> dict[str, Any]:  # fmt: skip
    from heartpole.jax.ppo import train_seeds

    def compiled(seconds: float) -> None:
        if not args.json:
            which = "all seeds at once" if seeds is not None else f"seed {config.seed}"
            print(f"compiled in {seconds:.1f} s; training {which} ...", flush=True)

    return train_seeds(
        config, seeds, staging, eval_episodes=episodes, eval_seed=eval_seed, progress=True, final_folder=out,
        on_compiled=compiled,
        on_run=None if args.json or seeds is None else lambda run: print(format_run(run), flush=True),
    )  # fmt: skip


def missing_training_modules() -> list[str]:
    """The modules of the ``train`` extra that this Python cannot import (empty when training can run)."""
    return [name for name in TRAINING_MODULES if importlib.util.find_spec(name) is None]


def _require_training_extra() -> None:
    missing = missing_training_modules()
    if missing:
        raise CommandError(
            f"training needs {', '.join(missing)}, which this Python cannot import: pip install 'heartpole[train]'"
        )


def _announce(config: Any, seeds: list[int] | None, out: Any, backend: str = "sb3") -> None:
    which = f"seeds {', '.join(map(str, seeds))}" if seeds is not None else f"seed {config.seed}"
    print(
        f"training {config.algo.upper()} ({config.preset} preset) on {config.env_id}: {config.timesteps:,} steps, "
        f"{config.n_envs} envs, {which}, backend {backend}; reward: {config.reward.describe()} -> {out}",
        flush=True,
    )


# ------------------------------------------------------------------------------------------------------
# formatting


def format_run(run: dict[str, Any]) -> str:
    """One seed's result in one line."""
    low, high = run["ci95"]
    verdict = "solved" if run["solved"] else "not solved"
    return (
        f"seed {run['seed']}: heart attacks {run['heart_attacks_per_episode']:.3f}/episode, "
        f"score {run['score']:.4f}, return {run['mean_return']:.2f} [{low:.2f}, {high:.2f}], "
        f"expected-risk return {run['expected_return']:.3f}, "
        + (f"{run['compile_seconds']:.0f} s compiling, " if "compile_seconds" in run else "")
        + f"{run['train_seconds']:.0f} s training, {run['wall_seconds']:.0f} s in all: {verdict}"
    )


def format_summary(summary: dict[str, Any]) -> str:
    """Every seed's row, then the interquartile mean across seeds with its 95% bootstrap interval."""
    from heartpole.training import aggregate_figures
    headers = ["seed", "heart attacks/ep", "score", "return", "return 95% CI", "expected-risk return", "s", "solved"]
    rows = [
        [
            run["seed"],
            f"{run['heart_attacks_per_episode']:.3f}",
            f"{run['score']:.4f}",
            f"{run['mean_return']:.2f}",
            f"[{run['ci95'][0]:.2f}, {run['ci95'][1]:.2f}]",
            f"{run['expected_return']:.3f}",
            f"{run['wall_seconds']:.0f}",
            "yes" if run["solved"] else "no",
        ]
        for run in summary["runs"]
    ]
    agg = summary["aggregate"]
    lines = [format_table(headers, rows), "", f"across {agg['seeds']} seeds, interquartile mean [95% bootstrap CI]:"]
    lines += [f"  {label:<22} {figure}" for label, figure in aggregate_figures(agg) if label != "wall time (s)"]
    lines.append(f"solved (heart attacks <= 1.30, score >= 0.30): {summary['solved_seeds']} of {agg['seeds']} seeds")
    return "\n".join(lines)
