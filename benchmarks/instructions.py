"""Machine instructions per single-env step, HeartPole against CartPole: a speed figure without less noise.

    python benchmarks/instructions.py              # needs valgrind; about a minute
    python benchmarks/instructions.py --steps 5000

Wall-clock rates on a shared machine move by 30% between runs (see speed.py); the number of instructions
a step executes moves by a few percent only (HeartPole 29,400 to 33,200 in four runs of the same code, hash
seed fixed; the source of the rest was not found). Each env runs under ``valgrind --tool=callgrind``
twice, for a short and a long run of random actions (all of the env's actions, reset when an episode
ends); the difference of the two totals divided by the difference of steps is the cost of one step,
without start-up and imports. Fewer instructions is not the same as less time (memory, branch
prediction), but a change that removes a tenth of the work shows here clearly. Instructions are
counted for the Python interpreter that runs this script.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys

ENVS = ("CartPole-v1", "HeartPole-v0")


def run_steps(env_id: str, steps: int) -> None:
    """Step one unwrapped env ``steps`` times under random actions (the code valgrind measures)."""
    import gymnasium as gym
    import numpy as np

    import heartpole  # noqa: F401  (registers HeartPole-v0)

    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    actions = np.random.default_rng(0).integers(0, env.action_space.n, size=steps).tolist()
    step, reset = env.step, env.reset
    for action in actions:
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            reset()


def instructions(env_id: str, steps: int) -> int:
    """Instructions executed by a whole Python process that steps ``env_id`` ``steps`` times."""
    command = [
        "valgrind",
        "--tool=callgrind",
        "--callgrind-out-file=/dev/null",
        sys.executable,
        __file__,
        "--run",
        env_id,
        str(steps),
    ]
    fixed_hashes = {**os.environ, "PYTHONHASHSEED": "0"}  # string hashes decide dict probing, hence counts
    output = subprocess.run(command, check=True, capture_output=True, text=True, env=fixed_hashes).stderr
    match = re.search(r"Collected\s*:\s*(\d+)", output)
    if match is None:
        raise RuntimeError(f"callgrind printed no instruction count:\n{output[-2000:]}")
    return int(match.group(1))


def per_step(env_id: str, steps: int) -> float:
    """Instructions of one step: the difference between a run of ``steps`` and one of ``steps // 6``."""
    short = steps // 6
    return (instructions(env_id, steps) - instructions(env_id, short)) / (steps - short)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=12_000, help="steps of the long run (default 12000)")
    parser.add_argument("--run", nargs=2, metavar=("ENV", "STEPS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.run:
        run_steps(args.run[0], int(args.run[1]))
        return
    if args.steps < 600:
        parser.error(f"--steps must be at least 600, got {args.steps}")
    if shutil.which("valgrind") is None:
        sys.exit("benchmarks/instructions.py needs valgrind (apt install valgrind); speed.py needs nothing")
    counts = {env_id: per_step(env_id, args.steps) for env_id in ENVS}
    anchor = counts["CartPole-v1"]
    print(f"instructions per step, unwrapped single env, random actions ({sys.executable})")
    for env_id, count in counts.items():
        print(f"  {env_id:<14} {count:>9,.0f}   CartPole-v1 / this: {anchor / count:4.2f}x")


if __name__ == "__main__":
    main()
