"""The optimum over every no-drink policy (heartpole.optimum.whole) against the sleep-timing optimum, by horizon.

For each ``max_steps``: the program's lower value (the expected score of its history-aware policy), its upper value,
the sleep-timing optimum's score on the same waking grid, what the history is worth (lower - sleep-timing), the
program's gap and time, and the coarse solve that `OptimumSolution.history_worth` (the regret margin's share) uses.
``python benchmarks/history_bounds.py --steps 300 400 701 1000 [--env-kwargs '{"sleep_half_hours": 14}']``.
"""

from __future__ import annotations

import argparse
import json
import time

from heartpole.optimum.whole import history_worth, solve_history
from heartpole.parameters import Params


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, nargs="+", default=[300, 400, 701, 1000], help="horizons (max_steps)")
    parser.add_argument("--grid", type=int, default=50, help="waking-alertness grid points")
    parser.add_argument("--points", type=int, default=25, help="work grid points per (decisions left, sleeps)")
    parser.add_argument("--env-kwargs", type=json.loads, default={}, help="other Params fields, as JSON")
    args = parser.parse_args()
    print(f"Params: {args.env_kwargs or 'v0'}; grid {args.grid}, work points {args.points}")
    print(
        "| decisions | lower (its policy) | upper | sleep-timing | history worth | upper - lower | s | margin's worth |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for steps in args.steps:
        kwargs = {**args.env_kwargs, "max_steps": steps}
        if "wake_alertness" in kwargs:
            kwargs["wake_alertness"] = tuple(kwargs["wake_alertness"])
        params = Params(**kwargs)
        start = time.perf_counter()
        solved = solve_history(params, grid=args.grid, points=args.points)
        took = time.perf_counter() - start
        print(
            f"| {steps:,} | {solved.lower:.9f} | {solved.upper:.9f} | {solved.markov:.9f} | {solved.gain:.2e} "
            f"| {solved.gap:.1e} | {took:.0f} | {history_worth(params):.2e} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
