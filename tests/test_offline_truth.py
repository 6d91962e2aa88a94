"""The true value of a policy: a closed-form case, consistency with heartpole.evaluate, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from heartpole.evaluation import evaluate
from heartpole.model import heart_attack_risk
from heartpole.offline.truth import true_value


def test_heart_attack_part_in_closed_form():
    """``nothing`` never raises blood pressure: every step's risk is 0.5 * sigmoid(-6), so the value lost to
    heart attacks is ``-100 * risk * (1 - gamma^T) / (1 - gamma)``, exactly, with no coin noise."""
    gamma, steps, episodes = 0.95, 300, 200
    risky = true_value("nothing", gamma, episodes, env_kwargs={"max_steps": steps}, seed=3)
    safe = true_value(
        "nothing", gamma, episodes, env_kwargs={"max_steps": steps, "heart_attack_proclivity": 0.0}, seed=3
    )
    risk = float(np.float32(heart_attack_risk(0.0)))
    closed_form = -100 * risk * (1 - gamma**steps) / (1 - gamma)
    assert risky.value - safe.value == pytest.approx(closed_form, rel=1e-5)
    assert risky.expected_return - safe.expected_return == pytest.approx(-100 * risk * steps, rel=1e-5)
    assert risky.value_ci95[1] - risky.value_ci95[0] == pytest.approx(safe.value_ci95[1] - safe.value_ci95[0])
    # realized heart attacks: a binomial count with mean steps * risk, within 4 standard errors
    se = math.sqrt(steps * risk * (1 - risk) / episodes)
    assert abs(risky.heart_attacks - steps * risk) < 4 * se
    assert safe.heart_attacks == 0


def test_undiscounted_value_is_the_return_and_agrees_with_evaluate():
    truth = true_value("expert", 1.0, 300, seed=1)
    assert truth.value == pytest.approx(truth.expected_return)
    assert truth.realized_value == pytest.approx(truth.mean_return)
    result = evaluate("expert", episodes=300, seed=2)
    se = [(high - low) / (2 * 1.96) for low, high in (truth.expected_return_ci95, result.expected_ci95)]
    assert abs(truth.expected_return - result.expected_return) < 4 * math.hypot(*se)
    assert truth.value_ci95[0] < truth.value < truth.value_ci95[1]
    assert "expert" in truth.describe() and truth.to_dict()["gamma"] == 1.0


def test_expected_risk_interval_is_tighter_than_the_realized_one():
    truth = true_value("reference", 0.99, 200)
    realized = truth.realized_value_ci95[1] - truth.realized_value_ci95[0]
    assert realized > 5 * (truth.value_ci95[1] - truth.value_ci95[0])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"gamma": 0.0}, "gamma"), ({"gamma": 1.5}, "gamma"), ({"episodes": 1}, "episodes"), ({"env_id": "X-v0"}, "X")],
)
def test_bad_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        true_value("expert", **kwargs)


def test_invalid_actions_are_named():
    with pytest.raises(ValueError, match="returned actions"):
        true_value(lambda obs: np.full(len(obs), 9), 0.9, 4)


def test_the_optimal_policy_is_told_the_decisions_left_and_meets_evaluates_episodes():
    """``true_value`` and ``evaluate`` run the same loop: with one chunk and the same seed they meet the same
    episodes, so a policy that needs the decisions left (``optimal``) gets the same returns in both."""
    kwargs = {"max_steps": 1000}  # v0's, solved once for the whole suite
    truth = true_value("optimal", 1.0, 40, seed=5, env_kwargs=kwargs)
    result = evaluate("optimal", episodes=40, seed=5, num_envs=40, env_kwargs=kwargs, regret=False)
    assert truth.mean_return == pytest.approx(result.mean_return, abs=1e-9)
    assert truth.expected_return == pytest.approx(result.expected_return, abs=1e-5)  # float32 rewards summed
