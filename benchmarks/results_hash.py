"""One hash of what the envs return: 1,500 steps of v0 and v1 (vector and single), a people vector env and a single
env of one person, under seeded random actions.

Two trees whose engines agree bit for bit print the same hash; run it in each (`PYTHONPATH=/path/to/tree/src`):

    python benchmarks/results_hash.py           # one line per env and the hash of them all

It uses the public API only (``gym.make``, ``gym.make_vec``, ``HeartPoleVectorEnv``), so it runs on any commit.
"""

from __future__ import annotations

import argparse
import hashlib
from typing import Any

import gymnasium as gym
import numpy as np

import heartpole

STEPS = 1500
"""Steps of each env hashed."""


def _digest(pieces: list[Any]) -> str:
    """The SHA-256 of ``pieces``' bytes (arrays as NumPy holds them, the rest as ``repr``)."""
    digest = hashlib.sha256()
    for piece in pieces:
        digest.update(np.ascontiguousarray(piece).tobytes() if isinstance(piece, np.ndarray) else repr(piece).encode())
    return digest.hexdigest()


def vector_run(env: Any, steps: int, seed: int) -> str:
    """The hash of ``steps`` steps of the vector ``env`` under seeded random actions: observations, rewards,
    terminations, truncations and every ``info`` array, in order."""
    rng = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    pieces: list[Any] = [obs, *(info[k] for k in sorted(info) if isinstance(info[k], np.ndarray))]
    for _ in range(steps):
        out = env.step(rng.integers(0, env.single_action_space.n, env.num_envs))
        obs, reward, terminated, truncated, info = out
        pieces += [obs, reward, terminated, truncated]
        pieces += [info[k] for k in sorted(info) if isinstance(info[k], np.ndarray) and info[k].dtype != object]
    return _digest(pieces)


def single_run(env: Any, steps: int, seed: int) -> str:
    """The hash of ``steps`` steps of the single ``env`` (reset at each episode's end) under seeded random actions."""
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    pieces: list[Any] = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(int(rng.integers(0, env.action_space.n)))
        pieces += [obs, float(reward), terminated, truncated, sorted((k, repr(v)) for k, v in info.items())]
        if terminated or truncated:
            obs, _ = env.reset()
            pieces.append(obs)
    return _digest(pieces)


def runs(steps: int) -> dict[str, str]:
    """Each env's hash, by name."""
    vector = lambda env_id, n: gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point")  # noqa: E731
    return {
        "v0 vector (64 envs)": vector_run(vector("HeartPole-v0", 64), steps, 1),
        "v1 vector (64 envs)": vector_run(vector("HeartPole-v1", 64), steps, 2),
        "people vector (64 envs)": vector_run(heartpole.HeartPoleVectorEnv(64, people="default"), steps, 3),
        "v0 single": single_run(gym.make("HeartPole-v0"), steps, 4),
        "v1 single": single_run(gym.make("HeartPole-v1"), steps, 5),
        "people single": single_run(heartpole.HeartPole(people="default"), steps, 6),
    }


def main() -> None:
    """Print each env's hash and the hash of them all."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=STEPS, help="steps of each env (default 1,500)")
    args = parser.parse_args()
    if args.steps < 1:
        parser.error(f"--steps must be at least 1, got {args.steps}")
    hashes = runs(args.steps)
    for name, value in hashes.items():
        print(f"{name}: {value[:16]}")
    print(f"all: {_digest(list(hashes.items()))}")


if __name__ == "__main__":
    main()
