"""The NumPy envs with a population of people (``people=``, ``observe_traits=``) and imperfect measurements
(``measurement=``): reproducibility, the draw of a person per episode, the single env as vector env 0, a
person's dynamics as their own env's, observations and spaces, autoreset and bad input."""

from __future__ import annotations

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from heartpole.env import HeartPole
from heartpole.measurement import Measurement
from heartpole.people import People, Person, Uniform
from heartpole.vector import HeartPoleVectorEnv

UNIFORM = People(
    heart_attack_proclivity=Uniform(0.3, 0.7),
    sleep_half_hours=Uniform(12, 20),
    wake_alertness=Uniform((0.6, 1.2), (0.8, 1.4)),
    decay_rate=0.95,
)
POPULATIONS = [pytest.param("default", id="cohort"), pytest.param(UNIFORM, id="distribution")]


def run_vector(env: HeartPoleVectorEnv, steps: int, seed: int = 0) -> list[tuple[np.ndarray, ...]]:
    """Observations, rewards and people of ``steps`` steps with random actions from ``seed``."""
    actions = np.random.default_rng(seed).integers(0, 4, size=(steps, env.num_envs))
    obs, info = env.reset(seed=seed)
    out = [(obs.copy(), info["person"].copy())]
    for a in actions:
        obs, reward, _, _, info = env.step(a)
        out.append((obs.copy(), reward.copy(), info["person"].copy()))
    return out


@pytest.mark.slow  # each population compiles its own loop: seconds each
@pytest.mark.parametrize("people", POPULATIONS)
def test_seeds_reproduce_and_differ(people: People | str) -> None:
    a = run_vector(HeartPoleVectorEnv(8, people=people, max_steps=30), 70, seed=4)
    b = run_vector(HeartPoleVectorEnv(8, people=people, max_steps=30), 70, seed=4)
    c = run_vector(HeartPoleVectorEnv(8, people=people, max_steps=30), 70, seed=5)
    assert all(all(np.array_equal(x, y) for x, y in zip(s, t)) for s, t in zip(a, b))
    assert not np.array_equal(a[0][0], c[0][0])


# The distribution's loops are compiled for it alone (tens of seconds): a slow test. The cohort's are in the cache.
@pytest.mark.parametrize("people", [POPULATIONS[0], pytest.param(UNIFORM, id="distribution", marks=pytest.mark.slow)])
@pytest.mark.parametrize("observe_traits", [False, True])
def test_single_env_is_vector_env_zero_bit_for_bit(people: People | str, observe_traits: bool) -> None:
    single = HeartPole(people=people, observe_traits=observe_traits)
    vector = HeartPoleVectorEnv(6, people=people, observe_traits=observe_traits)
    for seed in (0, 11):
        one, one_info = single.reset(seed=seed)
        many, many_info = vector.reset(seed=seed)
        assert np.array_equal(one, many[0]) and one_info["person"] == many_info["person"][0]
        assert np.array_equal(one_info["traits"], many_info["traits"][0])
        for action in np.random.default_rng(seed).integers(0, 4, size=(400, 6)):
            one, reward, _, _, one_info = single.step(int(action[0]))
            many, rewards, _, _, many_info = vector.step(action)
            assert np.array_equal(one, many[0]) and reward == rewards[0]
            assert one_info["heart_attack_risk"] == many_info["heart_attack_risk"][0]


COHORT_OF_ONE = {
    "heart_attack_proclivity": 0.8,
    "decay_rate": 0.9,
    "sleep_half_hours": 12,
    "wake_alertness": (0.5, 1.5),
}


@pytest.mark.parametrize("make", [HeartPole, lambda **kw: HeartPoleVectorEnv(3, **kw)], ids=["single", "vector"])
def test_a_person_is_their_own_env_bit_for_bit(make) -> None:
    """A cohort of one person steps as an env made with that person's parameters, and so does a fixed field."""
    own = make(**COHORT_OF_ONE, max_steps=200)
    for people in (People(cohort=[Person("x", **COHORT_OF_ONE)]), People(**COHORT_OF_ONE)):
        env = make(people=people, max_steps=200)
        a, _ = env.reset(seed=9)
        b, _ = own.reset(seed=9)
        assert np.array_equal(a, b)
        actions = np.random.default_rng(1).integers(0, 4, size=(450, 3))
        for action in actions:
            step = int(action[0]) if isinstance(env, HeartPole) else action
            x, y = env.step(step), own.step(step)
            assert np.array_equal(x[0], y[0]) and np.array_equal(x[1], y[1])


def test_person_changes_the_dynamics() -> None:
    """Each person's sleep lasts their own sleep_half_hours and their wake-up is in their own range."""
    env = HeartPoleVectorEnv(500, people="default", max_steps=5)
    obs, info = env.reset(seed=3)
    people = People.default()
    sleep = np.array([dict(p.traits)["sleep_half_hours"] for p in people.cohort])[info["person"]]
    wake = np.array([dict(p.traits)["wake_alertness"] for p in people.cohort])[info["person"]]
    assert np.all((obs[:, 0] >= wake[:, 0]) & (obs[:, 0] <= wake[:, 1]))
    obs, *_ = env.step(np.full(500, 3))
    assert np.array_equal(obs[:, 4], sleep + 1)


def test_people_are_drawn_with_equal_chances_at_reset_and_autoreset() -> None:
    """24 people, 48,000 draws (2,000 expected each) at reset then again at NEXT_STEP autoreset: chi-square
    statistic below 60 (23 degrees of freedom; p < 1e-4 under equal chances), and the autoreset's people
    are new draws (agreeing with the ended episode's about 1 time in 24, within 0.02)."""
    n = 48_000
    env = HeartPoleVectorEnv(n, people="default", max_steps=1)
    _, info = env.reset(seed=2)
    first = info["person"]
    env.step(np.zeros(n, dtype=np.int64))
    _, _, _, _, info = env.step(np.zeros(n, dtype=np.int64))  # NEXT_STEP: every env restarts
    second = info["person"]
    for drawn in (first, second):
        counts = np.bincount(drawn, minlength=24)
        assert ((counts - n / 24) ** 2 / (n / 24)).sum() < 60
    assert abs(np.mean(first == second) - 1 / 24) < 0.02


@pytest.mark.parametrize("mode", list(AutoresetMode))
def test_autoreset_modes_draw_new_people(mode: AutoresetMode) -> None:
    n = 200
    env = HeartPoleVectorEnv(n, people="default", max_steps=2, autoreset_mode=mode)
    _, info = env.reset(seed=0)
    before = info["person"].copy()
    for _ in range(2):
        _, _, _, truncated, info = env.step(np.zeros(n, dtype=np.int64))
    assert truncated.all()
    if mode == AutoresetMode.SAME_STEP:
        assert np.array_equal(info["final_info"]["person"], before)
        after = info["person"]
    elif mode == AutoresetMode.NEXT_STEP:
        assert np.array_equal(info["person"], before)  # the ended episode's, until the next step
        _, _, _, _, info = env.step(np.zeros(n, dtype=np.int64))
        after = info["person"]
    else:
        mask = np.zeros(n, dtype=bool)
        mask[: n // 2] = True
        _, info = env.reset(options={"reset_mask": mask})
        after = info["person"]
        assert np.array_equal(after[~mask], before[~mask])
        before, after = before[mask], after[mask]
    assert np.mean(before != after) > 0.8  # new people (the same one again about 1 time in 24)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_an_info_kept_keeps_its_people(mode: AutoresetMode) -> None:
    """info's person and traits go out with no copy per step: read-only, and never changed afterwards by the
    env (later steps, autoresets drawing new people, a masked reset)."""
    n = 50
    env = HeartPoleVectorEnv(n, people=UNIFORM, max_steps=3, autoreset_mode=mode)
    _, info = env.reset(seed=0)
    kept = [info]
    for t in range(10):
        kept.append(env.step(np.zeros(n, dtype=np.int64))[4])
        if t == 4:
            kept.append(env.reset(options={"reset_mask": np.arange(n) % 2 == 0})[1])
    copies = [(info["person"].copy(), info["traits"].copy()) for info in kept]
    for _ in range(4):
        env.step(np.zeros(n, dtype=np.int64))
    for info, (person, traits) in zip(kept, copies):
        assert np.array_equal(info["person"], person) and np.array_equal(info["traits"], traits)
        with pytest.raises(ValueError, match="read-only"):
            info["traits"][0] = 0.0
    assert not np.array_equal(copies[0][1], copies[-1][1])  # new people were drawn meanwhile


def test_observe_traits_observation_and_space() -> None:
    env = gym.make("HeartPole-v0", people="default", observe_traits=True)
    traits = People.default().traits
    assert env.observation_space.shape == (6 + len(traits),)
    low, high = People.default().trait_bounds()
    assert np.array_equal(env.observation_space.low[6:], low) and np.array_equal(env.observation_space.high[6:], high)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and np.array_equal(obs[6:], info["traits"])
    obs, *_, info = env.step(0)
    assert np.array_equal(obs[6:], info["traits"]) and env.unwrapped.people == People.default()
    vector = gym.make_vec("HeartPole-v0", num_envs=3, people="default", observe_traits=True)
    obs, info = vector.reset(seed=0)
    assert obs.shape == (3, 6 + len(traits)) and np.array_equal(obs[:, 6:], info["traits"])
    assert vector.single_observation_space == env.observation_space


def test_without_people_nothing_changes() -> None:
    env = HeartPole()
    obs, info = env.reset(seed=0)
    assert env.people is None and "person" not in info and obs.shape == (6,)
    assert "person" not in env.step(0)[4]
    assert "person" not in HeartPoleVectorEnv(2).reset(seed=0)[1]


def test_measurement_noise_sd_and_the_state_unchanged() -> None:
    """Alertness read with noise sd 0.5 every step over 20,000 envs: the sample sd of (observed - true) is
    within 3% of 0.5 (its standard error is 0.5%); the states are those of the env without measurement."""
    n = 20_000
    noisy = HeartPoleVectorEnv(n, measurement=Measurement({"alertness": 0.5}))
    exact = HeartPoleVectorEnv(n)
    obs, _ = noisy.reset(seed=1)
    true, _ = exact.reset(seed=1)
    for _ in range(3):
        action = np.ones(n, dtype=np.int64)
        obs, *_ = noisy.step(action)
        true, *_ = exact.step(action)
        error = obs[:, 0] - true[:, 0]
        assert abs(error.std() - 0.5) < 0.015 and abs(error.mean()) < 0.015
        assert np.array_equal(obs[:, 1:], true[:, 1:]) and np.array_equal(noisy.state, exact.state)


def test_measurement_every_k_carries_forward_with_its_age() -> None:
    env = HeartPole(measurement=Measurement({"alertness": 0.1, "hypertension": 0.0}, every=4))
    assert env.observation_space.shape == (7,) and env.observation_space.high[6] == 4
    obs, _ = env.reset(seed=0)
    assert obs[6] == 0
    ages, seen = [obs[6]], [obs[0]]
    for _ in range(7):
        obs, *_ = env.step(1)
        ages.append(obs[6])
        seen.append(obs[0])
        assert obs[3] == env.state["time_since_slept"]  # not measured: exact
    assert ages == [0, 1, 2, 3, 0, 1, 2, 3]
    assert seen[0] == seen[1] == seen[2] == seen[3] != seen[4] == seen[5]
    obs, *_ = env.step(3)  # a sleep passes 17 half-hours: measured again
    assert obs[6] == 0


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"people": "nobody"}, ValueError, "unknown population 'nobody'"),
        ({"people": 3}, TypeError, "people must be a People"),
        ({"observe_traits": True}, ValueError, "observe_traits=True needs a population"),
        ({"people": "default", "observe_traits": "yes"}, TypeError, "observe_traits must be True or False"),
        ({"measurement": {"alertness": 0.1}}, TypeError, "measurement must be a heartpole.measurement.Measurement"),
        ({"measurement": Measurement({"stress": 0.1})}, ValueError, "unknown variables"),
        ({"peeple": "default"}, TypeError, "unexpected keyword argument 'peeple'"),
    ],
)
@pytest.mark.parametrize("make", [HeartPole, HeartPoleVectorEnv], ids=["single", "vector"])
def test_bad_arguments(make, kwargs: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        make(**kwargs)


NO_JIT = """
import numpy as np, heartpole
from heartpole.people import People, Uniform
for people in ("default", People(sleep_half_hours=Uniform(12, 20), wake_alertness=Uniform((0.6, 1.2), (0.8, 1.4)))):
    env = heartpole.HeartPole(max_steps=30, people=people, observe_traits=True)
    obs, _ = env.reset(seed=5)
    for t in range(30):
        obs, reward, terminated, truncated, info = env.step(t % 4)
    print(obs.tobytes().hex(), info["person"])
vec = heartpole.HeartPoleVectorEnv(3, max_steps=10, people="default")
many, _ = vec.reset(seed=5)
for t in range(30):
    many, rewards, *_ = vec.step(np.array([t % 4, 3, 1]))
print(many.tobytes().hex(), rewards.tobytes().hex())
"""


@pytest.mark.slow  # runs the loops as plain Python in a subprocess
def test_people_run_the_same_without_numba_compiling() -> None:
    """With NUMBA_DISABLE_JIT=1 the people's loops run as plain Python to the same observations, bit for bit."""

    def run(extra: dict[str, str]) -> str:
        environment = {**os.environ, **extra}
        return subprocess.run(
            [sys.executable, "-c", NO_JIT], capture_output=True, text=True, check=True, env=environment
        ).stdout

    assert run({"NUMBA_DISABLE_JIT": "1"}) == run({}) != ""


@pytest.mark.parametrize(
    "kwargs",
    [
        pytest.param({"people": "default", "observe_traits": True}, id="traits"),
        pytest.param({"people": UNIFORM}, id="distribution"),
        pytest.param({"measurement": Measurement({"alertness": 0.2}, every=3)}, id="measurement"),
    ],
)
def test_copies_of_a_single_env_with_people_or_measurement_continue_identically(kwargs: dict) -> None:
    import copy
    import pickle

    env = HeartPole(max_steps=40, **kwargs)
    env.reset(seed=16)
    for t in range(25):
        env.step(t % 4)
    twins = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    runs = []
    for e in [env, *twins]:
        out = []
        for t in range(60):  # across the end of the episode and a reset
            obs, reward, _, truncated, info = e.step(t % 3)
            out.append((obs.tobytes(), reward, info.get("person"), np.asarray(info.get("traits", ())).tobytes()))
            if truncated:
                e.reset()
        runs.append(out)
    assert runs[0] == runs[1] == runs[2]


def test_a_single_envs_info_traits_are_its_own() -> None:
    env = HeartPole(people="default")
    _, reset_info = env.reset(seed=17)
    first = env.step(0)[-1]
    first["traits"][:] = -1.0  # the caller's to change: later infos keep the person's traits
    second = env.step(0)[-1]
    assert second["traits"].tobytes() == reset_info["traits"].tobytes() != first["traits"].tobytes()
    assert second["person"] == reset_info["person"] == first["person"]


def test_a_measurement_given_as_its_json_description_is_the_measurement() -> None:
    # what a preset's env_kwargs or --env-kwargs hold, as `heartpole dataset --measurement` and datasets take it
    described = {"noise": {"alertness": 0.2}, "every": 4}
    a = HeartPoleVectorEnv(3, measurement=described)
    b = HeartPoleVectorEnv(3, measurement=Measurement({"alertness": 0.2}, every=4))
    np.testing.assert_array_equal(a.reset(seed=1)[0], b.reset(seed=1)[0])
    for _ in range(6):
        np.testing.assert_array_equal(a.step(np.ones(3, np.int64))[0], b.step(np.ones(3, np.int64))[0])
