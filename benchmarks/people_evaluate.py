"""How long an evaluation under people takes once the people's optima are cached (the issue's bar: 60 s).

    python benchmarks/people_evaluate.py               # 3 repeats, 2,000 episodes
    python benchmarks/people_evaluate.py --repeats 5 --policy oracle

Each repeat runs the whole command in a fresh process, as a user does:
``heartpole evaluate --policy P --people default --episodes 2000 --json`` (start-up, loading each person's
optimum from the disk cache, the episodes and the oracle regret). The anchor, in the same run: the same
command without ``--people`` (v0, one optimum). The cache is filled first (``solve_people("default")``, not
timed). Medians and ranges over the repeats, and the ratio of the medians, are printed with the machine's
load.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time


def timed(argv: list[str]) -> float:
    """Wall seconds of ``python -m heartpole *argv`` in a fresh process (which must succeed)."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "heartpole", *argv], check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="repeats (default 3)")
    parser.add_argument("--episodes", type=int, default=2000, help="episodes (default 2000)")
    parser.add_argument("--policy", default="expert", help="the policy evaluated (default expert)")
    args = parser.parse_args()
    from heartpole.optimum import solve_people

    solve_people("default")  # the bar is for a filled cache: fill it, untimed
    command = ["evaluate", "--policy", args.policy, "--episodes", str(args.episodes), "--json"]
    people, anchor = [], []
    for _ in range(args.repeats):  # interleaved: a load change hits both alike
        anchor.append(timed(command))
        people.append(timed([*command, "--people", "default"]))
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; {args.repeats} repeats")
    for label, values in (("without people (anchor)", anchor), ("--people default", people)):
        print(
            f"heartpole {' '.join(command)} {label}: median {statistics.median(values):.2f} s "
            f"(range {min(values):.2f} to {max(values):.2f} s)"
        )
    print(f"ratio of the medians: {statistics.median(people) / statistics.median(anchor):.2f}x the anchor")


if __name__ == "__main__":
    main()
