"""How HeartPole's results read as text: a value with its interval, the ranked table, the published Table 1,
and words for what is missing. (Their JSON form, ``null`` for what is missing, is
`json_number`'s.)

Fewer than two episodes give no interval, and a variant the optimum does not cover gives no regret; no
output shows ``nan`` or ``inf`` for them. Text says so in words
(`missing_notes`), JSON has ``null``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from heartpole.evaluation import EvaluationResult, rank
from heartpole.stats import t_quantile_975

PUBLISHED_TABLE1: tuple[tuple[str, str, float], ...] = (
    ("CEM", "linear (0 hidden)", -524.12),
    ("CEM", "3x16", -523.88),
    ("SARSA", "linear", -130.9),
    ("SARSA", "3x16", -134.95),
    ("DQN", "linear", -119.95),
    ("DQN", "3x16", -84.96),
    ("reference: sleep every night, then a cup of coffee", "-", -119.76),
)
"""Table 1 of the HEALTHINF abstract on HeartPole: (algorithm, model, mean return over 20 episodes)."""
PUBLISHED_EPISODES = 20
"""Episodes per row of [`PUBLISHED_TABLE1`][heartpole.reporting.PUBLISHED_TABLE1]."""

NO_INTERVAL = "no 95% intervals: fewer than 2 episodes (an interval needs at least 2)"


def has_interval(interval: Sequence[float]) -> bool:
    """Whether ``interval`` is an interval (finite ends), not the ``nan`` of fewer than two episodes."""
    return all(math.isfinite(end) for end in interval)


def missing_notes(results: Sequence[EvaluationResult]) -> list[str]:
    """One line each for what ``results`` lack: intervals (fewer than two episodes), the regret (and why)."""
    notes = [NO_INTERVAL] if any(result.episodes < 2 for result in results) else []
    for what, key in (("regret", "no_regret_reason"), ("oracle regret", "no_oracle_regret_reason")):
        reasons = [getattr(result, key) for result in results if getattr(result, key)]
        if reasons:
            notes.append(f"no {what}: {reasons[0]}")
    return notes


def under_people(results: Sequence[EvaluationResult]) -> bool:
    """Whether ``results`` ran under ``people`` (they have an oracle regret, or a reason for none)."""
    return any(math.isfinite(r.oracle_regret) or r.no_oracle_regret_reason for r in results)


def plus_minus(value: float, interval: tuple[float, float]) -> str:
    """``value +- half-width`` with two significant digits in the half-width, e.g. ``-138.785 +- 0.078``;
    the value alone where there is no interval (fewer than two episodes: say so beside it, see
    [`missing_notes`][heartpole.reporting.missing_notes]), ``-`` where there is no value."""
    if not math.isfinite(value):
        return "-"
    half = (interval[1] - interval[0]) / 2
    if not math.isfinite(half):
        return f"{value:.3f}"
    if half == 0:
        return f"{value:.4f} +- 0"
    decimals = min(max(2 - math.ceil(math.log10(half)), 0), 8)
    return f"{value:.{decimals}f} +- {half:.{decimals}f}"


def table_rows(results: Sequence[EvaluationResult]) -> tuple[list[str], list[list[object]]]:
    """Headers and rows of the results table (best expected-risk return first), values as text; under people
    the oracle regret takes the regret's column (one optimum is no one's: see
    [`heartpole.truth`][heartpole.truth])."""
    oracle = under_people(results)
    headers = [
        "rank",
        "policy",
        "expected-risk return (95% CI)",
        "oracle regret (95% CI)" if oracle else "regret (95% CI)",
        "realized return (95% CI)",
        "heart attacks / ep",
        "score",
        "drinks / ep",
        "sleeps / ep",
    ]
    rows = [
        [
            n,
            result.policy,
            plus_minus(result.expected_return, result.expected_ci95),
            plus_minus(result.oracle_regret, result.oracle_regret_ci95)
            if oracle
            else plus_minus(result.regret, result.regret_ci95),
            plus_minus(result.mean_return, result.ci95),
            f"{result.heart_attacks_per_episode:.3f}",
            f"{result.score:.4f}",
            f"{result.drinks_per_episode:.1f}",
            f"{result.sleeps_per_episode:.1f}",
        ]
        for n, result in enumerate(rank(results), start=1)
    ]
    return headers, rows


def published_rows(sd: float = 110.0) -> tuple[list[str], list[list[object]]]:
    """Headers and rows of the published Table 1, with the 95% half-width its 20 episodes allow."""
    half = t_quantile_975(PUBLISHED_EPISODES - 1) * sd / math.sqrt(PUBLISHED_EPISODES)
    headers = ["algorithm", "model", f"mean return ({PUBLISHED_EPISODES} episodes)", "95% CI at sd 110"]
    rows: list[list[object]] = [
        [algo, model, f"{value:.2f}", f"+-{half:.0f}"] for algo, model, value in PUBLISHED_TABLE1
    ]
    return headers, rows
