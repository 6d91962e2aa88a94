"""The env against an independent implementation of the tutorial, and against ANCHORS.md, in distribution.

Each comparison runs thousands of episodes on both sides and checks that the difference of the means is
within 4.5 combined standard errors (a false alarm about once in 150,000 comparisons); the seeds are
fixed, so the test is deterministic. The expected-risk return (final score - 100 x the sum of the
steps' heart-attack probabilities) has a tiny variance, so it pins the dynamics down sharply.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

import heartpole
from tests.tutorial_model import TutorialHeartPole

Policy = Callable[[np.ndarray, int], np.ndarray]
TOLERANCE_SE = 4.5
FLOAT32_RELATIVE = 1e-6  # the vector env computes in float32; some metrics have no sampling noise


def always_coffee(obs: np.ndarray, t: int) -> np.ndarray:
    return np.ones(len(obs), dtype=np.int64)


def beer_heavy(obs: np.ndarray, t: int) -> np.ndarray:
    """Chase the Ballmer peak: beer while intoxication is under 0.12, sleep after 40 half-hours awake."""
    return np.where(obs[:, 3] >= 40, 3, np.where(obs[:, 2] < 0.12, 2, 0))


def reference_cycle(obs: np.ndarray, t: int) -> np.ndarray:
    """The published reference: one coffee, 31 steps of work, sleep; repeat (33 steps a cycle)."""
    phase = t % 33
    return np.full(len(obs), 1 if phase == 0 else 3 if phase == 32 else 0)


def random_actions(obs: np.ndarray, t: int) -> np.ndarray:
    return np.random.default_rng([t, len(obs)]).integers(0, 4, len(obs))


def sleep_when_tired(obs: np.ndarray, t: int) -> np.ndarray:
    """Never drink; sleep when alertness falls below 0.35."""
    return np.where(obs[:, 0] < 0.35, 3, 0)


POLICIES = {
    "coffee": always_coffee,
    "beer_heavy": beer_heavy,
    "reference": reference_cycle,
    "random": random_actions,
    "sleep_when_tired": sleep_when_tired,
}


def run_vector_env(policy: Policy, episodes: int, seed: int, max_steps: int = 1000) -> dict[str, np.ndarray]:
    env = heartpole.HeartPoleVectorEnv(episodes, max_steps=max_steps)
    obs, _ = env.reset(seed=seed)
    total, attacks, risk_sum = np.zeros(episodes), np.zeros(episodes), np.zeros(episodes)
    for t in range(max_steps):
        obs, reward, terminated, truncated, info = env.step(policy(obs, t))
        total += reward
        attacks += info["heart_attack"]
        risk_sum += info["heart_attack_risk"]
        assert not terminated.any()
    assert truncated.all()
    return {"return": total, "attacks": attacks, "risk_sum": risk_sum, "score": info["score"].astype(float)}


def run_single_env(policy: Policy, episodes: int, seed: int, max_steps: int) -> dict[str, np.ndarray]:
    env = heartpole.HeartPole(max_steps=max_steps)
    out = {key: np.zeros(episodes) for key in ("return", "attacks", "risk_sum", "score")}
    for e in range(episodes):
        obs, _ = env.reset(seed=seed + e)
        for t in range(max_steps):
            obs, reward, _, truncated, info = env.step(int(policy(obs[None], t)[0]))
            out["return"][e] += reward
            out["attacks"][e] += info["heart_attack"]
            out["risk_sum"][e] += info["heart_attack_risk"]
        assert truncated
        out["score"][e] = info["score"]
    return out


def assert_same_distribution(a: dict[str, np.ndarray], b: dict[str, np.ndarray], label: str) -> None:
    for key in ("return", "attacks", "risk_sum", "score"):
        x, y = a[key], b[key]
        se = np.sqrt(x.var(ddof=1) / len(x) + y.var(ddof=1) / len(y))
        gap = abs(x.mean() - y.mean())
        assert gap <= TOLERANCE_SE * se + FLOAT32_RELATIVE * abs(y.mean()), (
            f"{label}: mean {key} {x.mean():.6g} vs {y.mean():.6g}, gap {gap:.3g} > {TOLERANCE_SE} x SE {se:.3g}"
        )


@pytest.mark.parametrize("name", list(POLICIES))
def test_vector_env_matches_the_tutorial(name: str) -> None:
    policy = POLICIES[name]
    ours = run_vector_env(policy, episodes=2000, seed=11)
    tutorial = TutorialHeartPole(2000, seed=12).run(policy)
    assert_same_distribution(ours, tutorial, f"vector env vs tutorial, policy {name}")


@pytest.mark.parametrize("name", ["coffee", "beer_heavy", "reference", "sleep_when_tired"])
def test_single_env_matches_the_tutorial(name: str) -> None:
    policy = POLICIES[name]
    ours = run_single_env(policy, episodes=400, seed=1000, max_steps=150)
    tutorial = TutorialHeartPole(4000, seed=13, max_steps=150).run(policy)
    assert_same_distribution(ours, tutorial, f"single env vs tutorial, policy {name}")


def test_single_and_vector_envs_agree() -> None:
    single = run_single_env(sleep_when_tired, episodes=400, seed=0, max_steps=150)
    vector = run_vector_env(sleep_when_tired, episodes=4000, seed=1, max_steps=150)
    assert_same_distribution(single, vector, "single vs vector env")


def cups_to_first_attack_vector_env(episodes: int, seed: int) -> np.ndarray:
    env = heartpole.HeartPoleVectorEnv(episodes, max_steps=300)
    env.reset(seed=seed)
    first = np.full(episodes, -1)
    for cup in range(1, 301):
        _, _, _, _, info = env.step(np.ones(episodes, dtype=np.int64))
        first[(first < 0) & info["heart_attack"]] = cup
    return first


def cups_to_first_attack_tutorial(episodes: int, seed: int) -> np.ndarray:
    tutorial = TutorialHeartPole(episodes, seed=seed, max_steps=300)
    first = np.full(episodes, -1)
    for cup in range(1, 301):
        _, attack, _ = tutorial.step(np.ones(episodes, dtype=np.int64))
        first[(first < 0) & attack] = cup
    return first


def test_coffee_every_step_gives_a_heart_attack_like_the_tutorials_28_cups() -> None:
    """The tutorial's first heart attack came after 28 cups: an ordinary outcome here, and the
    distribution of cups to the first attack matches the independent implementation."""
    ours, theirs = cups_to_first_attack_vector_env(4000, seed=3), cups_to_first_attack_tutorial(4000, seed=4)
    assert (ours > 0).all() and (theirs > 0).all(), "coffee every step must bring a heart attack within 300 steps"
    low, high = np.percentile(ours, [2.5, 97.5])
    assert low <= 28 <= high, f"28 cups outside the central 95% [{low}, {high}] of cups to the first attack"
    se = np.sqrt(ours.var(ddof=1) / len(ours) + theirs.var(ddof=1) / len(theirs))
    assert abs(ours.mean() - theirs.mean()) <= TOLERANCE_SE * se


def expected_return(run: dict[str, np.ndarray]) -> np.ndarray:
    return run["score"] - 100 * run["risk_sum"]


def ci_halfwidth(x: np.ndarray) -> float:
    return float(4 * x.std(ddof=1) / np.sqrt(len(x)))


def test_anchor_figures_come_out() -> None:
    """ANCHORS.md: random about -235, reference about -140 (20,000 episodes, 95% CI about +-1.6);
    expected-risk estimates: reference -138.74, never drink and sleep below alertness 0.35 -123.305
    with a final score of 0.326. Tolerance: 4 standard errors plus the anchors' rounding."""
    random_run = run_vector_env(random_actions, episodes=20000, seed=5)
    assert abs(random_run["return"].mean() - (-235)) <= ci_halfwidth(random_run["return"]) + 1.0
    reference_run = run_vector_env(reference_cycle, episodes=20000, seed=6)
    assert abs(reference_run["return"].mean() - (-140)) <= ci_halfwidth(reference_run["return"]) + 1.6
    estimate = expected_return(reference_run)
    assert abs(estimate.mean() - (-138.74)) <= ci_halfwidth(estimate) + 0.005
    tired = run_vector_env(sleep_when_tired, episodes=20000, seed=7)
    estimate = expected_return(tired)
    assert abs(estimate.mean() - (-123.305)) <= ci_halfwidth(estimate) + 0.0005
    assert abs(tired["score"].mean() - 0.326) <= 0.0015
    # The floor: 1000 steps x 0.5 x sigmoid(-6) = 1.236 heart attacks per episode.
    assert abs(tired["risk_sum"].mean() - 1000 * 0.5 / (1 + np.exp(6))) < 1e-3
