"""What Ray costs and buys on this machine: start-up overhead, and N seeds on Ray against one after another.

Measures, in fresh processes so that nothing is warm:

1. Ray's overhead: ``ray.init`` (local, quiet, as :func:`heartpole.scale.ray_session` does) and a Tune run
   of ``--empty-trials`` trials that do nothing, then ``ray.shutdown``; the time left when the trials
   do nothing is what Ray adds to any ``--ray`` run.
2. ``heartpole train --seeds S --ray`` against ``heartpole train --seeds S`` (the same seeds one after
   another): wall-clock time and CPU time (user + system of the command and everything it started).

Prints a Markdown table (docs/scale.md shows one) and writes it as JSON with ``--json FILE``. Run it on a
quiet machine if you can; on a shared one, run both halves close together and compare ratios::

    nice -n 10 python benchmarks/scale.py --seeds 0-3 --timesteps 100000
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

OVERHEAD_CODE = """
import json, time
started = time.perf_counter()
from heartpole import scale
from ray import tune
imported = time.perf_counter()
def nothing(params):
    tune.report({{"x": 1.0}})
with scale.ray_session():
    ready = time.perf_counter()
    bar = scale.TrialsBar({trials}, "trials", "x")
    tuner = tune.Tuner(nothing, param_space={{"i": tune.grid_search(list(range({trials})))}},
                       run_config=scale.run_config(__import__("pathlib").Path("{storage}"), "empty", bar))
    scale.fit(tuner, bar)
    fitted = time.perf_counter()
stopped = time.perf_counter()
print(json.dumps({{"import_s": imported - started, "init_s": ready - imported, "empty_trials_s": fitted - ready,
                  "shutdown_s": stopped - fitted, "total_s": stopped - started}}))
"""


def children_cpu() -> float:
    """User + system CPU seconds of all waited-for child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(command: list[str]) -> dict[str, float]:
    """Run ``command``; its wall-clock and CPU seconds (Ray's worker processes are its descendants)."""
    cpu, started = children_cpu(), time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{result.stderr}")
    seeds = [run["wall_seconds"] for run in json.loads(result.stdout)["runs"]]
    return {"wall_s": wall, "cpu_s": children_cpu() - cpu, "seed_wall_s": seeds}


def overhead(trials: int) -> dict[str, float]:
    """Ray's start-up, an empty Tune run of ``trials`` trials, and shutdown, in a fresh process."""
    with tempfile.TemporaryDirectory() as storage:
        code = OVERHEAD_CODE.format(trials=trials, storage=storage)
        cpu, started = children_cpu(), time.perf_counter()
        result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        wall = time.perf_counter() - started
    if result.returncode != 0:
        raise RuntimeError(result.stderr)
    figures = json.loads(result.stdout.strip().splitlines()[-1])
    return {**figures, "process_wall_s": wall, "cpu_s": children_cpu() - cpu}


def train_pair(seeds: str, timesteps: int, eval_episodes: int) -> dict[str, dict[str, float]]:
    """``heartpole train --seeds`` with and without ``--ray``, in that order, into throwaway folders."""
    heartpole = [sys.executable, "-m", "heartpole", "train", "--seeds", seeds, "--timesteps", str(timesteps),
                 "--eval-episodes", str(eval_episodes), "--json"]  # fmt: skip
    out = Path(tempfile.mkdtemp(prefix="heartpole-scale-"))
    try:
        return {
            "ray": timed([*heartpole, "--ray", "--out", str(out / "ray")]),
            "sequential": timed([*heartpole, "--out", str(out / "sequential")]),
        }
    finally:
        shutil.rmtree(out, ignore_errors=True)


def main() -> None:
    """Measure and print."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-3", help="seeds to train (default 0-3)")
    parser.add_argument("--timesteps", type=int, default=100_000, help="steps per seed (default 100,000)")
    parser.add_argument("--eval-episodes", type=int, default=2000, help="evaluation episodes (default 2000)")
    parser.add_argument("--empty-trials", type=int, default=4, help="trials of the overhead run (default 4)")
    parser.add_argument("--skip-training", action="store_true", help="measure Ray's overhead only")
    parser.add_argument("--json", metavar="FILE", help="also write the figures as JSON")
    args = parser.parse_args()
    figures: dict[str, Any] = {"cpus": os.cpu_count(), "load_average": os.getloadavg()[0]}
    figures["overhead"] = overhead(args.empty_trials)
    o = figures["overhead"]
    rows = [
        ("import heartpole.scale (Ray, Tune)", f"{o['import_s']:.1f}", ""),
        ("ray.init (local, quiet)", f"{o['init_s']:.1f}", ""),
        (f"Tune run of {args.empty_trials} empty trials", f"{o['empty_trials_s']:.1f}", ""),
        ("ray.shutdown", f"{o['shutdown_s']:.1f}", ""),
        ("whole process", f"{o['process_wall_s']:.1f}", f"{o['cpu_s']:.1f}"),
    ]
    if not args.skip_training:
        figures["train"] = train_pair(args.seeds, args.timesteps, args.eval_episodes)
        for name in ("sequential", "ray"):
            run = figures["train"][name]
            flag = " --ray" if name == "ray" else ""
            rows.append((f"heartpole train --seeds {args.seeds}{flag}", f"{run['wall_s']:.0f}", f"{run['cpu_s']:.0f}"))
            seconds = ", ".join(f"{x:.0f}" for x in run["seed_wall_s"])
            rows.append((f"... each seed's own wall time ({name})", seconds, ""))
    figures["settings"] = vars(args)
    print(f"{os.cpu_count()} CPUs, load average {figures['load_average']:.1f} at the start; "
          f"{args.timesteps:,} steps and {args.eval_episodes} evaluation episodes per seed\n")  # fmt: skip
    print("| what | wall-clock s | CPU s |\n|---|---|---|")
    for row in rows:
        print(f"| {' | '.join(row)} |")
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
