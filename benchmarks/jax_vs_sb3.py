"""Five JAX seeds against one SB3 seed: ``heartpole train`` timed side by side, in interleaved pairs.

    python benchmarks/jax_vs_sb3.py                 # 3 pairs, after one JAX run that warms the cache
    python benchmarks/jax_vs_sb3.py --pairs 5 --nice 10

Each pair runs ``heartpole train --backend jax --seeds 0-4`` and ``heartpole train`` (the SB3 default,
seed 0) one right after the other, alternating which goes first, so that both meet the same load on a
shared machine. Every run is a fresh process (``python -m heartpole``), timed from its start to its exit
(wall and CPU time of the child), so start-up, imports, compiling, training, the 2,000-episode evaluation
of every seed and writing the files all count. A first JAX run (not counted) fills the persistent
compilation cache in ``--cache`` so that the pairs measure the warm-cache case; ``--cold`` clears it before
every JAX run instead. The table (markdown) shows each run, then the median and range of each column and
of the ratio JAX / SB3 per pair.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

JAX_ARGS = ["train", "--backend", "jax", "--seeds", "0-4", "--json", "--force"]
SB3_ARGS = ["train", "--json", "--force"]


def run(args: list[str], out: Path, env: dict[str, str], nice: int) -> dict[str, Any]:
    """Run ``heartpole *args --out out`` in a fresh process; its JSON result with wall and CPU seconds."""
    command = [sys.executable, "-m", "heartpole", *args, "--out", str(out)]
    if nice:
        command = ["nice", "-n", str(nice), *command]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode not in (0, 1):  # 1: trained but not solved, still a result
        raise RuntimeError(f"{' '.join(command)} failed ({done.returncode}): {done.stderr.strip()[-2000:]}")
    result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return result | {"process_wall": wall, "process_cpu": cpu}


def solved(result: dict[str, Any]) -> tuple[int, int]:
    """(seeds solved, seeds trained) of a one-seed or several-seed result."""
    if "runs" in result:
        return int(result["solved_seeds"]), len(result["runs"])
    return int(bool(result["solved"])), 1


def row(pair: int, name: str, result: dict[str, Any]) -> list[str]:
    """One table row of a run."""
    compile_seconds = result.get("compile_seconds")
    good, total = solved(result)
    return [
        str(pair),
        name,
        "-" if compile_seconds is None else f"{compile_seconds:.1f}",
        f"{result['train_seconds']:.1f}",
        f"{result['process_wall']:.1f}",
        f"{result['process_cpu']:.1f}",
        f"{good} of {total}",
    ]


def median_range(values: list[float], digits: int = 1) -> str:
    """``median [min, max]``."""
    return f"{statistics.median(values):.{digits}f} [{min(values):.{digits}f}, {max(values):.{digits}f}]"


def table(pairs: list[tuple[dict[str, Any], dict[str, Any]]]) -> str:
    """The markdown table of all runs, their medians and ranges, and the ratios."""
    headers = ["pair", "run", "compile (s)", "training (s)", "process wall (s)", "CPU (s)", "solved"]
    rows = []
    for n, (jax_run, sb3_run) in enumerate(pairs, start=1):
        rows.append(row(n, "JAX, seeds 0-4", jax_run))
        rows.append(row(n, "SB3, seed 0", sb3_run))
    for name, index in (("JAX, seeds 0-4", 0), ("SB3, seed 0", 1)):
        runs = [pair[index] for pair in pairs]
        compiles = [r["compile_seconds"] for r in runs if r.get("compile_seconds") is not None]
        good = sum(solved(r)[0] for r in runs)
        total = sum(solved(r)[1] for r in runs)
        rows.append([
            "median [range]", name, median_range(compiles) if compiles else "-",
            median_range([r["train_seconds"] for r in runs]), median_range([r["process_wall"] for r in runs]),
            median_range([r["process_cpu"] for r in runs]), f"{good} of {total}",
        ])  # fmt: skip
    ratios = [jax_run["process_wall"] / sb3_run["process_wall"] for jax_run, sb3_run in pairs]
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(cells) + " |" for cells in rows]
    lines.append("")
    lines.append(f"process wall time, JAX 5 seeds / SB3 1 seed, per pair: {median_range(ratios, 2)} (median [range])")
    return "\n".join(lines)


def main() -> None:
    """Parse the options, warm the cache, run the pairs and print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pairs", type=int, default=3, help="pairs of runs (default 3)")
    parser.add_argument("--nice", type=int, default=0, help="run both commands under nice -n N (default 0)")
    parser.add_argument("--cache", type=Path, help="compilation cache folder (default: a temporary one)")
    parser.add_argument("--cold", action="store_true", help="clear the compilation cache before every JAX run")
    parser.add_argument("--json", type=Path, help="also write every run's result to this JSON file")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="heartpole-jax-vs-sb3-") as scratch:
        root = Path(scratch)
        cache = args.cache or root / "cache"
        env = {**os.environ, "HEARTPOLE_JAX_CACHE": str(cache), "HEARTPOLE_PROGRESS": "0"}
        if not args.cold:
            print("warming the compilation cache (one JAX run, not counted) ...", file=sys.stderr, flush=True)
            run(JAX_ARGS, root / "jax", env, args.nice)
        pairs = []
        for n in range(args.pairs):
            order = ("jax", "sb3") if n % 2 == 0 else ("sb3", "jax")
            results: dict[str, dict[str, Any]] = {}
            for name in order:
                if name == "jax" and args.cold:
                    shutil.rmtree(cache, ignore_errors=True)
                results[name] = run(JAX_ARGS if name == "jax" else SB3_ARGS, root / name, env, args.nice)
                print(f"pair {n + 1}: {name} {results[name]['process_wall']:.1f} s", file=sys.stderr, flush=True)
            pairs.append((results["jax"], results["sb3"]))
    if args.json is not None:
        args.json.write_text(json.dumps([{"jax": j, "sb3": s} for j, s in pairs], indent=1))
    print(table(pairs))


if __name__ == "__main__":
    main()
