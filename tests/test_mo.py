"""mo-heartpole-v0 (heartpole.mo) with MO-Gymnasium itself: its vector reward, scalarised by MO-Gymnasium's
LinearReward into HeartPole's own reward, and its Pareto front, the frontier's. The env itself needs no MO-Gymnasium
(the last tests run without it); the others skip where the ``mo`` extra is not installed (scripts/test_min_deps.sh)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest

import heartpole  # noqa: F401 - registers the ids
from heartpole import mo
from heartpole.optimum import NotCoveredError, tradeoff

DRINKS = (1, 2)  # coffee and beer: blood pressure, hence heart attacks, with proclivity 1


def _episode_pairs(env_kwargs: dict[str, object], weight: np.ndarray, episodes: int) -> tuple[int, int, list[bool]]:
    """Steps of the scalarised mo env and of HeartPole-v0 side by side, same seeds and actions (drinks often): the
    steps, the heart attacks, and whether each scalar reward equals HeartPole's bit for bit."""
    mo_gym = pytest.importorskip("mo_gymnasium")
    scalar = mo_gym.wrappers.LinearReward(mo_gym.make("mo-heartpole-v0", **env_kwargs), weight=weight)
    plain = gym.make("HeartPole-v0", **env_kwargs)
    rng = np.random.default_rng(0)
    same, attacks = [], 0
    for seed in range(episodes):
        scalar.reset(seed=seed)
        plain.reset(seed=seed)
        truncated = False
        while not truncated:
            action = int(rng.choice(DRINKS)) if rng.random() < 0.7 else int(rng.integers(4))
            _, reward, _, truncated, info = scalar.step(action)
            _, expected, *_ = plain.step(action)
            same.append(bool(np.float32(reward) == np.float32(expected)) and type(reward) is np.float32)
            attacks += bool(info["heart_attack"])
            assert info["vector_reward"][1] == -float(info["heart_attack"])
    return len(same), attacks, same


@pytest.mark.parametrize("penalty", [100.0, 30.0, 0.0])
def test_linear_reward_with_weights_one_and_the_penalty_is_heartpoles_reward_bit_for_bit(penalty: float) -> None:
    kwargs = {"heart_attack_proclivity": 1.0, "heart_attack_penalty": penalty, "max_steps": 300}
    steps, attacks, same = _episode_pairs(kwargs, np.array([1.0, penalty], dtype=np.float32), episodes=4)
    assert steps == 1200 and attacks >= 10  # the drinks raise the pressure: attacks, not a quiet run
    assert all(same), f"{same.count(False)} of {steps} rewards differ"


def test_float64_weights_agree_to_float32_rounding() -> None:
    mo_gym = pytest.importorskip("mo_gymnasium")
    scalar = mo_gym.wrappers.LinearReward(mo_gym.make("mo-heartpole-v0", heart_attack_proclivity=1.0),
                                          weight=np.array([1.0, 100.0]))  # fmt: skip
    plain = gym.make("HeartPole-v0", heart_attack_proclivity=1.0)
    scalar.reset(seed=3)
    plain.reset(seed=3)
    for action in [1, 2] * 200:
        _, reward, *_ = scalar.step(action)
        _, expected, *_ = plain.step(action)
        assert reward == pytest.approx(expected, abs=1e-5)  # float32's spacing at 100 is 7.6e-6


def test_the_vector_reward_sums_to_the_final_score_and_minus_the_attacks() -> None:
    env = gym.make("mo-heartpole-v0", heart_attack_proclivity=1.0, max_steps=500)
    assert env.unwrapped.reward_dim == 2 and env.unwrapped.reward_space.shape == (2,)
    env.reset(seed=1)
    total, attacks, truncated = np.zeros(2, dtype=np.float64), 0, False
    while not truncated:
        _, vector, _, truncated, info = env.step(1)
        assert vector.dtype == np.float32 and env.unwrapped.reward_space.contains(vector)
        total += vector
        attacks += bool(info["heart_attack"])
    assert attacks > 0 and total[1] == -attacks
    assert total[0] == pytest.approx(info["score"], abs=1e-5)  # float32 steps, as HeartPole's own rewards


def test_same_seed_same_episode_as_heartpole() -> None:
    mo_env, plain = gym.make("mo-heartpole-v0"), gym.make("HeartPole-v0")
    first, _ = mo_env.reset(seed=7)
    assert np.array_equal(first, plain.reset(seed=7)[0])
    for action in [0, 1, 2, 3, 0, 0, 1]:
        assert np.array_equal(mo_env.step(action)[0], plain.step(action)[0])


@dataclass
class _Coffee:
    """A made-up drinking solver's answer: more score and more heart attacks the lower the penalty."""

    penalty: float

    def __getattr__(self, name: str) -> float:
        more = 1.0 / (1.0 + self.penalty)
        figures = {"expected_score": 0.36 + 0.5 * more, "expected_attacks": 0.2 + 10.0 * more, "lower": 0.0,
                   "expected_return": 0.0, "upper": math.nan, "coffees_per_episode": 100 * more,
                   "beers_per_episode": 0.0, "drinks_per_episode": 100 * more}  # fmt: skip
        if name == "optimal":
            return False
        return figures[name]


@pytest.fixture
def made_up_drinking(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The drinking solver replaced by `_Coffee` (a real one takes minutes a penalty), the front's cache emptied."""
    monkeypatch.setattr(tradeoff, "package_drinking", lambda env_id, kwargs: _Coffee(kwargs["heart_attack_penalty"]))
    mo._front.cache_clear()
    yield
    mo._front.cache_clear()


def test_the_pareto_front_is_the_frontiers_non_dominated_points(made_up_drinking: None) -> None:
    env = gym.make("mo-heartpole-v0", max_steps=100).unwrapped
    front = env.pareto_front(gamma=1.0)
    solved = tradeoff.frontier(env_kwargs={"max_steps": 100}, drinking=tradeoff.package_drinking)
    assert [tuple(point) for point in front] == solved.pareto_front()
    assert len(front) == len(solved.points) == tradeoff.DEFAULT_POINTS  # each made-up point on the front
    for point in front:
        assert point.shape == (2,) and point[1] < 0
        others = [p for p in front if p is not point]
        assert not any((p >= point).all() and (p > point).any() for p in others)  # none dominated
    assert tuple(front[-1]) == (solved.points[-1].expected_score, -solved.points[-1].expected_heart_attacks)
    with pytest.raises(ValueError, match="only gamma=1.0 is accepted"):
        env.pareto_front(gamma=0.99)


def test_a_penalty_no_solver_covers_is_left_out_with_a_warning(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(env_id: str, kwargs: dict[str, object]) -> object:
        raise NotCoveredError("not here")

    monkeypatch.setattr(tradeoff, "package_drinking", refuse)
    mo._front.cache_clear()
    try:
        with pytest.warns(UserWarning, match="leaves out penalties 0, 1, "):
            front = gym.make("mo-heartpole-v0", max_steps=100).unwrapped.pareto_front()
    finally:
        mo._front.cache_clear()
    assert len(front) == 1 and front[0][1] == pytest.approx(-0.12363115783173871)  # the no-drink optimum alone
