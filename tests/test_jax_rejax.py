"""heartpole.jax.LegacyStep: gymnax's older five-value step, so that rejax (0.1.3) trains on HeartPole.

The wrapper's cases run everywhere JAX is. The training case (named ``rejax``) needs rejax, which is no
dependency of HeartPole (it brings gymnax, whose pins would downgrade HeartPole's Gymnasium): it runs in the
venv that scripts/test_rejax.sh builds, and is skipped elsewhere.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

pytest.importorskip("jax")

import jax  # noqa: E402

from heartpole.jax import LegacyStep, make  # noqa: E402


def test_step_returns_five_values_with_done_at_the_time_limit() -> None:
    env, params = make("HeartPole-v0", max_steps=3)
    legacy = LegacyStep(env)
    obs, state = legacy.reset(jax.random.key(0), params)
    dones = []
    for i in range(6):
        key = jax.random.key(i + 1)
        obs, state, reward, done, info = legacy.step(key, state, 2, params)
        dones.append(bool(done))
        assert bool(done) == bool(info["terminated"] | info["truncated"])
    assert dones == [False, False, True, False, False, True]


def test_it_equals_the_envs_own_step_under_vmap() -> None:
    env, params = make("HeartPole-v0")
    legacy = LegacyStep(env)
    keys = jax.random.split(jax.random.key(0), 8)
    _, states = jax.vmap(legacy.reset, in_axes=(0, None))(keys, params)
    actions = jax.numpy.arange(8) % env.num_actions
    ours = jax.jit(jax.vmap(legacy.step, in_axes=(0, 0, 0, None)))(keys, states, actions, params)
    theirs = jax.jit(jax.vmap(env.step, in_axes=(0, 0, 0, None)))(keys, states, actions, params)
    assert len(ours) == 5
    for mine, its in zip((ours[0], ours[1], ours[2], ours[4]), (theirs[0], theirs[1], theirs[2], theirs[5])):
        jax.tree_util.tree_map(np.testing.assert_array_equal, mine, its)
    np.testing.assert_array_equal(ours[3], theirs[3] | theirs[4])


def test_everything_else_is_the_envs_and_it_deep_copies() -> None:
    env, params = make("HeartPole-v0", max_steps=7)
    legacy = LegacyStep(env)
    assert legacy.env is env and legacy.num_actions == env.num_actions and legacy.name == env.name
    assert int(legacy.default_params.max_steps_in_episode) == 7
    assert legacy.observation_space(params).shape == env.observation_space(params).shape
    copied = copy.deepcopy({"env": legacy})["env"]  # rejax's PPO.create deep-copies its config
    assert isinstance(copied, LegacyStep) and copied.env is not env
    assert copied.action_space(params).n == env.num_actions
    assert len(copied.step(jax.random.key(0), copied.reset(jax.random.key(0), params)[1], 0, params)) == 5
    with pytest.raises(AttributeError):
        _ = legacy.no_such_thing
    with pytest.raises(TypeError, match="LegacyStep wraps"):
        LegacyStep(legacy)  # type: ignore[arg-type]


def test_rejax_ppo_trains_on_heartpole() -> None:
    """docs/rejax.md's example, tiny: rejax's PPO trains and evaluates on HeartPole with finite results."""
    rejax = pytest.importorskip("rejax")
    env, params = make("HeartPole-v0", max_steps=64)
    algo = rejax.PPO.create(
        env=LegacyStep(env),
        env_params=params,
        total_timesteps=2048,
        eval_freq=1024,
        num_envs=4,
        num_steps=64,
        num_epochs=2,
        num_minibatches=4,
    )
    train_state, (lengths, returns) = jax.jit(algo.train)(jax.random.key(0))
    assert int(train_state.global_step) == 2048
    assert lengths.shape == returns.shape == (3, 128)  # the initial evaluation and one per eval_freq steps
    assert np.all(np.asarray(lengths) == 64) and np.all(np.isfinite(np.asarray(returns)))
    actions = jax.vmap(algo.make_act(train_state))(jax.numpy.zeros((5, *env.observation_space(params).shape)),
                                                   jax.random.split(jax.random.key(1), 5))  # fmt: skip
    assert np.all((np.asarray(actions) >= 0) & (np.asarray(actions) < env.num_actions))
