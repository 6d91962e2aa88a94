"""heartpole.jax with people: a person per episode, per-env params the gymnax way, observe_traits, in
distribution equal to the NumPy model run with each person's Params."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

jax = pytest.importorskip("jax", reason="heartpole.jax needs the 'jax' extra: pip install 'heartpole[jax]'")
import jax.numpy as jnp  # noqa: E402

import heartpole  # noqa: E402
from heartpole.dynamics import Dynamics  # noqa: E402
from heartpole.jax import EnvParams, EnvState, HeartPoleJax, make  # noqa: E402
from heartpole.model import ALERTNESS, HYPERTENSION, INTOXICATION, TIME_ELAPSED, TIME_SINCE_SLEPT  # noqa: E402
from heartpole.parameters import Params  # noqa: E402
from heartpole.people import People, Person, Sample, Uniform  # noqa: E402

pytestmark = pytest.mark.slow  # people: a cohort solved, their loop compiled (minutes in all)

SLEEP = 3  # v0's sleep action
TOLERANCE_SE = 4.5
"""Means compared across backends may differ by this many standard errors of their difference (a false
failure has probability 7e-6 per comparison)."""
Z = 3.72
"""The normal quantile of 1e-4: chi-square statistics are compared with their 1e-4 upper quantile."""


def chi2_limit(df: int) -> float:
    """The chi-square distribution's upper 1e-4 quantile, by Wilson and Hilferty (within 1% for df >= 8)."""
    return df * (1 - 2 / (9 * df) + Z * math.sqrt(2 / (9 * df))) ** 3


def chi2_equal_chances(draws: np.ndarray, values: int) -> float:
    counts = np.bincount(draws, minlength=values)
    assert counts.size == values, f"drew values outside 0..{values - 1}: {np.unique(draws)}"
    expected = draws.size / values
    return float(((counts - expected) ** 2 / expected).sum())


def cohort_values(people: People) -> np.ndarray:
    """Each member's values, one row per person (the columns of a Sample)."""
    return np.array([[x for _, v in p.traits for x in (v if isinstance(v, tuple) else (v,))] for p in people.cohort])


def whole_cohort(people: People) -> Sample:
    return Sample(people, np.arange(len(people.cohort)), cohort_values(people))


def leaves_equal(a: EnvParams, b: EnvParams) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)))


# ------------------------------------------------------------------------------------------------------
# one person: exactly that person's env


def test_a_cohort_member_runs_on_exactly_their_params() -> None:
    """Every person of the default cohort: the params their episodes run on, and params_for's, equal bit for
    bit those of an env made with their values (the same float64 arithmetic rounded once to float32)."""
    people = People.default()
    env, params = make("HeartPole-v0", people=people)
    batch = HeartPoleJax().params_for(whole_cohort(people))
    for index, person in enumerate(people.cohort):
        own = make("HeartPole-v0", **person.values())[1]
        state = EnvState(jnp.zeros(6), jnp.int32(0), jnp.int32(index), jnp.asarray(cohort_values(people)[index]))
        assert leaves_equal(env.person_params(state, params), own), person.name
        assert leaves_equal(jax.tree_util.tree_map(lambda x, i=index: x[i], batch), own), person.name


def test_a_cohort_steps_on_each_members_action_row_read_by_index() -> None:
    """Under jit (person and action traced), the effects and tables a cohort's step reads by ``[person, action]``
    equal bit for bit those of an env made with that person's values; entries no person sets come from the
    params given (a changed field is followed)."""
    people = People.default()
    env, params = make("HeartPole-v0", people=people)
    changed = params.replace(effect_low=params.effect_low + 0.25, heart_attack_penalty=jnp.float32(50.0))
    inputs = jax.jit(env._inputs)
    for index, person in enumerate(people.cohort):
        own_env, own = make("HeartPole-v0", **person.values())
        own = own.replace(effect_low=own.effect_low + 0.25, heart_attack_penalty=jnp.float32(50.0))
        state = EnvState(tuple(jnp.zeros(6)), jnp.int32(0), jnp.int32(index))
        own_state = EnvState(tuple(jnp.zeros(6)), jnp.int32(0))
        for action in range(4):
            effects, tables = inputs(state, changed, jnp.int32(action))
            own_effects, own_tables = own_env._inputs(own_state, own, jnp.int32(action))
            assert jax.tree_util.tree_all(jax.tree_util.tree_map(np.array_equal, effects, own_effects)), person.name
            assert jax.tree_util.tree_all(jax.tree_util.tree_map(np.array_equal, tables, own_tables)), person.name


def test_a_cohort_of_one_steps_exactly_as_that_persons_env() -> None:
    """A cohort of one is the env made with that person's values: the same reset from the same key (a cohort's
    person is picked by a uniform apart from the wake-up one), the same steps."""
    cleo = People.default().cohort[2]
    env, params = make("HeartPole-v0", people=People(cohort=[cleo]), max_steps=40)
    own, own_params = make("HeartPole-v0", max_steps=40, **cleo.values())
    key = jax.random.key(5)
    obs, state = env.reset(key, params)
    own_obs, own_state = own.reset(key, own_params)
    np.testing.assert_array_equal(obs, own_obs)
    step, own_step = jax.jit(env.step_env), jax.jit(own.step_env)
    for t, step_key in enumerate(jax.random.split(jax.random.key(6), 40)):
        action = (0, 1, 2, SLEEP)[t % 4]
        obs, state, reward, _, info = step(step_key, state, action, params)
        own_obs, own_state, own_reward, _, own_info = own_step(step_key, own_state, action, own_params)
        np.testing.assert_array_equal(obs, own_obs)
        assert float(reward) == float(own_reward) and bool(info["heart_attack"]) == bool(own_info["heart_attack"])
        assert int(info["person"]) == 0
        np.testing.assert_array_equal(info["traits"], np.float32([0.75, 0.95, 19, 0.55, 1.35]))


def test_a_distributions_person_runs_on_their_params_in_float32() -> None:
    """A distribution's person: the params equal an env's made with the drawn values (float32 arithmetic in
    JAX: within relative 2e-6), with the fixed field fixed and the task's numbers the env's."""
    people = People(decay_rate=0.95, sleep_half_hours=Uniform(10, 20), wake_alertness=Uniform((0.5, 1.1), (0.8, 1.5)))
    env, params = make("HeartPole-v0", people=people, heart_attack_penalty=50.0)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(0), 16), params)
    assert np.all(np.asarray(states.person) == -1)
    for i in range(16):
        state = jax.tree_util.tree_map(lambda x, i=i: x[i], states)
        decay, sleep, low, high = np.asarray(state.person_values, dtype=np.float64)
        assert decay == np.float32(0.95) and sleep == int(sleep) and 10 <= sleep <= 20
        own = Params(
            decay_rate=0.95, sleep_half_hours=int(sleep), wake_alertness=(low, high), heart_attack_penalty=50.0
        )
        expected = EnvParams.from_dynamics(Dynamics(params=own))
        mine = env.person_params(state, params)
        for a, b in zip(jax.tree_util.tree_leaves(mine), jax.tree_util.tree_leaves(expected)):
            # rest_fade: the float32 decay rate (relative error 6e-8) to a power up to 20, so within 2e-6
            np.testing.assert_allclose(a, b, rtol=2e-6, atol=0)


# ------------------------------------------------------------------------------------------------------
# the draws


def test_each_episode_draws_its_person_with_equal_chances() -> None:
    """48,000 resets and 48,000 autoresets of the default cohort (24 people): the counts pass a chi-square
    test of equal chances at level 1e-4, and an env's consecutive episodes share their person 1 time in 24
    (within 4.5 standard errors), as independent draws do."""
    env, params = make("HeartPole-v0", people="default", max_steps=1)  # every step starts a new episode
    n, people = 2000, 24
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(jax.random.split(jax.random.key(0), 24 * n), params)
    assert chi2_equal_chances(np.asarray(states.person), people) < chi2_limit(people - 1)

    step = jax.vmap(env.step, in_axes=(0, 0, None, None))

    def body(states, key):
        _, states, _, _, truncated, info = step(jax.random.split(key, n), states, 0, params)
        return states, (states.person, info["person"], truncated)

    first = jax.tree_util.tree_map(lambda x: x[:n], states)
    _, (new, ended, truncated) = jax.jit(lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.key(1), 24)))(
        first
    )
    new, ended = np.asarray(new), np.asarray(ended)
    assert np.asarray(truncated).all()
    assert chi2_equal_chances(new.ravel(), people) < chi2_limit(people - 1)
    np.testing.assert_array_equal(ended[1:], new[:-1])  # info names the ended episode's person
    np.testing.assert_array_equal(ended[0], np.asarray(first.person))
    same = (new[1:] == new[:-1]).mean()
    se = math.sqrt((1 / people) * (1 - 1 / people) / new[1:].size)
    assert abs(same - 1 / people) <= TOLERANCE_SE * se, same


def test_a_distribution_draws_each_field_uniformly() -> None:
    """20,000 draws: the integer field's 11 values pass a chi-square test of equal chances (level 1e-4);
    each float column's mean is its range's middle within 4.5 standard errors, its values inside the range."""
    people = People(heart_attack_proclivity=Uniform(0.3, 0.7), sleep_half_hours=Uniform(10, 20))
    env, params = make("HeartPole-v0", people=people)
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(jax.random.split(jax.random.key(3), 20_000), params)
    proclivity, sleep = np.asarray(states.person_values, dtype=np.float64).T
    assert chi2_equal_chances(sleep.astype(np.int64) - 10, 11) < chi2_limit(10)
    assert 0.3 <= proclivity.min() and proclivity.max() <= 0.7
    assert abs(proclivity.mean() - 0.5) <= TOLERANCE_SE * 0.4 / math.sqrt(12 * proclivity.size)


# ------------------------------------------------------------------------------------------------------
# per-env dynamics


def test_vmapped_params_give_each_env_its_own_dynamics() -> None:
    """gymnax's way: params_for(sample) is a batch of EnvParams; vmap(step, in_axes=(0, 0, 0, 0)) sleeps each
    env its own person's half-hours, and keeps the given task numbers."""
    people = People(cohort=[Person("short", sleep_half_hours=6), Person("long", sleep_half_hours=20)])
    sample = people.sample(np.random.default_rng(0), 64)
    env, params = make("HeartPole-v0", heart_attack_penalty=7.0)
    batch = env.params_for(sample)
    assert batch.rest.shape == (64, 4) and batch.max_steps_in_episode.shape == (64,)
    np.testing.assert_array_equal(batch.heart_attack_penalty, np.full(64, 7.0, np.float32))
    keys = jax.random.split(jax.random.key(0), 64)
    _, states = jax.vmap(env.reset)(keys, batch)
    obs, *_ = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, 0)))(keys, states, jnp.full(64, SLEEP), batch)
    expected = np.where(sample.person == 0, 6, 20) + 1  # asleep, then a half-hour of work
    np.testing.assert_array_equal(np.asarray(obs[:, TIME_ELAPSED]), expected)
    assert set(sample.person.tolist()) == {0, 1}


def test_envs_with_people_each_sleep_their_own_persons_half_hours() -> None:
    env, params = make("HeartPole-v0", people="default")
    keys = jax.random.split(jax.random.key(1), 256)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    obs, states, *_ = jax.jit(jax.vmap(env.step, in_axes=(0, 0, None, None)))(keys, states, SLEEP, params)
    sleep = cohort_values(People.default())[np.asarray(states.person), 2]
    np.testing.assert_array_equal(np.asarray(obs[:, TIME_ELAPSED]), sleep + 1)
    assert len(set(sleep.tolist())) > 5


# ------------------------------------------------------------------------------------------------------
# equal in distribution to the NumPy model, person by person


def rule(obs, xp):
    """Sleep after 30 half-hours awake, coffee when sleepy and calm, a beer now and then: all v0 actions."""
    coffee = xp.where((obs[:, ALERTNESS] < 1.0) & (obs[:, HYPERTENSION] < 1.0), 1, 0)
    beer = xp.where(obs[:, INTOXICATION] < 0.05, 2, coffee)
    return xp.where(obs[:, TIME_SINCE_SLEPT] > 30, 3, beer).astype(xp.int32)


def jax_figures(env: HeartPoleJax, params: EnvParams, episodes: int, steps: int):
    """Per episode: its person, expected-risk return (final score - penalty x summed risk), final score and
    half-hours elapsed (sleep included)."""

    def one_episode(key):
        reset_key, key = jax.random.split(key)
        obs, state = env.reset(reset_key, params)

        def body(carry, step_key):
            obs, state = carry
            obs, state, _, _, _, info = env.step(step_key, state, rule(obs[None], jnp)[0], params)
            return (obs, state), (info["heart_attack_risk"], info["score"], info["final_observation"], info["person"])

        _, (risks, scores, final, person) = jax.lax.scan(body, (obs, state), jax.random.split(key, steps))
        penalty = params.heart_attack_penalty
        return person[-1], scores[-1] - penalty * risks.sum(), scores[-1], final[-1, TIME_ELAPSED]

    out = jax.jit(jax.vmap(one_episode))(jax.random.split(jax.random.key(11), episodes))
    return [np.asarray(x, dtype=np.float64) for x in out]


def numpy_figures(person: Person, episodes: int, steps: int):
    with heartpole.policies.quiet_version_warnings():
        envs = gym.make_vec("HeartPole-v0", num_envs=episodes, vectorization_mode="vector_entry_point",
                            max_steps=steps, **person.values())  # fmt: skip
    obs, _ = envs.reset(seed=11)
    risks = np.zeros(episodes)
    for _ in range(steps):
        obs, _, _, _, info = envs.step(rule(obs, np).astype(np.int64))
        risks += info["heart_attack_risk"]
    envs.close()
    score = np.asarray(info["score"], dtype=np.float64)
    return score - 100.0 * risks, score


@pytest.mark.slow  # about 10 s
def test_equal_in_distribution_to_the_numpy_model_person_by_person() -> None:
    """Two people of the default cohort (Cleo: proclivity 0.75, 9.5 hours' sleep; Eli: 0.45, 6.5 hours),
    4,000 JAX episodes of 300 decisions against 2,000 NumPy episodes per person made with that person's
    values: each person's expected-risk return and final score agree within 4.5 standard errors, and the
    JAX episodes' half-hours elapsed are 300 plus whole sleeps of the person's length."""
    default = People.default()
    cleo, eli = default.cohort[2], default.cohort[4]
    steps = 300
    env, params = make("HeartPole-v0", people=People(cohort=[cleo, eli]), max_steps=steps)
    person, expected_return, score, elapsed = jax_figures(env, params, 4000, steps)
    assert abs((person == 0).mean() - 0.5) <= TOLERANCE_SE * 0.5 / math.sqrt(person.size)
    for index, member in enumerate((cleo, eli)):
        mine = person == index
        sleeps = (elapsed[mine] - steps) / member.values()["sleep_half_hours"]
        np.testing.assert_array_equal(sleeps, np.round(sleeps))
        assert sleeps.mean() > 3
        numpy_return, numpy_score = numpy_figures(member, 2000, steps)
        for name, a, b in (("expected-risk return", expected_return[mine], numpy_return),
                           ("score", score[mine], numpy_score)):  # fmt: skip
            se = math.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
            assert abs(a.mean() - b.mean()) <= TOLERANCE_SE * se, f"{member.name} {name}: {a.mean()} vs {b.mean()}"


# ------------------------------------------------------------------------------------------------------
# observing the traits, and bad input


def test_observe_traits_appends_them_to_the_observation_and_its_space() -> None:
    people = People(heart_attack_proclivity=Uniform(0.3, 0.7), decay_rate=0.95, sleep_half_hours=Uniform(12, 20))
    blind, params = make("HeartPole-v0", people=people)
    seeing, _ = make("HeartPole-v0", people=people, observe_traits=True)
    assert blind.observation_space(params).shape == (6,) and people.traits == ("heart_attack_proclivity",
                                                                                "sleep_half_hours")  # fmt: skip
    space = seeing.observation_space(params)
    assert space.shape == (8,) and space.dtype == jnp.float32
    np.testing.assert_array_equal(space.low[6:], np.float32([0.3, 12]))
    np.testing.assert_array_equal(space.high[6:], np.float32([0.7, 20]))
    np.testing.assert_array_equal(space.low[:6], blind.observation_space(params).low)
    obs, state = seeing.reset(jax.random.key(0), params)
    assert obs.shape == (8,) and bool(space.contains(obs))
    np.testing.assert_array_equal(obs[6:], state.person_values[jnp.array([0, 2])])
    obs, state, _, _, _, info = jax.jit(seeing.step)(jax.random.key(1), state, 0, params)
    np.testing.assert_array_equal(obs[6:], info["traits"])
    np.testing.assert_array_equal(obs[:6], state.variables)
    assert int(info["person"]) == -1
    cohort, cohort_params = make("HeartPole-v0", people="default", observe_traits=True)
    assert cohort.observation_space(cohort_params).shape == (11,)
    plain, plain_params = make("HeartPole-v0")
    obs, plain_state = plain.reset(jax.random.key(0), plain_params)
    assert obs.shape == (6,) and "person" not in plain.step(jax.random.key(1), plain_state, 0, plain_params)[-1]


def test_bad_input_is_refused_with_what_is_accepted() -> None:
    with pytest.raises(ValueError, match="observe_traits=True needs a population"):
        make("HeartPole-v0", observe_traits=True)
    with pytest.raises(TypeError, match="observe_traits must be True or False"):  # as the NumPy envs say
        make("HeartPole-v0", people="default", observe_traits="yes")
    make("HeartPole-v0", people="default", observe_traits=np.True_)  # NumPy's bool is a bool, as there
    with pytest.raises(ValueError, match=r"unknown population 'everyone'.*\['default'\]"):
        make("HeartPole-v0", people="everyone")
    with pytest.raises(TypeError, match="people must be a People"):
        make("HeartPole-v0", people=3)
    with pytest.raises(TypeError, match="params_for\\(\\) takes a heartpole.people.Sample"):
        make("HeartPole-v0")[0].params_for(np.zeros((2, 1)))
    with pytest.raises(TypeError, match="unexpected keyword argument 'persons'"):
        make("HeartPole-v0", persons="default")


# ------------------------------------------------------------------------------------------------------
# training on people


@pytest.mark.slow  # compiles PPO twice, about 30 s
@pytest.mark.parametrize("observe_traits", [False, True])
def test_jax_ppo_trains_on_people(observe_traits: bool) -> None:
    """A short PPO run (2 updates of 8 envs x 128 steps) on the default people, trait-blind and seeing."""
    from heartpole import training
    from heartpole.jax import ppo

    config = training.preset_config("default", timesteps=2048, n_envs=8)
    env = HeartPoleJax.from_id("HeartPole-v0", max_steps=64, people="default", observe_traits=observe_traits)
    runner, ended = jax.jit(ppo.make_train(env, env.default_params, ppo.PPOSettings.from_config(config)))(
        jax.random.key(0)
    )
    assert runner.obs.shape == (8, 11 if observe_traits else 6)
    done = np.asarray(ended[0])
    assert done.sum() == 2 * 128 * 8 // 64 and np.isfinite(np.asarray(ended[1])[done]).all()
    assert len(set(np.asarray(runner.env_state.person).tolist())) > 1


def test_any_variant_takes_people() -> None:
    """HeartPole-v1 (seven variables, eight actions, THC fading at its own rate): each person's params equal
    those of v1 made with their values."""
    people = People.default()
    env, params = make("HeartPole-v1", people=people)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(2), 8), params)
    for i in range(8):
        state = jax.tree_util.tree_map(lambda x, i=i: x[i], states)
        own = make("HeartPole-v1", **people.cohort[int(state.person)].values())[1]
        assert leaves_equal(env.person_params(state, params), own)
    obs, *_ = jax.vmap(env.step, in_axes=(0, 0, None, None))(jax.random.split(jax.random.key(3), 8), states, 7, params)
    assert obs.shape == (8, 7)
