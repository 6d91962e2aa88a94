"""``heartpole optimum``: solve a variant's optimal policy by dynamic programming, check it, save it."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from heartpole import paths
from heartpole.cli.common import (
    CommandError,
    Subparsers,
    at_least,
    env_id_type,
    error_line,
    format_table,
    output_files,
    seed_int,
)
from heartpole.cli.frontier import add_frontier_arguments, check_frontier_arguments, run_frontier
from heartpole.signals import interruptible

if TYPE_CHECKING:
    from heartpole.evaluation import EvaluationResult
    from heartpole.optimum import OptimumSolution

ORDER = 15

DESCRIPTION = """\
Solve the optimal policy of a HeartPole variant by dynamic programming and report its expected return,
the ceiling every policy's regret is measured from.

On HeartPole-v0 drinks never pay (each costs at least 0.018 of expected return through its own step's
heart-attack risk, more than it can buy), so only the sleep timing is left: the solver's state is
(decisions left, waking alertness, half-hours awake), the ratio work / time is handled by Dinkelbach's
method, and the waking alertness is a midpoint grid (--grid). The error bound is the change of the
expected return when the grid is halved; --check runs the `optimal` policy through the standard evaluator
(expected-risk estimate, 95% interval) beside `expert` with common random numbers.

Covered: HeartPole-v0's actions and variables with other parameters (--param), as long as drinking
provably never pays (refused with the reason otherwise: HeartPole-v1, heart_attack_proclivity=0, short
episodes). See docs/optimum.md.

--frontier solves the optimum at heart-attack penalties from 0 up to where drinks stop paying and prints
the productivity-risk frontier: each penalty's optimal expected score, heart attacks and drinks per episode;
--plot draws it, with --policy and --model evaluated (--check episodes) and drawn on it.

--people NAME solves each person of a population (named: default) once, cached (a progress bar while it
solves; the first solve of the default cohort takes a minute or two), and prints each person's optimum;
--check then evaluates `oracle` and `expert` under the people and reports their oracle regret. See
docs/people.md."""


def register(subparsers: Subparsers) -> None:
    """Add ``heartpole optimum``."""
    parser = subparsers.add_parser(
        "optimum",
        help="solve the optimal policy by dynamic programming (the ceiling for regret)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  heartpole optimum\n  heartpole optimum --param heart_attack_proclivity=0.8 --out opt/\n"
        "  heartpole optimum --grid 800 --check 0 --json\n  heartpole optimum --people default\n"
        "  heartpole optimum --frontier --plot frontier.png --policy expert --policy coffee",
    )
    parser.add_argument(
        "--env", default="HeartPole-v0", type=env_id_type, metavar="ID", help="env id (default: HeartPole-v0)"
    )
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="an env keyword argument, e.g. heart_attack_proclivity=0.8 or max_steps=2000 (repeatable; "
        "values are read as JSON, so wake_alertness=[0.6,1.4] works)",
    )
    parser.add_argument("--out", metavar="DIR", help="save the solution there (optimum.json and optimum.npz)")
    parser.add_argument(
        "--grid", type=at_least(4), default=None, metavar="N", help="waking-alertness grid points, >= 4 (default: 400)"
    )
    parser.add_argument(
        "--check",
        type=at_least(0),
        default=2000,
        metavar="EPISODES",
        help="episodes of the Monte-Carlo check through the evaluator (default 2000; 0 skips it)",
    )
    parser.add_argument("--seed", type=seed_int, default=0, help="seed of the Monte-Carlo check (default 0)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    parser.add_argument("--people", metavar="NAME", help="solve each person of a population instead (named: default)")
    parser.add_argument(
        "--history",
        action="store_true",
        help="also solve the optimum over every policy (one that sees the work done and time elapsed too): its "
        "policy's value, the bound above it, and with --check its policy through the evaluator",
    )
    add_frontier_arguments(parser)
    parser.set_defaults(handler=run_optimum)


def run_optimum(args: argparse.Namespace) -> int:
    """Solve (or load from the cache), check, save and print."""
    from heartpole import optimum

    kwargs = _params(args.param)
    check_frontier_arguments(args)
    if args.frontier:
        return run_frontier(args, kwargs)
    if args.people is not None:
        return _run_people(args, kwargs)
    if args.out:
        output_files(args.out, ["optimum.npz", "optimum.json"], force=True)  # before solving: can it be written?
    if args.grid is not None:
        _check_memory(args.env, kwargs, args.grid)
    print(f"solving {args.env}{' ' + str(kwargs) if kwargs else ''}...", file=sys.stderr, flush=True)
    try:
        # in a worker thread: a signal ends the command within a second, even in a long compiled loop
        if args.grid is None:
            solution = interruptible(lambda: optimum.optimum(args.env, kwargs))
        else:
            solution = interruptible(lambda: optimum.solve(args.env, grid=args.grid, **kwargs))
        checks = _check(args, kwargs) if args.check else {}
        history = _history(args, kwargs, solution) if args.history else []
        if args.out:  # last, so that an interrupted command leaves --out as it was
            solution.save(args.out)
    except (ValueError, TypeError, OSError) as error:  # TypeError: a --param the env does not take
        raise CommandError(_param_error(error, args.param)) from None
    if args.json:
        data = {**solution.summary(), **{f"check_{k}": v.to_dict() for k, v in checks.items()}}
        if args.history:
            data["history"] = {row[0]: row[1] for row in history}
        print(json.dumps(data, allow_nan=False))
    else:
        print(format_solution(solution, checks))
        if history:
            print("\nthe optimum over every policy (it also sees the work done and the time elapsed)")
            shown = [[name, f"{v:.2e}" if abs(v) < 1e-3 else f"{v:.7f}", note] for name, v, note in history]
            print(format_table(["measure", "value", "note"], shown))
        if args.out:
            print(f"\nwrote {args.out}/optimum.json and optimum.npz")
    return 0


def _history(
    args: argparse.Namespace, kwargs: dict[str, Any], solution: OptimumSolution
) -> list[tuple[str, float, str]]:
    """``--history``: the program over day starts' figures, and its policy through the evaluator with ``--check``."""
    from heartpole.evaluation import evaluate
    from heartpole.optimum import solve_history
    from heartpole.policies import HistoryOptimalPolicy
    from heartpole.progress import progress
    from heartpole.registry import env_dynamics

    solved = interruptible(lambda: solve_history(solution.params))
    floor = solution.expected_return - solution.expected_score  # the heart-attack part: the same for both
    rows = [
        ("expected return, its policy", solved.lower + floor, "exact on its waking grid"),
        ("bound above", solved.upper + floor, "no policy in the solved region does better"),
        ("over the sleep-timing optimum", solved.gain, "what the history is worth (same grid)"),
    ]
    if args.check:
        policy = HistoryOptimalPolicy(env_dynamics(args.env, kwargs), solved)
        with progress(args.check * solution.params.max_steps, "checking optimal-history") as bar:
            result = evaluate(policy, args.env, args.check, args.seed, env_kwargs=kwargs, progress=bar.update)
        low, high = result.expected_ci95
        rows.append(
            ("through the evaluator", result.expected_return, f"[{low:.5f}, {high:.5f}], {args.check} episodes")
        )
    return rows


def _run_people(args: argparse.Namespace, kwargs: dict[str, Any]) -> int:
    """``--people``: each person's optimum (solved or loaded, a bar meanwhile), and the check under people."""
    from heartpole.optimum import PeopleOptimum
    from heartpole.truth import people_truth

    if args.grid is not None or args.out:
        raise CommandError("--grid and --out solve one person; with --people each person gets the default grid")
    env_kwargs = {**kwargs, "people": args.people}
    try:
        truth = interruptible(lambda: people_truth(args.env, env_kwargs, show_progress=True))
        if not isinstance(truth, PeopleOptimum):
            raise CommandError(f"--people {args.people}: {truth}")
        checks = _check(args, env_kwargs, ("oracle", "expert")) if args.check else {}
    except (ValueError, TypeError, OSError) as error:
        raise CommandError(error_line(error)) from None
    rows = [
        [person.name, f"{s.expected_return:.5f}", f"{s.error_bound:.1e}", f"{s.expected_sleeps:.2f}", s.max_awake]
        for person, s in zip(truth.people.cohort, truth.solutions)
    ]
    if args.json:
        people = [{"name": row[0], **s.summary()} for row, s in zip(rows, truth.solutions)]
        print(json.dumps({"people": people, **{f"check_{k}": v.to_dict() for k, v in checks.items()}}))
        return 0
    headers = ["person", "optimal expected return", "grid error", "sleeps / episode", "always sleeps after"]
    print(f"{args.env}, people {args.people}: each person's optimum")
    print(format_table(headers, rows))
    for name, result in checks.items():
        low, high = result.oracle_regret_ci95
        print(f"{name}: oracle regret {result.oracle_regret:.5f} [{low:.5f}, {high:.5f}] ({result.episodes} episodes)")
    return 0


SOLVER_ARRAYS = 8
"""Arrays of ``grid x (max_awake + 1)`` float64 the sleep-timing program holds at once, NumPy's temporaries
included (a bound: about 4 measured at grid 4,000)."""


def _check_memory(env_id: str, kwargs: dict[str, Any], grid: int) -> None:
    """Refuse a ``--grid`` whose solve would need more memory than the machine has, before it starts."""
    from heartpole.optimum.common import max_awake
    from heartpole.registry import env_dynamics

    try:
        columns = max_awake(env_dynamics(env_id, kwargs).params) + 1
    except (ValueError, TypeError):
        return  # the solve says what is wrong with the env or its parameters
    needed, total = SOLVER_ARRAYS * grid * columns * 8, paths.physical_memory()
    if total is not None and needed > total:
        raise CommandError(
            f"--grid {grid}: the solver would need about {needed / 2**30:,.0f} GiB of memory ({SOLVER_ARRAYS} arrays "
            f"of {grid:,} x {columns} numbers), more than this machine's {total / 2**30:,.0f} GiB; give a smaller "
            f"--grid (default 400; the grid's error falls as 1 / grid**2)"
        )


def _param_error(error: Exception, items: list[str]) -> str:
    """The error's line; one the env raised about the keyword arguments (a keyword it does not take, a value of the
    wrong type) names the ``--param`` options given."""
    line = error_line(error)
    if isinstance(error, TypeError) and items:
        return f"--param {' --param '.join(items)}: {line}"
    return line


def _params(items: list[str]) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise CommandError(f"--param takes NAME=VALUE, e.g. max_steps=2000; got {item!r}")
        try:
            value = json.loads(text)
        except ValueError:
            raise CommandError(f"--param {name}: {text!r} is not a number or JSON value") from None
        params[name] = tuple(value) if isinstance(value, list) else value
    return params


def _check(
    args: argparse.Namespace, kwargs: dict[str, Any], policies: tuple[str, ...] = ("optimal", "expert")
) -> dict[str, EvaluationResult]:
    from heartpole.evaluation import evaluate
    from heartpole.progress import progress
    from heartpole.registry import env_dynamics

    results = {}
    length = int(env_dynamics(args.env, kwargs).params.max_steps)  # a variant's, or a max_episode_steps below it
    for policy in policies:
        steps = args.check * length
        with progress(steps, f"checking {policy}") as bar:
            results[policy] = evaluate(policy, args.env, args.check, args.seed, env_kwargs=kwargs, progress=bar.update)
    return results


def format_solution(solution: OptimumSolution, checks: Mapping[str, EvaluationResult]) -> str:
    """The solution's figures as a table, with the Monte-Carlo check if run."""
    from heartpole.reporting import has_interval, missing_notes

    p = solution.params
    if solution.history is not None:
        note = f"+- {solution.error_bound:.1e} (grids); any policy adds <= {solution.history_worth:.1e} (solved)"
        gain = [["seeing the work and time so far adds", f"{solution.history.gain:.1e}", "to the sleep-timing policy"]]
    else:
        note = f"+- {solution.error_bound:.1e} (grid); history worth <= {solution.history_worth:.1e} (solved)"
        gain = []
    rows = [
        ["expected return (optimum)", f"{solution.expected_return:.5f}", note],
        ["expected score (work / time)", f"{solution.expected_score:.5f}", ""],
        *gain,
        ["expected heart attacks / episode", f"{solution.expected_heart_attacks:.5f}", "the floor: never drink"],
        ["sleeps / episode", f"{solution.expected_sleeps:.2f}", "the sleep-timing policy's"],
        ["Dinkelbach rate E[work] / E[time]", f"{solution.rate:.5f}", "the sleep-timing policy's"],
        ["each drink costs at least", f"{solution.drink_floor:.4f}", "of expected return"],
        ["a coffee's best gain, any state", f"{solution.coffee_best_gain:.2f}", "units of work (< 0: never pays)"],
    ]
    for name, result in checks.items():
        rows.append([f"{name} through the evaluator", f"{result.expected_return:.5f}", _check_note(result)])
    header = (
        f"{solution.env_id}{' ' + str(solution.env_kwargs) if solution.env_kwargs else ''}: {p.max_steps} decisions, "
        f"proclivity "
        f"{p.heart_attack_proclivity:g}, sleep {p.sleep_half_hours} half-hours, grid {solution.grid}"
    )
    lines = [header, format_table(["measure", "value", "note"], rows)]
    if "optimal" in checks and has_interval(checks["optimal"].expected_ci95):
        result = checks["optimal"]
        inside = solution.within(result.expected_ci95)
        lines.append(
            f"the evaluator's 95% interval for `optimal` ({result.episodes} episodes, seed {result.seed}) "
            + ("contains" if inside else "does NOT contain")
            + " the solver's value"
        )
    lines += missing_notes(list(checks.values()))
    return "\n".join(lines)


def _check_note(result: EvaluationResult) -> str:
    """The evaluator's 95% interval of the expected-risk return and the regret, if there are intervals."""
    from heartpole.reporting import has_interval

    if not has_interval(result.expected_ci95):
        return f"regret {result.regret:.5f}"
    low, high = result.expected_ci95
    regret = f"regret {result.regret:.5f} [{result.regret_ci95[0]:.5f}, {result.regret_ci95[1]:.5f}]"
    return f"[{low:.5f}, {high:.5f}]; {regret}"
