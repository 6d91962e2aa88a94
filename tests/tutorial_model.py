"""An independent re-implementation of the tutorial's HeartPole, for comparing distributions.

Written straight from the tutorial's facts 0-8, on purpose in a different shape from the package:
a dict of per-episode arrays, one function per fact, sleep as sixteen explicit half-hours followed by
waking up, float64 throughout, and its own random stream. It shares no code with ``heartpole``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

DECAY_RATE = 0.97
KEYS = ("alertness", "hypertension", "intoxication", "time_since_slept", "time_elapsed", "work_done")


def logistic(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        return 1 / (1 + np.exp(-x))


def bell(x: np.ndarray, mu: float, sig: float) -> np.ndarray:
    return np.exp(-np.power(x - mu, 2.0) / (2 * np.power(sig, 2.0)))


class TutorialHeartPole:
    """``n`` parallel episodes of the tutorial's env; ``run(policy)`` plays them to the end."""

    def __init__(self, n: int, seed: int, proclivity: float = 0.5, max_steps: int = 1000) -> None:
        self.n, self.proclivity, self.max_steps = n, proclivity, max_steps
        self.rng = np.random.default_rng(seed)
        self.state = {key: np.zeros(n) for key in KEYS}
        self.wakeup(np.ones(n, dtype=bool))

    # facts -------------------------------------------------------------------------------------------
    def wakeup(self, who: np.ndarray) -> None:
        self.state["alertness"] = np.where(who, self.rng.uniform(0.7, 1.3, self.n), self.state["alertness"])
        self.state["time_since_slept"] = np.where(who, 0.0, self.state["time_since_slept"])

    def drink_coffee(self, who: np.ndarray) -> None:
        self.state["alertness"] += who * self.rng.uniform(0, 1, self.n)
        self.state["hypertension"] += who * self.rng.uniform(0, 0.3, self.n)

    def drink_beer(self, who: np.ndarray) -> None:
        self.state["alertness"] -= who * self.rng.uniform(0, 0.5, self.n)
        self.state["hypertension"] += who * self.rng.uniform(0, 0.3, self.n)
        self.state["intoxication"] += who * self.rng.uniform(0.01, 0.03, self.n)

    def half_hour_passed(self, who: np.ndarray) -> None:
        st = self.state
        st["alertness"] -= who * logistic((st["time_since_slept"] - 40) / 10)
        st["hypertension"] = np.where(who, DECAY_RATE * st["hypertension"], st["hypertension"])
        st["intoxication"] = np.where(who, DECAY_RATE * st["intoxication"], st["intoxication"])
        st["time_since_slept"] += who
        st["time_elapsed"] += who

    def sleep(self, who: np.ndarray) -> None:
        for _ in range(16):
            self.half_hour_passed(who)
        self.wakeup(who)

    def productivity(self) -> np.ndarray:
        a, x = self.state["alertness"], self.state["intoxication"]
        skill = logistic((0.05 - x) * 50) + 2 * bell(x, 0.135, 0.005)
        return a * (1 - logistic(a - 3)) * skill

    def risk(self) -> np.ndarray:
        return self.proclivity * logistic(self.state["hypertension"] - 6)

    # the env's step --------------------------------------------------------------------------------------
    def step(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        st = self.state
        old = np.where(st["time_elapsed"] == 0, 0.0, st["work_done"] / np.maximum(st["time_elapsed"], 1))
        self.drink_coffee(action == 1)
        self.drink_beer(action == 2)
        self.sleep(action == 3)
        st["work_done"] += self.productivity()
        self.half_hour_passed(np.ones(self.n, dtype=bool))
        reward = st["work_done"] / st["time_elapsed"] - old
        risk = self.risk()
        attack = self.rng.uniform(0, 1, self.n) < risk
        st["hypertension"] = np.where(attack, 0.0, st["hypertension"])
        return reward - 100 * attack, attack, risk

    def observation(self) -> np.ndarray:
        return np.stack([self.state[key] for key in KEYS], axis=1)

    def run(self, policy: Callable[[np.ndarray, int], np.ndarray]) -> dict[str, np.ndarray]:
        """Play every episode for ``max_steps``; per-episode return, heart attacks, risk sum, final score."""
        total, attacks, risk_sum = np.zeros(self.n), np.zeros(self.n), np.zeros(self.n)
        for t in range(self.max_steps):
            reward, attack, risk = self.step(policy(self.observation(), t))
            total += reward
            attacks += attack
            risk_sum += risk
        final_score = self.state["work_done"] / self.state["time_elapsed"]
        return {"return": total, "attacks": attacks, "risk_sum": risk_sum, "score": final_score}
