"""HeartPole's ids in Gymnasium's registry."""

from __future__ import annotations

import gymnasium as gym

V0_ID = "HeartPole-v0"


def register_envs() -> None:
    """Register ``HeartPole-v0`` (single env and native vector env) unless it is registered already."""
    if V0_ID not in gym.registry:
        gym.register(
            id=V0_ID,
            entry_point="heartpole.env:HeartPole",
            vector_entry_point="heartpole.vector:HeartPoleVectorEnv",
        )
