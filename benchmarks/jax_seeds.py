"""N seeds trained and evaluated end to end with the JAX backend, time per phase.

    python benchmarks/jax_seeds.py --seeds 64                      # the default preset, 2,000 episodes a seed
    python benchmarks/jax_seeds.py --seeds 64 --timesteps 100000   # a shorter training, the same phases
    python benchmarks/jax_seeds.py --seeds 4096                    # on a GPU: issue 31's goal, <= 3 minutes

It runs ``heartpole train --backend jax --seeds 0-<N-1> --out <a temporary folder>`` as a user would (a fresh
process, the JAX compilation cache of that folder) and prints the whole command's wall time and its phases, read
from the files it wrote: compiling, training (all seeds in one compiled call), evaluating (``eval_seconds``: all
seeds in one compiled call; older versions evaluated and wrote each seed apart, and their per-seed
``eval_seconds`` are summed) and writing (each seed's ``write_seconds``, summed).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def phases(out: Path) -> dict[str, float]:
    """The phases' seconds from a ``--seeds`` run's ``summary.json`` and its seeds' ``heartpole.json``."""
    summary = json.loads((out / "summary.json").read_text())
    sidecars = [json.loads(path.read_text()) for path in sorted(out.glob("seed_*/heartpole.json"))]
    found = {"compile": summary["compile_seconds"], "train": summary["train_seconds"]}
    if "eval_seconds" in summary:
        found["evaluate"] = summary["eval_seconds"]
        found["write"] = sum(sidecar.get("write_seconds", 0.0) for sidecar in sidecars)
    else:  # one seed at a time: each seed's writing and evaluating together
        found["evaluate and write"] = sum(sidecar["eval_seconds"] for sidecar in sidecars)
    found["solved"] = summary["solved_seeds"]
    return found


def main() -> None:
    """Run the command once and print its phases."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=64, help="how many seeds, 0..N-1 (default 64)")
    parser.add_argument("--timesteps", type=int, default=None, help="training steps a seed (default: the preset's)")
    parser.add_argument("--eval-episodes", type=int, default=2000, help="evaluation episodes a seed (default 2000)")
    args = parser.parse_args()
    if args.seeds < 2:
        parser.error("--seeds must be at least 2")
    with tempfile.TemporaryDirectory(prefix="heartpole-jax-seeds-") as scratch:
        out = Path(scratch) / "runs"
        command = [sys.executable, "-m", "heartpole", "train", "--backend", "jax", "--seeds", f"0-{args.seeds - 1}",
                   "--eval-episodes", str(args.eval_episodes), "--out", str(out), "--json"]  # fmt: skip
        if args.timesteps is not None:
            command += ["--timesteps", str(args.timesteps)]
        environment = {**os.environ, "HEARTPOLE_JAX_CACHE": str(Path(scratch) / "jax-cache")}
        started = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, env=environment)
        wall = time.perf_counter() - started
        found = phases(out)
    print(" ".join(command[1:]).replace(str(out), "<tmp>"))
    print(f"| seeds | whole command (s) | {' | '.join(f'{k} (s)' if k != 'solved' else k for k in found)} |")
    print("|---:|---:|" + "---:|" * len(found))
    cells = [f"{v:.1f}" if isinstance(v, float) else str(v) for v in found.values()]
    print(f"| {args.seeds} | {wall:.1f} | {' | '.join(cells)} |")


if __name__ == "__main__":
    main()
