"""heartpole.jax.LegacyStep: gymnax's older five-value step, so that rejax (0.1.3) trains on HeartPole.

The wrapper's cases run everywhere JAX is. The training case (docs/rejax.md's example, fewer steps) needs rejax,
which is no dependency of HeartPole (it brings gymnax, whose pins would downgrade HeartPole's Gymnasium): it runs
in the venv that scripts/test_rejax.sh builds, and is skipped elsewhere.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path

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


DOCS = Path(__file__).resolve().parents[1] / "docs" / "rejax.md"
SCALED = {"total_timesteps=5_000_000": "total_timesteps=8_192", "eval_freq=1_000_000": "eval_freq=4_096"}
"""docs/rejax.md's step counts, scaled down: two PPO updates of 64 x 64 steps instead of 1,221."""


def docs_example() -> str:
    """docs/rejax.md's Python example with `SCALED`'s step counts (each replaced exactly once)."""
    found = re.search(r"<!-- no-test: needs rejax[^>]*-->\n```python\n(.*?)```", DOCS.read_text(), re.DOTALL)
    assert found, f"{DOCS}: its rejax example (after the no-test line) is gone"
    code = found.group(1)
    for old, new in SCALED.items():
        assert code.count(old) == 1, f"{DOCS}: the example no longer has {old}"
        code = code.replace(old, new)
    return code


def test_the_docs_example_trains_with_fewer_steps(capsys: pytest.CaptureFixture[str]) -> None:
    """docs/rejax.md's example as written but for its step counts: rejax's PPO trains and evaluates on HeartPole
    with finite results, and its trained policy acts."""
    pytest.importorskip("rejax")
    namespace: dict[str, object] = {}
    exec(compile(docs_example(), str(DOCS), "exec"), namespace)
    lengths, returns = (np.asarray(namespace[name]) for name in ("lengths", "returns"))
    assert lengths.shape == returns.shape == (3, 128)  # the initial evaluation and one per eval_freq steps
    assert np.all(lengths == 1000) and np.all(np.isfinite(returns))
    printed = capsys.readouterr().out
    assert printed.startswith("[") and printed.count("\n") == 1, printed  # the example's print: the mean returns
    env, params = make("HeartPole-v0")
    act = namespace["act"]
    keys = jax.random.split(jax.random.key(1), 5)
    actions = jax.vmap(act)(jax.numpy.zeros((5, *env.observation_space(params).shape)), keys)  # type: ignore[arg-type]
    assert np.all((np.asarray(actions) >= 0) & (np.asarray(actions) < env.num_actions))
