"""HeartPole: a reinforcement-learning environment for healthcare-style decisions, "CartPole for health".

``import heartpole`` registers ``HeartPole-v0`` with Gymnasium::

    import gymnasium as gym
    import heartpole  # noqa: F401

    env = gym.make("HeartPole-v0")
"""

from heartpole.actions import V0_ACTIONS, Action
from heartpole.dynamics import Dynamics
from heartpole.env import HeartPole, HeartPoleEnv
from heartpole.model import (
    Params,
    Variable,
    alertness_decay,
    ballmer,
    crippling_anxiety,
    gaussian,
    heart_attack_risk,
    productivity,
    sigmoid,
)
from heartpole.registry import register_envs
from heartpole.vector import HeartPoleVectorEnv

register_envs()

__version__ = "0.1.0"

__all__ = [
    "Action",
    "Dynamics",
    "HeartPole",
    "HeartPoleEnv",
    "HeartPoleVectorEnv",
    "Params",
    "V0_ACTIONS",
    "Variable",
    "alertness_decay",
    "ballmer",
    "crippling_anxiety",
    "gaussian",
    "heart_attack_risk",
    "productivity",
    "sigmoid",
]
