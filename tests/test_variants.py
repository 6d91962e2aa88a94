"""HeartPole-v1 and users' variants: v0 pinned, v1's actions against their stated distributions, the
register_variant round trip (bad definitions: test_variants_definitions.py).

Statistical tests draw 20,000 effects from the vector env with fixed seeds, so they are deterministic. An
effect stated as U(low, high) passes when its sample mean is within 4.5 standard errors of (low + high) / 2,
every sample lies in [low, high] (up to float32 rounding, 1e-5), the extremes come within 0.1% of the
width of both ends, and the Kolmogorov-Smirnov distance to U(low, high) is below 2.23 / sqrt(n) (a false
alarm about once in 10,000 for a true uniform).
"""

from __future__ import annotations

import copy
import hashlib
import math
import pickle

import gymnasium as gym
import numpy as np
import pytest

import heartpole
from heartpole import Action
from heartpole.actions import (
    DRINK_TEA,
    EXERCISE,
    SMOKE_CANNABIS,
    TAKE_NAP,
    V1_NEW_ACTIONS,
)
from heartpole.model import alertness_decay, productivity

N = 20_000
TOLERANCE_SE = 4.5
KS_CRITICAL = 2.23  # / sqrt(n): the Kolmogorov-Smirnov critical value for p = 1e-4
FLOAT32_SLACK = 1e-5
ALERTNESS, HYPERTENSION, INTOXICATION, TIME_SINCE_SLEPT, TIME_ELAPSED, WORK_DONE, THC = range(7)


# ------------------------------------------------------------------------------------------------------
# v0 is pinned: v1, the variants API and later work must not change v0's trajectories. Recorded for package
# 0.3, when the step became one compiled function (heartpole.kernel) in float32 with a counter-based random
# number generator and fused multiply-adds; the dynamics' distribution is tested in test_faithfulness.py.
# Compiled floating-point code may differ in the last bits between CPU families (as NumPy's and libm's do).

V0_SINGLE_SHA256 = "1208c6dfe420157ed21cf6571dfb557ff8ad167db50deb6347a32797cbd3c155"
V0_VECTOR_SHA256 = "60b58ecef069c88b148af166b2c74f595b35be969d9a89abdd0519545c5e4d12"


def v0_single_hash(seed: int = 2024, steps: int = 3000) -> str:
    env = heartpole.HeartPole()
    digest = hashlib.sha256()
    obs, _ = env.reset(seed=seed)
    digest.update(obs.tobytes())
    for action in np.random.default_rng(seed).integers(0, 4, steps).tolist():
        obs, reward, _, truncated, info = env.step(action)
        if truncated:
            obs, _ = env.reset()
        digest.update(obs.tobytes())
        digest.update(np.float64(reward).tobytes())
        digest.update(bytes([info["heart_attack"]]))
    return digest.hexdigest()


def v0_vector_hash(seed: int = 2024, steps: int = 1200, num_envs: int = 16) -> str:
    env = heartpole.HeartPoleVectorEnv(num_envs, max_steps=500)
    digest = hashlib.sha256()
    obs, _ = env.reset(seed=seed)
    digest.update(obs.tobytes())
    truncated = np.zeros(num_envs, dtype=bool)
    for actions in np.random.default_rng(seed).integers(0, 4, (steps, num_envs)):
        restart = truncated.all()  # recorded when a restart's info was empty; now it holds reset()'s values
        obs, reward, _, truncated, info = env.step(actions)
        for array in (obs, reward, np.array([]) if restart else info["heart_attack"], truncated):
            digest.update(array.tobytes())
    return digest.hexdigest()


def test_v0_trajectories_are_bit_for_bit_those_recorded() -> None:
    assert v0_single_hash() == V0_SINGLE_SHA256
    assert v0_vector_hash() == V0_VECTOR_SHA256


def test_v0_keeps_its_spaces_actions_and_formula() -> None:
    dynamics = heartpole.Dynamics()
    assert [a.name for a in dynamics.actions] == ["do_nothing", "drink_coffee", "drink_beer", "sleep"]
    assert dynamics.tables.anxiety_relief == (0.0,) * 6  # no calm: productivity is the tutorial's
    spec = dynamics.spec
    assert (spec.variables, spec.rest_offsets, spec.actions) == (6, 0, 4)
    assert heartpole.HeartPole().observation_space.shape == (6,)
    assert productivity(2.7, 0.02) == productivity(2.7, 0.02, 0.0)


# ------------------------------------------------------------------------------------------------------
# HeartPole-v1


def make_v1_vec(num_envs: int, **kwargs) -> heartpole.HeartPoleVectorEnv:
    return gym.make_vec("HeartPole-v1", num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def test_v1_is_registered_with_v0s_state_and_actions_first() -> None:
    env = gym.make("HeartPole-v1")
    assert isinstance(env.unwrapped, heartpole.HeartPoleV1) and isinstance(env.unwrapped, heartpole.HeartPole)
    names = [a.name for a in env.unwrapped.actions]
    assert names == [
        "do_nothing",
        "drink_coffee",
        "drink_beer",
        "sleep",
        "drink_tea",
        "take_nap",
        "exercise",
        "smoke_cannabis",
    ]
    assert env.unwrapped.actions[:4] == heartpole.V0_ACTIONS
    assert env.action_space == gym.spaces.Discrete(8)
    space = env.observation_space
    assert space.shape == (7,) and space.dtype == np.float32
    assert space.low[THC] == 0 and space.low[HYPERTENSION] == 0
    assert env.unwrapped.dynamics.names == (*[v.name for v in heartpole.V0_VARIABLES], "thc")
    obs, _ = env.reset(seed=0)
    assert 0.7 <= obs[ALERTNESS] <= 1.3 and not obs[1:].any()
    vec = make_v1_vec(3)
    assert isinstance(vec, heartpole.HeartPoleV1VectorEnv)
    assert vec.single_action_space == gym.spaces.Discrete(8) and vec.observation_space.shape == (3, 7)


def test_v1_passes_gymnasiums_env_checker() -> None:
    from gymnasium.utils.env_checker import check_env

    check_env(gym.make("HeartPole-v1").unwrapped)
    check_env(gym.make("HeartPole-v1", render_mode="ansi").unwrapped)


def test_v1_takes_v0s_parameters_but_not_other_actions() -> None:
    env = gym.make("HeartPole-v1", heart_attack_proclivity=0.2, max_steps=30, sleep_half_hours=12)
    assert env.unwrapped.dynamics.params.sleep_half_hours == 12 and env.unwrapped.max_steps == 30
    with pytest.raises(ValueError, match="fixed.*register_variant"):
        gym.make("HeartPole-v1", actions=heartpole.V0_ACTIONS)
    with pytest.raises(ValueError, match="fixed"):
        heartpole.HeartPoleV1VectorEnv(2, variables=heartpole.V0_VARIABLES)
    with pytest.raises(ValueError, match="heart_attack_proclivity"):
        gym.make("HeartPole-v1", heart_attack_proclivity=2.0)


def test_v1_reward_is_v0s_and_telescopes() -> None:
    env = heartpole.HeartPoleV1()
    env.reset(seed=3)
    total, attacks = 0.0, 0
    for action in np.random.default_rng(3).integers(0, 8, 600).tolist():
        _, reward, _, _, info = env.step(action)
        total += reward
        attacks += info["heart_attack"]
    assert attacks > 0
    assert total == pytest.approx(info["score"] - 100 * attacks, abs=1e-4)  # float32 rounding


def test_v1_manual_states_each_new_actions_amounts_fact_and_source() -> None:
    manual = heartpole.HeartPoleV1.__doc__
    for action in V1_NEW_ACTIONS:
        assert action.fact and action.source, action.name
        for variable, (low, high) in action.effects.items():
            if low < 0 and high <= 0:
                stated = f"{variable} -= U({abs(high):g}, {abs(low):g})"
            else:
                stated = f"{variable} += U({low:g}, {high:g})"
            assert stated in manual, f"{action.name}: the manual does not state {stated!r}"
        if action.rest_half_hours:
            rest = action.rest_half_hours
            assert f"{rest} rest half-hour{'s' if rest > 1 else ''}" in manual, action.name
    assert "| 6     | thc" in manual


# ------------------------------------------------------------------------------------------------------
# each new action against its stated distribution, over N draws in the vector env


def assert_uniform(samples: np.ndarray, low: float, high: float, label: str) -> None:
    samples = np.sort(np.asarray(samples, dtype=np.float64))
    n, width = len(samples), high - low
    assert n >= 10_000, f"{label}: only {n} samples"
    se = width / math.sqrt(12 * n)
    assert abs(samples.mean() - (low + high) / 2) <= TOLERANCE_SE * se, (
        f"{label}: mean {samples.mean():.5f}, stated U({low}, {high}) has mean {(low + high) / 2}"
    )
    assert samples[0] >= low - FLOAT32_SLACK and samples[-1] <= high + FLOAT32_SLACK, (
        f"{label}: range [{samples[0]:.5f}, {samples[-1]:.5f}] outside U({low}, {high})"
    )
    assert samples[0] <= low + 1e-3 * width and samples[-1] >= high - 1e-3 * width, f"{label}: ends not reached"
    cdf = np.clip((samples - low) / width, 0.0, 1.0)
    ranks = np.arange(1, n + 1) / n
    ks = max(np.max(ranks - cdf), np.max(cdf - (ranks - 1 / n)))
    assert ks <= KS_CRITICAL / math.sqrt(n), f"{label}: Kolmogorov-Smirnov distance {ks:.4f} to U({low}, {high})"


def step_all(env, action: int) -> tuple[np.ndarray, np.ndarray, dict]:
    before = env.unwrapped.state.T.copy()
    obs, _, _, _, info = env.step(np.full(env.num_envs, action))
    return before.astype(np.float64), obs.astype(np.float64), info


def test_drink_tea_has_half_of_coffees_effects() -> None:
    env = make_v1_vec(N)
    env.reset(seed=10)
    before, after, info = step_all(env, 4)
    ok = ~info["heart_attack"]  # an attack would reset hypertension; at this blood pressure about 1 in 400
    assert ok.mean() > 0.99
    d0 = alertness_decay(0.0)
    assert_uniform((after[:, ALERTNESS] - before[:, ALERTNESS] + d0)[ok], 0.0, 0.5, "tea: alertness")
    assert_uniform((after[:, HYPERTENSION] / 0.97 - before[:, HYPERTENSION])[ok], 0.0, 0.15, "tea: hypertension")
    assert (after[:, [INTOXICATION, THC]] == 0).all() and (after[:, TIME_ELAPSED] == 1).all()
    assert DRINK_TEA.effects == {"alertness": (0.0, 0.5), "hypertension": (0.0, 0.15)}


def test_take_nap_raises_alertness_and_costs_a_half_hour() -> None:
    env = make_v1_vec(N)
    env.reset(seed=11)
    before, after, info = step_all(env, 5)
    # the nap's rest half-hour (decay at time_since_slept 0), then the half-hour of work (decay at 1)
    gained = after[:, ALERTNESS] - before[:, ALERTNESS] + alertness_decay(0.0) + alertness_decay(1.0)
    assert_uniform(gained, 0.3, 0.6, "nap: alertness")
    assert (after[:, TIME_ELAPSED] == 2).all() and (after[:, TIME_SINCE_SLEPT] == 2).all()  # no reset: a nap
    worked = productivity(before[:, ALERTNESS] + gained - alertness_decay(0.0), 0.0)
    np.testing.assert_allclose(after[:, WORK_DONE], worked, rtol=1e-5, atol=1e-5)  # one half-hour of work
    assert (after[:, HYPERTENSION] == 0).all() and TAKE_NAP.rest_half_hours == 1


def test_exercise_lowers_hypertension_never_below_zero_and_costs_an_hour() -> None:
    env = make_v1_vec(N)
    env.reset(seed=12)
    for _ in range(8):  # coffee raises blood pressure above the most exercise can take off (0.15)
        env.step(np.full(N, 1))
    before, after, info = step_all(env, 6)
    ok = ~info["heart_attack"] & (before[:, HYPERTENSION] > 0.15)
    assert ok.mean() > 0.95
    change = after[:, HYPERTENSION] / 0.97**3 - before[:, HYPERTENSION]  # 2 rest half-hours + 1 of work fade
    assert_uniform(change[ok], -0.15, -0.05, "exercise: hypertension")
    assert (after[:, TIME_ELAPSED] - before[:, TIME_ELAPSED] == 3).all()
    decays = alertness_decay(before[:, TIME_SINCE_SLEPT, None] + np.arange(3.0)).sum(axis=1)
    np.testing.assert_allclose(after[:, ALERTNESS], before[:, ALERTNESS] - decays, rtol=1e-5, atol=1e-5)
    # from rest, blood pressure stays at its floor of 0
    env.reset(seed=13)
    _, after, _ = step_all(env, 6)
    assert (after[:, HYPERTENSION] == 0).all()
    assert EXERCISE.rest_half_hours == 2


def test_smoke_cannabis_thc_relieves_anxiety_dulls_and_raises_blood_pressure() -> None:
    env = make_v1_vec(N)
    env.reset(seed=14)
    before, after, info = step_all(env, 7)
    ok = ~info["heart_attack"]
    thc = after[:, THC] / 0.7
    alert = after[:, ALERTNESS] - before[:, ALERTNESS] + alertness_decay(0.0)
    pressure = after[:, HYPERTENSION] / 0.97 - before[:, HYPERTENSION]
    assert_uniform(thc, 0.5, 1.0, "cannabis: thc")
    assert_uniform(alert, -0.4, 0.0, "cannabis: alertness")
    assert_uniform(pressure[ok], 0.0, 0.2, "cannabis: hypertension")
    for x, y in ((thc, alert), (thc, pressure), (alert, pressure)):  # three independent draws
        assert abs(np.corrcoef(x[ok], y[ok])[0, 1]) < TOLERANCE_SE / math.sqrt(ok.sum())
    # the half-hour of work saw the THC: anxiety sets in thc units of alertness later
    worked = productivity(before[:, ALERTNESS] + alert, 0.0, thc)
    np.testing.assert_allclose(info["productivity"], worked, rtol=1e-5, atol=1e-5)
    assert set(SMOKE_CANNABIS.effects) == {"thc", "alertness", "hypertension"}


def test_thc_fades_with_its_own_half_life_and_moves_the_onset_of_anxiety() -> None:
    env = heartpole.HeartPoleV1()
    env.reset(seed=15)
    env.step(7)
    levels = [env.state["thc"]]
    for _ in range(6):
        env.step(0)
        levels.append(env.state["thc"])
    np.testing.assert_allclose(np.array(levels[1:]) / np.array(levels[:-1]), 0.7, rtol=1e-6)  # float32
    assert levels[-1] / levels[0] == pytest.approx(0.7**6, rel=1e-5)  # 12% left after three hours
    # at alertness 3.5 anxiety takes sigmoid(0.5) = 62% of the work; one unit of THC brings that to 38%
    assert productivity(3.5, 0.0, 1.0) / productivity(3.5, 0.0) == pytest.approx(math.exp(0.5), rel=1e-12)
    relieved = 3.5 * (1 - heartpole.crippling_anxiety(2.5)) * heartpole.ballmer(0.0)
    assert productivity(3.5, 0.0, 1.0) == pytest.approx(relieved, rel=1e-12)


# ------------------------------------------------------------------------------------------------------
# users' variants


@pytest.fixture
def variants():
    """register_variant, with every id it registered removed from Gymnasium's registry afterwards."""
    registered: list[str] = []

    def register(env_id: str, *args, **kwargs):
        spec = heartpole.register_variant(env_id, *args, **kwargs)
        registered.append(env_id)
        return spec

    yield register
    for env_id in registered:
        gym.registry.pop(env_id, None)


WALK = Action(
    "take_a_walk",
    {"alertness": (0.1, 0.3)},
    rest_half_hours=1,
    fact="A 10-minute brisk walk raises energy for up to two hours.",
    source="Thayer RE (1987) J Pers Soc Psychol 52(1):119-125",
)


@pytest.mark.slow  # compiles the variant's own loops, single and vector: about 17 s of a fresh clone's default suite
def test_variant_round_trip_define_make_vector_make_and_evaluate(variants) -> None:
    spec = variants(
        "WalkPole-v0",
        actions=[*heartpole.V0_ACTIONS, WALK],
        max_steps=200,
        heart_attack_proclivity=0.3,
        decay_rate=0.95,
        sleep_half_hours=14,
    )
    assert spec.id == "WalkPole-v0" and spec.vector_entry_point is not None
    env = gym.make("WalkPole-v0")
    params = env.unwrapped.dynamics.params
    assert (params.max_steps, params.heart_attack_proclivity, params.decay_rate, params.sleep_half_hours) == (
        200,
        0.3,
        0.95,
        14,
    )
    assert env.action_space == gym.spaces.Discrete(5) and env.observation_space.shape == (6,)
    assert gym.make("WalkPole-v0", max_steps=50).unwrapped.max_steps == 50  # defaults, not locks
    assert pickle.loads(pickle.dumps(env.unwrapped)).actions == env.unwrapped.actions
    obs, _ = env.reset(seed=0)
    obs, _, _, _, info = env.step(4)
    assert env.unwrapped.action_names[info["action_taken"]] == "take_a_walk" and obs[TIME_ELAPSED] == 2

    episodes = 500
    vec = gym.make_vec("WalkPole-v0", num_envs=episodes, vectorization_mode="vector_entry_point")
    assert vec.single_action_space == gym.spaces.Discrete(5) and vec.max_steps == 200
    obs, _ = vec.reset(seed=1)
    total, attacks, risk = np.zeros(episodes), np.zeros(episodes), np.zeros(episodes)
    walks = 0
    for _ in range(200):  # walk when a little tired, sleep when very tired, else work
        actions = np.where(obs[:, ALERTNESS] < 0.3, 3, np.where(obs[:, ALERTNESS] < 0.8, 4, 0))
        walks += (actions == 4).sum()
        obs, reward, terminated, truncated, info = vec.step(actions)
        total += reward
        attacks += info["heart_attack"]
        risk += info["heart_attack_risk"]
    assert truncated.all() and not terminated.any() and walks > 0
    np.testing.assert_allclose(total, info["score"] - 100 * attacks, atol=1e-3)  # v0's reward
    assert 0.3 < info["score"].mean() < 1.5  # walking keeps a productive day going
    # attacks happen at the rate the env reports: E[attacks] = E[sum of risks] (4.5 standard errors)
    assert abs(attacks.mean() - risk.mean()) <= TOLERANCE_SE * attacks.std() / math.sqrt(episodes)
    assert risk.mean() == pytest.approx(200 * 0.3 / (1 + math.exp(6)), rel=1e-3)  # never drinks: the floor

    sync = gym.make_vec("WalkPole-v0", num_envs=2, vectorization_mode="sync")
    sync.reset(seed=0)
    assert sync.step(np.array([4, 0]))[4]["action_taken"].tolist() == [4, 0]  # indices, as the native vector env's


@pytest.mark.slow  # compiles the loops of a variant with a seventh variable: about 9 s in a fresh clone
def test_variant_with_its_own_variable_defined_as_plain_data(variants) -> None:
    """A variant read from a config file: mappings instead of objects, and a variable of its own."""
    variants(
        "config/StressPole-v2",
        actions=[
            {"name": "do_nothing"},
            {"name": "sleep", "sleeps": True},
            {"name": "meeting", "effects": {"stress": [0.5, 1.0], "alertness": [0.0, 0.2]}, "fact": "..."},
        ],
        variables=[*heartpole.V0_VARIABLES, {"name": "stress", "low": 0.0, "decay": 0.8, "anxiety_relief": -1.0}],
    )
    vec = gym.make_vec("config/StressPole-v2", num_envs=4000, vectorization_mode="vector_entry_point")
    vec.reset(seed=2)
    before = vec.unwrapped.state.astype(np.float64)
    obs, _, _, _, info = vec.step(np.full(4000, 2))
    assert vec.observation_space.shape == (4000, 7)
    stress = obs[:, 6] / 0.8
    assert 0.5 - FLOAT32_SLACK <= stress.min() and stress.max() <= 1.0 + FLOAT32_SLACK
    alert = obs[:, ALERTNESS] - before[ALERTNESS] + alertness_decay(0.0)
    worked = productivity(before[ALERTNESS] + alert, 0.0, -stress)  # stress brings anxiety on earlier
    np.testing.assert_allclose(info["productivity"], worked, rtol=1e-5, atol=1e-5)
    assert (info["productivity"] < productivity(before[ALERTNESS] + alert, 0.0) + 1e-6).all()


def test_variant_built_on_v1_and_replaced(variants) -> None:
    decaf = Action("drink_decaf", {"alertness": (0.0, 0.05)}, fact="Decaf keeps ~3% of the caffeine.")
    variants("DecafPole-v0", actions=[*heartpole.V1_ACTIONS, decaf], variables=heartpole.V1_VARIABLES)
    assert gym.make("DecafPole-v0").action_space == gym.spaces.Discrete(9)
    with pytest.raises(ValueError, match="already registered.*replace=True"):
        heartpole.register_variant(
            "DecafPole-v0", actions=[*heartpole.V1_ACTIONS, decaf], variables=heartpole.V1_VARIABLES
        )
    variants("DecafPole-v0", replace=True, max_steps=10)
    env = gym.make("DecafPole-v0")
    assert env.action_space == gym.spaces.Discrete(4) and env.unwrapped.max_steps == 10
    with pytest.raises(ValueError, match="not a HeartPole variant"):
        heartpole.register_variant("CartPole-v1", replace=True)
    assert gym.spec("CartPole-v1").entry_point != "heartpole.env:HeartPole"


def test_definitions_are_copied_so_later_edits_cannot_break_a_variant(variants) -> None:
    actions = [*heartpole.V0_ACTIONS, WALK]
    variants("CopyPole-v0", actions=actions)
    actions.append("not an action")
    env = gym.make("CopyPole-v0")
    assert env.action_space == gym.spaces.Discrete(5)
    assert copy.deepcopy(env.unwrapped.actions) == tuple(actions[:5])
