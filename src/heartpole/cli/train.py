"""``heartpole train``: train an agent with Stable-Baselines3 on the native vector env, then evaluate it.

The work is done by [`heartpole.launch.train`][heartpole.launch.train] (on `heartpole.training`
or the other backends; imported only when the command runs, so the rest of the command line works without
the optional ``train`` extra); this module parses, checks and prints.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import types
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, overload

from heartpole import paths
from heartpole.cli.common import (
    CommandError,
    Subparsers,
    add_people_arguments,
    env_id_type,
    error_line,
    format_table,
    not_empty,
    one_line_error,
)
from heartpole.cli.envs import DEFAULT_ENV, checked_env, env_kwargs_type, joined_kwargs
from heartpole.policies import SB3_ALGORITHMS, VECNORMALIZE_NAME
from heartpole.solved import SOLVED_ATTACKS_ABOVE_FLOOR, SOLVED_REGRET, SOLVED_SHARE_OF_BEST_SCORE, V1_BAR

if TYPE_CHECKING:
    from heartpole.training import ScoreRate, TrainConfig

ORDER = 20

ALGORITHMS = SB3_ALGORITHMS
PRESETS = ("default", "tutorial")
MAX_SEEDS = {"sb3": 100, "jax": 65_536}
"""The most seeds one ``--seeds`` run takes, per backend: SB3 trains them one after another (100 is hours of a
CPU), JAX in one compiled call (4,096 seeds train in under a minute on a GPU)."""
TRAINING_MODULES = ("stable_baselines3", "torch")
RAY_MODULES = ("ray", "optuna")
RAY_EXTRA = "pip install 'heartpole[ray]'"
TRAIN_ENV_KWARGS_HELP = "the env's keywords: JSON or NAME=VALUE pairs, e.g. heart_attack_penalty=10 (over a preset's)"

ABOVE_FLOOR, SHARE_OF_BEST = SOLVED_ATTACKS_ABOVE_FLOOR - 1, SOLVED_SHARE_OF_BEST_SCORE
DESCRIPTION = f"""\
Train an agent on HeartPole with Stable-Baselines3 on the native vector env, with a progress bar, and
write to --out: model.zip, vecnormalize.pkl and .json (observation/reward normalisation, when used),
heartpole.json (the configuration), learning_curve.csv (timesteps, mean_return, heart_attacks, score)
and evaluation.json (2,000 evaluation episodes of the saved model). With --seeds, one folder per seed
(seed_<s>/) and summary.json with the interquartile mean across seeds and its bootstrap interval.

Presets:
  default   PPO on a variance-reduced, rate-shaped reward with VecNormalize on 16 envs, 400,000 steps:
            solves HeartPole-v0 (regret <= {SOLVED_REGRET:g} at 95%) in 1-2 minutes
  tutorial  the tutorial's setup: DQN, MlpPolicy, net_arch [16, 16], SB3's default hyperparameters,
            the env's own reward, one env, 500,000 steps

On another env (--env HeartPole-v1 or a variant) the default preset charges the shaped reward's
half-hours at 98% of that env's best known score (--score-rate best: 0.32 for v0, 0.68 for v1), or
estimates the rate while training where none is known (--score-rate auto). A run is solved when its
regret against the true optimum (heartpole optimum) is at most {SOLVED_REGRET:g} at the 95% upper bound;
where no optimum is known (v1, most variants), by the env's own bar: heart attacks at most
{ABOVE_FLOOR:.0%} above the unavoidable floor and a score of at least {SHARE_OF_BEST:.0%} of the best known
(v1: {V1_BAR.heart_attacks_at_most:.2f} and {V1_BAR.score_at_least:.2f}).

--people default trains over a population, one person drawn per episode (hidden from the agent unless
--observe-traits appends their traits to the observation); the evaluation then reports the oracle regret
(each episode against its own person's optimum, solved once and cached) and a run is solved when the
oracle regret is at most {SOLVED_REGRET:g} at the 95% upper bound. See docs/people.md.
"""

EPILOG = """\
examples:
  heartpole train --out runs/ppo                       # the default: PPO that solves HeartPole-v0
  heartpole train --preset tutorial --out runs/tutorial
  heartpole train --seeds 0-4 --out runs/ppo-seeds     # five seeds, IQM with a bootstrap interval
  heartpole train --env HeartPole-v1 --out runs/v1     # v1, rate from v1's best known score
  heartpole train --env HeartPole-v1 --score-rate auto --out runs/v1-auto
  heartpole train --seeds 0-19 --ray --out runs/ppo-20 # twenty seeds as Ray Tune trials, side by side
  heartpole train --preset runs/tune-ppo/best_preset.json --seeds 0-9   # a configuration 'heartpole tune' found
  heartpole evaluate --policy runs/ppo/model.zip       # evaluate the trained model again
  heartpole train --backend jax --seeds 0-4 --out runs/ppo-jax   # PPO in JAX, five seeds in one compiled call
  heartpole train --people default --out runs/ppo-people          # trait-blind PPO over the default people
  heartpole train --env-kwargs heart_attack_penalty=10 --out runs/ppo-penalty-10   # where drinks are cheaper

--backend jax (needs the 'jax' extra too) trains the same PPO on the same reward with JAX: the whole run
is one compiled function and the seeds run side by side (vmapped); compiled code is cached on disk, so
later runs skip most of the compile time. Its default preset differs in two numbers: minibatches of 256
(twice the gradient steps for the same arithmetic) and 250,000 steps. It saves the same files (an SB3
model.zip with the trained weights), so heartpole evaluate and heartpole plot read them alike.
"""


def register(subparsers: Subparsers) -> None:
    """Add the ``train`` subcommand."""
    parser = subparsers.add_parser(
        "train",
        help="train an agent with Stable-Baselines3 (needs the 'train' extra)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.error = types.MethodType(one_line_error, parser)  # type: ignore[method-assign]
    parser.add_argument("--algo", metavar="ALGO", help="ppo, a2c or dqn (default: the preset's: ppo, or dqn)")
    parser.add_argument(
        "--preset",
        default="default",
        metavar="NAME",
        help="default, tutorial, or a preset file (.json) such as 'heartpole tune' writes (default: default)",
    )
    parser.add_argument(
        "--env", type=env_id_type, metavar="ID", help="env id (default: the preset's; HeartPole-v0 for built-in ones)"
    )
    parser.add_argument("--env-kwargs", type=env_kwargs_type, metavar="KWARGS", help=TRAIN_ENV_KWARGS_HELP)
    parser.add_argument("--timesteps", metavar="N", help="env steps to train for (default: the preset's)")
    parser.add_argument(
        "--score-rate",
        metavar="R",
        help="the shaped reward's rate (default preset): best (98%% of the env's best known score), auto "
        "(estimated while training) or a number (default: best)",
    )
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument("--seed", default="0", metavar="S", help="seed of the model and the env (default 0)")
    seeds.add_argument("--seeds", metavar="LIST", help="train several seeds, e.g. 0-4 or 0,3,7, and aggregate them")
    parser.add_argument("--n-envs", metavar="K", help="envs stepped side by side (default: the preset's, 16 or 1)")
    parser.add_argument("--out", metavar="DIR", help="output folder (default: runs/<algo> or runs/tutorial-<algo>)")
    parser.add_argument("--force", action="store_true", help="replace an earlier run in --out")
    parser.add_argument("--eval-episodes", default="2000", metavar="N", help="evaluation episodes (default 2000)")
    parser.add_argument("--eval-seed", default="0", metavar="S", help="evaluation seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print the results as one JSON object")
    add_people_arguments(parser, "the evaluation reports the oracle regret")
    parser.add_argument(
        "--backend",
        default="sb3",
        metavar="NAME",
        help="sb3 (Stable-Baselines3, default) or jax (PPO compiled with JAX, seeds vmapped)",
    )
    ray = parser.add_argument_group("Ray (needs the 'ray' extra; see docs/scale.md)")
    ray.add_argument("--ray", action="store_true", help="run the seeds of --seeds as Ray Tune trials, side by side")
    ray.add_argument("--address", metavar="ADDR", help="a Ray cluster to join, e.g. auto or ray://host:10001 "
                     "(default: start Ray on this machine)")  # fmt: skip
    ray.add_argument("--cpus-per-trial", metavar="K", help="CPUs (and PyTorch threads) per seed (default 1)")
    parser.set_defaults(handler=run_train)


# ------------------------------------------------------------------------------------------------------
# parsing


@overload
def whole_number(name: str, text: str, minimum: int) -> int: ...
@overload
def whole_number(name: str, text: None, minimum: int) -> None: ...
@overload
def whole_number(name: str, text: str | None, minimum: int) -> int | None: ...
def whole_number(name: str, text: str | None, minimum: int) -> int | None:
    """``text`` as an integer >= ``minimum`` (``None`` stays ``None``); else a one-line
    [`CommandError`][heartpole.cli.common.CommandError]."""
    if text is None:
        return None
    try:
        value = int(str(text).replace("_", ""))
    except ValueError:
        raise CommandError(f"{name} must be a whole number >= {minimum}, got {text!r}") from None
    if value < minimum:
        raise CommandError(f"{name} must be a whole number >= {minimum}, got {value}")
    return value


def training_seed(name: str, seed: int) -> int:
    """``seed`` if training can use it (NumPy's and Stable-Baselines3's seeding takes 0 to 2**32 - 1), else a
    one-line [`CommandError`][heartpole.cli.common.CommandError] naming ``name`` and the accepted range."""
    from heartpole.training.presets import MAX_TRAINING_SEED

    if seed > MAX_TRAINING_SEED:
        raise CommandError(f"{name}: a training seed is a whole number from 0 to {MAX_TRAINING_SEED:,} (2**32 - 1), "
                           f"got {seed:,}")  # fmt: skip
    return seed


def parse_seeds(text: str, backend: str = "sb3") -> list[int]:
    """Seeds from ``"0-4"``, ``"0,3,7"`` or a mix (``"0-2,9"``): distinct whole numbers >= 0, in order given.

    Raises:
        CommandError: anything else, repeated seeds, or more than ``backend``'s
            [`MAX_SEEDS`][heartpole.cli.train.MAX_SEEDS].
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
        training_seed("--seeds", last)
        if last - first + len(seeds) >= MAX_SEEDS[backend]:
            raise CommandError(f"--seeds: at most {MAX_SEEDS[backend]:,} seeds with --backend {backend}, got {text!r}")
        seeds.extend(range(first, last + 1))
    if len(set(seeds)) != len(seeds):
        raise CommandError(f"--seeds lists a seed twice: {text!r}")
    return seeds


def build_config(args: argparse.Namespace) -> TrainConfig:
    """The [`heartpole.training.TrainConfig`][heartpole.training.presets.TrainConfig] of the parsed arguments; bad
    values raise CommandError."""
    from dataclasses import replace

    from heartpole.training import BACKENDS, load_preset, preset_config

    is_file = args.preset not in PRESETS and (args.preset.endswith(".json") or os.path.isfile(args.preset))
    if args.preset not in PRESETS and not is_file:
        raise CommandError(f"unknown preset {args.preset!r}; choose one of {', '.join(PRESETS)} or a preset file")
    if args.algo is not None and args.algo.lower() not in ALGORITHMS:
        raise CommandError(f"unknown algorithm {args.algo!r}; choose one of {', '.join(ALGORITHMS)}")
    overrides: dict[str, Any] = {} if args.env is None else {"env_id": args.env}
    timesteps = whole_number("--timesteps", args.timesteps, 1)
    n_envs = whole_number("--n-envs", args.n_envs, 1)
    if timesteps is not None:
        overrides["timesteps"] = timesteps
    if n_envs is not None:
        overrides["n_envs"] = n_envs
    overrides["seed"] = training_seed("--seed", whole_number("--seed", args.seed, 0))
    kwargs = joined_kwargs(getattr(args, "env_kwargs", None) or {}, _people_kwargs(args))
    if kwargs and not is_file:  # a preset file's env and keywords are checked together, by check_config
        overrides["env_kwargs"] = checked_env(overrides.get("env_id", DEFAULT_ENV), kwargs)[1]
    score_rate = _score_rate(args.score_rate or "best")
    if is_file and args.score_rate is not None:  # the file's reward is kept whole, as its hyperparameters are
        raise CommandError(f"--score-rate applies to the built-in presets; preset file {args.preset} sets its own "
                           "reward.score_rate: leave --score-rate out (or edit the file)")  # fmt: skip
    try:
        if not is_file:
            if args.preset == "tutorial" and score_rate != "best":
                raise ValueError("--score-rate applies to the default preset; the tutorial trains on the env's reward")
            algo = args.algo.lower() if args.algo else None
            backend = getattr(args, "backend", "sb3")
            backend = backend if backend in BACKENDS else "sb3"  # run_train refuses others
            return preset_config(args.preset, algo, score_rate=score_rate, backend=backend, **overrides)
        config = load_preset(args.preset)
    except (ValueError, OSError) as error:
        raise CommandError(error_line(error)) from None
    if args.algo is not None and args.algo.lower() != config.algo:
        raise CommandError(f"--algo {args.algo} differs from the preset file's {config.algo}; leave --algo out")
    if kwargs:
        overrides["env_kwargs"] = {**config.env_kwargs, **kwargs}
    return replace(config, **overrides)


def _people_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The env keyword arguments of ``--people`` and ``--observe-traits`` (empty without ``--people``)."""
    people, observe = getattr(args, "people", None), getattr(args, "observe_traits", False)
    if observe and people is None:
        raise CommandError("--observe-traits needs --people (the traits are the person's)")
    if people is None:
        return {}
    from heartpole.people import POPULATIONS

    if people not in POPULATIONS:
        raise CommandError(f"unknown population {people!r} for --people; named populations: {sorted(POPULATIONS)}")
    return {"people": people, "observe_traits": True} if observe else {"people": people}


def _score_rate(text: str) -> ScoreRate:
    if text in ("best", "auto"):
        return "best" if text == "best" else "auto"
    try:
        value = float(text)
    except ValueError:
        raise CommandError(f"--score-rate takes best, auto or a number, got {text!r}") from None
    from heartpole.training.checks import check_score_rate

    try:
        check_score_rate("--score-rate", value)
    except ValueError as error:
        raise CommandError(str(error)) from None
    return value


# ------------------------------------------------------------------------------------------------------
# the handler


def run_train(args: argparse.Namespace) -> int:
    """``heartpole train``: check everything, train (one seed or several), print the evaluation."""
    _require_training_extra()
    from heartpole import launch, training

    if args.backend not in training.BACKENDS:
        raise CommandError(f"unknown backend {args.backend!r}; choose one of {', '.join(training.BACKENDS)}")
    if args.backend == "jax" and importlib.util.find_spec("jax") is None:
        raise CommandError("--backend jax needs JAX, which this Python cannot import: pip install 'heartpole[jax]'")

    not_empty("--out", args.out)
    config = build_config(args)
    seeds = parse_seeds(args.seeds, args.backend) if args.seeds is not None else None
    episodes = whole_number("--eval-episodes", args.eval_episodes, 2)
    eval_seed = whole_number("--eval-seed", args.eval_seed, 0)
    cpus_per_trial = _check_ray_options(args, seeds)
    try:
        if config.timesteps < config.n_envs:
            raise ValueError(f"--timesteps ({config.timesteps}) must be at least --n-envs ({config.n_envs})")
        out = launch.check_run(config, args.out or launch.default_out(config, args.backend), args.backend,
                                 args.force)  # fmt: skip
    except (ValueError, OSError) as error:
        raise CommandError(error_line(error)) from None
    paths.expect_output(out)
    if not args.json:
        _announce(config, seeds, out, args.backend)
    say = None if args.json else lambda run: print(format_run(run), flush=True)

    def compiled(seconds: float) -> None:
        if not args.json:
            which = "all seeds at once" if seeds is not None else f"seed {config.seed}"
            print(f"compiled in {seconds:.1f} s; training {which} ...", flush=True)

    try:
        with _ray_errors(args, out):
            result = launch.train(
                config, out, seeds=seeds, backend=args.backend, ray=args.ray, address=args.address,
                cpus_per_trial=cpus_per_trial, force=args.force, eval_episodes=episodes, eval_seed=eval_seed,
                on_run=say, on_compiled=compiled,
            )  # fmt: skip
    except OSError as error:
        raise CommandError(f"cannot write {out}: {error.strerror or error}; nothing written") from None
    if args.json:
        print(json.dumps({"out": str(out), **result}, allow_nan=False))
    elif seeds is None:
        print(format_run(result))
        print(f"wrote {out}/: model.zip, heartpole.json, learning_curve.csv, evaluation.json"
              + (", vecnormalize.pkl, vecnormalize.json" if (out / VECNORMALIZE_NAME).exists() else ""))  # fmt: skip
    else:
        print(format_summary(result))
        print(f"wrote {out}/seed_<s>/ for seeds {args.seeds} and {out}/{training.SUMMARY_FILE}")
    return 1 if result.get("failed") else 0


def _check_ray_options(args: argparse.Namespace, seeds: list[int] | None) -> int:
    """``--cpus-per-trial`` (default 1); the Ray options only with ``--ray``, ``--ray`` only with ``--seeds``."""
    if not args.ray:
        given = [name for name, value in (("--address", args.address), ("--cpus-per-trial", args.cpus_per_trial))
                 if value is not None]  # fmt: skip
        if given:
            raise CommandError(f"{' and '.join(given)} {'needs' if len(given) == 1 else 'need'} --ray")
        return 1
    if seeds is None:
        raise CommandError("--ray runs the seeds of --seeds as Ray Tune trials; give --seeds, e.g. --seeds 0-19")
    missing = missing_ray_modules()
    if missing:
        raise CommandError(f"--ray needs {', '.join(missing)}, which this Python cannot import: {RAY_EXTRA}")
    return check_cpus_per_trial(whole_number("--cpus-per-trial", args.cpus_per_trial, 1) or 1, args.address)


def check_cpus_per_trial(cpus: int, address: str | None) -> int:
    """``cpus`` if Ray started on this machine (no ``--address``) can give a trial that many: more than the
    machine's CPUs and every trial would wait for them forever. A cluster (``--address``) is Ray's to judge.

    Raises:
        CommandError: one line, naming the machine's CPUs.
    """
    available = os.cpu_count() or 1
    if address is None and cpus > available:
        raise CommandError(
            f"--cpus-per-trial {cpus}: this machine has {available} CPUs, and Ray started here would wait forever "
            f"for a trial's {cpus}; give at most {available} (or --address a cluster)"
        )
    return cpus


@contextmanager
def _ray_errors(args: argparse.Namespace, out: Path) -> Iterator[None]:
    """With ``--ray``: every seed failing, or an unreachable cluster, as one line (the failures on stderr)."""
    if not args.ray:
        yield
        return
    from heartpole import scale

    try:
        yield
    except scale.AllTrialsFailedError as error:
        for failure in error.failures:
            print(failure.line(), file=sys.stderr)
        raise CommandError(f"every seed failed; nothing written to {out}") from None
    except ConnectionError as error:
        raise CommandError(f"cannot reach the Ray cluster at {args.address}: {error}") from None


def missing_ray_modules() -> list[str]:
    """The modules of the ``ray`` extra that this Python cannot import (empty when Ray can run)."""
    return [name for name in RAY_MODULES if importlib.util.find_spec(name) is None]


def missing_training_modules() -> list[str]:
    """The modules of the ``train`` extra that this Python cannot import (empty when training can run)."""
    return [name for name in TRAINING_MODULES if importlib.util.find_spec(name) is None]


def _require_training_extra() -> None:
    missing = missing_training_modules()
    if missing:
        raise CommandError(
            f"training needs {', '.join(missing)}, which this Python cannot import: pip install 'heartpole[train]'"
        )


def _announce(config: TrainConfig, seeds: list[int] | None, out: Path, backend: str = "sb3") -> None:
    which = f"seeds {', '.join(map(str, seeds))}" if seeds is not None else f"seed {config.seed}"
    print(
        f"training {config.algo.upper()} ({config.preset} preset) on {config.env_id}: {config.timesteps:,} steps, "
        f"{config.n_envs} envs, {which}, backend {backend}; "
        f"reward: {config.reward.describe(config.heart_attack_penalty)} -> {out}",
        flush=True,
    )


# ------------------------------------------------------------------------------------------------------
# formatting


def format_run(run: dict[str, Any]) -> str:
    """One seed's result in one line."""
    low, high = run["ci95"]
    verdict = ("solved" if run["solved"] else "not solved") + (
        f" ({describe_bar(run['solved_bar'])})" if "solved_bar" in run else ""
    )
    regret = "" if run.get("regret") is None else f"regret {format_regret(run)}, "
    if run.get("oracle_regret") is not None:
        low_o, high_o = run["oracle_regret_ci95"]
        regret += f"oracle regret {run['oracle_regret']:.4f} [{low_o:.4f}, {high_o:.4f}], "
    return (
        f"seed {run['seed']}: heart attacks {run['heart_attacks_per_episode']:.3f}/episode, "
        f"score {run['score']:.4f}, return {run['mean_return']:.2f} [{low:.2f}, {high:.2f}], "
        f"expected-risk return {run['expected_return']:.3f}, {regret}"
        + (f"{run['compile_seconds']:.0f} s compiling, " if "compile_seconds" in run else "")
        + f"{run['train_seconds']:.0f} s training, {run['wall_seconds']:.0f} s in all: {verdict}"
    )


def format_cpu(what: str, seconds: float) -> str:
    """One line for the CPU time ``what`` took, in seconds and CPU-hours (what it costs on any machine)."""
    return f"CPU time of {what}: {seconds:,.0f} s ({seconds / 3600:.2f} CPU-hours)"


def format_regret(run: dict[str, Any]) -> str:
    """A run's regret with its 95% interval, or ``-`` where no optimum is known."""
    if run.get("regret") is None:
        return "-"
    low, high = run["regret_ci95"]
    return f"{run['regret']:.4f} [{low:.4f}, {high:.4f}]"


def describe_bar(bar: dict[str, Any]) -> str:
    """A solved bar in words: ``regret <= 0.01 (95% upper bound)`` or ``heart attacks <= 1.30, score >= 0.30``."""
    if "oracle_regret_at_most" in bar:
        return f"oracle regret <= {bar['oracle_regret_at_most']:g} (95% upper bound)"
    if "regret_at_most" in bar:
        return f"regret <= {bar['regret_at_most']:g} (95% upper bound)"
    text = f"heart attacks <= {bar['heart_attacks_per_episode_at_most']:.2f}"
    return text if bar["score_at_least"] is None else f"{text}, score >= {bar['score_at_least']:.2f}"


def format_summary(summary: dict[str, Any]) -> str:
    """Every seed's row, then the interquartile mean across seeds with its 95% bootstrap interval."""
    from heartpole.training import aggregate_figures

    headers = ["seed", "heart attacks/ep", "score", "return", "return 95% CI", "expected-risk return",
               "regret [95% CI]", "s", "solved"]  # fmt: skip
    rows = [
        [
            run["seed"],
            f"{run['heart_attacks_per_episode']:.3f}",
            f"{run['score']:.4f}",
            f"{run['mean_return']:.2f}",
            f"[{run['ci95'][0]:.2f}, {run['ci95'][1]:.2f}]",
            f"{run['expected_return']:.3f}",
            format_regret(run),
            f"{run['wall_seconds']:.0f}",
            "yes" if run["solved"] else "no",
        ]
        for run in summary["runs"]
    ]
    agg = summary["aggregate"]
    lines = [format_table(headers, rows), "", f"across {agg['seeds']} seeds, interquartile mean [95% bootstrap CI]:"]
    lines += [f"  {label:<22} {figure}" for label, figure in aggregate_figures(agg) if label != "wall time (s)"]
    lines.append(f"solved ({describe_bar(summary['solved_bar'])}): {summary['solved_seeds']} of {agg['seeds']} seeds")
    if "cpu_seconds" in summary:
        lines.append(format_cpu("the runs (training and evaluation)", summary["cpu_seconds"]))
    lines += [f"{failure['trial']} failed: {failure['error']}" for failure in summary.get("failed", ())]
    return "\n".join(lines)
