"""What an evaluation returns, whichever engine played its episodes.

[`EvaluationResult`][heartpole.results.EvaluationResult] is a policy's summary with 95% intervals and per-episode
values; [`Comparison`][heartpole.results.Comparison] pairs two results episode by episode;
[`Episodes`][heartpole.results.Episodes] are the per-episode values summarised.
[`heartpole.evaluate`][heartpole.evaluation.evaluate] (the NumPy vector env) and
[`heartpole.jax.evaluate`][heartpole.jax.evaluation.evaluate] (the JAX device) both return these, with the same JSON.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from heartpole.solved import regret_solved
from heartpole.stats import confidence_interval, json_interval, json_number

SUMMARIES = (
    ("mean_return", "ci95", "returns"),
    ("expected_return", "expected_ci95", "expected_returns"),
    ("heart_attacks_per_episode", "heart_attacks_ci95", "heart_attacks"),
    ("expected_heart_attacks_per_episode", None, "expected_heart_attacks"),
    ("score", "score_ci95", "scores"),
    ("drinks_per_episode", None, "drinks"),
    ("sleeps_per_episode", None, "sleeps"),
)
"""How [`EvaluationResult`][heartpole.results.EvaluationResult] summarises per-episode values: (its mean's
field, its 95% interval's field or ``None``, the per-episode field)."""


@dataclass(frozen=True)
class EvaluationResult:
    """A policy's performance over ``episodes`` episodes, with 95% intervals and the per-episode values.

    ``mean_return`` is the realized mean return; ``expected_return`` the expected-risk estimate of the same
    quantity (final score - 100 x the summed heart-attack probabilities). ``score`` is the mean final
    ``work_done / time_elapsed``. Per-episode arrays (float64 or int64) are in episode order. With fewer
    than two episodes the intervals are ``nan``; without an optimum the regret is, and ``no_regret_reason``
    says why. Under ``people``, ``person`` is each episode's person (cohort index, -1 without one) and
    ``oracle_regret`` the mean of (that person's optimum - expected-risk return), [`heartpole.truth`][heartpole.truth]'s
    (``nan`` without people or a cohort's optima: ``no_oracle_regret_reason`` says why).
    """

    policy: str
    env_id: str
    episodes: int
    seed: int
    num_envs: int
    max_steps: int
    mean_return: float
    ci95: tuple[float, float]
    expected_return: float
    expected_ci95: tuple[float, float]
    heart_attacks_per_episode: float
    heart_attacks_ci95: tuple[float, float]
    expected_heart_attacks_per_episode: float
    score: float
    score_ci95: tuple[float, float]
    drinks_per_episode: float
    sleeps_per_episode: float
    seconds: float
    returns: np.ndarray = field(repr=False, compare=False)
    expected_returns: np.ndarray = field(repr=False, compare=False)
    scores: np.ndarray = field(repr=False, compare=False)
    heart_attacks: np.ndarray = field(repr=False, compare=False)
    expected_heart_attacks: np.ndarray = field(repr=False, compare=False)
    drinks: np.ndarray = field(repr=False, compare=False)
    sleeps: np.ndarray = field(repr=False, compare=False)
    person: np.ndarray = field(repr=False, compare=False)
    optimal_return: float = math.nan
    regret: float = math.nan
    regret_ci95: tuple[float, float] = (math.nan, math.nan)
    no_regret_reason: str | None = None
    oracle_regret: float = math.nan
    oracle_regret_ci95: tuple[float, float] = (math.nan, math.nan)
    no_oracle_regret_reason: str | None = None

    def with_regret(self, optimal_return: float, error_bound: float = 0.0) -> EvaluationResult:
        """This result with its regret: ``optimal_return`` minus the expected-risk return.

        The 95% interval is the expected-risk interval reflected, widened by ``error_bound``: the optimum's
        [`margin`][heartpole.optimum.solution.OptimumSolution.margin] (its grids' errors and what any policy may add
        to it) where evaluation computes the regret.
        """
        low, high = self.expected_ci95
        interval = (optimal_return - high - error_bound, optimal_return - low + error_bound)
        regret = optimal_return - self.expected_return
        return replace(self, optimal_return=optimal_return, regret=regret, regret_ci95=interval)

    @property
    def solved(self) -> bool | None:
        """Whether the regret's 95% upper bound is at most [`SOLVED_REGRET`][heartpole.solved.SOLVED_REGRET];
        ``None`` without an optimum."""
        return regret_solved(self.regret_ci95[1])

    @classmethod
    def from_episodes(cls, episodes: Episodes, **about: Any) -> EvaluationResult:
        """Summarise per-episode values; ``about`` holds policy, env_id, seed, num_envs, max_steps, seconds."""
        summary: dict[str, Any] = {}
        for mean, interval, values in SUMMARIES:
            array = getattr(episodes, values)
            summary[mean] = float(array.mean())
            if interval is not None:
                summary[interval] = confidence_interval(array)
        arrays = {name: getattr(episodes, name) for name in Episodes.__dataclass_fields__}
        return cls(episodes=len(episodes.returns), **summary, **arrays, **about)

    @property
    def width_ratio(self) -> float:
        """How many times narrower the expected-risk interval is than the realized one (``inf`` where the
        expected-risk return is the same in every episode, ``nan`` with fewer than two episodes)."""
        expected = self.expected_ci95[1] - self.expected_ci95[0]
        realized = self.ci95[1] - self.ci95[0]
        return realized / expected if expected > 0 else math.inf

    def to_dict(self, per_episode: bool = False) -> dict[str, Any]:
        """JSON-safe summary (NaN and infinities become ``None``); ``per_episode`` adds the arrays as lists."""
        out: dict[str, Any] = {
            "policy": self.policy,
            "env_id": self.env_id,
            "episodes": self.episodes,
            "seed": self.seed,
            "num_envs": self.num_envs,
            "max_steps": self.max_steps,
            "mean_return": json_number(self.mean_return),
            "ci95": json_interval(self.ci95),
            "expected_return": json_number(self.expected_return),
            "expected_ci95": json_interval(self.expected_ci95),
            "heart_attacks_per_episode": json_number(self.heart_attacks_per_episode),
            "heart_attacks_ci95": json_interval(self.heart_attacks_ci95),
            "expected_heart_attacks_per_episode": json_number(self.expected_heart_attacks_per_episode),
            "score": json_number(self.score),
            "score_ci95": json_interval(self.score_ci95),
            "drinks_per_episode": json_number(self.drinks_per_episode),
            "sleeps_per_episode": json_number(self.sleeps_per_episode),
            "optimal_return": json_number(self.optimal_return),
            "regret": json_number(self.regret),
            "regret_ci95": json_interval(self.regret_ci95),
            "solved": self.solved,
            "no_regret_reason": self.no_regret_reason,
            "oracle_regret": json_number(self.oracle_regret),
            "oracle_regret_ci95": json_interval(self.oracle_regret_ci95),
            "no_oracle_regret_reason": self.no_oracle_regret_reason,
            "seconds": round(self.seconds, 3),
        }
        if per_episode:
            for key in ("returns", "expected_returns", "scores", "heart_attacks", "drinks", "sleeps", "person"):
                out[key] = getattr(self, key).tolist()
        return out


@dataclass(frozen=True)
class Comparison:
    """Policy ``a`` minus policy ``b``, episode by episode, from evaluations with common random numbers.

    ``difference`` is the mean realized return of ``a`` minus that of ``b``, ``expected_difference`` the
    same for the expected-risk estimate, ``score_difference`` for the final score; each with the 95%
    interval of the paired differences.
    """

    a: EvaluationResult
    b: EvaluationResult
    difference: float
    ci95: tuple[float, float]
    expected_difference: float
    expected_ci95: tuple[float, float]
    score_difference: float
    score_ci95: tuple[float, float]

    @classmethod
    def of(cls, a: EvaluationResult, b: EvaluationResult) -> Comparison:
        """Pair two results episode by episode; they must come from the same env, seed and chunking.

        Raises:
            ValueError: if the results cannot be paired.
        """
        for key in ("env_id", "episodes", "seed", "num_envs", "max_steps"):
            mine, theirs = getattr(a, key), getattr(b, key)
            if mine != theirs:
                raise ValueError(f"cannot pair evaluations with different {key}: {mine} vs {theirs}")
        returns = a.returns - b.returns
        expected = a.expected_returns - b.expected_returns
        scores = a.scores - b.scores
        return cls(
            a=a,
            b=b,
            difference=float(returns.mean()),
            ci95=confidence_interval(returns),
            expected_difference=float(expected.mean()),
            expected_ci95=confidence_interval(expected),
            score_difference=float(scores.mean()),
            score_ci95=confidence_interval(scores),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: both results' summaries and the paired differences."""
        return {
            "a": self.a.to_dict(),
            "b": self.b.to_dict(),
            "difference": {
                "mean_return": json_number(self.difference),
                "ci95": json_interval(self.ci95),
                "expected_return": json_number(self.expected_difference),
                "expected_ci95": json_interval(self.expected_ci95),
                "score": json_number(self.score_difference),
                "score_ci95": json_interval(self.score_ci95),
            },
            "env_id": self.a.env_id,
            "episodes": self.a.episodes,
            "seed": self.a.seed,
        }


@dataclass
class Episodes:
    """Per-episode values of an evaluation, or of one chunk of its episodes: the returns, expected-risk returns
    and final scores (float64), heart attacks (int64), summed heart-attack probabilities (float64), drinks and
    sleeps (int64) and each episode's person (int64, -1 without one)."""

    returns: np.ndarray
    expected_returns: np.ndarray
    scores: np.ndarray
    heart_attacks: np.ndarray
    expected_heart_attacks: np.ndarray
    drinks: np.ndarray
    sleeps: np.ndarray
    person: np.ndarray

    @classmethod
    def concatenate(cls, parts: Sequence[Episodes]) -> Episodes:
        """The episodes of ``parts``, in order."""
        return cls(*(np.concatenate([getattr(part, f) for part in parts]) for f in cls.__dataclass_fields__))
