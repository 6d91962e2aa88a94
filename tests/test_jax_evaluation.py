"""heartpole.jax.evaluate and the one random-number definition: the same seed plays the same episodes on numba
and on JAX, and the device's evaluation gives heartpole.evaluate's table."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

jax = pytest.importorskip("jax", reason="heartpole.jax needs the 'jax' extra: pip install 'heartpole[jax]'")
import jax.numpy as jnp  # noqa: E402

import heartpole  # noqa: E402
from heartpole import kernel, rng  # noqa: E402
from heartpole.evaluation import Comparison  # noqa: E402
from heartpole.jax import RNG, evaluate, evaluate_batch, make  # noqa: E402
from heartpole.model import ALERTNESS, INTOXICATION  # noqa: E402

COLUMNS = ("mean_return", "expected_return", "heart_attacks_per_episode", "score", "drinks_per_episode",
           "sleeps_per_episode", "regret", "optimal_return")  # fmt: skip


def same_episodes(a: heartpole.EvaluationResult, b: heartpole.EvaluationResult) -> float:
    """The share of episodes in which both played alike: the same heart attacks, drinks and sleeps, final scores
    equal to float32 rounding (1e-5 relative)."""
    scores = np.abs(a.scores - b.scores) <= 1e-5 * np.maximum(1.0, np.abs(a.scores))
    alike = (a.heart_attacks == b.heart_attacks) & (a.drinks == b.drinks) & (a.sleeps == b.sleeps) & scores
    return float(alike.mean())


def test_every_backend_draws_the_same_uniforms_bit_for_bit() -> None:
    """heartpole.rng on NumPy, compiled by numba (the envs' kernel) and traced by JAX: 64 keys x 3 counters (the
    last about to wrap) x a step's 8 uniforms, equal to the bit."""
    states = rng.generator_states(np.random.default_rng(11), 64)
    low, high = states[rng.KEY_LOW], states[rng.KEY_HIGH]
    zeros = (np.float32(0.0),) * 6
    for counter in (0, 977, 2**32 - 1):
        numpy = np.array([rng.draws(low[i], high[i], counter, zeros) for i in range(64)], dtype=np.float32)
        numba = np.array(
            [[kernel.uniform(low[i], high[i], np.uint32(counter), j) for j in range(8)] for i in range(64)]
        )
        numba[:, 3:6] = 0.0  # the draws the step keeps no use for (time and work) are 0 in draws
        traced = jax.jit(jax.vmap(lambda lo, hi, c: jnp.stack(RNG.draws(lo, hi, c, (jnp.float32(0),) * 6))))
        device = np.asarray(traced(jnp.asarray(low), jnp.asarray(high), jnp.full(64, counter, jnp.uint32)))
        np.testing.assert_array_equal(numpy, numba)
        np.testing.assert_array_equal(numpy, device)
        assert numpy.dtype == device.dtype == np.float32 and numpy.max() < 1.0


def test_a_gymnax_step_takes_its_randomness_from_its_key() -> None:
    """gymnax's contract: the same state and key give the same future, another key another one."""
    env, params = make("HeartPole-v0")
    _, state = env.reset(jax.random.key(0), params)
    step = jax.jit(env.step)
    a = step(jax.random.key(1), state, 1, params)
    b = step(jax.random.key(1), state, 1, params)
    c = step(jax.random.key(2), state, 1, params)
    np.testing.assert_array_equal(a[0], b[0])
    assert not np.array_equal(a[0], c[0])


def test_a_step_s_generator_key_is_its_key_s_own_bits() -> None:
    """A threefry key's data is the step's generator key (no threefry call of the step's own), a raw
    ``uint32[2]`` key's the same; a key of another implementation (rbg, four words) is drawn from once, and
    steps as well."""
    from heartpole.jax.traced import key_draw

    typed, raw = jax.random.key(7), jax.random.PRNGKey(7)
    words = [int(x) for x in jax.random.key_data(typed)]
    assert [int(x) for x in key_draw(typed)] == words == [int(x) for x in key_draw(raw)]
    env, params = make("HeartPole-v0")
    obs_typed, _ = env.reset(typed, params)
    np.testing.assert_array_equal(obs_typed, env.reset(raw, params)[0])
    rbg = jax.random.key(7, impl="rbg")
    assert key_draw(rbg)[0].dtype == jnp.uint32
    obs, state = env.reset(rbg, params)
    assert np.all(np.isfinite(np.asarray(env.step(rbg, state, 1, params)[0])))


@pytest.mark.parametrize(("policy", "env_kwargs"), [("expert", {}), ("optimal", {}), ("reference", {"max_steps": 100})])
def test_the_same_seed_plays_the_same_episodes_and_gives_the_same_table(policy, env_kwargs) -> None:
    """2,000 evaluation episodes on numba and on JAX: at least 99.9% identical (float32 rounding of ``exp`` may
    move a coin or a threshold in a few), and every column of the table within 1e-4."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        numpy = heartpole.evaluate(policy, episodes=2000, seed=3, env_kwargs=env_kwargs)
    device = evaluate(policy, episodes=2000, seed=3, env_kwargs=env_kwargs)
    assert same_episodes(numpy, device) >= 0.999
    for column in COLUMNS:
        mine, theirs = getattr(numpy, column), getattr(device, column)
        assert abs(mine - theirs) <= 1e-4 or (np.isnan(mine) and np.isnan(theirs)), (column, mine, theirs)
    assert numpy.to_dict().keys() == device.to_dict().keys()
    assert (numpy.policy, numpy.episodes, numpy.seed, numpy.num_envs) == (
        device.policy,
        device.episodes,
        device.seed,
        device.num_envs,
    )


def test_compare_pairs_a_jax_result_with_a_numpy_one_on_common_random_numbers() -> None:
    """A JAX evaluation pairs with a NumPy one of the same seed as two NumPy ones do: the paired interval of
    expert - nothing is as tight either way, and the differences agree."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        numpy_pair = heartpole.compare("expert", "nothing", episodes=500, env_kwargs={"max_steps": 100})
    mixed = Comparison.of(evaluate("expert", episodes=500, env_kwargs={"max_steps": 100}, regret=False), numpy_pair.b)
    assert abs(mixed.expected_difference - numpy_pair.expected_difference) < 1e-4
    width = lambda ci: ci[1] - ci[0]  # noqa: E731
    assert width(mixed.expected_ci95) < 1.5 * width(numpy_pair.expected_ci95)


@pytest.mark.slow  # five compiled rollouts: about 5-10 s
def test_a_batch_of_policies_is_each_evaluated_on_the_same_episodes() -> None:
    """evaluate_batch over four thresholds equals evaluate of each threshold on its own."""
    thresholds = jnp.asarray([0.2, 0.3, 0.33, 0.4], jnp.float32)
    _, params = make("HeartPole-v0")

    def policy(rate, obs):
        coming = heartpole.jax.MODEL.productivity(obs[:, ALERTNESS], obs[:, INTOXICATION])
        return jnp.where(coming < rate, 3, 0)

    kwargs = {"episodes": 200, "env_kwargs": {"max_steps": 200}}
    results = evaluate_batch(policy, thresholds, **kwargs)
    assert [r.policy for r in results] == [f"policy[{i}]" for i in range(4)]
    for i, result in enumerate(results):
        alone = evaluate(lambda obs, rate=thresholds[i]: policy(rate, obs), **kwargs)
        np.testing.assert_array_equal(result.expected_returns, alone.expected_returns)
    assert results[2].expected_return > results[0].expected_return


def test_evaluate_refuses_what_it_cannot_play() -> None:
    from heartpole.measurement import Measurement

    with pytest.raises(ValueError, match="measurement"):
        evaluate("expert", episodes=2, env_kwargs={"measurement": Measurement({"alertness": 0.1})})
    with pytest.raises(ValueError, match="unknown policy 'nosuch'"):
        evaluate("nosuch", episodes=2)
    with pytest.raises(ValueError, match="episodes must be an integer >= 1"):
        evaluate("expert", episodes=0)


# ------------------------------------------------------------------------------------------------------
# invalid actions and options (issue 35's A12 and B18)


@pytest.mark.parametrize("action", [4, 7, -1])
def test_a_concrete_invalid_action_is_refused_as_the_numpy_envs_refuse_it(action) -> None:
    env, params = make("HeartPole-v0")
    _, state = env.reset(jax.random.key(0), params)
    with pytest.raises(ValueError, match=r"invalid HeartPole action .*valid actions: 0 \(do_nothing\)"):
        env.step(jax.random.key(1), state, action, params)
    with pytest.raises(ValueError, match="invalid HeartPole action"):
        env.step(jax.random.key(1), state, jnp.int32(action), params)


@pytest.mark.parametrize("action", [1.5, True, np.float32(1.0)])
def test_a_non_integer_action_is_a_type_error_even_under_jit(action) -> None:
    env, params = make("HeartPole-v0")
    _, state = env.reset(jax.random.key(0), params)
    with pytest.raises(TypeError, match="actions are integers in 0..3"):
        env.step(jax.random.key(1), state, action, params)
    with pytest.raises(TypeError, match="actions are integers"):
        jax.jit(env.step)(jax.random.key(1), state, jnp.asarray(action), params)


def test_under_jit_an_invalid_action_changes_nothing_and_says_so() -> None:
    env, params = make("HeartPole-v0")
    _, state = env.reset(jax.random.key(0), params)
    step = jax.jit(env.step)
    _, new, reward, _, _, info = step(jax.random.key(1), state, jnp.int32(9), params)
    assert bool(info["invalid_action"]) and float(reward) == 0.0 and not bool(info["heart_attack"])
    assert int(new.time) == int(state.time)
    np.testing.assert_array_equal(jnp.stack(new.variables), jnp.stack(state.variables))
    _, _, _, _, _, info = step(jax.random.key(1), state, jnp.int32(3), params)
    assert not bool(info["invalid_action"])


def test_a_render_mode_is_refused() -> None:
    with pytest.raises(ValueError, match="do not render"):
        make("HeartPole-v0", render_mode="human")
    env, _ = make("HeartPole-v0", render_mode=None)
    assert env.num_actions == 4


# ------------------------------------------------------------------------------------------------------
# refusals: what heartpole.evaluate refuses, in its words


def _at_step(step: int, action: object) -> object:
    """A policy that does nothing until ``step`` decisions are left, then plays ``action`` (a NumPy value)."""

    def policy(obs: object, left: object) -> object:
        n = obs.shape[0]  # type: ignore[attr-defined]
        return jnp.where(jnp.asarray(left) > step, jnp.zeros(n, jnp.int32), jnp.full(n, action, jnp.int32))

    policy.needs_decisions_left = True  # type: ignore[attr-defined]
    return policy


INVALID = {
    "seven": lambda obs: np.full(obs.shape[0], 7),
    "minus one": lambda obs: np.full(obs.shape[0], -1),
    "uint8 255": lambda obs: np.full(obs.shape[0], 255, dtype=np.uint8),
    "floats": lambda obs: np.full(obs.shape[0], 1.0),
    "a list of floats": lambda obs: [1.0] * obs.shape[0],
    "bools": lambda obs: np.zeros(obs.shape[0], dtype=bool),
    "a column": lambda obs: np.zeros((obs.shape[0], 1), dtype=np.int64),
    "too few": lambda obs: np.zeros(obs.shape[0] - 1, dtype=np.int64),
    "7 late in the episode": _at_step(3, 7),
}


@pytest.mark.parametrize("name", list(INVALID))
def test_invalid_actions_are_refused_with_numpys_message(name: str) -> None:
    policy = INVALID[name]
    options = {"episodes": 6, "seed": 2, "env_kwargs": {"max_steps": 8}, "regret": False}
    with pytest.raises(ValueError) as numpy:
        heartpole.evaluate(policy, **options)
    with pytest.raises(ValueError) as device:
        evaluate(policy, **options)
    assert str(device.value) == str(numpy.value)
    assert "expected 6 integer actions in 0..3" in str(device.value)


def test_invalid_actions_of_a_batch_are_refused() -> None:
    weights = jnp.asarray([0, 9], dtype=jnp.int32)
    with pytest.raises(ValueError, match=r"returned actions 9\.\.9; expected 4 integer actions in 0\.\.3"):
        evaluate_batch(lambda w, obs: jnp.full(obs.shape[0], w), weights, episodes=4, env_kwargs={"max_steps": 5})


@pytest.mark.parametrize("seed", [-1, True, 1.0, "0", 2**63, 2**64, 10**30, np.uint64(2**64 - 1)])
def test_seeds_are_refused_and_accepted_as_numpys(seed: object) -> None:
    options = {"episodes": 2, "env_kwargs": {"max_steps": 4}, "regret": False}
    try:
        expected = heartpole.evaluate("random", seed=seed, **options)
    except ValueError as error:
        with pytest.raises(ValueError) as device:
            evaluate("random", seed=seed, **options)
        assert str(device.value) == str(error)
    else:
        assert evaluate("random", seed=seed, **options).seed == expected.seed


# ------------------------------------------------------------------------------------------------------
# the summed risk, as exact as float64's (issue 42, item 5)


@pytest.mark.parametrize("env_kwargs", [{}, {"people": "default"}])
def test_expected_risk_return_is_exact_where_blood_pressure_stays_0(env_kwargs: dict) -> None:
    """``expert`` never drinks: the expected-risk return is ``score - 100 * max_steps * proclivity * sigmoid(-6)``
    to 1e-7 (Kahan-summed float32 risks put it 2.3e-6 above, on v0), the episodes' proclivities their people's."""
    from heartpole.people import People

    result = evaluate("expert", episodes=4, seed=0, env_kwargs=env_kwargs, regret=False)
    assert result.drinks_per_episode == 0
    members = [np.float32(m.values().get("heart_attack_proclivity", 0.5)) for m in People.resolve("default").cohort]
    proclivity = np.array([0.5 if i < 0 else float(members[i]) for i in result.person])
    exact = result.scores - 100.0 * result.max_steps * proclivity / (1.0 + np.exp(6.0))
    assert np.max(np.abs(result.expected_returns - exact)) < 1e-7


def test_exact_sigmoid_is_float64s_to_2e_12() -> None:
    """``exact_sigmoid``'s float32 pair is ``sigmoid(h - 6)`` computed in float64 of the float32 pressure ``h``, on
    the table's grid, between its points, at its ends and beyond them."""
    from heartpole.jax.evaluation import exact_sigmoid, sigmoid_table

    generator = np.random.default_rng(3)
    pressure = np.concatenate([
        generator.uniform(0.0, 12.0, 20_000), generator.uniform(-45.0, 45.0, 5_000),
        [0.0, 1e-30, 6.0, 1 / 512, -1 / 512, 40.0, -40.0, 40.001, -40.001, 100.0, -100.0, 39.998],
    ]).astype(np.float32)  # fmt: skip
    high, low = jax.jit(exact_sigmoid)(jnp.asarray(pressure), jnp.asarray(sigmoid_table()))
    found = np.asarray(high, np.float64) + np.asarray(low, np.float64)
    exact = 1.0 / (1.0 + np.exp(6.0 - pressure.astype(np.float64)))
    np.testing.assert_allclose(found, exact, rtol=2e-12, atol=1e-18)  # below 1e-18: float32 pressures under -35


@pytest.mark.parametrize("env_kwargs", [{"max_steps": 300}, {"max_steps": 300, "people": "default"}])
def test_summed_risk_is_numpys_where_drinks_change_blood_pressure(env_kwargs: dict) -> None:
    """With drinks (``reference``) the summed risks are NumPy's (each step's risk in float64 from its state) where
    both engines play the same episode: up to the float32 rounding of the states (``exp`` is each backend's)."""
    numpy = heartpole.evaluate("reference", episodes=8, seed=0, env_kwargs=env_kwargs, regret=False)
    found = evaluate("reference", episodes=8, seed=0, env_kwargs=env_kwargs, regret=False)
    assert numpy.drinks_per_episode >= 5 and same_episodes(numpy, found) == 1.0
    np.testing.assert_allclose(found.expected_heart_attacks, numpy.expected_heart_attacks, rtol=1e-9)
