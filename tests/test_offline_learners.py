"""Offline learners on a small expert dataset: they learn the data's actions and act sensibly."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from heartpole.evaluation import evaluate  # noqa: E402
from heartpole.offline.behaviour import EpsilonGreedy  # noqa: E402
from heartpole.offline.learners import behaviour_cloning, conservative_q_learning  # noqa: E402
from heartpole.offline.trajectories import collect  # noqa: E402
from heartpole.policies import ExpertPolicy  # noqa: E402


@pytest.fixture(scope="module")
def expert_data():
    return collect(EpsilonGreedy(ExpertPolicy(), 0.1, 4, rng=0), 8, seeds=(1,))


def test_behaviour_cloning_recovers_the_expert(expert_data):
    state = torch.random.get_rng_state()
    policy, log = behaviour_cloning(expert_data, steps=400, seed=0)
    assert torch.equal(state, torch.random.get_rng_state())  # PyTorch's global generator untouched
    assert log.losses[-1] < log.losses[0]
    obs = expert_data.observations[:, :-1].reshape(-1, 6)
    agreement = (policy(obs) == ExpertPolicy()(obs)).mean()
    assert agreement > 0.9, agreement


def test_conservative_q_learning_stays_near_the_data(expert_data):
    policy, log = conservative_q_learning(expert_data, steps=400, alpha=1.0, seed=0)
    assert np.isfinite(log.losses).all()
    result = evaluate(policy, episodes=50, seed=3)
    assert result.drinks_per_episode < 50  # the expert never drinks; random drinks 500 times an episode
    assert result.expected_return > -200  # random's is about -234
