"""How much of the v0 vector loop is its random-number generator: what a cheaper one could buy (issue 32).

    python benchmarks/generator_share.py                 # 16,384 envs
    python benchmarks/generator_share.py --envs 65536 --blocks 40

Times three loops over the same envs in one process, in turn, with arrays placed as the vector env places its
own (`heartpole.arrays`), and reports the 10th percentile of each:

* **as defined**: the vector env's own loop (`heartpole.kernel`), with `heartpole.rng`'s generator: three rounds
  of `mix32` a draw, two of them shared by its uniforms;
* **half the hashing**: a generator of one half round shared and one half round a uniform (`mix32` without its
  last multiply and shift): about the cheapest keyed hash whose uniforms still look independent;
* **no generator**: every uniform of a step is the env's counter as a fraction, no hashing at all: the most any
  generator could buy.

Only the first is HeartPole: the others play other episodes, and exist here only to be timed. A cheaper
generator would change every seeded episode on every backend, which issue 32 rules out ("no change of
results"); this measures what that decision is worth.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from numba import njit

from heartpole import kernel
from heartpole.jit import INLINE, JIT, no_alias, wide_vectors
from heartpole.lanes import F32, U32, U64, add32, mul32, shr32, xor32
from heartpole.rng import GOLDEN, MIX_1
from heartpole.vector import HeartPoleVectorEnv


@njit(**JIT, **INLINE)
def _half_mix(x: Any) -> Any:
    x = xor32(x, shr32(x, U32(16)))
    x = mul32(x, U32(MIX_1))
    return xor32(x, shr32(x, U32(15)))


@njit(**JIT, **INLINE)
def _half_hashing(key_low: Any, key_high: Any, counter: Any, zeros: Any) -> Any:
    h = _half_mix(add32(xor32(counter, key_low), mul32(key_high, U32(GOLDEN))))
    u = zeros + (F32(0.0), F32(0.0))
    for j in range(len(u)):
        x = _half_mix(xor32(h, U32(((j + 1) * GOLDEN) & 0xFFFFFFFF)))
        u = kernel.tuple_setitem(u, j, F32(shr32(x, U32(8))) * F32(2.0**-24))
    return u


@njit(**JIT, **INLINE)
def _no_generator(key_low: Any, key_high: Any, counter: Any, zeros: Any) -> Any:
    c = F32(counter & U32(255)) * F32(1.0 / 256.0)
    u = zeros + (F32(0.0), F32(0.0))
    for j in range(len(u)):
        u = kernel.tuple_setitem(u, j, c)
    return u


def _loop_with(draws: Any) -> Any:
    """`kernel._loop` with its uniforms from ``draws`` instead of `heartpole.rng`'s generator."""

    @njit(**JIT)
    def loop(envs: Any, results: Any, rng: Any, packed: Any, cells: Any, spec: Any) -> None:
        wide_vectors()
        no_alias()
        actions, flat = results.actions, packed.reshape(packed.size)
        known = kernel.read(spec, flat)
        for index in range(actions.shape[0]):
            i = U64(index)
            zeros, effects, tables = kernel.numbers(spec, known, flat, cells, actions[i], i)
            state = zeros
            for v in range(len(zeros)):
                state = kernel.tuple_setitem(state, v, envs[U64(v), i])
            uniforms = draws(
                rng[U64(kernel.KEY_LOW), i], rng[U64(kernel.KEY_HIGH), i], rng[U64(kernel.COUNTER), i], zeros
            )
            kernel.store_env(envs, results, rng, i, kernel._step(state, effects, uniforms, tables))

    return loop


LOOPS = {
    "as defined": kernel._loop,
    "half the hashing": _loop_with(_half_hashing),
    "no generator": _loop_with(_no_generator),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--envs", type=int, default=16384, help="envs (default 16384)")
    parser.add_argument("--blocks", type=int, default=30, help="blocks of 25 steps per loop, in turn (default 30)")
    args = parser.parse_args()
    if args.envs < 1 or args.blocks < 1:
        parser.error(f"--envs and --blocks must be positive integers, got {args.envs} and {args.blocks}")
    actions = np.random.default_rng(0).integers(0, 4, args.envs)
    runs = []
    for loop in LOOPS.values():  # an env each: its arrays placed apart in the caches, as the env steps them
        env = HeartPoleVectorEnv(args.envs)
        env.reset(seed=0)
        env.step(actions)
        results = env._results()
        results.actions[:] = actions
        runs.append((loop, (env._envs, results, env._rng, *env._loop_arguments), []))
        loop(*runs[-1][1])  # compiled before timing
    for _ in range(args.blocks):
        for loop, arguments, times in runs:
            for _ in range(25):
                start = time.perf_counter()
                loop(*arguments)
                times.append(time.perf_counter() - start)
    print(f"the v0 loop over {args.envs:,} envs: 10th percentile of {25 * args.blocks} steps each, in this process")
    base = float(np.percentile(runs[0][2], 10))
    for name, (_, _, times) in zip(LOOPS, runs):
        p10 = float(np.percentile(times, 10))
        per_env = p10 / args.envs * 1e9
        print(f"  {name:<17} {p10 * 1e6:6.1f} us  ({per_env:.2f} ns per env, {p10 / base:.2f} of the time as defined)")


if __name__ == "__main__":
    main()
