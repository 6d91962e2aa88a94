"""``heartpole optimum --frontier``: the productivity-risk frontier as a table, and as a PNG with policies on it."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from heartpole import files
from heartpole.cli.common import CommandError, add_trust_pickles, error_line, format_table, output_file
from heartpole.signals import interruptible

if TYPE_CHECKING:
    from heartpole.evaluation import EvaluationResult
    from heartpole.optimum import Frontier
    from heartpole.plots import FrontierMark


def add_frontier_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--frontier`` and the options that go with it to ``heartpole optimum``."""
    group = parser.add_argument_group("the productivity-risk frontier (--frontier)")
    group.add_argument(
        "--frontier",
        action="store_true",
        help="solve the optimum at heart-attack penalties from 0 up to where drinks stop paying and print its "
        "expected score, heart attacks and drinks per episode (docs/optimum.md)",
    )
    group.add_argument(
        "--penalties",
        metavar="P,P,...",
        help="the penalties to solve, e.g. 0,10,30,100 (default: nine from 0 to where drinks never pay)",
    )
    group.add_argument("--plot", metavar="FILE.png", help="also draw the frontier as a PNG there")
    group.add_argument("--force", action="store_true", help="replace an existing --plot file")
    group.add_argument(
        "--policy",
        action="append",
        default=[],
        metavar="P",
        help="a built-in policy (or a model .zip) to evaluate and draw on the --plot, with its 95%% intervals "
        "(repeatable; --check episodes, --seed)",
    )
    group.add_argument(
        "--model",
        action="append",
        default=[],
        metavar="DIR",
        help="a 'heartpole train --out' folder (or its model .zip) to evaluate and draw, like --policy",
    )
    add_trust_pickles(parser)


def check_frontier_arguments(args: argparse.Namespace) -> None:
    """Refuse the frontier's options without ``--frontier``, and options ``--frontier`` does not take."""
    given = [name for name in ("penalties", "plot", "policy", "model") if getattr(args, name)]
    if not args.frontier:
        if given or args.force:
            options = ", ".join(f"--{name}" for name in [*given, *(["force"] if args.force else [])])
            raise CommandError(f"{options} go with --frontier")
        return
    clashing = [f"--{name}" for name in ("out", "grid", "people", "history") if getattr(args, name)]
    if clashing:
        raise CommandError(f"--frontier solves each penalty on the default grid; it takes no {', '.join(clashing)}")
    if (args.policy or args.model) and not args.plot:
        raise CommandError("--policy and --model are drawn on the frontier's picture: give --plot FILE.png too")
    if (args.policy or args.model) and not args.check:
        raise CommandError("--policy and --model are evaluated over --check episodes: give --check 1 or more")


def run_frontier(args: argparse.Namespace, kwargs: dict[str, Any]) -> int:
    """Solve the frontier (a progress bar meanwhile), evaluate the policies to draw, print, then write the PNG."""
    from heartpole.optimum import frontier
    from heartpole.optimum.tradeoff import DEFAULT_POINTS
    from heartpole.progress import progress

    penalties = _penalties(args.penalties)
    target = _plot_target(args)
    specs = [*args.policy, *args.model]
    try:
        loaded = {spec: _load(spec, args, kwargs) for spec in specs}  # before the long solve: fail early
        print(f"solving the frontier of {args.env}{' ' + str(kwargs) if kwargs else ''}: first where drinks stop "
              "paying, then each penalty...", file=sys.stderr, flush=True)  # fmt: skip
        total = len(penalties) if penalties is not None else DEFAULT_POINTS
        with progress(total, "solving the frontier") as bar:
            solved = interruptible(lambda: frontier(args.env, penalties, env_kwargs=kwargs, progress=bar.update))
        results = [_evaluate(spec, policy, args, kwargs) for spec, policy in loaded.items()]
    except (ValueError, TypeError, OSError) as error:
        raise CommandError(error_line(error)) from None
    if args.json:
        data = {**solved.summary(), "policies": [r.to_dict() for r in results]}
        print(json.dumps(data, allow_nan=False), flush=True)
    else:
        print(format_frontier(solved), flush=True)
    if target is not None:
        _write_plot(solved, [mark(r, spec) for r, spec in zip(results, specs)], target)
        if not args.json:
            print(f"\nwrote {target}")
    return 0


def _penalties(text: str | None) -> list[float] | None:
    """``--penalties``: numbers >= 0 separated by commas."""
    if text is None:
        return None
    try:
        values = [float(item) for item in text.split(",")]
    except ValueError:
        example = "e.g. 0,10,30,100"
        raise CommandError(f"--penalties takes numbers >= 0 separated by commas, {example}; got {text!r}") from None
    if not all(0 <= value < math.inf for value in values):
        raise CommandError(f"--penalties takes finite numbers >= 0, got {text!r}")
    return values


def _plot_target(args: argparse.Namespace) -> Path | None:
    """``--plot``, checked before any work (and matplotlib with it)."""
    if args.plot is None:
        return None
    from heartpole.plots import require_matplotlib

    target = output_file(args.plot, force=args.force, suffixes=[".png"])
    try:
        require_matplotlib()
    except ImportError as error:
        raise CommandError(f"--plot: {error}") from None
    return target


def _load(spec: str, args: argparse.Namespace, kwargs: dict[str, Any]) -> Any:
    """A built-in policy's name as it is (the evaluator builds it with the run's seed), or the loaded model."""
    from heartpole.policies import BUILTIN_POLICIES, load_policy
    from heartpole.policies.trained_env import model_file

    if spec in BUILTIN_POLICIES:
        load_policy(spec, args.env, env_kwargs=kwargs)  # checks it plays this env
        return spec
    return load_policy(model_file(spec), args.env, env_kwargs=kwargs, trust_pickles=args.trust_pickles)


def _evaluate(spec: str, policy: Any, args: argparse.Namespace, kwargs: dict[str, Any]) -> EvaluationResult:
    """``policy`` over ``--check`` episodes from ``--seed``, a progress bar named ``spec``."""
    from heartpole.evaluation import evaluate
    from heartpole.progress import progress
    from heartpole.registry import env_dynamics

    steps = args.check * env_dynamics(args.env, kwargs).params.max_steps
    with progress(steps, spec) as bar:
        return evaluate(policy, args.env, args.check, args.seed, env_kwargs=kwargs, progress=bar.update, regret=False)


def mark(result: EvaluationResult, label: str) -> FrontierMark:
    """An evaluated policy as a point of the frontier's picture: its expected heart attacks (the summed risks'
    mean, with a 95% interval over episodes) and its score."""
    from heartpole.plots import FrontierMark
    from heartpole.stats import confidence_interval

    return FrontierMark(
        label=label,
        heart_attacks=result.expected_heart_attacks_per_episode,
        heart_attacks_ci95=confidence_interval(result.expected_heart_attacks),
        score=result.score,
        score_ci95=result.score_ci95,
    )


def _write_plot(solved: Frontier, marks: list[FrontierMark], target: Path) -> None:
    from heartpole import plots

    figure = plots.frontier_figure(solved, marks)
    files.atomic_write(target, lambda temporary: plots.save_figure(figure, temporary))


def format_frontier(solved: Frontier) -> str:
    """The frontier as a table: one row per solved penalty, then the threshold and what was not solved."""
    from heartpole.optimum.tradeoff import LOWER_BOUND

    rows = [
        [
            f"{p.penalty:g}",
            f"{p.expected_score:.5f}",
            f"{p.expected_heart_attacks:.5f}",
            _drinks(p.coffees),
            _drinks(p.beers),
            f"{p.expected_return:.5f}",
            f"[{_number(p.lower)}, {_number(p.upper)}]",
            p.solver,
        ]
        for p in solved.points
    ]
    headers = ["penalty", "score", "heart attacks", "coffees", "beers", "expected return", "interval", "solver"]
    extra = f" {solved.env_kwargs}" if solved.env_kwargs else ""
    lines = [f"{solved.env_id}{extra}: the optimum at each heart-attack penalty", format_table(headers, rows)]
    lines.append(
        f"drinks never pay from penalty {solved.threshold:.4g} on, by the per-step check (bisection on it); every "
        "penalty above has the same optimum"
    )
    if solved.proven_from < solved.threshold:
        lines.append(f"the solver's check proves it from penalty {solved.proven_from:g} on (the points above)")
    if solved.drinks_stop < solved.proven_from:
        lines.append(f"the solved policies drink nothing from penalty {solved.drinks_stop:g} on")
    if any(p.solver == LOWER_BOUND for p in solved.points):
        lines.append(
            f"{LOWER_BOUND}: not a proven optimum; its return is a lower bound (the interval's upper end unknown)"
        )
    if solved.missing:
        penalty, reason = solved.missing[-1]
        listed = ", ".join(f"{p:g}" for p, _ in solved.missing)
        lines.append(f"not solved: penalties {listed}; at {penalty:g}: {reason}")
    return "\n".join(lines)


def _number(value: float) -> str:
    """A return to 5 decimals, or ``none`` where the solver has no bound."""
    return "none" if math.isnan(value) else f"{value:.5f}"


def _drinks(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.2f}"
