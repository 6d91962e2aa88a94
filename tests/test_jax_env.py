"""heartpole.jax: the gymnax API contract, jit/vmap, and equality in distribution with the NumPy env."""

from __future__ import annotations

import ast
import inspect
import math
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

jax = pytest.importorskip("jax", reason="heartpole.jax needs the 'jax' extra: pip install 'heartpole[jax]'")
import jax.numpy as jnp  # noqa: E402

import heartpole  # noqa: E402
from heartpole import model  # noqa: E402
from heartpole.jax import EnvParams, EnvState, HeartPoleJax, make  # noqa: E402
from heartpole.model import ALERTNESS, HYPERTENSION, INTOXICATION, TIME_ELAPSED, TIME_SINCE_SLEPT  # noqa: E402


def rollout(env: HeartPoleJax, params: EnvParams, policy, key: jax.Array, episodes: int, steps: int):
    """``episodes`` episodes of ``steps`` decisions, vmapped and scanned: the per-episode sums of the
    reward, heart attacks and heart-attack risk, and the final score."""

    def one_episode(key: jax.Array):
        key, reset_key = jax.random.split(key)
        obs, state = env.reset(reset_key, params)

        def body(carry, step_key):
            obs, state = carry
            obs, state, reward, _, _, info = env.step(step_key, state, policy(obs[None], jnp)[0], params)
            return (obs, state), (reward, info["heart_attack"], info["heart_attack_risk"], info["score"])

        _, (rewards, attacks, risks, scores) = jax.lax.scan(body, (obs, state), jax.random.split(key, steps))
        return rewards.sum(), attacks.sum(), risks.sum(), scores[-1]

    out = jax.jit(jax.vmap(one_episode))(jax.random.split(key, episodes))
    return [np.asarray(x, dtype=np.float64) for x in out]


def numpy_rollout(env_id: str, policy, seed: int, episodes: int, **env_kwargs):
    """The same per-episode figures from the NumPy vector env (all its episodes end together)."""
    with heartpole.policies.quiet_version_warnings():
        envs = gym.make_vec(env_id, num_envs=episodes, vectorization_mode="vector_entry_point", **env_kwargs)
    steps = envs.unwrapped.max_steps
    obs, _ = envs.reset(seed=seed)
    totals = np.zeros((3, episodes))
    for _ in range(steps):
        obs, reward, _, _, info = envs.step(policy(obs, np).astype(np.int64))
        totals += (reward, info["heart_attack"], info["heart_attack_risk"])
    envs.close()
    return [*totals, np.asarray(info["score"], dtype=np.float64)]


# Policies written once for both backends (xp is numpy or jax.numpy), functions of the observation only.
def do_nothing(obs, xp):
    return xp.zeros(obs.shape[0], dtype=xp.int32)


def rule(obs, xp):
    """Sleep after 30 half-hours awake, coffee when sleepy and calm, a beer now and then: all v0 actions."""
    coffee = xp.where((obs[:, ALERTNESS] < 1.0) & (obs[:, HYPERTENSION] < 1.0), 1, 0)
    beer = xp.where(obs[:, INTOXICATION] < 0.05, 2, coffee)
    return xp.where(obs[:, TIME_SINCE_SLEPT] > 30, 3, beer).astype(xp.int32)


def cycle(obs, xp):
    """Every action in turn, by the half-hours elapsed (for variants with any number of actions)."""
    return (xp.floor(obs[:, TIME_ELAPSED]).astype(xp.int32) % obs.shape[1]).astype(xp.int32)


# ------------------------------------------------------------------------------------------------------
# packaging and the one-source rule


def test_import_heartpole_does_not_import_jax() -> None:
    code = "import sys, heartpole, heartpole.evaluation; print('jax' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout == "False\n"


def test_without_jax_one_clear_error() -> None:
    code = "import sys; sys.modules['jax'] = None\nimport heartpole.jax"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode != 0
    assert "heartpole.jax needs JAX: pip install 'heartpole[jax]'" in result.stderr.strip().splitlines()[-1]


def test_the_dynamics_live_in_model_step_only() -> None:
    """The JAX env runs model's own code objects; its modules hold none of the formulas' constants."""
    from heartpole.jax import MODEL, ppo, spaces, traced
    from heartpole.jax import env as jax_env

    for name in model.FUNCTIONS:
        assert getattr(MODEL, name).__code__.co_code == getattr(model, name).__code__.co_code
    formula_constants = {0.135, 0.005, 0.05, 40.0, 50.0, 0.97, 6.0, 100.0}
    for module in (jax_env, spaces, ppo, traced):
        numbers = {node.value for node in ast.walk(ast.parse(inspect.getsource(module)))
                   if isinstance(node, ast.Constant) and type(node.value) in (int, float)}  # fmt: skip
        assert not numbers & formula_constants, f"{module.__name__} holds {numbers & formula_constants}"


# ------------------------------------------------------------------------------------------------------
# the gymnax API contract


def test_reset_and_step_shapes_dtypes_and_spaces() -> None:
    env, params = make("HeartPole-v0")
    assert env.num_actions == 4 and env.action_space(params).n == 4 and env.name == "HeartPole"
    space = env.observation_space(params)
    assert space.shape == (6,) and space.dtype == jnp.float32
    obs, state = env.reset(jax.random.key(0), params)
    assert isinstance(state, EnvState) and obs.shape == (6,) and obs.dtype == jnp.float32
    assert bool(space.contains(obs)) and 0.7 <= float(obs[ALERTNESS]) <= 1.3 and not obs[1:].any()
    action = env.action_space(params).sample(jax.random.key(1))
    assert action.dtype == jnp.int32 and bool(env.action_space(params).contains(action))
    obs, state, reward, terminated, truncated, info = jax.jit(env.step)(jax.random.key(2), state, action, params)
    assert obs.shape == (6,) and obs.dtype == reward.dtype == jnp.float32 and reward.shape == ()
    assert terminated.dtype == truncated.dtype == jnp.bool_ and not bool(terminated | truncated)
    assert int(state.time) == 1 and bool(space.contains(obs))
    expected = {"truncated", "terminated", "discount", "final_observation", "heart_attack", "heart_attack_risk"}
    assert set(info) >= expected | {"productivity", "score"}
    assert info["heart_attack_risk"].dtype == info["score"].dtype == info["productivity"].dtype == jnp.float32
    np.testing.assert_array_equal(env.get_obs(state), jnp.stack(state.variables))
    stepped = env.step_env(jax.random.key(3), state, 0, params)
    assert len(stepped) == 5 and int(stepped[1].time) == 2 and not bool(stepped[3])
    np.testing.assert_array_equal(env.observe(jax.random.key(4), stepped[1], 0, params), stepped[0])


def test_default_params_equal_the_dynamics() -> None:
    env = HeartPoleJax()
    dynamics = heartpole.Dynamics()
    np.testing.assert_array_equal(env.default_params.effect_low, np.array([e.effect_low for e in dynamics.effects]))
    assert int(env.default_params.max_steps_in_episode) == 1000
    assert all(leaf.dtype in (jnp.float32, jnp.int32) for leaf in jax.tree_util.tree_leaves(env.default_params))


def test_params_are_the_models_tables_by_name() -> None:
    """EnvParams is derived from the model's ActionEffects and StepTables: every number of either, by name,
    equal to the Dynamics'; the Shape fields stay with the env (static under jit)."""
    dynamics = heartpole.Dynamics(heartpole.V1_ACTIONS, variables=heartpole.V1_VARIABLES)
    params = HeartPoleJax(dynamics).default_params
    for name in model.ActionEffects._fields:
        np.testing.assert_array_equal(getattr(params, name), np.array([getattr(e, name) for e in dynamics.effects]))
    shape = model.table_fields(model.StepTables).shape
    for name in model.StepTables._fields:
        if name in shape:
            assert getattr(params.tables, name) == ()
        else:
            np.testing.assert_array_equal(getattr(params, name), np.asarray(getattr(dynamics.tables, name)))
    changed = params.replace(heart_attack_penalty=jnp.float32(5.0), max_steps_in_episode=jnp.int32(3))
    assert float(changed.heart_attack_penalty) == 5.0 and int(changed.max_steps_in_episode) == 3
    assert float(params.heart_attack_penalty) == 100.0
    with pytest.raises(TypeError, match=r"unknown field\(s\) \['penalty'\]"):
        params.replace(penalty=1.0)
    with pytest.raises(AttributeError, match="EnvParams has no field 'penalty'"):
        params.penalty  # noqa: B018


def test_truncation_at_the_limit_and_autoreset() -> None:
    env, params = make("HeartPole-v0", max_steps=5)
    obs, state = env.reset(jax.random.key(0), params)

    def body(carry, key):
        obs, state = carry
        obs, state, reward, terminated, truncated, info = env.step(key, state, 1, params)
        return (obs, state), (obs, state.time, terminated | truncated, info)

    _, (observations, times, done, info) = jax.lax.scan(body, (obs, state), jax.random.split(jax.random.key(1), 12))
    np.testing.assert_array_equal(done, [False] * 4 + [True] + [False] * 4 + [True] + [False] * 2)
    np.testing.assert_array_equal(info["truncated"], done)  # done is truncation only
    assert not info["terminated"].any() and (info["discount"] == 1.0).all()
    np.testing.assert_array_equal(times, [1, 2, 3, 4, 0, 1, 2, 3, 4, 0, 1, 2])
    # After the limit the observation is the new episode's; the episode's last one is in final_observation.
    assert (observations[done][:, 1:] == 0).all() and (info["final_observation"][done][:, TIME_ELAPSED] >= 5).all()
    np.testing.assert_allclose(
        info["final_observation"][~done], observations[~done], rtol=1e-6
    )  # XLA may fuse differently


def test_jit_and_vmap_over_keys_and_params() -> None:
    """A batch of parameters: proclivity 0 never has a heart attack; proclivity 1 (drinking coffee) has as many
    as its summed risks say, within 5 standard deviations (Poisson-binomial: sd <= sqrt(sum of risks))."""
    n = 512
    env, params = make("HeartPole-v0", max_steps=50)
    keys = jax.random.split(jax.random.key(0), n)
    obs, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    assert obs.shape == (n, 6) and len(set(np.asarray(obs[:, ALERTNESS]).tolist())) == n
    batch = jax.tree_util.tree_map(lambda x: jnp.stack([x] * n), params)
    proclivity = jnp.where(jnp.arange(n) < n // 2, 0.0, 1.0).astype(jnp.float32)
    batch = batch.replace(heart_attack_proclivity=proclivity)
    step = jax.jit(jax.vmap(env.step, in_axes=(0, 0, None, 0)))

    def body(carry, key):
        obs, states, attacks, risks = carry
        obs, states, _, _, _, info = step(jax.random.split(key, n), states, 1, batch)
        return (obs, states, attacks + info["heart_attack"], risks + info["heart_attack_risk"]), None

    start = (obs, states, jnp.zeros(n, jnp.int32), jnp.zeros(n, jnp.float32))
    (_, _, attacks, risks), _ = jax.lax.scan(body, start, jax.random.split(keys[0], 50))
    expected = float(risks[n // 2 :].sum())
    assert int(attacks[: n // 2].sum()) == 0 and expected > 100
    assert abs(int(attacks[n // 2 :].sum()) - expected) < 5 * math.sqrt(expected)


def test_v1_and_user_variants() -> None:
    env, params = make("HeartPole-v1", max_steps=20)
    assert env.num_actions == 8 and env.observation_space(params).shape == (7,)
    decaf = heartpole.Action("drink_decaf", {"alertness": (0.0, 0.05)})
    spec = heartpole.register_variant("JaxDecafPole-v0", actions=[*heartpole.V0_ACTIONS, decaf], replace=True,
                                      max_steps=7)  # fmt: skip
    try:
        env, params = make(spec.id)
    finally:
        gym.registry.pop(spec.id)
    assert env.num_actions == 5 and int(params.max_steps_in_episode) == 7
    obs, state = env.reset(jax.random.key(0), params)
    obs, state, *_ = env.step(jax.random.key(1), state, 4, params)
    assert 0.0 <= float(obs[ALERTNESS]) - float(jnp.float32(0)) and int(state.time) == 1
    direct = HeartPoleJax(heartpole.Dynamics(params=heartpole.Params(sleep_half_hours=8)))
    obs, state, *_ = direct.step(jax.random.key(0), direct.reset(jax.random.key(1))[1], 3)
    assert float(obs[TIME_ELAPSED]) == 9.0  # 8 half-hours asleep, then one of work


# ------------------------------------------------------------------------------------------------------
# equal in distribution to the NumPy env

TOLERANCE_SE = 4.5
"""Each figure's means may differ by at most this many standard errors of their difference. The test
makes 4 figures x 4 cases = 16 comparisons, so a false failure has probability below 16 x 7e-6 ~ 1e-4."""

CASES = [
    pytest.param("HeartPole-v0", do_nothing, id="v0-do_nothing", marks=pytest.mark.slow),
    pytest.param("HeartPole-v0", rule, id="v0-rule"),
    pytest.param("HeartPole-v0", cycle, id="v0-cycle", marks=pytest.mark.slow),
    pytest.param("HeartPole-v1", cycle, id="v1-cycle", marks=pytest.mark.slow),
]


@pytest.mark.parametrize(("env_id", "policy"), CASES)
def test_equal_in_distribution_to_the_numpy_env(env_id: str, policy) -> None:
    """Over 2,000 episodes of each backend: the return, the heart attacks, the expected-risk return
    (final score - penalty x summed risk: the same mean without the coin's noise) and the final score."""
    episodes = 2000
    env, params = make(env_id)
    rewards, attacks, risks, scores = rollout(env, params, policy, jax.random.key(7), episodes, 1000)
    n_rewards, n_attacks, n_risks, n_scores = numpy_rollout(env_id, policy, 7, episodes)
    penalty = float(params.heart_attack_penalty)
    figures = {
        "return": (rewards, n_rewards),
        "heart attacks": (attacks, n_attacks),
        "expected-risk return": (scores - penalty * risks, n_scores - penalty * n_risks),
        "score": (scores, n_scores),
    }
    for name, (a, b) in figures.items():
        se = np.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
        gap = abs(a.mean() - b.mean())
        assert gap <= TOLERANCE_SE * se + 1e-6 * abs(b.mean()), (
            f"{name}: JAX {a.mean():.5f} vs NumPy {b.mean():.5f}, se {se:.2e}"
        )


def test_gymnax_wrappers_accept_it() -> None:
    """With gymnax installed (it is not an extra: gymnax 1.0.1 pins gymnasium<1.4), its LogWrapper counts
    HeartPole's episodes, which end by truncation."""
    pytest.importorskip("gymnax", reason="gymnax is not installed (optional; it pins gymnasium<1.4)")
    from gymnax.wrappers.purerl import FlattenObservationWrapper, LogWrapper

    env, params = make("HeartPole-v0", max_steps=3)
    env = LogWrapper(FlattenObservationWrapper(env))
    obs, state = env.reset(jax.random.key(0), params)
    step = jax.jit(env.step)
    for i in range(3):
        obs, state, reward, terminated, truncated, info = step(jax.random.key(i + 1), state, 1, params)
    assert bool(truncated) and not bool(terminated) and bool(info["returned_episode"])
    assert int(info["returned_episode_lengths"]) == 3 and obs.shape == (6,)
