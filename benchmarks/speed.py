"""HeartPole's speed against Gymnasium's CartPole, measured side by side in one run.

    python benchmarks/speed.py                  # every section, about ten minutes on a 2-core machine
    python benchmarks/speed.py --quick          # fewer repeats
    python benchmarks/speed.py --only vector    # one section: single, vector, people, blas, anatomy, flat, compile
    python benchmarks/speed.py --busy           # the same with a second CPU-bound process running
    python benchmarks/speed.py --against REV    # this tree against commit REV, side by side (benchmarks/against.py)

Every figure is a ratio against its anchor measured in the same run: HeartPole and CartPole are measured
in turn, ``--repeats`` times, each time in a fresh Python process (the allocator's state left by one env
changes the other's speed), and the ratio of each pair is reported as the median and the range over the
pairs. Env steps run under random actions drawn before timing. The goals are issue 13's.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial
from typing import Any

import against  # benchmarks/against.py, beside this file
import gymnasium as gym
import numpy as np
from gymnasium.envs.classic_control.cartpole import CartPoleEnv, CartPoleVectorEnv

import heartpole

Factory = Callable[[], Any]

SINGLE_ENVS: dict[str, Factory] = {
    "CartPole-v1": CartPoleEnv,
    "HeartPole-v0": heartpole.HeartPole,
    "make:CartPole-v1": lambda: gym.make("CartPole-v1"),
    "make:HeartPole-v0": lambda: gym.make("HeartPole-v0"),
}
VECTOR_ENVS: dict[str, Callable[[int], Any]] = {
    "CartPoleVectorEnv": lambda n: CartPoleVectorEnv(num_envs=n),
    "HeartPoleVectorEnv": lambda n: heartpole.HeartPoleVectorEnv(n),
    "HeartPoleVectorEnv:people=default": lambda n: heartpole.HeartPoleVectorEnv(n, people="default"),
    "HeartPole-v1": lambda n: gym.make_vec("HeartPole-v1", num_envs=n, vectorization_mode="vector_entry_point"),
}
VECTOR_GOALS = {256: 2.0, 1024: 3.0, 16384: 5.0, 65536: 3.0}
V1_SIZE = 16384
SINGLE_GOALS = {"HeartPole-v0": 3.0, "make:HeartPole-v0": 2.5}


def warm_up(env: str) -> bool:
    """Make ``env`` (a name of `SINGLE_ENVS` or `VECTOR_ENVS`), reset and step it, so that its compiled loops are
    loaded or compiled into the cache; ``False`` if this heartpole does not have it (an older commit refuses an
    unknown keyword with ``TypeError`` or ``ValueError``)."""
    try:
        made = SINGLE_ENVS[env]() if env in SINGLE_ENVS else VECTOR_ENVS[env](4)
    except (TypeError, ValueError):
        return False
    made.reset(seed=0)
    space = made.action_space if env in SINGLE_ENVS else made.single_action_space
    for action in range(space.n):
        made.step(action if env in SINGLE_ENVS else np.full(4, action))
    return True


def machine_line() -> str:
    """The machine, Python and the packages measured, in one line."""
    return (
        f"machine: {platform.machine()}, {os.cpu_count()} CPUs, {platform.python_implementation()} "
        f"{platform.python_version()}, numpy {np.__version__}, gymnasium {gym.__version__}, "
        f"heartpole {heartpole.__version__}"
    )


CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}
"""The clocks a rate can be timed with: wall time, or this process's CPU time (on a shared machine, the time
the process ran, not the time it waited for a core)."""


def single_rate(make: Factory, steps: int, seed: int = 0, clock: str = "wall") -> float:
    """Steps per second of one env under random actions (reset when an episode ends), timed with ``clock``."""
    now = CLOCKS[clock]
    env = make()
    env.reset(seed=seed)
    actions = np.random.default_rng(seed).integers(0, env.action_space.n, size=steps).tolist()
    step, reset = env.step, env.reset
    for action in actions[:1000]:  # warm-up
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            reset()
    gc.disable()
    start = now()
    for action in actions:
        _, _, terminated, truncated, _ = step(action)
        if terminated or truncated:
            reset()
    elapsed = now() - start
    gc.enable()
    return steps / elapsed


def vector_rate(make: Factory, num_envs: int, steps: int, seed: int = 0, clock: str = "wall") -> float:
    """Env-steps per second of a native vector env under random actions (it autoresets itself), timed with
    ``clock``."""
    now = CLOCKS[clock]
    env = make()
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    actions = [rng.integers(0, env.single_action_space.n, size=num_envs) for _ in range(min(steps, 64))]
    for t in range(3):  # warm-up
        env.step(actions[t % len(actions)])
    start = now()
    for t in range(steps):
        env.step(actions[t % len(actions)])
    return steps * num_envs / (now() - start)


def measure(env: str, num_envs: int, steps: int, faults: bool = False, clock: str = "wall") -> float:
    """One measurement in this process: a single env when ``num_envs`` is 0, else a vector env (its page
    faults a step with ``faults``), timed with ``clock``."""
    if faults:
        return page_faults(VECTOR_ENVS[env](num_envs), steps)
    if num_envs == 0:
        return single_rate(SINGLE_ENVS[env], steps, clock=clock)
    return vector_rate(lambda: VECTOR_ENVS[env](num_envs), num_envs, steps, clock=clock)


def fresh(
    env: str, num_envs: int, steps: int, environment: dict[str, str] | None = None, faults: bool = False
) -> float:
    """:func:`measure` in a fresh Python process (with ``environment`` instead of this one's, if given)."""
    command = [sys.executable, __file__, "--measure", env, str(num_envs), str(steps)] + (["--faults"] * faults)
    return float(subprocess.run(command, check=True, capture_output=True, text=True, env=environment).stdout)


def paired_ratios(repeats: int, subject: Callable[[], float], anchor: Callable[[], float]) -> list[float]:
    """``subject / anchor`` for ``repeats`` pairs measured in turn."""
    return [subject() / anchor() for _ in range(repeats)]


def report(name: str, ratios: list[float], anchor: str, goal: float | None = None) -> None:
    median = statistics.median(ratios)
    verdict = "" if goal is None else f"  goal >= {goal:.1f}x: {'met' if median >= goal else 'NOT met'}"
    print(f"  {name:<36} {median:5.2f}x {anchor} (range {min(ratios):.2f}-{max(ratios):.2f}){verdict}", flush=True)


def section_single(repeats: int) -> None:
    print(f"single env, random actions: ratio of steps/s, median (range) of {repeats} pairs")
    steps = 100_000
    unwrapped = paired_ratios(repeats, lambda: fresh("HeartPole-v0", 0, steps), lambda: fresh("CartPole-v1", 0, steps))
    report("HeartPole-v0 unwrapped", unwrapped, "CartPole-v1 unwrapped", SINGLE_GOALS["HeartPole-v0"])
    made = paired_ratios(
        repeats, lambda: fresh("make:HeartPole-v0", 0, steps), lambda: fresh("make:CartPole-v1", 0, steps)
    )
    report("HeartPole-v0 via gym.make", made, "CartPole-v1 via gym.make", SINGLE_GOALS["make:HeartPole-v0"])


def section_vector(repeats: int, sizes: list[int]) -> None:
    print(f"vector env, random actions: ratio of env-steps/s, median (range) of {repeats} pairs")
    for n in sizes:
        steps = max(30, min(3000, 6_000_000 // n))
        ratios = paired_ratios(
            repeats, partial(fresh, "HeartPoleVectorEnv", n, steps), partial(fresh, "CartPoleVectorEnv", n, steps)
        )
        report(f"HeartPoleVectorEnv n={n}", ratios, f"CartPoleVectorEnv n={n}", VECTOR_GOALS.get(n))
    n = V1_SIZE  # v1's eight actions take another path (gathers, not masks): reported, no goal
    steps = max(30, min(3000, 6_000_000 // n))
    ratios = paired_ratios(
        repeats, partial(fresh, "HeartPole-v1", n, steps), partial(fresh, "CartPoleVectorEnv", n, steps)
    )
    report(f"HeartPole-v1 vector env n={n}", ratios, f"CartPoleVectorEnv n={n}")


PEOPLE_SIZE, PEOPLE_GOAL = 16384, 0.8
"""Issue 26: with ``people="default"`` the vector env keeps at least 0.8x v0's own speed at 16,384 envs."""


def section_people(repeats: int, n: int = PEOPLE_SIZE) -> None:
    print(f"vector env with people, random actions: ratio of env-steps/s, median (range) of {repeats} pairs")
    steps = max(30, min(3000, 6_000_000 // n))
    ratios = paired_ratios(
        repeats,
        partial(fresh, "HeartPoleVectorEnv:people=default", n, steps),
        partial(fresh, "HeartPoleVectorEnv", n, steps),
    )
    report(f"people='default' n={n}", ratios, f"HeartPoleVectorEnv n={n}", PEOPLE_GOAL)


def section_blas(repeats: int, n: int = 16384) -> None:
    print("vector env with OpenBLAS limited to one thread and with its default threads (no BLAS in the step)")
    steps = max(30, 6_000_000 // n)
    for threads in ("1", None):
        environment = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
        if threads:
            environment["OPENBLAS_NUM_THREADS"] = threads
        ratios = paired_ratios(
            repeats,
            partial(fresh, "HeartPoleVectorEnv", n, steps, environment),
            partial(fresh, "CartPoleVectorEnv", n, steps, environment),
        )
        label = f"OPENBLAS_NUM_THREADS={threads}" if threads else "OpenBLAS default threads"
        report(f"n={n}, {label}", ratios, "CartPoleVectorEnv")


def children_cpu_seconds() -> float:
    """CPU time (user and system) of this process's finished child processes so far: on a shared machine,
    a compile's wall time measures the other jobs too, its CPU time only the compile."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


COMPILE_SCRIPT = (
    "import sys, time, heartpole, numpy as np; people = (sys.argv[1:] or [None])[0]; start = time.process_time(); "
    "e = heartpole.HeartPole(people=people); e.reset(seed=0); e.step(0); "
    "v = heartpole.HeartPoleVectorEnv(4, people=people); v.reset(seed=0); v.step(np.zeros(4, dtype=int)); "
    "print(time.process_time() - start)"
)
"""The first reset and step of a single and a vector env, in a fresh process: their loops compiled or loaded."""


def section_compile() -> None:
    print("compile time of the loops (single and vector env, v0 and with people), in a fresh process")
    for name, arguments in (("v0", []), ("people='default'", ["default"])):
        cache = tempfile.mkdtemp(prefix="heartpole-numba-")
        try:
            for label in ("first use (empty cache)", "cached"):
                start, cpu = time.perf_counter(), children_cpu_seconds()
                environment = {**os.environ, "NUMBA_CACHE_DIR": cache}
                command = [sys.executable, "-c", COMPILE_SCRIPT, *arguments]
                done = subprocess.run(command, check=True, env=environment, capture_output=True)
                wall, cpu = time.perf_counter() - start, children_cpu_seconds() - cpu
                print(
                    f"  {name:<16} {label:<25} {wall:5.1f} s wall, {cpu:5.1f} s CPU with process start and "
                    f"imports; {float(done.stdout):4.1f} s CPU after the imports"
                )
        finally:
            shutil.rmtree(cache, ignore_errors=True)


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


def best_time(call: Callable[[], Any], repeats: int = 300) -> float:
    """The 10th percentile of ``repeats`` timings of ``call``, in microseconds (near the best, not the
    one lucky run)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return sorted(times)[len(times) // 10] * 1e6


def section_anatomy(n: int = 16384) -> None:
    print(f"where a vector env step goes at {n} envs: 10th percentile of 300 timings, in this process")
    cartpole = CartPoleVectorEnv(num_envs=n)
    cartpole.reset(seed=0)
    pushes = np.random.default_rng(0).integers(0, 2, size=n)
    anchor = best_time(lambda: cartpole.step(pushes))
    print(f"  CartPoleVectorEnv.step  {anchor:5.0f} us")
    for env_id in ("HeartPole-v0", "HeartPole-v1"):
        anatomy(env_id, n, anchor)
    print("page faults a step (minor faults over 500 steps in a fresh process, each step's results kept until")
    print("the next returns; they depend on the allocator's history, so on what else the process did)")
    for size in (16384, 65536):
        faults = {name: fresh(name, size, 500, faults=True) for name in ("HeartPoleVectorEnv", "CartPoleVectorEnv")}
        print("  " + "   ".join(f"{name} n={size}: {count:.1f}" for name, count in faults.items()))


def page_faults(env: Any, steps: int) -> float:
    """Minor page faults per step of the vector env ``env`` under random actions."""
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = [rng.integers(0, env.single_action_space.n, size=env.num_envs) for _ in range(8)]
    results = None
    for t in range(20):
        results = env.step(actions[t % 8])
    start = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for t in range(steps):
        results = env.step(actions[t % 8])
    del results
    return (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - start) / steps


def anatomy(env_id: str, n: int, anchor: float) -> None:
    """One line of :func:`section_anatomy`: ``env_id``'s step at ``n`` envs and its parts."""
    from heartpole import kernel
    from heartpole.arrays import new_results

    env = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point").unwrapped
    env.reset(seed=0)
    env.max_steps = 10**9  # no restart while timing
    dynamics = env.dynamics
    actions = np.random.default_rng(0).integers(0, len(dynamics.actions), size=n)
    whole = best_time(lambda: env.step(actions))

    results = new_results(n, len(env._envs))

    def loop() -> None:  # the actions' check, the step and the observations, as one call
        kernel.step_envs(env._envs, results, actions, env._rng, *env._loop_arguments)

    compiled = best_time(loop)
    print(
        f"  {env_id} step     {whole:5.0f} us ({anchor / whole:.2f}x CartPole's): compiled loop {compiled:.0f} us "
        f"({compiled / whole:.0%}; {compiled * 1e3 / n:.1f} ns per env; it checks the actions and writes the "
        f"observations too), the rest (small arrays, info, Python) {whole - compiled:.0f} us"
    )


BUSY_LOOP = "while True: sum(i * i for i in range(10_000))"


@contextmanager
def busy(enabled: bool) -> Iterator[None]:
    """With ``enabled``, a second CPU-bound process runs until the block ends."""
    process = subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) if enabled else None
    try:
        yield
    finally:
        if process is not None:
            process.terminate()
            process.wait()


def child(arguments: list[str]) -> None:
    """What ``against.py`` runs in each tree's fresh process (``speed.py --child ...``), answering one JSON line:
    ``--machine``, ``--warm-up NAME...`` or ``--pair SUBJECT ANCHOR NUM_ENVS STEPS CLOCK`` (the anchor, the
    subject, the anchor again)."""
    if arguments[:1] == ["--machine"]:
        print(json.dumps({"machine": machine_line()}))
    elif arguments[:1] == ["--warm-up"]:
        start = time.perf_counter()
        available = [name for name in arguments[1:] if warm_up(name)]
        print(json.dumps({"available": available, "file": heartpole.__file__, "seconds": time.perf_counter() - start}))
    elif arguments[:1] == ["--pair"] and len(arguments) == 6:
        subject, anchor, num_envs, steps, clock = (
            arguments[1],
            arguments[2],
            int(arguments[3]),
            int(arguments[4]),
            arguments[5],
        )
        first = measure(anchor, num_envs, steps, clock=clock)
        rate = measure(subject, num_envs, steps, clock=clock)
        last = measure(anchor, num_envs, steps, clock=clock)
        print(json.dumps({"subject": rate, "anchors": [first, last]}))
    else:
        raise SystemExit(f"unknown child arguments {arguments!r}")


def main() -> None:
    if sys.argv[1:2] == ["--child"]:
        child(sys.argv[2:])
        return
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="3 pairs per figure instead of 7")
    parser.add_argument("--repeats", type=int, help="pairs per figure")
    parser.add_argument("--busy", action="store_true", help="run a second CPU-bound process meanwhile")
    parser.add_argument(
        "--only", choices=["single", "vector", "people", "blas", "anatomy", "flat", "compile"], help="one section"
    )
    parser.add_argument("--measure", nargs=3, metavar=("ENV", "NUM_ENVS", "STEPS"), help=argparse.SUPPRESS)
    parser.add_argument("--faults", action="store_true", help=argparse.SUPPRESS)
    against.add_arguments(parser)  # --against REV and its options; --sizes serves the sections too
    args = parser.parse_args()
    if args.measure:
        env, num_envs, steps = args.measure
        print(measure(env, int(num_envs), int(steps), args.faults))
        return
    try:
        config = against.from_arguments(args)
    except ValueError as error:
        parser.error(str(error))
    if config.against is not None:
        against.compare(config)
        return
    repeats = args.repeats or (3 if args.quick else 7)
    print(machine_line() + (", with a second CPU-bound process" if args.busy else ""))
    sections = {
        "single": lambda: section_single(repeats),
        "vector": lambda: section_vector(repeats, args.sizes),
        "people": lambda: section_people(repeats),
        "blas": lambda: section_blas(max(3, repeats // 2)),
        "anatomy": section_anatomy,
        "compile": section_compile,
        "flat": section_flat,
    }
    with busy(args.busy):
        for name, run in sections.items():
            if args.only in (None, name):
                run()


if __name__ == "__main__":
    main()
