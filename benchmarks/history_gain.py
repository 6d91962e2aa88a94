"""What the work and time so far are worth: the history-aware sleep rule against ``optimal``, on paired episodes.

    python benchmarks/history_gain.py                          # v0, 200,000 paired episodes
    python benchmarks/history_gain.py --people default --episodes 20000 --only Ada,Fay
    python benchmarks/history_gain.py --people default         # every member of the default cohort

One row per env or person: the history-aware rule's gain in expected return over the solved optimum, its 95%
interval and z, and the optimum's mean score on the same episodes against its exact expected score (the paired
simulator's check). ``heartpole.optimum.common.HISTORY_GAIN`` must stay above every gain measured here; the
regret intervals are widened by it. See ``heartpole.optimum.history`` and docs/optimum.md.
"""

from __future__ import annotations

import argparse
import os
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", default=None, help="a population (default: v0 alone)")
    parser.add_argument("--only", default=None, help="comma-separated names of the cohort to measure")
    parser.add_argument("--episodes", type=int, default=200_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from heartpole.optimum import optimum, solve_people
    from heartpole.optimum.common import HISTORY_GAIN
    from heartpole.optimum.history import history_gain

    if args.people is None:
        targets = [("v0", optimum("HeartPole-v0"))]
    else:
        solved = solve_people(args.people)
        wanted = None if args.only is None else set(args.only.split(","))
        targets = [
            (person.name, solution)
            for person, solution in zip(solved.people.cohort, solved.solutions)
            if wanted is None or person.name in wanted
        ]
    print(f"{args.episodes:,} paired episodes each, seed {args.seed}; HISTORY_GAIN = {HISTORY_GAIN:g}")
    print("| who | gain | 95% CI | z | optimal's mean score (exact) | seconds |")
    print("|---|---:|---|---:|---|---:|")
    for name, solution in targets:
        started = time.perf_counter()
        gain = history_gain(solution, episodes=args.episodes, seed=args.seed)
        half = (gain.ci95[1] - gain.ci95[0]) / 2
        print(
            f"| {name} | {gain.gain:.2e} | [{gain.ci95[0]:.2e}, {gain.ci95[1]:.2e}] | {gain.gain / half * 1.96:.1f} | "
            f"{gain.optimal_score:.5f} ({solution.expected_score:.5f}) | {time.perf_counter() - started:.0f} |",
            flush=True,
        )
    print(f"load average: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
