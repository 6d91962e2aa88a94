"""The true value of a policy, the quantity every off-policy estimate is scored against.

HeartPole's dynamics are known, so a policy's value can be measured almost exactly by running it: with
the expected-risk estimate (each step's heart-attack coin replaced by its probability, see
[`heartpole.evaluation`][heartpole.evaluation]) the 95% intervals are hundreds of times narrower than the realized
returns'. [`true_value`][heartpole.offline.truth.true_value] reports both the value HeartPole reports (the
undiscounted episode return, the final score, heart attacks) and the value OPE estimators usually estimate: the
expected discounted return ``E[sum_t gamma^t r_t]`` from the start state, ``t = 0 .. max_steps - 1``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from heartpole.evaluation import chunk_seed, policy_rng
from heartpole.parameters import check_integer
from heartpole.paths import check_memory
from heartpole.policies import Policy, load_policy, policy_name
from heartpole.reporting import plus_minus
from heartpole.rewards import expected_risk
from heartpole.rollout import ENV_BYTES, base_env, episode_steps, policy_actions, step_risks, vector_env
from heartpole.stats import confidence_interval

DEFAULT_GAMMA = 0.95


@dataclass(frozen=True)
class TrueValue:
    """A policy's value with 95% Student-t intervals over ``episodes`` episodes.

    ``value`` is the expected-risk estimate of the discounted return from the start state, ``value_ci95``
    its interval; ``realized_value`` the same from the realized rewards. ``expected_return`` and
    ``mean_return`` are the undiscounted counterparts (HeartPole's return); ``score`` the final
    ``work_done / time_elapsed``; ``heart_attacks`` per episode.
    """

    policy: str
    env_id: str
    gamma: float
    episodes: int
    seed: int
    value: float
    value_ci95: tuple[float, float]
    realized_value: float
    realized_value_ci95: tuple[float, float]
    expected_return: float
    expected_return_ci95: tuple[float, float]
    mean_return: float
    mean_return_ci95: tuple[float, float]
    score: float
    score_ci95: tuple[float, float]
    heart_attacks: float
    heart_attacks_ci95: tuple[float, float]

    def describe(self) -> str:
        """One line: the discounted value and the undiscounted return, score and heart attacks."""
        return (
            f"{self.policy}: value(gamma={self.gamma:g}) {plus_minus(self.value, self.value_ci95)}, "
            f"return {plus_minus(self.expected_return, self.expected_return_ci95)}, "
            f"score {plus_minus(self.score, self.score_ci95)}, "
            f"heart attacks {plus_minus(self.heart_attacks, self.heart_attacks_ci95)}"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe fields."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


def true_value(
    policy: Policy | str,
    gamma: float = DEFAULT_GAMMA,
    episodes: int = 2000,
    env_id: str = "HeartPole-v0",
    seed: int = 0,
    *,
    env_kwargs: dict[str, Any] | None = None,
) -> TrueValue:
    """Run ``policy`` for ``episodes`` whole episodes and measure its true value (see
    [`TrueValue`][heartpole.offline.truth.TrueValue]).

    Args:
        policy: a policy callable (stochastic ones sample inside their call), a built-in name or a model path.
        gamma: the discount of the discounted value, in (0, 1].
        episodes: how many episodes (>= 2).
        env_id: a HeartPole env id.
        seed: the seed of the env and of the ``random`` policy.
        env_kwargs: the env's keyword arguments.

    Raises:
        ValueError: bad arguments, an unknown env or policy, invalid actions.
    """
    if not 0.0 < float(gamma) <= 1.0:
        raise ValueError(f"gamma must be in (0, 1], got {gamma!r}")
    check_integer("episodes", episodes, 2)
    if isinstance(policy, str):
        rng = policy_rng(seed)
        act, name = load_policy(policy, env_id, env_kwargs=env_kwargs, rng=rng), policy
    else:
        act, name = policy, policy_name(policy)
    runs = _run(act, name, float(gamma), int(episodes), env_id, seed, env_kwargs or {})
    summary = {key: (float(values.mean()), confidence_interval(values)) for key, values in runs.items()}
    return TrueValue(
        policy=name,
        env_id=env_id,
        gamma=float(gamma),
        episodes=int(episodes),
        seed=seed,
        value=summary["value"][0],
        value_ci95=summary["value"][1],
        realized_value=summary["realized_value"][0],
        realized_value_ci95=summary["realized_value"][1],
        expected_return=summary["expected_return"][0],
        expected_return_ci95=summary["expected_return"][1],
        mean_return=summary["mean_return"][0],
        mean_return_ci95=summary["mean_return"][1],
        score=summary["score"][0],
        score_ci95=summary["score"][1],
        heart_attacks=summary["heart_attacks"][0],
        heart_attacks_ci95=summary["heart_attacks"][1],
    )


def _run(
    act: Policy, name: str, gamma: float, episodes: int, env_id: str, seed: int, env_kwargs: dict[str, Any]
) -> dict[str, np.ndarray]:
    """Per-episode discounted and undiscounted sums, realized and expected-risk, in one pass."""
    check_memory(episodes * (ENV_BYTES + 64), f"a truth of {episodes:,} episodes (run side by side)")
    sums = {key: np.zeros(episodes) for key in ("value", "realized_value", "expected_return", "mean_return")}
    attacks = np.zeros(episodes)
    discount = 1.0
    with vector_env(env_id, env_kwargs, episodes) as env:
        penalty = float(base_env(env).dynamics.params.heart_attack_penalty)
        proclivity = None  # each env's, read at the first step: an episode keeps its person
        for step in episode_steps(env, chunk_seed(seed, 0), policy_actions(act, name, env)):
            proclivity = base_env(env).heart_attack_proclivity if proclivity is None else proclivity
            reward, coin = step.rewards, np.asarray(step.info["heart_attack"], dtype=np.float64)
            expected = expected_risk(reward, step_risks(env, step.info, proclivity), penalty, coin)
            sums["value"] += discount * expected
            sums["realized_value"] += discount * reward
            sums["expected_return"] += expected
            sums["mean_return"] += reward
            attacks += coin
            discount *= gamma
    score = np.asarray(step.info["score"], dtype=np.float64)
    return {**sums, "score": score, "heart_attacks": attacks}
