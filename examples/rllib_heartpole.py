"""HeartPole in RLlib: register the env with Ray Tune's registry, then train PPO on it.

Run it (RLlib is not one of HeartPole's extras: ``pip install "ray[rllib]"``, which pins its own
Gymnasium version; see docs/scale.md)::

    python examples/rllib_heartpole.py --iterations 5

Why the registration: RLlib builds its envs inside its own worker processes (EnvRunners). Those
processes never imported ``heartpole``, so the plain id ``"HeartPole-v0"`` is unknown there and
``gym.make("HeartPole-v0")`` fails with ``NameNotFound``. Gymnasium's ``"module:id"`` form imports the
module first, which registers the ids: ``gym.make("heartpole:HeartPole-v0")`` works in any process that
can import heartpole. The creator below uses that form, and :func:`register` puts it in Ray Tune's
registry under the name RLlib's config refers to (``config.environment("HeartPole-v0")``).

HeartPole's episodes are 1,000 decisions long and end by truncation only (never ``terminated``), so
RLlib bootstraps through the time limit. The return counts each heart attack as -100: see
docs/training.md for why the project's own trainer (Stable-Baselines3, ``heartpole train``) learns from a
variance-reduced reward instead; this example trains on the env's own reward, as an RLlib user would.
"""

from __future__ import annotations

import argparse
from typing import Any

import gymnasium as gym

ENV_NAME = "HeartPole-v0"
"""The name RLlib's config uses for the registered env."""


def env_creator(env_config: dict[str, Any] | None = None) -> gym.Env:
    """A HeartPole env for RLlib; ``env_config`` holds ``gym.make``'s keyword arguments (``max_steps``, ...).

    ``"heartpole:HeartPole-v0"`` imports heartpole in the worker, which registers the id.
    """
    return gym.make("heartpole:HeartPole-v0", **dict(env_config or {}))


def register(name: str = ENV_NAME) -> str:
    """Register :func:`env_creator` with Ray Tune's registry as ``name`` (what RLlib looks up); return it."""
    from ray.tune.registry import register_env

    register_env(name, env_creator)
    return name


def train(iterations: int, seed: int = 0) -> list[float]:
    """Train RLlib's PPO on HeartPole for ``iterations`` iterations; return the mean episode return of each."""
    import ray
    from ray.rllib.algorithms.ppo import PPOConfig

    name = register()
    config = (
        PPOConfig()
        .environment(name, env_config={})
        .env_runners(num_env_runners=1, num_envs_per_env_runner=4)
        .training(gamma=0.95, lr=3e-4, train_batch_size_per_learner=4000, minibatch_size=500, num_epochs=5)
        .debugging(seed=seed)
    )
    ray.init(include_dashboard=False, ignore_reinit_error=True)
    algorithm = config.build_algo()
    returns = []
    try:
        for iteration in range(iterations):
            result = algorithm.train()
            mean = result["env_runners"].get("episode_return_mean", float("nan"))
            returns.append(float(mean))
            print(f"iteration {iteration + 1}: mean episode return {mean:.1f}", flush=True)
    finally:
        algorithm.stop()
        ray.shutdown()
    return returns


def main() -> None:
    """Parse the arguments and train."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--iterations", type=int, default=5, help="PPO training iterations (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    args = parser.parse_args()
    train(args.iterations, args.seed)


if __name__ == "__main__":
    main()
