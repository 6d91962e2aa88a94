"""Raw stepping speed of HeartPole's JAX env against gymnax's CartPole, at several sizes, in one run on whatever
device JAX has (a GPU where JAX finds one, else the CPU).

    python benchmarks/jax_speed.py                                   # 1,024 and 16,384 envs, median of 3
    python benchmarks/jax_speed.py --envs 1024 16384 262144 1048576 4194304 --steps 100   # a GPU's table
    python benchmarks/jax_speed.py --envs 16384 --numpy              # + the NumPy vector envs (CPU)
    python benchmarks/jax_speed.py --fusions                         # + XLA's fused kernels in one step
    python benchmarks/jax_speed.py --fusions --hlo out/hlo           # + each column's compiled step (HLO text)
    XLA_FLAGS=--xla_cpu_multi_thread_eigen=false python benchmarks/jax_speed.py --clock cpu   # a busy CPU

JAX envs run as their users run them: ``jit(vmap(step))`` over all envs, ``lax.scan`` over the steps, random
actions drawn inside the compiled loop, autoreset on. Columns: HeartPole-v0, HeartPole-v0 with
``people="default"``, and gymnax's CartPole-v1 when gymnax is installed, with the ratio HeartPole / CartPole
measured in the same process. Compile time is not counted. gymnax pins ``gymnasium<1.4``, so it is not part of
HeartPole's extras: ``bash scripts/test_gymnax.sh --setup-only`` builds ``.venv-gymnax``, where this script runs
with gymnax (see docs/jax.md). ``--numpy`` adds HeartPole's native vector env (numba) and Gymnasium's
``CartPoleVectorEnv``, stepped with actions drawn before timing.
"""

from __future__ import annotations

import argparse
import re
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np

import heartpole
from heartpole.jax import make


def stepper(env: Any, params: Any, num_envs: int, steps: int) -> Callable[[jax.Array], jax.Array]:
    """``run(key)``: reset ``num_envs`` envs and step them ``steps`` times with random actions (autoreset on)."""
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def run(key: jax.Array) -> jax.Array:
        _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, num_envs), params)

        def body(carry: Any, key: jax.Array) -> tuple[Any, None]:
            state, total = carry
            action_key, step_key = jax.random.split(key)
            actions = jax.random.randint(action_key, (num_envs,), 0, env.num_actions)
            out = step(jax.random.split(step_key, num_envs), state, actions, params)
            return (out[1], total + out[2].sum()), None

        (_, total), _ = jax.lax.scan(body, (state, jnp.float32(0.0)), jax.random.split(key, steps))
        return total

    return run


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
"""What a run is timed by: wall time (a device's figures), or the process's CPU time, all its threads (a
shared CPU's: a run's waits for a core do not count; run XLA on one thread then, as the module docstring shows)."""


def jax_env_speed(env: Any, params: Any, num_envs: int, steps: int, repeats: int, clock: str = "wall") -> float:
    """Steps per second of a gymnax-API env stepped ``num_envs`` wide for ``steps`` (median of ``repeats``), by
    ``clock`` (`CLOCKS`)."""
    now = CLOCKS[clock]
    compiled = jax.jit(stepper(env, params, num_envs, steps)).lower(jax.random.key(0)).compile()
    compiled(jax.random.key(0)).block_until_ready()  # the first call may load or allocate
    times = []
    for repeat in range(repeats):
        started = now()
        compiled(jax.random.key(repeat + 1)).block_until_ready()
        times.append(now() - started)
    return num_envs * steps / statistics.median(times)


def fusions(env: Any, params: Any, num_envs: int, hlo: Path | None = None) -> int:
    """How many fused kernels XLA makes of one vmapped step (the body of the loop a training or rollout runs);
    with ``hlo``, the compiled step's HLO text is written there too."""
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))
    _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(0), num_envs), params)
    keys = jax.random.split(jax.random.key(1), num_envs)
    actions = jnp.zeros(num_envs, jnp.int32)
    text = jax.jit(step).lower(keys, state, actions, params).compile().as_text()
    if hlo is not None:
        hlo.write_text(text)
    entry = text[text.index("ENTRY") :]
    return len(re.findall(r"= \S+ fusion\(", entry))


def numpy_vector_speed(make_envs: Any, num_envs: int, steps: int, repeats: int) -> float:
    """Steps per second of a NumPy vector env, random actions drawn before timing."""
    envs = make_envs(num_envs)
    actions = np.random.default_rng(0).integers(0, envs.single_action_space.n, size=(steps, num_envs))
    times = []
    for repeat in range(repeats):
        envs.reset(seed=repeat)
        started = time.perf_counter()
        for t in range(steps):
            envs.step(actions[t])
        times.append(time.perf_counter() - started)
    envs.close()
    return num_envs * steps / statistics.median(times)


def envs_to_measure() -> list[tuple[str, Any, Any]]:
    """(column, env, params): HeartPole-v0, with the default people, and gymnax's CartPole-v1 if installed."""
    columns = [("HeartPole-v0", *make("HeartPole-v0")), ('people="default"', *make("HeartPole-v0", people="default"))]
    try:
        import gymnax
    except ImportError:
        print("gymnax is not installed here: no CartPole-v1 column (see docs/jax.md)")
    else:
        from importlib.metadata import version

        columns.append((f"CartPole-v1 (gymnax {version('gymnax')})", *gymnax.make("CartPole-v1")))
    return columns


def main() -> None:
    """Measure and print one Markdown table: a row per size."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, nargs="+", default=[1024, 16384], help="sizes (default 1024 16384)")
    parser.add_argument("--steps", type=int, default=1000, help="steps per timed run (default 1000)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs; the median is reported (default 3)")
    parser.add_argument("--numpy", action="store_true", help="add the NumPy vector envs (CPU) at every size")
    parser.add_argument("--fusions", action="store_true", help="print XLA's fused kernels in one vmapped step")
    parser.add_argument("--hlo", type=Path, default=None, help="with --fusions: write each step's HLO into this folder")
    parser.add_argument("--clock", choices=CLOCKS, default="wall", help="wall (default) or cpu time of the process")
    args = parser.parse_args()
    if min(args.envs) < 1 or args.steps < 1 or args.repeats < 1:
        parser.error("--envs, --steps and --repeats must be positive")
    columns = envs_to_measure()
    if args.fusions:
        if args.hlo is not None:
            args.hlo.mkdir(parents=True, exist_ok=True)
        for number, (name, env, params) in enumerate(columns):
            hlo = None if args.hlo is None else args.hlo / f"step{number}.hlo.txt"
            print(f"{name}: {fusions(env, params, args.envs[0], hlo)} fused kernels in one vmapped step")
    header = ["envs", *(name for name, _, _ in columns)]
    if len(columns) == 3:
        header += ["HeartPole / CartPole", "people / v0"]
    if args.numpy:
        header += ["HeartPole-v0 NumPy (numba)", "CartPoleVectorEnv"]
    print(f"\n{args.steps} steps a run, median of {args.repeats} ({args.clock} time); jax {jax.__version__}, "
          f"devices {jax.devices()}\n")  # fmt: skip
    print("| " + " | ".join(header) + " |\n|" + "---:|" * len(header))
    for n in args.envs:
        speeds = [jax_env_speed(env, params, n, args.steps, args.repeats, args.clock) for _, env, params in columns]
        cells = [f"{n:,}", *(f"{s / 1e6:,.1f} M" for s in speeds)]
        if len(columns) == 3:
            cells += [f"{speeds[0] / speeds[2]:.2f}", f"{speeds[1] / speeds[0]:.2f}"]
        if args.numpy:
            with heartpole.policies.quiet_version_warnings():
                native = lambda k: gym.make_vec("HeartPole-v0", num_envs=k, vectorization_mode="vector_entry_point")  # noqa: E731
                cells.append(f"{numpy_vector_speed(native, n, args.steps, args.repeats) / 1e6:,.1f} M")
            cartpole = lambda k: gym.make_vec("CartPole-v1", num_envs=k, vectorization_mode="vector_entry_point")  # noqa: E731
            cells.append(f"{numpy_vector_speed(cartpole, n, args.steps, args.repeats) / 1e6:,.1f} M")
        print("| " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
