"""``heartpole dataset`` and ``heartpole ope``: Minari datasets and off-policy evaluation against the truth.

The work is done by [`heartpole.offline`][heartpole.offline]; these commands parse, call it and print.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import warnings
from collections.abc import Callable
from types import ModuleType
from typing import TYPE_CHECKING, Any, TypeVar

from heartpole.cli.common import (
    CommandError,
    Subparsers,
    add_people_arguments,
    at_least,
    format_table,
    not_empty,
    positive_int,
    raise_arg,
    seed_int,
)
from heartpole.cli.envs import add_env_options, choose_env
from heartpole.progress import progress
from heartpole.stats import fixed

if TYPE_CHECKING:
    from heartpole.measurement import Measurement
    from heartpole.offline.ope import OPEReport

ORDER = 40
WITH_PEOPLE = " with the dataset's people"
T = TypeVar("T")

OFFLINE_POLICIES = ("random", "nothing", "coffee", "reference", "expert")
"""The built-in policies a dataset can record and off-policy evaluation can estimate: those that act on the
observation alone (``optimal`` needs the decisions left, ``oracle`` each episode's person)."""
POLICY_HELP = (
    f"a built-in policy ({', '.join(OFFLINE_POLICIES)}) or the path of a model .zip saved by 'heartpole train'"
)
NOT_OFFLINE = {
    "optimal": "acts on the number of decisions left as well as the observation",
    "oracle": "acts on each episode's person as well as the observation",
}
DATASET_DESCRIPTION = """\
Record whole episodes of a behaviour policy, which takes a uniformly random action with probability
EPSILON and its own otherwise, as a Minari dataset. Infos hold the behaviour's action probabilities at
every observation (propensities, for importance sampling), heart_attack_risk and productivity. The id
reads heartpole/v0/<policy>-eps<percent>-v0.

Datasets live in Minari's folder: $MINARI_DATASETS_PATH if set, else ~/.minari/datasets. Load one with
minari.load_dataset(ID); dataset.recover_environment() makes its env. Nothing is left half written: the
dataset is written under a temporary name and moved into place when complete."""
FOLDER_NOTE = (
    "Datasets live in Minari's folder: $MINARI_DATASETS_PATH if set, else ~/.minari/datasets. "
    "Load one with minari.load_dataset(ID); dataset.recover_environment() makes its env."
)


def register(subparsers: Subparsers) -> None:
    """Add the ``dataset`` and ``ope`` subcommands."""
    _register_dataset(subparsers)
    _register_ope(subparsers)


def _register_dataset(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "dataset",
        help="record a Minari dataset of a policy's episodes (offline RL, off-policy evaluation)",
        description=DATASET_DESCRIPTION,
        epilog="examples:\n"
        "  heartpole dataset --policy reference --epsilon 0.2       # heartpole/v0/reference-eps20-v0\n"
        "  heartpole dataset --policy expert --epsilon 0.1 --episodes 200 --seed 1\n"
        "  heartpole dataset --standard --force                      # the standard collection\n"
        "  heartpole dataset --policy expert --epsilon 0.1 --people default   # a person per episode",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--policy", metavar="P", help=POLICY_HELP)
    parser.add_argument("--standard", action="store_true", help="record the standard collection instead")
    parser.add_argument(
        "--epsilon", type=_epsilon, default=0.0, metavar="E", help="share of random actions in [0, 1] (default 0)"
    )
    parser.add_argument("--episodes", type=positive_int, default=1000, metavar="N", help="episodes (default 1000)")
    add_env_options(parser)
    parser.add_argument("--seed", type=seed_int, default=0, metavar="S", help="seed, >= 0 (default 0)")
    parser.add_argument("--id", dest="dataset_id", metavar="ID", help="dataset id (default: from policy and epsilon)")
    parser.add_argument("--force", action="store_true", help="replace an existing dataset of the same id")
    add_people_arguments(parser, "each episode's person is recorded with it")
    parser.add_argument(
        "--measurement",
        type=_measurement,
        metavar="JSON",
        help='observe the state through a heartpole.Measurement, as JSON: \'{"noise": {"alertness": 0.2}, '
        '"every": 4}\' (noise sd per variable; measured every 4 half-hours); recorded with the dataset',
    )
    parser.set_defaults(handler=run_dataset)


def _register_ope(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "ope",
        help="off-policy evaluation of a policy from a dataset, scored against its true value",
        description="Estimate a target policy's discounted value from a dataset recorded by 'heartpole dataset' "
        "with per-decision importance sampling (PDIS), weighted PDIS, fitted Q evaluation (linear FQE) and "
        "doubly robust (DR), and print each estimate's error against the true value, measured by running the "
        "policy (expected-risk estimate, 95% interval). " + FOLDER_NOTE,
        epilog="example: heartpole ope --dataset heartpole/v0/reference-eps20-v0 --policy expert --gamma 0.95",
    )
    parser.add_argument("--dataset", required=True, metavar="ID", help="a local dataset id")
    parser.add_argument("--policy", required=True, metavar="P", help="the target policy: " + POLICY_HELP)
    parser.add_argument("--gamma", type=_gamma, default=0.95, metavar="G", help="discount in (0, 1] (default 0.95)")
    parser.add_argument(
        "--truth-episodes",
        type=at_least(2),
        default=2000,
        metavar="N",
        help="episodes for the truth, >= 2 (default 2000)",
    )
    parser.add_argument(
        "--expected-risk",
        action="store_true",
        help="estimate from rewards with each heart-attack coin replaced by its probability (less noise)",
    )
    parser.add_argument("--seed", type=seed_int, default=0, metavar="S", help="seed of the truth's episodes")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.set_defaults(handler=run_ope)


# ------------------------------------------------------------------------------------------------------
# handlers


def run_dataset(args: argparse.Namespace) -> int:
    """``heartpole dataset``: record one dataset, or the standard collection."""
    from heartpole.policies.trained_env import model_file

    datasets = _offline("datasets")
    if args.standard == bool(args.policy):
        raise CommandError("give either --policy P or --standard")
    not_empty("--id", args.dataset_id)
    if args.standard and args.dataset_id:
        raise CommandError("--id names one dataset; it cannot be used with --standard")
    if args.observe_traits and args.people is None:
        raise CommandError("--observe-traits needs --people (the traits are the person's)")
    if args.standard and args.people is not None:
        raise CommandError("--people records one dataset: give --policy P, not --standard")
    if args.standard and args.measurement is not None:
        raise CommandError("--measurement records one dataset: give --policy P, not --standard")
    if args.policy is not None:
        _check_policy(args.policy)
    args.env, env_kwargs = choose_env(args, [] if args.policy is None else [args.policy])
    if args.standard and env_kwargs:
        raise CommandError("--env-kwargs records one dataset: give --policy P, not --standard")
    max_steps = _library(lambda: _max_steps(args.env, env_kwargs))
    _check_room(args, env_kwargs)
    if args.standard:
        total = len(datasets.STANDARD_DATASETS) * args.episodes * max_steps
        with progress(total, "recording the standard datasets") as bar:
            ids = _library(
                lambda: datasets.record_standard(
                    args.episodes, args.env, args.seed, force=args.force, progress=bar.update
                )
            )
        print(format_table(["dataset", "episodes"], [[i, args.episodes] for i in ids]))
        print(f"\nin {datasets.local_root()}")
        return 0
    with progress(args.episodes * max_steps, f"recording {args.policy}") as bar:
        dataset = _library(
            lambda: datasets.record_dataset(
                model_file(args.policy),
                args.epsilon,
                args.episodes,
                args.env,
                args.seed,
                dataset_id=args.dataset_id,
                force=args.force,
                progress=bar.update,
                people=args.people,
                observe_traits=args.observe_traits,
                measurement=args.measurement,
                env_kwargs=env_kwargs,
            )
        )
    meta = dataset.storage.metadata
    print(
        f"recorded {meta['dataset_id']}: {meta['total_episodes']} episodes, {meta['total_steps']} steps "
        f"in {meta['recording_seconds']:.1f} s (behaviour {meta['behaviour_policy']}, epsilon {meta['epsilon']}, "
        f"seed {meta['seed']}{_people_note(meta)}{', measured' if meta.get('measurement') else ''})\n"
        f"in {datasets.local_root()}"
    )
    return 0


def run_ope(args: argparse.Namespace) -> int:
    """``heartpole ope``: each estimator's estimate, its error against the truth, the truth's interval."""
    from heartpole.policies.trained_env import model_file

    ope = _offline("ope")
    _check_policy(args.policy)
    _tell_trained_env(args.policy, args.dataset)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        report = _library(
            lambda: ope.evaluate_off_policy(
                args.dataset,
                model_file(args.policy),
                args.gamma,
                truth_episodes=args.truth_episodes,
                seed=args.seed,
                expected_rewards=args.expected_risk,
            )
        )
    for warning in caught:  # one line each on stderr, not Python's file:line form
        if issubclass(warning.category, RuntimeWarning):
            print(f"warning: {warning.message}", file=sys.stderr)
        else:
            warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
    if args.json:
        print(json.dumps(report.to_dict(), allow_nan=False))
        return 0
    print(format_report(report))
    return 0


def format_report(report: OPEReport) -> str:
    """The estimates as a table under a header naming the truth and its interval."""
    truth = report.truth
    low, high = truth.value_ci95
    rows = [
        [
            e.estimator,
            fixed(e.value, 4),
            _ci(e.ci95),
            fixed(report.error(e), 4, sign=True),
            fixed(abs(report.error(e)), 4),
            "-" if e.weights is None else f"{e.weights.effective_sample_size:.1f}",
        ]
        for e in report.estimates
    ]
    rewards = "expected-risk rewards" if report.expected_rewards else "realized rewards"
    header = (
        f"{report.policy} from {report.dataset_id}, gamma {report.gamma:g}, {rewards}\n"
        f"true value {fixed(truth.value, 4)} (95% CI {_ci((low, high))}, {truth.episodes} episodes run on the env"
        f"{WITH_PEOPLE if report.people else ''})"
    )
    if report.people:
        header += "\n" + _oracle_line(report)
    return "\n".join([header, format_table(["estimator", "estimate", "95% CI", "error", "|error|", "ESS"], rows)])


# ------------------------------------------------------------------------------------------------------
# helpers


def _measurement(text: str) -> Measurement:
    """``--measurement``'s JSON as a [`Measurement`][heartpole.measurement.Measurement]."""
    from heartpole.measurement import Measurement

    accepted = 'a JSON object such as \'{"noise": {"alertness": 0.2}, "every": 4}\''
    try:
        spec = json.loads(text)
    except json.JSONDecodeError:
        raise argparse.ArgumentTypeError(f"--measurement must be {accepted}, got {text!r}") from None
    if not isinstance(spec, dict) or set(spec) - {"noise", "every"} or "noise" not in spec:
        raise argparse.ArgumentTypeError(f"--measurement must be {accepted} (keys noise and every), got {text!r}")
    try:
        return Measurement(**spec)
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"--measurement {text!r}: {error}") from None


def _people_note(meta: dict[str, object]) -> str:
    """``, people: 24 in a cohort`` (and traits observed) for a dataset recorded with people."""
    people = meta.get("people")
    if not isinstance(people, dict):
        return ""
    size = f"{len(people['cohort'])} in a cohort" if "cohort" in people else "a distribution"
    return f", people: {size}" + (", traits observed" if meta.get("observe_traits") else "")


def _oracle_line(report: OPEReport) -> str:
    """The target's oracle regret over the dataset's people (undiscounted), or why there is none."""
    oracle = report.oracle
    if "oracle_regret" in oracle:
        return f"oracle regret {oracle['oracle_regret']:.4f} (95% CI {_ci(oracle['oracle_regret_ci95'])}, return)"
    return f"no oracle regret: {oracle.get('no_oracle_regret_reason')}"


def _ci(interval: tuple[float, float]) -> str:
    if not all(math.isfinite(v) for v in interval):
        return "-"
    return f"[{fixed(interval[0], 4)}, {fixed(interval[1], 4)}]"


def _check_policy(spec: str) -> str:
    """``--policy`` checked before anything runs: a built-in policy of the observation alone, or a model path; the
    error lists exactly what ``--help`` does."""
    accepted = f"use one of {', '.join(OFFLINE_POLICIES)}, or the path of a model .zip saved by 'heartpole train'"
    if spec in NOT_OFFLINE:
        raise CommandError(f"--policy {spec}: it {NOT_OFFLINE[spec]}, which datasets do not record; {accepted}")
    from heartpole.policies import BUILTIN_POLICIES

    if spec not in BUILTIN_POLICIES and not (spec.endswith(".zip") or "/" in spec or os.path.exists(spec)):
        raise CommandError(f"unknown policy {spec!r} for --policy; {accepted}")
    return spec


def _tell_trained_env(spec: str, dataset_id: str) -> None:
    """Say on stderr, for a model whose folder records the env it was trained on, that ``ope`` plays the dataset's
    env (the one whose behaviour the importance weights correct for), naming both."""
    from heartpole.policies.trained_env import trained_env

    trained = _library(lambda: trained_env(spec))
    if trained is not None:
        meta = _library(lambda: _offline("datasets").load_local(dataset_id).storage.metadata)
        print(f"playing the dataset's env {meta.get('env_id')} ({meta.get('max_steps')} steps per episode); {spec} "
              f"was trained on {trained.describe()} as recorded in {trained.source}", file=sys.stderr)  # fmt: skip


def _offline(module: str) -> ModuleType:
    import importlib

    try:
        importlib.import_module("minari")
    except ImportError:
        raise CommandError("Minari is not installed; install it with: pip install 'heartpole[offline]'") from None
    return importlib.import_module(f"heartpole.offline.{module}")


def _check_room(args: argparse.Namespace, env_kwargs: dict[str, Any]) -> None:
    """Refuse ``--episodes`` whose dataset(s) would not fit in Minari's folder, before anything is recorded."""
    datasets = _offline("datasets")
    count = len(datasets.STANDARD_DATASETS) if args.standard else 1
    what = f"--episodes {args.episodes:,}" + (f" for each of the {count} standard datasets" if args.standard else "")
    _library(lambda: datasets.check_dataset_room(args.episodes, args.env, env_kwargs, what, count))


def _max_steps(env_id: str, env_kwargs: dict[str, Any] | None = None) -> int:
    from heartpole.registry import env_dynamics

    return int(env_dynamics(env_id, env_kwargs).params.max_steps)


def _library(call: Callable[[], T]) -> T:
    """Run ``call``; turn the errors a user can cause into [`CommandError`][heartpole.cli.common.CommandError] s (one
    line, exit 2)."""
    try:
        return call()
    except (ValueError, OSError) as error:
        raise CommandError(" ".join(str(error).split())) from None


def _epsilon(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 <= value <= 1.0:
        raise_arg(f"expected a number in [0, 1], got {text!r}")
    return value


def _gamma(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0.0 < value <= 1.0:
        raise_arg(f"expected a discount in (0, 1], got {text!r}")
    return value
