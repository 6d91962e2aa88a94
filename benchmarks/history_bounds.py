"""The optimum over every no-drink policy (heartpole.optimum.whole) against the sleep-timing optimum, by horizon.

For each ``max_steps``: the program's lower value (the score of its history-aware policy), its upper value, the
sleep-timing optimum's score on the same waking grid, what the history is worth (lower - sleep-timing) and the
program's time. ``python benchmarks/history_bounds.py --steps 300 400 701 1000``.
"""

from __future__ import annotations

import argparse
import time

from heartpole.model import Params
from heartpole.optimum.whole import solve_history


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, nargs="+", default=[300, 400, 701, 1000], help="horizons (max_steps)")
    parser.add_argument("--grid", type=int, default=50, help="waking-alertness grid points")
    parser.add_argument("--points", type=int, default=25, help="work grid points per (decisions left, sleeps)")
    args = parser.parse_args()
    print("| decisions | lower (its policy) | upper | sleep-timing optimum | history worth | upper - lower | s |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for steps in args.steps:
        start = time.perf_counter()
        solved = solve_history(Params(max_steps=steps), grid=args.grid, points=args.points)
        took = time.perf_counter() - start
        print(
            f"| {steps:,} | {solved.lower:.9f} | {solved.upper:.9f} | {solved.markov:.9f} | {solved.gain:.2e} "
            f"| {solved.gap:.1e} | {took:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
