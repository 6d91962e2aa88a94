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

__version__ = "0.3.0"

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

from heartpole.actions import V1_ACTIONS, V1_VARIABLES  # noqa: E402
from heartpole.model import V0_VARIABLES  # noqa: E402
from heartpole.registry import register_variant  # noqa: E402
from heartpole.variants import HeartPoleV1, HeartPoleV1VectorEnv  # noqa: E402

__all__ += ["HeartPoleV1", "HeartPoleV1VectorEnv", "V0_VARIABLES", "V1_ACTIONS", "V1_VARIABLES", "register_variant"]

from heartpole.evaluation import Comparison, EvaluationResult, baselines, compare, evaluate  # noqa: E402
from heartpole.policies import BUILTIN_POLICIES, load_policy  # noqa: E402

__all__ += ["BUILTIN_POLICIES", "Comparison", "EvaluationResult", "baselines", "compare", "evaluate", "load_policy"]
