"""HeartPole: a reinforcement-learning environment for healthcare-style decisions, "CartPole for health".

``import heartpole`` registers ``HeartPole-v0`` (and ``HeartPole-v1``) with Gymnasium:

>>> import gymnasium as gym
>>> import heartpole
>>> env = gym.make("HeartPole-v0")
>>> env.action_space
Discrete(4)
>>> obs, info = env.reset(seed=0)
>>> obs.shape, env.observation_space.contains(obs)
((6,), True)
>>> obs, reward, terminated, truncated, info = env.step(1)
>>> info["action_taken"], env.unwrapped.action_names[info["action_taken"]], terminated
(1, 'drink_coffee', False)

Policies are judged over many episodes, with 95% intervals:

>>> result = heartpole.evaluate("expert", episodes=20, seed=0, regret=False)
>>> result.episodes, result.ci95[0] <= result.mean_return <= result.ci95[1]
(20, True)
"""

from heartpole.actions import V0_ACTIONS, Action
from heartpole.dynamics import Dynamics
from heartpole.env import HeartPole, HeartPoleEnv
from heartpole.model import (
    alertness_decay,
    ballmer,
    crippling_anxiety,
    gaussian,
    heart_attack_risk,
    productivity,
    sigmoid,
)
from heartpole.parameters import Params, Variable
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
from heartpole.parameters import V0_VARIABLES  # noqa: E402
from heartpole.registry import register_variant  # noqa: E402
from heartpole.variants import HeartPoleV1, HeartPoleV1VectorEnv  # noqa: E402

__all__ += ["HeartPoleV1", "HeartPoleV1VectorEnv", "V0_VARIABLES", "V1_ACTIONS", "V1_VARIABLES", "register_variant"]

from heartpole.evaluation import Comparison, EvaluationResult, baselines, compare, evaluate  # noqa: E402
from heartpole.policies import BUILTIN_POLICIES, load_policy  # noqa: E402

__all__ += ["BUILTIN_POLICIES", "Comparison", "EvaluationResult", "baselines", "compare", "evaluate", "load_policy"]
