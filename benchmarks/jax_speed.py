"""Raw stepping speed of HeartPole's JAX env, beside gymnax's CartPole (when gymnax is installed) and
the NumPy vector envs, measured in one run on this machine's CPU.

    python benchmarks/jax_speed.py                    # 1,024 envs x 1,000 steps, median of 5
    python benchmarks/jax_speed.py --envs 4096 --repeats 3

JAX envs run as their users run them: ``jit(vmap(step))`` over all envs, ``lax.scan`` over the steps,
random actions drawn inside the compiled loop, autoreset on. The NumPy vector envs (HeartPole's native
one and Gymnasium's ``CartPoleVectorEnv``) step with actions drawn before timing. Compile time is
reported apart and not counted. gymnax pins ``gymnasium<1.4``, so it is not part of HeartPole's extras:
install it in a separate virtualenv to get its column (see docs/jax.md).
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np

import heartpole
from heartpole.jax import make


def jax_env_speed(env: Any, params: Any, num_envs: int, steps: int, repeats: int) -> tuple[float, float]:
    """(steps per second, compile seconds) of a gymnax-API env stepped ``num_envs`` wide for ``steps``."""
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

    started = time.perf_counter()
    compiled = jax.jit(run).lower(jax.random.key(0)).compile()
    compile_seconds = time.perf_counter() - started
    times = []
    for repeat in range(repeats):
        started = time.perf_counter()
        compiled(jax.random.key(repeat + 1)).block_until_ready()
        times.append(time.perf_counter() - started)
    return num_envs * steps / statistics.median(times), compile_seconds


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


def main() -> None:
    """Measure and print a Markdown table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, default=1024, help="envs stepped side by side (default 1024)")
    parser.add_argument("--steps", type=int, default=1000, help="steps per run (default 1000)")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs; the median is reported (default 5)")
    args = parser.parse_args()
    n, steps, repeats = args.envs, args.steps, args.repeats
    rows: list[tuple[str, float, float | None]] = []
    env, params = make("HeartPole-v0")
    rows.append(("HeartPole-v0, heartpole.jax (jit, vmap, scan)", *jax_env_speed(env, params, n, steps, repeats)))
    try:
        import gymnax
    except ImportError:
        print("gymnax is not installed here: no gymnax CartPole column")
    else:
        from importlib.metadata import version

        cartpole, cartpole_params = gymnax.make("CartPole-v1")
        rows.append((f"CartPole-v1, gymnax {version('gymnax')} (jit, vmap, scan)",
                     *jax_env_speed(cartpole, cartpole_params, n, steps, repeats)))  # fmt: skip
    with heartpole.policies.quiet_version_warnings():
        native = lambda k: gym.make_vec("HeartPole-v0", num_envs=k, vectorization_mode="vector_entry_point")  # noqa: E731
        rows.append(("HeartPole-v0, NumPy vector env (numba)", numpy_vector_speed(native, n, steps, repeats), None))
    cartpole_np = lambda k: gym.make_vec("CartPole-v1", num_envs=k, vectorization_mode="vector_entry_point")  # noqa: E731
    rows.append(("CartPole-v1, Gymnasium CartPoleVectorEnv", numpy_vector_speed(cartpole_np, n, steps, repeats), None))
    print(f"\n{n} envs x {steps} steps, median of {repeats}; jax {jax.__version__}, "
          f"gymnasium {gym.__version__}, devices {jax.devices()}\n")  # fmt: skip
    print("| env | steps/s | compile (s) |\n|---|---:|---:|")
    for name, speed, compile_seconds in rows:
        compiled = "" if compile_seconds is None else f"{compile_seconds:.1f}"
        print(f"| {name} | {speed / 1e6:.1f} M | {compiled} |")


if __name__ == "__main__":
    main()
