"""When a HeartPole policy counts as solved: every bar and threshold defined here, once.

Two bars, for two situations:

* where the optimum is known ([`heartpole.optimum`][heartpole.optimum]), a policy is solved when the
  upper end of the 95% interval of its regret is at most [`SOLVED_REGRET`][heartpole.solved.SOLVED_REGRET]
  ([`regret_solved`][heartpole.solved.regret_solved]);
* elsewhere, the env's [`SolvedBar`][heartpole.solved.SolvedBar]: few heart attacks and a score close to
  the best known ([`solved_bar`][heartpole.solved.solved_bar]). Its ``reward_threshold`` is the return of an
  episode exactly at both bars, the ``reward_threshold`` of the env's Gymnasium spec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from heartpole.parameters import Params
from heartpole.rewards import least_heart_attacks

SOLVED_REGRET = 0.01
"""The "solved" bar as a regret: the upper end of the 95% regret interval over 2,000 evaluation episodes at
most 0.01 of expected return. Why 0.01: one drink an episode already costs at least 0.018 (the drink floor of
the optimum), so the bar rules out habitual drinking; a score 0.01 below the optimum's 0.327 (3%) is the most
sleep timing may lose. ``expert`` (0.00076) and the trained PPO agents of the README (0.002-0.006) meet it; a
policy that sleeps every half-hour (0.28) or a PPO agent trained on the telescoping score (0.059) do not. For a
policy that never drinks the 2,000-episode interval is about +-0.0004, 25 times narrower than the bar, so the
verdict does not hinge on the evaluation's luck. The previous bar (heart attacks <= 1.30 and score >= 0.30)
let through a regret of up to about 6.5."""

SOLVED_ATTACKS_ABOVE_FLOOR = 1.05
"""The heart-attack bar as a multiple of the unavoidable floor (the risk at zero blood pressure)."""
SOLVED_SHARE_OF_BEST_SCORE = 0.92
"""The score bar as a share of the best known long-run score (the ``expert`` policy's rate)."""


@dataclass(frozen=True)
class SolvedBar:
    """When a HeartPole env counts as solved: few heart attacks and a score close to the best known.

    Attributes:
        heart_attacks_at_most: heart attacks per episode: 5% above the unavoidable floor, the risk at zero
            blood pressure over ``max_steps`` steps (1.30 for v0).
        score_at_least: final score: 92% of the best known long-run rate (the ``expert`` policy's: 0.30 for
            v0, 0.63 for v1); ``None`` when no rate is known (a variant without ``do_nothing`` and
            ``sleep``).
        reward_threshold: the return of an episode exactly at both bars, Gymnasium's ``reward_threshold``.
    """

    heart_attacks_at_most: float
    score_at_least: float | None
    reward_threshold: float

    def meets(self, heart_attacks: float, score: float) -> bool:
        """Whether an evaluation's heart attacks per episode and mean score meet this bar."""
        return meets_bar(heart_attacks, score, self.heart_attacks_at_most, self.score_at_least)


def meets_bar(heart_attacks: float, score: float, heart_attacks_at_most: float, score_at_least: float | None) -> bool:
    """Whether ``heart_attacks`` per episode and a mean ``score`` meet a bar (no score bar when ``None``)."""
    score_ok = score_at_least is None or score >= score_at_least
    return bool(heart_attacks <= heart_attacks_at_most and score_ok)


def bar(heart_attacks_at_most: float, score_at_least: float | None, penalty: float) -> SolvedBar:
    """The [`SolvedBar`][heartpole.solved.SolvedBar] of the two bars, its reward threshold worked out with the
    env's heart-attack ``penalty``."""
    threshold = round((score_at_least or 0.0) - penalty * heart_attacks_at_most, 6)
    return SolvedBar(heart_attacks_at_most, score_at_least, threshold)


def solved_bar(params: Params, best_rate: float | None) -> SolvedBar:
    """The solved bar of an env with ``params`` and the best known long-run score ``best_rate`` (``None``:
    unknown): v0's issue-3 bar (<= 1.30 heart attacks, score >= 0.30) carried over to any variant by the same
    proportions."""
    attacks = round(SOLVED_ATTACKS_ABOVE_FLOOR * least_heart_attacks(params), 2)
    score = None if best_rate is None else round(SOLVED_SHARE_OF_BEST_SCORE * best_rate, 2)
    return bar(attacks, score, params.heart_attack_penalty)


def regret_solved(regret_upper: float) -> bool | None:
    """Whether the upper end of a regret's 95% interval is at most
    [`SOLVED_REGRET`][heartpole.solved.SOLVED_REGRET]; ``None`` where it is not finite (no optimum known)."""
    if not math.isfinite(regret_upper):
        return None
    return bool(regret_upper <= SOLVED_REGRET)


# The bars of v0 and v1 as solved_bar computes them from the expert's rates (a test checks they agree),
# written out so that ``import heartpole`` registers their reward thresholds without solving anything.
V0_HEART_ATTACKS_AT_MOST = 1.30
"""Issue 3's bar for HeartPole-v0: at most this many heart attacks per episode over 2,000 episodes ..."""
V0_SCORE_AT_LEAST = 0.30
"""... and at least this final score."""
V0_BAR = bar(V0_HEART_ATTACKS_AT_MOST, V0_SCORE_AT_LEAST, Params.heart_attack_penalty)
"""HeartPole-v0's solved bar: at most 1.30 heart attacks per episode and a score of at least 0.30."""
V1_BAR = bar(V0_HEART_ATTACKS_AT_MOST, 0.63, Params.heart_attack_penalty)
"""HeartPole-v1's solved bar: at most 1.30 heart attacks per episode and a score of at least 0.63."""
