"""HeartPole's speed against Gymnasium's CartPole, measured side by side in one run.

    python benchmarks/speed.py                 # all sections, a few minutes on a 2-core machine
    python benchmarks/speed.py --quick         # fewer repeats, fewer sizes
    python benchmarks/speed.py --only single   # one section: single, vector, scaling, flat

Every figure is steps per second with random actions (all of an env's actions), the best of several
interleaved repeats (the machine is shared; the best run is the least disturbed), and is reported as a
ratio against the anchor measured in the same run. Actions are drawn before timing, so the figures
measure the envs alone. Each measurement runs in a fresh Python process: glibc's allocator adapts its
thresholds to the arrays a process frees, and in one process the env measured first changed the speed
of the other by up to 25%.
"""

from __future__ import annotations

import argparse
import gc
import platform
import subprocess
import sys
import time
import tracemalloc
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.classic_control.cartpole import CartPoleEnv, CartPoleVectorEnv

import heartpole

Factory = Callable[[], Any]


def single_rate(make: Factory, steps: int, seed: int = 0) -> float:
    """Steps per second of one unwrapped env under random actions (reset when an episode ends)."""
    env = make()
    env.reset(seed=seed)
    actions = np.random.default_rng(seed).integers(0, env.action_space.n, size=steps).tolist()
    step, reset = env.step, env.reset
    gc.disable()
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            reset()
    elapsed = time.perf_counter() - start
    gc.enable()
    return steps / elapsed


def vector_rate(make: Factory, num_envs: int, steps: int, seed: int = 0) -> float:
    """Env-steps per second of a native vector env under random actions (it autoresets itself)."""
    env = make()
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    actions = [rng.integers(0, env.single_action_space.n, size=num_envs) for _ in range(min(steps, 64))]
    env.step(actions[0])  # warm-up
    start = time.perf_counter()
    for t in range(steps):
        env.step(actions[t % len(actions)])
    return steps * num_envs / (time.perf_counter() - start)


SINGLE_ENVS: dict[str, Factory] = {
    "CartPole-v1": CartPoleEnv,
    "HeartPole-v0": heartpole.HeartPole,
    "make:CartPole-v1": lambda: gym.make("CartPole-v1"),
    "make:HeartPole-v0": lambda: gym.make("HeartPole-v0"),
}
VECTOR_ENVS: dict[str, Callable[[int], Any]] = {
    "CartPoleVectorEnv": lambda n: CartPoleVectorEnv(num_envs=n),
    "HeartPoleVectorEnv": lambda n: heartpole.HeartPoleVectorEnv(n),
}


def measure(env: str, num_envs: int, steps: int) -> float:
    """One measurement in this process: a single env when ``num_envs`` is 0, else a vector env."""
    if num_envs == 0:
        return single_rate(SINGLE_ENVS[env], steps)
    return vector_rate(lambda: VECTOR_ENVS[env](num_envs), num_envs, steps)


def fresh(env: str, num_envs: int, steps: int) -> Callable[[], float]:
    """A measurement to run in a fresh Python process (see the module docstring for why)."""
    command = [sys.executable, __file__, "--measure", env, str(num_envs), str(steps)]
    return lambda: float(subprocess.run(command, check=True, capture_output=True, text=True).stdout)


def best_of(repeats: int, *measurements: Callable[[], float]) -> list[float]:
    """Run the measurements interleaved ``repeats`` times; the best rate of each."""
    best = [0.0] * len(measurements)
    for _ in range(repeats):
        for i, measure in enumerate(measurements):
            best[i] = max(best[i], measure())
    return best


def report(name: str, rate: float, anchor_name: str, anchor: float, goal: float | None = None) -> None:
    ratio = rate / anchor
    verdict = "" if goal is None else f"  (goal >= {goal:.1f}x: {'met' if ratio >= goal else 'NOT met'})"
    print(f"  {name:<34} {rate:>14,.0f} steps/s   {ratio:5.2f}x {anchor_name}{verdict}")


def section_single(repeats: int) -> None:
    print("single env, unwrapped, random actions")
    steps = 100_000
    cartpole, heart, made_cartpole, made_heart = best_of(repeats, *(fresh(env, 0, steps) for env in SINGLE_ENVS))
    report("CartPole-v1 unwrapped (anchor)", cartpole, "CartPole", cartpole)
    report("HeartPole-v0 unwrapped", heart, "CartPole", cartpole, goal=3.0)
    report("CartPole-v1 via gym.make", made_cartpole, "CartPole", cartpole)
    report("HeartPole-v0 via gym.make", made_heart, "CartPole via make", made_cartpole)


def section_vector(repeats: int, num_envs: int = 16384) -> None:
    print(f"vector env, {num_envs} envs, random actions")
    steps = 300
    cartpole, heart = best_of(repeats, *(fresh(env, num_envs, steps) for env in VECTOR_ENVS))
    report("CartPoleVectorEnv (anchor)", cartpole, "CartPoleVec", cartpole)
    report("HeartPoleVectorEnv", heart, "CartPoleVec", cartpole, goal=3.0)


def section_scaling(repeats: int, sizes: list[int]) -> None:
    print("vector env scaling (env-steps/s; ratio against CartPoleVectorEnv of the same size)")
    for n in sizes:
        steps = max(20, min(3000, 4_000_000 // n))
        cartpole, heart = best_of(repeats, *(fresh(env, n, steps) for env in VECTOR_ENVS))
        report(f"HeartPoleVectorEnv n={n}", heart, f"CartPoleVec n={n}", cartpole)


def section_flat(chunks: int = 10, chunk_steps: int = 50_000) -> None:
    print(f"long run: single env with render_mode='ansi', never rendered, {chunks} x {chunk_steps} steps")
    env = heartpole.HeartPole(render_mode="ansi")
    env.reset(seed=0)
    tracemalloc.start()
    rates, memory = [], []
    for _ in range(chunks):
        start = time.perf_counter()
        for _ in range(chunk_steps):
            _, _, _, truncated, _ = env.step(0)
            if truncated:
                env.reset()
        rates.append(chunk_steps / (time.perf_counter() - start))
        memory.append(tracemalloc.get_traced_memory()[0])
    tracemalloc.stop()
    print(f"  steps/s per chunk: first {rates[0]:,.0f}, last {rates[-1]:,.0f} (last/first {rates[-1] / rates[0]:.2f})")
    print(f"  traced memory: first {memory[0] / 1e3:,.0f} kB, last {memory[-1] / 1e3:,.0f} kB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer repeats and sizes")
    parser.add_argument("--only", choices=["single", "vector", "scaling", "flat"], help="run one section")
    parser.add_argument("--measure", nargs=3, metavar=("ENV", "NUM_ENVS", "STEPS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        env, num_envs, steps = args.measure
        print(measure(env, int(num_envs), int(steps)))
        return
    repeats = 2 if args.quick else 5
    sizes = [1, 64, 1024, 16384] if args.quick else [1, 16, 256, 1024, 4096, 16384, 65536]
    print(
        f"machine: {platform.processor() or platform.machine()}, {platform.python_implementation()} "
        f"{platform.python_version()}, numpy {np.__version__}, gymnasium {gym.__version__}"
    )
    sections = {
        "single": lambda: section_single(repeats),
        "vector": lambda: section_vector(repeats),
        "scaling": lambda: section_scaling(max(1, repeats // 2), sizes),
        "flat": section_flat,
    }
    for name, run in sections.items():
        if args.only in (None, name):
            run()


if __name__ == "__main__":
    main()
