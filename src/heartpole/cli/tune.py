"""``heartpole tune``: a hyperparameter search with Optuna on Ray Tune (the work is
[`heartpole.scale`][heartpole.scale]'s).

This module parses, checks and prints; Ray is imported only when the command runs.
"""

from __future__ import annotations

import argparse
import json
import sys
import types
from pathlib import Path
from typing import TYPE_CHECKING, Any

from heartpole import files, paths
from heartpole.cli.common import CommandError, Subparsers, format_table, heartpole_env, not_empty, one_line_error
from heartpole.cli.train import (
    MAX_SEEDS,
    RAY_EXTRA,
    check_cpus_per_trial,
    format_cpu,
    missing_ray_modules,
    missing_training_modules,
    whole_number,
)

if TYPE_CHECKING:
    from heartpole.scale import SearchSettings

ORDER = 25
SEARCHABLE = ("ppo", "a2c")

DESCRIPTION = """\
Search hyperparameters with Optuna (Ray Tune's OptunaSearch), locally or on a Ray cluster. Every trial
trains --seeds-per-trial seeds (0, 1, ...) with the default preset changed by the trial's parameters and
evaluates each with the standard protocol (--eval-episodes episodes); the objective, maximised, is the
interquartile mean over those seeds of the expected-risk return (score - 100 x the summed heart-attack
probabilities, the return without the heart-attack coin's noise); the score is reported beside it.

The default space (see heartpole.scale.default_space):
  learning_rate  log-uniform 1e-5 .. 3e-3       ent_coef   log-uniform 1e-4 .. 0.1
  gamma          uniform 0.90 .. 0.999          n_steps    PPO 32..512, A2C 5..32 (powers of two, and 5)
  net_width      16, 32, 64, 128, 256           net_depth  1, 2, 3 (net_arch = [net_width] * net_depth)

Written to --out: search.json (the settings), search/ (Ray Tune's state, pickles: --resume --trust-pickles continues an
interrupted search from it), trials/<id>/ (each trial's seeds), trials.csv (one row per trial), best_preset.json (for
'heartpole train --preset FILE'), search.png (the objective per trial) and tune_summary.json.
"""

EPILOG = """\
examples:
  heartpole tune --trials 20 --seeds-per-trial 2 --timesteps 200000 --out runs/tune-ppo
  heartpole tune --resume --trust-pickles --out runs/tune-ppo   # continue an interrupted search of yours
  heartpole tune --trials 100 --address auto --out /shared/tune-ppo   # on a Ray cluster
  heartpole train --preset runs/tune-ppo/best_preset.json --seeds 0-9
"""


def register(subparsers: Subparsers) -> None:
    """Add the ``tune`` subcommand."""
    parser = subparsers.add_parser(
        "tune",
        help="search hyperparameters with Optuna on Ray Tune (needs the 'ray' extra)",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.error = types.MethodType(one_line_error, parser)  # type: ignore[method-assign]
    parser.add_argument("--algo", default="ppo", metavar="ALGO", help="ppo or a2c (default: ppo)")
    parser.add_argument("--trials", default="20", metavar="N", help="trials to run (default 20)")
    parser.add_argument("--seeds-per-trial", default="2", metavar="K", help="seeds each trial trains (default 2)")
    parser.add_argument("--timesteps", metavar="N", help="env steps per seed (default: the preset's, 400,000)")
    parser.add_argument("--n-envs", metavar="K", help="envs stepped side by side (default: the preset's, 16)")
    parser.add_argument("--env", default="HeartPole-v0", metavar="ID", help="env id (default: HeartPole-v0)")
    parser.add_argument("--eval-episodes", default="2000", metavar="N", help="evaluation episodes (default 2000)")
    parser.add_argument("--eval-seed", default="0", metavar="S", help="evaluation seed (default 0)")
    parser.add_argument("--search-seed", default="0", metavar="S", help="seed of Optuna's sampler (default 0)")
    parser.add_argument("--out", metavar="DIR", help="output folder (default: runs/tune-<algo>)")
    parser.add_argument("--resume", action="store_true", help="continue the interrupted search in --out")
    parser.add_argument("--force", action="store_true", help="replace an earlier search in --out")
    parser.add_argument("--trust-pickles", action="store_true", help="with --resume: let Ray Tune unpickle the "
                        "saved search in --out (search/tuner.pkl and its state), which can run any code the "
                        "folder's author chose: only for a search you trust")  # fmt: skip
    parser.add_argument("--address", metavar="ADDR", help="a Ray cluster to join, e.g. auto or ray://host:10001 "
                        "(default: start Ray on this machine)")  # fmt: skip
    parser.add_argument("--cpus-per-trial", default="1", metavar="K", help="CPUs per trial (default 1)")
    parser.add_argument("--json", action="store_true", help="print the results as one JSON object")
    parser.set_defaults(handler=run_tune)


def build_settings(args: argparse.Namespace) -> SearchSettings:
    """The [`heartpole.scale.SearchSettings`][heartpole.scale.search.SearchSettings] of the arguments; bad values
    raise CommandError."""
    from heartpole.scale import MAX_TRIALS, SearchSettings
    from heartpole.training import preset_config

    algo = args.algo.lower()
    if algo not in SEARCHABLE:
        raise CommandError(f"unknown algorithm {args.algo!r} for a search; choose one of {', '.join(SEARCHABLE)}")
    trials = whole_number("--trials", args.trials, 1)
    if trials > MAX_TRIALS:
        raise CommandError(f"--trials {trials:,}: a search runs at most {MAX_TRIALS:,} trials (Optuna's TPE sampler is "
                           "meant for 100 to 1,000 and slows with every trial; Ray Tune holds them all in memory); "
                           "run several searches")  # fmt: skip
    per_trial = whole_number("--seeds-per-trial", args.seeds_per_trial, 1)
    if per_trial is not None and per_trial > MAX_SEEDS["sb3"]:  # a trial trains its seeds as `train --seeds` does
        raise CommandError(f"--seeds-per-trial must be at most {MAX_SEEDS['sb3']} (the seeds one trial trains with "
                           f"Stable-Baselines3, as train --seeds), got {per_trial:,}")  # fmt: skip
    overrides: dict[str, Any] = {"env_id": heartpole_env(args.env)}
    for name, key in (("--timesteps", "timesteps"), ("--n-envs", "n_envs")):
        value = whole_number(name, getattr(args, key), 1)
        if value is not None:
            overrides[key] = value
    try:
        base = preset_config("default", algo, **overrides)
    except ValueError as error:
        raise CommandError(str(error)) from None
    if base.timesteps < base.n_envs:
        raise CommandError(f"--timesteps ({base.timesteps}) must be at least --n-envs ({base.n_envs})")
    return SearchSettings(
        base=base,
        trials=int(trials),
        seeds=tuple(range(int(per_trial))),
        eval_episodes=int(whole_number("--eval-episodes", args.eval_episodes, 2)),
        eval_seed=int(whole_number("--eval-seed", args.eval_seed, 0)),
        search_seed=int(whole_number("--search-seed", args.search_seed, 0)),
    )


def run_tune(args: argparse.Namespace) -> int:
    """``heartpole tune``: check everything, search, print the table of trials and the best configuration."""
    missing = missing_training_modules() + missing_ray_modules()
    if missing:
        raise CommandError(f"tune needs {', '.join(missing)}, which this Python cannot import: {RAY_EXTRA}")
    settings = build_settings(args)
    cpus = check_cpus_per_trial(whole_number("--cpus-per-trial", args.cpus_per_trial, 1), args.address)
    from heartpole import scale
    from heartpole.registry import env_dynamics

    try:
        env_dynamics(settings.base.env_id)
    except ValueError as error:
        raise CommandError(" ".join(str(error).split())) from None
    out = Path(not_empty("--out", args.out) or f"runs/tune-{settings.base.algo}").resolve()
    try:
        scale.prepare_search_folder(out, args.resume, args.force, trust_pickles=args.trust_pickles)
        with files.folder_lock(out):  # before announcing; tune_search holds it for the search
            pass
    except (ValueError, files.FolderInUseError) as error:
        raise CommandError(str(error)) from None
    paths.expect_output(out)  # once the search is complete in --out, a signal ends the command as a success
    if not args.json:
        print(_announce(scale.read_settings(out) if args.resume else settings, out, args.resume), flush=True)
    try:
        summary = scale.tune_search(settings, out, resume=args.resume, force=args.force, address=args.address,
                                    cpus_per_trial=cpus, trust_pickles=args.trust_pickles)  # fmt: skip
    except scale.AllTrialsFailedError as error:
        for failure in error.failures:
            print(failure.line(), file=sys.stderr)
        raise CommandError(f"every trial failed; see {out / scale.TRIALS_FILE}") from None
    except KeyboardInterrupt:  # Ctrl-C, SIGTERM or SIGHUP: --out holds the search to resume, or what it held
        if args.force or paths.outputs_placed() or not scale.can_resume(out):  # --force: the earlier search is back
            raise
        print(f"heartpole tune: interrupted; continue with: heartpole tune --resume --trust-pickles --out {out}",
              file=sys.stderr)  # fmt: skip
        return files.exit_code()
    except ConnectionError as error:
        raise CommandError(f"cannot reach the Ray cluster at {args.address}: {error}") from None
    except files.FolderInUseError as error:  # another search took --out since the check above
        raise CommandError(str(error)) from None
    if args.json:
        print(json.dumps({"out": str(out), **summary}, allow_nan=False))
    else:
        print(format_trials(summary))
        print(f"wrote {out}/: trials.csv, best_preset.json, tune_summary.json"
              + (", search.png" if "plot" in summary else "") + "; train it with:")  # fmt: skip
        print(f"  heartpole train --preset {out / scale.PRESET_FILE} --seeds 0-9")
    return 1 if summary["failed"] else 0


def _announce(settings: SearchSettings, out: Path, resume: bool) -> str:
    base = settings.base
    verb = "resuming the search" if resume else "searching"
    return (
        f"{verb}: {settings.trials} trials of {base.algo.upper()} on {base.env_id}, {len(settings.seeds)} seeds "
        f"x {base.timesteps:,} steps each, {settings.eval_episodes} evaluation episodes per seed -> {out}"
    )


def format_trials(summary: dict[str, Any]) -> str:
    """The table of trials, the best one, and one line per failed trial."""
    headers = ["trial", "learning_rate", "ent_coef", "gamma", "n_steps", "net", "expected-risk return", "score",
               "heart attacks/ep"]  # fmt: skip
    rows = []
    for row in summary["trials"]:
        done = row.get("objective") is not None
        rows.append([
            row["trial"],
            f"{row['learning_rate']:.2e}" if "learning_rate" in row else "",
            f"{row['ent_coef']:.2e}" if "ent_coef" in row else "",
            f"{row['gamma']:.4f}" if "gamma" in row else "",
            row.get("n_steps", ""),
            f"{row['net_depth']}x{row['net_width']}" if "net_width" in row and "net_depth" in row else "",
            f"{row['objective']:.3f}" if done else "failed",
            f"{row['score']:.4f}" if done else "",
            f"{row['heart_attacks_per_episode']:.3f}" if done else "",
        ])  # fmt: skip
    best = summary["best"]
    lines = [format_table(headers, rows), ""]
    lines.append(
        f"best: trial {best['trial']}, expected-risk return {best['objective']:.3f}, score {best['score']:.4f}"
    )
    if "cpu_seconds" in summary:
        lines.append(format_cpu("the finished trials (training and evaluation)", summary["cpu_seconds"]))
    lines += [f"{failure['trial']} failed: {failure['error']}" for failure in summary["failed"]]
    return "\n".join(lines)
