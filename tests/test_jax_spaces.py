"""heartpole.jax's spaces: gymnax's own classes wherever gymnax is in use, never an import of gymnax otherwise.

The gymnax cases (named ``gymnax``) run in the venv that scripts/test_gymnax.sh builds, where gymnax is
installed; the others run everywhere, gymnax's module stood in for by a fake one.
"""

from __future__ import annotations

import pickle
import subprocess
import sys
import types

import numpy as np
import pytest

pytest.importorskip("jax")

import jax  # noqa: E402

from heartpole.jax import make  # noqa: E402
from heartpole.jax.spaces import GYMNAX_SPACES, Box, Discrete  # noqa: E402


def test_without_gymnax_the_spaces_are_heartpoles_own(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(sys.modules, GYMNAX_SPACES, raising=False)
    env, params = make("HeartPole-v0")
    assert type(env.observation_space(params)) is Box and type(env.action_space(params)) is Discrete


def test_importing_heartpole_jax_never_imports_gymnax() -> None:
    code = (
        "import sys, heartpole.jax; heartpole.jax.make('HeartPole-v0'); "
        "print(any(m.startswith('gymnax') for m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def fake_gymnax_spaces() -> types.ModuleType:
    """A stand-in for gymnax's spaces module: classes of the same names, as gymnax defines them."""
    module = types.ModuleType(GYMNAX_SPACES)

    class Space:
        pass

    class Discrete(Space):
        pass

    class Box(Space):
        pass

    module.Space, module.Discrete, module.Box = Space, Discrete, Box  # type: ignore[attr-defined]
    return module


def test_with_gymnaxs_spaces_loaded_a_space_is_also_gymnaxs(monkeypatch: pytest.MonkeyPatch) -> None:
    theirs = fake_gymnax_spaces()
    monkeypatch.setitem(sys.modules, GYMNAX_SPACES, theirs)
    env, params = make("HeartPole-v0", people="default", observe_traits=True)
    box, discrete = env.observation_space(params), env.action_space(params)
    assert isinstance(box, theirs.Box) and isinstance(box, Box) and not isinstance(box, theirs.Discrete)
    assert isinstance(discrete, theirs.Discrete) and isinstance(discrete, Discrete)
    assert type(box) is type(env.observation_space(params))  # one class, made once
    assert box.shape == (11,) and discrete.n == 4 and repr(discrete) == "Discrete(4)"
    assert bool(box.contains(box.sample(jax.random.key(0)))) and bool(
        discrete.contains(discrete.sample(jax.random.key(1)))
    )
    again = pickle.loads(pickle.dumps(box))
    assert isinstance(again, theirs.Box)
    np.testing.assert_array_equal(again.low, box.low)


# ---------------------------------------------------------------------------------------- in gymnax's venv
@pytest.fixture
def gymnax() -> types.ModuleType:
    return pytest.importorskip("gymnax", reason="gymnax is not installed (optional; it pins gymnasium<1.4)")


def test_purejaxrl_ppo_setup_runs_in_gymnax(gymnax: types.ModuleType) -> None:
    """PureJaxRL's PPO setup (purejaxrl/ppo.py), verbatim but for the env and the step's arity, which is this
    gymnax's: the wrappers, the network's sizes from the spaces, vmapped reset and step."""
    from gymnax.wrappers.purerl import FlattenObservationWrapper, LogWrapper

    env, env_params = make("HeartPole-v0", people="default", observe_traits=True)
    env = FlattenObservationWrapper(env)
    env = LogWrapper(env)
    num_actions, obs_shape = env.action_space(env_params).n, env.observation_space(env_params).shape
    assert (num_actions, tuple(obs_shape)) == (4, (11,))
    reset_rng = jax.random.split(jax.random.key(0), 8)
    obsv, env_state = jax.vmap(env.reset, in_axes=(0, None))(reset_rng, env_params)
    assert obsv.shape == (8, *obs_shape)
    action = jax.vmap(env.action_space(env_params).sample)(jax.random.split(jax.random.key(1), 8))
    rng_step = jax.random.split(jax.random.key(2), 8)
    obsv, env_state, reward, *_, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
        rng_step, env_state, action, env_params
    )
    assert obsv.shape == (8, *obs_shape) and reward.shape == (8,) and "returned_episode_returns" in info


def test_gymnax_to_gym_wrappers_convert_its_spaces(gymnax: types.ModuleType) -> None:
    import gymnasium as gym
    from gymnax.wrappers.gym import GymnaxToGymWrapper, GymnaxToVectorGymWrapper

    env, params = make("HeartPole-v0")
    single = GymnaxToGymWrapper(env, params)
    assert single.observation_space.shape == (6,) and single.action_space == gym.spaces.Discrete(4)
    obs, _ = single.reset(seed=0)
    assert single.observation_space.contains(np.asarray(obs)) and np.isfinite(single.step(2)[1])
    vector = GymnaxToVectorGymWrapper(env, 3, params)
    assert vector.observation_space.shape == (3, 6) and vector.single_action_space == gym.spaces.Discrete(4)
    vector.reset(seed=0)
    assert np.asarray(vector.step(np.array([0, 1, 2]))[1]).shape == (3,)
