"""Every solved bar and threshold comes from heartpole.solved."""

from __future__ import annotations

import math

import pytest

from heartpole import solved
from heartpole.parameters import Params
from heartpole.policies import env_dynamics
from heartpole.registry import BUILTIN_REWARD_THRESHOLDS, V0_ID, V1_ID, best_known_rate


@pytest.mark.parametrize(("env_id", "written"), [(V0_ID, solved.V0_BAR), (V1_ID, solved.V1_BAR)])
def test_the_written_out_bars_are_what_the_rule_computes(env_id: str, written: solved.SolvedBar) -> None:
    dynamics = env_dynamics(env_id)
    assert solved.solved_bar(dynamics.params, best_known_rate(dynamics)) == written
    assert BUILTIN_REWARD_THRESHOLDS[env_id] == written.reward_threshold


def test_a_bar_without_a_known_score_judges_heart_attacks_alone() -> None:
    bar = solved.solved_bar(Params(), None)
    assert bar.score_at_least is None
    assert bar.reward_threshold == -Params.heart_attack_penalty * bar.heart_attacks_at_most
    assert bar.meets(bar.heart_attacks_at_most, -5.0)
    assert not bar.meets(bar.heart_attacks_at_most + 0.01, 1.0)


def test_meeting_a_bar_includes_its_edges() -> None:
    bar = solved.V0_BAR
    assert bar.meets(1.30, 0.30)
    assert not bar.meets(1.31, 0.30) and not bar.meets(1.30, 0.29)


def test_the_regret_bar() -> None:
    assert solved.regret_solved(solved.SOLVED_REGRET) is True
    assert solved.regret_solved(math.nextafter(solved.SOLVED_REGRET, 1.0)) is False
    assert solved.regret_solved(math.nan) is None and solved.regret_solved(math.inf) is None


def test_the_old_names_are_the_same_numbers() -> None:
    from heartpole import evaluation, registry

    assert evaluation.SOLVED_REGRET == solved.SOLVED_REGRET
    assert registry.solved_bar(env_dynamics(V0_ID)) == solved.V0_BAR
    presets = pytest.importorskip("heartpole.training.presets")
    assert (presets.SOLVED_HEART_ATTACKS, presets.SOLVED_SCORE) == (1.30, 0.30)
    assert presets.meets_bar({"heart_attacks_per_episode": 1.3, "score": 0.3}, presets.env_solved_bar(V0_ID))
