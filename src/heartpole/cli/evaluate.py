"""``heartpole evaluate``, ``heartpole compare`` and ``heartpole baselines``: honest numbers for policies
([`heartpole.evaluation`][heartpole.evaluation] does the work; these commands parse, call it and print)."""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from heartpole import files
from heartpole.cli.common import (
    CommandError,
    Subparsers,
    add_people_arguments,
    add_trust_pickles,
    error_line,
    format_table,
    markdown_table,
    output_files,
    positive_int,
    seed_int,
    tell_normalization,
)
from heartpole.cli.envs import add_env_options, choose_env
from heartpole.progress import progress
from heartpole.stats import fixed

if TYPE_CHECKING:
    from heartpole.evaluation import Comparison, EvaluationResult, PolicyLike

ORDER = 10

POLICY_HELP = (
    "a built-in policy (random, nothing, coffee, reference, expert, optimal; oracle with --people) or the path "
    "of a model .zip saved by 'heartpole train' (with the statistics its heartpole.json records, if any)"
)
PROTOCOL = (
    "Every policy runs the same episodes: same seed, same chunks of side-by-side envs, so the same random "
    "numbers meet the same events (common random numbers). Intervals are 95% Student-t intervals over "
    "episodes. The expected-risk return (final score - 100 x the summed heart-attack probabilities) "
    "estimates the same expected return as the realized one, without the heart-attack coin's noise."
)
T = TypeVar("T")


def register(subparsers: Subparsers) -> None:
    """Add the ``evaluate``, ``compare`` and ``baselines`` subcommands."""
    _register_evaluate(subparsers)
    _register_compare(subparsers)
    _register_baselines(subparsers)


def _register_evaluate(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "evaluate",
        help="evaluate a policy over many episodes, with 95%% intervals",
        description="Evaluate a policy over many episodes on the native vector env. " + PROTOCOL,
        epilog="example: heartpole evaluate --policy expert --episodes 2000 --json",
    )
    parser.add_argument("--policy", required=True, metavar="P", help=POLICY_HELP)
    _add_run_options(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.set_defaults(handler=run_evaluate)


def _register_compare(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "compare",
        help="compare two policies episode by episode (paired, common random numbers)",
        description="Evaluate two policies on the same episodes and report A - B with a paired 95% interval, "
        "far tighter than the two separate intervals. " + PROTOCOL,
        epilog="example: heartpole compare --policy expert --policy reference",
    )
    parser.add_argument("--policy", action="append", required=True, metavar="P", help=POLICY_HELP + "; give two")
    _add_run_options(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.set_defaults(handler=run_compare)


def _register_baselines(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "baselines",
        help="the table of all built-in policies (and models) beside the published Table 1",
        description="Evaluate every built-in policy (and any --policy given) alike, rank them by the "
        "expected-risk return, print the table beside the published Table 1 and write it as "
        "baselines.md and baselines.csv. " + PROTOCOL,
        epilog="example: heartpole baselines --policy runs/ppo/model.zip --out results",
    )
    parser.add_argument("--policy", action="append", default=[], metavar="P", help="an extra policy or model")
    _add_run_options(parser)
    parser.add_argument(
        "--out",
        default="results",
        metavar="DIR",
        help="folder for baselines.md and .csv (default: results, in the current folder; existing files are "
        "replaced only with --force)",
    )
    parser.add_argument("--force", action="store_true", help="replace existing files (missing folders are created)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of tables")
    parser.set_defaults(handler=run_baselines)


def _add_run_options(parser: argparse.ArgumentParser) -> None:
    add_env_options(parser)
    parser.add_argument("--episodes", type=positive_int, default=2000, metavar="N", help="episodes (default 2000)")
    parser.add_argument("--seed", type=seed_int, default=0, metavar="S", help="seed, >= 0 (default 0)")
    parser.add_argument(
        "--num-envs",
        type=positive_int,
        default=None,
        metavar="N",
        help="episodes run side by side (default: all of them, up to 10000)",
    )
    add_people_arguments(parser, "reports the oracle regret")
    add_trust_pickles(parser)


def _env_kwargs(args: argparse.Namespace, specs: Sequence[str]) -> dict[str, Any]:
    """Set ``args.env`` and return the env keyword arguments: ``--env`` and ``--env-kwargs``, else the env the
    models' folders record ([`choose_env`][heartpole.cli.envs.choose_env]), with ``--people`` and
    ``--observe-traits``; each person's optimum solved (once, cached; a progress bar meanwhile) before any policy
    is loaded."""
    from heartpole.truth import people_truth

    if args.observe_traits and args.people is None:
        raise CommandError("--observe-traits needs --people (the traits are the person's)")
    args.env, kwargs = choose_env(args, specs)
    if args.people is not None:  # --people replaces any people the record has
        traits = {"observe_traits": True} if args.observe_traits else {}
        kwargs = {k: v for k, v in kwargs.items() if k not in ("people", "observe_traits")} | {"people": args.people}
        kwargs |= traits
    if kwargs.get("people") is not None:
        _library(lambda: people_truth(args.env, kwargs, show_progress=True))
    return kwargs


# handlers ---------------------------------------------------------------------------------------------


def run_evaluate(args: argparse.Namespace) -> int:
    """``heartpole evaluate``: one policy's result, as a table or JSON."""
    args.env_kwargs = _env_kwargs(args, [args.policy])
    result = _evaluate(args.policy, _policy(args.policy, args), args)
    print(json.dumps(result.to_dict(), allow_nan=False) if args.json else format_result(result))
    return 0


def run_compare(args: argparse.Namespace) -> int:
    """``heartpole compare``: two policies, paired."""
    from heartpole.evaluation import Comparison

    if len(args.policy) != 2:
        raise CommandError(f"compare needs exactly two --policy options, got {len(args.policy)}")
    args.env_kwargs = _env_kwargs(args, args.policy)
    policies = [_policy(spec, args) for spec in args.policy]  # both checked before either runs
    a, b = (_evaluate(spec, policy, args) for spec, policy in zip(args.policy, policies))
    comparison = _library(lambda: Comparison.of(a, b))
    print(json.dumps(comparison.to_dict(), allow_nan=False) if args.json else format_comparison(comparison))
    return 0


def run_baselines(args: argparse.Namespace) -> int:
    """``heartpole baselines``: every built-in and extra policy, printed and written as Markdown and CSV."""
    from heartpole.evaluation import rank
    from heartpole.policies import BUILTIN_POLICIES, available_builtins

    markdown_path, csv_path = output_files(args.out, ["baselines.md", "baselines.csv"], force=args.force)
    args.env_kwargs = _env_kwargs(args, args.policy)
    extras = [spec for spec in args.policy if spec not in BUILTIN_POLICIES]
    loaded = {spec: _policy(spec, args) for spec in extras}  # fail before the long run, not after it
    builtins = _library(lambda: available_builtins(args.env, args.env_kwargs))
    results = rank(_evaluate(spec, loaded.get(spec, spec), args) for spec in [*builtins, *extras])
    if args.json:  # printed before the files are written: a failure writing them cannot lose the results
        data = {"results": [r.to_dict() for r in results], "published": _published_dicts()}
        print(json.dumps(data, allow_nan=False), flush=True)
    else:
        print(format_baselines(results), flush=True)
    _library(lambda: _write_both(markdown_path, baselines_markdown(results), csv_path, baselines_csv(results)))
    if not args.json:
        print(f"\nwrote {markdown_path} and {csv_path}")
    return 0


# running the library with clear errors --------------------------------------------------------------


def _policy(spec: str, args: argparse.Namespace) -> PolicyLike:
    """``spec`` checked before any episode runs: a built-in's name ([`evaluate`][heartpole.evaluation.evaluate]
    builds it with the run's seed), or the loaded model (the user hears which statistics it applies)."""
    from heartpole.policies import BUILTIN_POLICIES, load_policy
    from heartpole.policies.trained_env import model_file

    policy = _library(
        lambda: load_policy(model_file(spec), args.env, env_kwargs=args.env_kwargs, trust_pickles=args.trust_pickles)
    )
    if spec in BUILTIN_POLICIES:
        return spec
    tell_normalization(policy)
    return policy


def _evaluate(spec: str, policy: PolicyLike, args: argparse.Namespace) -> EvaluationResult:
    """Evaluate ``policy`` (from `_policy`) with the run options of ``args``, a progress bar on stderr
    named ``spec``, errors as one line."""
    from heartpole.evaluation import evaluate
    from heartpole.registry import env_dynamics

    max_steps = _library(lambda: env_dynamics(args.env, args.env_kwargs).params.max_steps)
    with progress(args.episodes * max_steps, f"{spec}") as bar:
        return _library(
            lambda: evaluate(
                policy,
                args.env,
                args.episodes,
                args.seed,
                num_envs=args.num_envs,
                env_kwargs=args.env_kwargs,
                progress=bar.update,
            )
        )


def _library(call: Callable[[], T]) -> T:
    """Run ``call``; turn the errors a user can cause into [`CommandError`][heartpole.cli.common.CommandError] s (one
    line, exit 2)."""
    try:
        return call()
    except (ValueError, OSError) as error:
        raise CommandError(error_line(error)) from None


def _write_both(first: Path, first_text: str, second: Path, second_text: str) -> None:
    """Write two text files, moved into place together (both or neither)."""
    with files.atomic_files(first, second) as (first_temporary, second_temporary):
        first_temporary.write_text(first_text)
        second_temporary.write_text(second_text)


# formatting -----------------------------------------------------------------------------------------


def _interval(value: float, interval: Sequence[float], digits: int) -> list[str]:
    """``[value, "[low, high]"]`` as text; ``-`` for an interval that is missing (fewer than 2 episodes)."""
    from heartpole.reporting import has_interval

    shown = f"[{fixed(interval[0], digits)}, {fixed(interval[1], digits)}]" if has_interval(interval) else "-"
    return [fixed(value, digits), shown]


def _joined(value: float, interval: Sequence[float], digits: int) -> str:
    """``value [low, high]`` as one cell; the value alone without an interval."""
    shown, ends = _interval(value, interval, digits)
    return shown if ends == "-" else f"{shown} {ends}"


def _episodes(count: int, what: str = "") -> str:
    return f"{count} {what}episode{'' if count == 1 else 's'}"


def format_result(result: EvaluationResult) -> str:
    """One evaluation as a small table, with the interval-width ratio and what is missing, in words."""
    from heartpole.reporting import missing_notes

    rows = [
        ["expected-risk return (ranks)", *_interval(result.expected_return, result.expected_ci95, 4)],
        ["realized return", *_interval(result.mean_return, result.ci95, 2)],
        ["heart attacks / episode", *_interval(result.heart_attacks_per_episode, result.heart_attacks_ci95, 3)],
        ["expected heart attacks / episode", f"{result.expected_heart_attacks_per_episode:.4f}", ""],
        ["final score (work / time)", *_interval(result.score, result.score_ci95, 4)],
        ["drinks / episode", f"{result.drinks_per_episode:.2f}", ""],
        ["sleeps / episode", f"{result.sleeps_per_episode:.2f}", ""],
    ]
    if math.isfinite(result.regret):
        rows.insert(1, ["regret (optimum - expected-risk return)", *_interval(result.regret, result.regret_ci95, 5)])
    if math.isfinite(result.oracle_regret):
        label = "oracle regret (person's optimum - expected-risk return)"
        rows.insert(1, [label, *_interval(result.oracle_regret, result.oracle_regret_ci95, 5)])
    header = (
        f"{result.policy} on {result.env_id}: {_episodes(result.episodes)} of {result.max_steps} steps, "
        f"seed {result.seed} ({result.seconds:.1f} s)"
    )
    notes = [*_width_note(result), *missing_notes([result])]
    if result.solved is not None:
        notes.append(_solved_line(result))
    return "\n".join([header, format_table(["measure", "mean", "95% CI"], rows), *notes])


def _width_note(result: EvaluationResult) -> list[str]:
    """How much narrower the expected-risk interval is than the realized one, where both exist."""
    from heartpole.reporting import has_interval

    if result.episodes < 2 or not (has_interval(result.ci95) and has_interval(result.expected_ci95)):
        return []
    if result.expected_ci95[1] > result.expected_ci95[0]:
        return [f"the expected-risk interval is {result.width_ratio:.0f}x narrower than the realized one"]
    if result.ci95[1] > result.ci95[0]:
        return ["the expected-risk return is the same in every episode: its interval has no width at all"]
    return []


def _solved_line(result: EvaluationResult) -> str:
    from heartpole.solved import SOLVED_REGRET

    bound = f"the regret's 95% upper bound {fixed(result.regret_ci95[1], 5)}"
    if result.solved:
        return f"optimum {result.optimal_return:.5f}; solved: {bound} <= {SOLVED_REGRET} (the regret bar)"
    bar = f"(the regret bar: <= {SOLVED_REGRET})"
    return f"optimum {result.optimal_return:.5f}; not solved: {bound} > {SOLVED_REGRET} {bar}"


def format_comparison(comparison: Comparison) -> str:
    """Two evaluations side by side and their paired difference, and what is missing, in words."""
    from heartpole.reporting import has_interval, missing_notes

    a, b = comparison.a, comparison.b
    rows = [
        [
            "expected-risk return",
            _joined(a.expected_return, a.expected_ci95, 4),
            _joined(b.expected_return, b.expected_ci95, 4),
            _joined(comparison.expected_difference, comparison.expected_ci95, 4),
        ],
        [
            "realized return",
            _joined(a.mean_return, a.ci95, 2),
            _joined(b.mean_return, b.ci95, 2),
            _joined(comparison.difference, comparison.ci95, 2),
        ],
        [
            "final score",
            _joined(a.score, a.score_ci95, 4),
            _joined(b.score, b.score_ci95, 4),
            _joined(comparison.score_difference, comparison.score_ci95, 4),
        ],
    ]
    if math.isfinite(a.regret) and math.isfinite(b.regret):
        low, high = comparison.expected_ci95
        rows.insert(
            1,
            [
                "regret",
                _joined(a.regret, a.regret_ci95, 5),
                _joined(b.regret, b.regret_ci95, 5),
                _joined(-comparison.expected_difference, (-high, -low), 5),
            ],
        )
    if math.isfinite(a.oracle_regret) and math.isfinite(b.oracle_regret) and np.array_equal(a.person, b.person):
        low, high = comparison.expected_ci95  # the same people: the gap's difference is the returns' negated
        paired = _joined(-comparison.expected_difference, (-high, -low), 4)
        oracle = [_joined(r.oracle_regret, r.oracle_regret_ci95, 4) for r in (a, b)]
        rows.insert(1, ["oracle regret", *oracle, paired])
    header = (
        f"{a.policy} - {b.policy} on {a.env_id}: {_episodes(a.episodes, 'paired ')} of {a.max_steps} steps, "
        f"seed {a.seed}, common random numbers"
    )
    notes = missing_notes([a, b])
    if all(has_interval(ci) for ci in (a.ci95, b.ci95, comparison.ci95)):
        half = [(ci[1] - ci[0]) / 2 for ci in (a.ci95, b.ci95, comparison.ci95)]
        notes.insert(
            0,
            f"realized return: the paired interval is +-{half[2]:.2f}, "
            f"against +-{half[0]:.2f} and +-{half[1]:.2f} for the two separate ones",
        )
    table = format_table(["measure (95% CI)", a.policy, b.policy, "difference (paired)"], rows)
    return "\n".join([header, table, *notes])


def format_baselines(results: Sequence[EvaluationResult]) -> str:
    """The results table and the published Table 1, for the terminal."""
    from heartpole.reporting import missing_notes, published_rows, table_rows

    first = results[0]
    return "\n".join(
        [
            f"{first.env_id}: {_episodes(first.episodes)} of {first.max_steps} steps per policy, seed {first.seed}",
            format_table(*table_rows(results)),
            *_optimal_note(results),
            *missing_notes(results),
            "",
            "published Table 1 (HEALTHINF abstract, keras-rl, 20 test episodes)",
            format_table(*published_rows()),
        ]
    )


def _optimal_note(results: Sequence[EvaluationResult], markdown: bool = False) -> list[str]:
    """``optimal`` minus ``expert`` with its paired interval, and the regret bar, if both were evaluated."""
    from heartpole.evaluation import Comparison
    from heartpole.reporting import has_interval, plus_minus
    from heartpole.solved import SOLVED_REGRET

    by_name = {result.policy: result for result in results}
    if "optimal" not in by_name or "expert" not in by_name:
        return []
    pair = Comparison.of(by_name["optimal"], by_name["expert"])
    paired = " (paired 95% CI)" if has_interval(pair.expected_ci95) else ""
    optimum = by_name["optimal"].optimal_return
    regret = (
        f"regret = optimum {optimum:.5f} minus the expected-risk return"
        if math.isfinite(optimum)  # under people each person has their own optimum
        else "oracle regret = each person's optimum minus the expected-risk return"
    )
    lines = [
        f"optimal - expert: {plus_minus(pair.expected_difference, pair.expected_ci95)} expected-risk return"
        f"{paired}; {regret}; solved: 95% upper bound of the {regret.split(' =')[0]} <= {SOLVED_REGRET}"
    ]
    return ["", *lines] if markdown else lines


def baselines_markdown(results: Sequence[EvaluationResult]) -> str:
    """The Markdown file written by ``heartpole baselines``."""
    from heartpole.reporting import PUBLISHED_EPISODES, missing_notes, published_rows, table_rows

    first = results[0]
    return "\n".join(
        [
            "# HeartPole baselines",
            "",
            f"{first.env_id}, {_episodes(first.episodes)} of {first.max_steps} steps per policy, seed {first.seed}. "
            + PROTOCOL
            + " Ranked by the expected-risk return.",
            "",
            markdown_table(*table_rows(results)),
            *_optimal_note(results, markdown=True),
            *(["", *missing_notes(results)] if missing_notes(results) else []),
            "",
            f"## Published Table 1 (HEALTHINF abstract, keras-rl, {PUBLISHED_EPISODES} test episodes)",
            "",
            "A heart attack costs 100 and happens about 1.2 times an episode, so one episode's return has a "
            f"standard deviation near 110 and a {PUBLISHED_EPISODES}-episode mean a 95% interval of about +-51: "
            "too wide to rank these rows.",
            "",
            markdown_table(*published_rows()),
            "",
        ]
    )


CSV_FIELDS = (
    "source",
    "policy",
    "episodes",
    "seed",
    "mean_return",
    "ci95_low",
    "ci95_high",
    "expected_return",
    "expected_ci95_low",
    "expected_ci95_high",
    "heart_attacks_per_episode",
    "expected_heart_attacks_per_episode",
    "score",
    "drinks_per_episode",
    "sleeps_per_episode",
    "regret",
    "regret_ci95_low",
    "regret_ci95_high",
    "oracle_regret",
    "oracle_regret_ci95_low",
    "oracle_regret_ci95_high",
)


def baselines_csv(results: Sequence[EvaluationResult]) -> str:
    """The CSV file written by ``heartpole baselines``: our rows, then the published ones (blank where unknown)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_FIELDS, lineterminator="\n")
    writer.writeheader()
    for result in results:
        row = result.to_dict()
        row["ci95_low"], row["ci95_high"] = row.pop("ci95")
        row["expected_ci95_low"], row["expected_ci95_high"] = row.pop("expected_ci95")
        row["regret_ci95_low"], row["regret_ci95_high"] = row.pop("regret_ci95")
        row["oracle_regret_ci95_low"], row["oracle_regret_ci95_high"] = row.pop("oracle_regret_ci95")
        writer.writerow({key: row.get(key) for key in CSV_FIELDS} | {"source": "heartpole evaluate"})
    for published in _published_dicts():
        writer.writerow({key: published.get(key) for key in CSV_FIELDS})
    return buffer.getvalue()


def _published_dicts() -> list[dict[str, Any]]:
    from heartpole.reporting import PUBLISHED_EPISODES, PUBLISHED_TABLE1

    return [
        {
            "source": "published Table 1",
            "policy": f"{algo} ({model})" if model != "-" else algo,
            "episodes": PUBLISHED_EPISODES,
            "mean_return": value,
        }
        for algo, model, value in PUBLISHED_TABLE1
    ]
