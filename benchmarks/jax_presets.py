"""How many env steps the JAX trainer's PPO needs to meet the solved bar, per seed, for given settings.

    python benchmarks/jax_presets.py                                   # the jax preset, seeds 0-9
    python benchmarks/jax_presets.py --set batch_size=512 --checkpoints 150000,200000,250000,300000,400000
    python benchmarks/jax_presets.py --set n_epochs=5 learning_rate=6e-4 --first-seed 10

Trains ``--seeds`` seeds side by side (one compiled, vmapped call, as ``heartpole train --backend jax``)
with the jax preset's settings (:data:`heartpole.training.JAX_PPO_HYPERPARAMETERS`) changed by ``--set
NAME=VALUE`` (fields of :class:`heartpole.jax.ppo.PPOSettings`), and at each checkpoint evaluates every
seed's greedy policy with the standard protocol (:func:`heartpole.evaluation.evaluate`: 2,000 episodes,
seed 0, the regret against the optimum). With a constant learning rate a checkpoint is the end of a
shorter run; with ``anneal_learning_rate=True`` give the run's length as ``timesteps`` and one checkpoint.
Prints, per checkpoint, how many seeds meet the bar (regret's 95% upper bound <= 0.01) and every seed's
upper bound.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import math
import time
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from heartpole import training
from heartpole.evaluation import evaluate
from heartpole.jax.env import HeartPoleJax
from heartpole.jax.ppo import PPOSettings, Runner, make_parts
from heartpole.solved import SOLVED_REGRET


def greedy_policy(runner: Runner) -> Any:
    """One seed's trained actor as a NumPy policy: VecNormalize's formula, the MLP, the argmax."""
    mean = np.asarray(runner.obs_stats.mean, np.float64)
    scale = np.sqrt(np.asarray(runner.obs_stats.var, np.float64) + 1e-8)
    layers = [(np.asarray(w), np.asarray(b)) for w, b in runner.network["actor"]]

    def act(obs: np.ndarray) -> np.ndarray:
        x = np.clip((obs - mean) / scale, -10, 10).astype(np.float32)
        for weight, bias in layers[:-1]:
            x = np.tanh(x @ weight + bias)
        weight, bias = layers[-1]
        return np.argmax(x @ weight + bias, axis=1)

    return act


def main() -> None:
    """Train, evaluate at each checkpoint, print."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10, help="how many seeds (default 10)")
    parser.add_argument("--first-seed", type=int, default=0, help="the first seed (default 0)")
    parser.add_argument("--checkpoints", default="150000,200000,250000", help="env steps to evaluate at")
    parser.add_argument("--episodes", type=int, default=2000, help="evaluation episodes (default 2000)")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE", help="change a PPOSettings field")
    args = parser.parse_args()
    settings = PPOSettings.from_config(training.preset_config("default", backend="jax"))
    changes = {}
    for item in args.set:
        name, _, value = item.partition("=")
        changes[name] = type(getattr(settings, name))(ast.literal_eval(value))
    settings = dataclasses.replace(settings, **changes)
    env = HeartPoleJax.from_id("HeartPole-v0")
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    keys = jax.vmap(jax.random.key)(jnp.asarray(seeds, dtype=jnp.uint32))
    start, _ = make_parts(env, env.default_params, settings, 1)
    runners = jax.jit(jax.vmap(start))(keys)
    print(f"settings: {dataclasses.asdict(settings)}; seeds {seeds[0]}-{seeds[-1]}")
    done, seconds = 0, 0.0
    for checkpoint in (int(c) for c in args.checkpoints.split(",")):
        updates = math.ceil(checkpoint / settings.rollout)
        if updates > done:
            _, run = make_parts(env, env.default_params, settings, updates - done)
            started = time.perf_counter()
            runners, _ = jax.block_until_ready(jax.jit(jax.vmap(run))(runners))
            seconds += time.perf_counter() - started
            done = updates
        uppers = []
        for i in range(len(seeds)):
            runner = jax.tree_util.tree_map(lambda x, i=i: x[i], runners)
            result = evaluate(greedy_policy(runner), "HeartPole-v0", episodes=args.episodes, seed=0)
            uppers.append(result.regret_ci95[1])
        solved = sum(upper <= SOLVED_REGRET for upper in uppers)
        print(f"{done * settings.rollout:,} steps: {solved} of {len(seeds)} seeds solved; regret upper bounds "
              + " ".join(f"{upper:.4f}" for upper in uppers) + f" ({seconds:.0f} s of training, compile included)",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
