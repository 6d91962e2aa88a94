"""How long the default population's optima take: the first solve (cold cache) and the lookups after it.

    python benchmarks/people_solve.py               # 3 repeats
    python benchmarks/people_solve.py --repeats 5

Each repeat runs in fresh processes with ``HEARTPOLE_CACHE_DIR`` set to a new temporary folder:

- ``cold``: ``solve_people("default")`` with an empty cache (the first person here, the rest two at a time
  in worker processes), the issue's bar is 120 s;
- ``cached``: the same call in a new process once the folder holds every solution (loads from disk);
- ``again``: the same call a second time in that process (memory).

The anchor, measured in the same run and process kind: one cold ``heartpole.optimum.solve()`` of v0 alone,
so the cold figure reads as "this many single solves". Medians and ranges over the repeats are printed
with the machine's load.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

CHILD = """
import json, sys, time
from heartpole.optimum import solve, solve_people
kind = sys.argv[1]
start = time.perf_counter()
if kind == "anchor":
    solve("HeartPole-v0")
    print(json.dumps({"anchor": time.perf_counter() - start}))
else:
    solve_people("default")
    first = time.perf_counter() - start
    start = time.perf_counter()
    solve_people("default")
    print(json.dumps({kind: first, "again": time.perf_counter() - start}))
"""


def child(kind: str, cache: str) -> dict[str, float]:
    """Run one timing in a fresh interpreter with its own cache folder; its figures."""
    env = {**os.environ, "HEARTPOLE_CACHE_DIR": cache, "HEARTPOLE_PROGRESS": "0"}
    out = subprocess.run([sys.executable, "-c", CHILD, kind], env=env, check=True, capture_output=True, text=True)
    figures: dict[str, float] = json.loads(out.stdout.strip().splitlines()[-1])
    return figures


def summary(values: list[float]) -> str:
    """``median (min-max)`` in seconds."""
    return f"{statistics.median(values):7.2f} s ({min(values):.2f}-{max(values):.2f})"


def main() -> None:
    """Time the repeats and print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rows: dict[str, list[float]] = {"anchor": [], "cold": [], "cached": [], "again": []}
    for repeat in range(args.repeats):
        with tempfile.TemporaryDirectory() as anchor_cache, tempfile.TemporaryDirectory() as cache:
            rows["anchor"].append(child("anchor", anchor_cache)["anchor"])
            cold = child("cold", cache)
            cached = child("cached", cache)
        rows["cold"].append(cold["cold"])
        rows["cached"].append(cached["cached"])
        rows["again"].append(cached["again"])
        print(f"repeat {repeat}: " + ", ".join(f"{k} {v[-1]:.2f} s" for k, v in rows.items()), flush=True)
    ratios = [c / a for c, a in zip(rows["cold"], rows["anchor"])]
    print(
        f"\n`python benchmarks/people_solve.py --repeats {args.repeats}` on {platform.platform()}, "
        f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.2f} at the end ({time.strftime('%Y-%m-%d')})"
    )
    print(f"anchor: one v0 solve         {summary(rows['anchor'])}")
    print(
        f"cold:   solve_people default {summary(rows['cold'])}   = {statistics.median(ratios):.1f} anchors "
        f"({min(ratios):.1f}-{max(ratios):.1f}); bar 120 s"
    )
    print(f"cached: new process, disk    {summary(rows['cached'])}")
    print(f"again:  same process, memory {summary(rows['again'])}")


if __name__ == "__main__":
    main()
