"""What the old history-aware rule gains over the new ``optimal`` (the played history-aware optimum), paired.

For each setting (v0 or a default-cohort person, at a horizon): the solution's expected return and margin, and
[`history_gain`][heartpole.optimum.history.history_gain] of the rule that takes the sleep-timing thresholds at the rate
its own work so far implies, against the solution's played policy, on ``--episodes`` paired episodes (float64, common
waking draws). The optimum is optimal over every policy that sees the observation, so the gain's 95% interval should
hold nothing above the margin. One setting at a time, one core: long (minutes a setting at 200,000 episodes).

``python benchmarks/history_against_optimal.py --people v0 Cleo --steps 300 1000 --episodes 200000``;
``--margins``: only each setting's margin and its parts (seconds a setting, once solved), no episodes.
"""

from __future__ import annotations

import argparse
import time

from heartpole.optimum import NotCoveredError, optimum
from heartpole.optimum.history import history_gain
from heartpole.people import DEFAULT_COHORT


def person_kwargs(name: str) -> dict[str, object]:
    """The env keyword arguments of ``v0`` (none) or of the default cohort's person ``name``."""
    if name == "v0":
        return {}
    for who, proclivity, decay, sleep, wake in DEFAULT_COHORT:
        if who == name:
            return {
                "heart_attack_proclivity": proclivity,
                "decay_rate": decay,
                "sleep_half_hours": sleep,
                "wake_alertness": wake,
            }
    names = ", ".join(row[0] for row in DEFAULT_COHORT)
    raise SystemExit(f"unknown person {name!r}: v0 or one of the default cohort ({names})")


def margins(people: list[str], horizons: list[int]) -> None:
    """Each setting's optimum, what the history adds, and the margin's parts."""
    print("| setting | expected return | history's gain | grid errors | gap (upper - lower) | margin |")
    print("|---|---:|---:|---:|---:|---:|")
    for name in people:
        for steps in horizons:
            try:
                solution = optimum("HeartPole-v0", {**person_kwargs(name), "max_steps": steps})
            except NotCoveredError:
                print(f"| {name}, {steps} | not covered (drinking may pay) | | | | |", flush=True)
                continue
            gain = f"{solution.history.gain:.2e}" if solution.history is not None else "not played"
            print(
                f"| {name}, {steps} | {solution.expected_return:.7f} | {gain} | {solution.error_bound:.1e} "
                f"| {solution.history_worth:.1e} | {solution.margin:.1e} |",
                flush=True,
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", nargs="+", default=["v0"], help="v0 and/or default-cohort names")
    parser.add_argument("--steps", type=int, nargs="+", default=[300, 400, 701, 1000], help="horizons (max_steps)")
    parser.add_argument("--episodes", type=int, default=200_000, help="paired episodes a setting")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--margins", action="store_true", help="only the margins and their parts, no episodes")
    args = parser.parse_args()
    if args.margins:
        margins(args.people, args.steps)
        return
    print(f"{args.episodes:,} paired episodes a setting, seed {args.seed}")
    print("| setting | optimum's expected return | margin | old rule's gain over `optimal` [95%] | verdict | s |")
    print("|---|---:|---:|---:|---|---:|")
    for name in args.people:
        for steps in args.steps:
            start = time.perf_counter()
            solution = optimum("HeartPole-v0", {**person_kwargs(name), "max_steps": steps})
            measured = history_gain(solution, episodes=args.episodes, seed=args.seed)
            low, high = measured.ci95
            verdict = "nothing significant" if low <= solution.margin else "GAINS: the optimum is not optimal"
            print(
                f"| {name}, {steps} | {solution.expected_return:.7f} | {solution.margin:.1e} "
                f"| {measured.gain:.2e} [{low:.2e}, {high:.2e}] | {verdict} | {time.perf_counter() - start:.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
