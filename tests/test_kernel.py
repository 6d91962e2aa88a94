"""The compiled step (heartpole.kernel): the model's code compiled as written, its random numbers, and the
envs that run it.

Statistical checks name their tolerance; the seeds are fixed, so each test is deterministic.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
import pickle
import re
import subprocess
import sys
import textwrap

import numba
import numpy as np
import pytest
from numba import njit

import heartpole
from heartpole import kernel, model, parameters
from heartpole.actions import V1_ACTIONS, V1_VARIABLES
from heartpole.dynamics import Dynamics
from tests.tutorial_model import bell, logistic

# ------------------------------------------------------------------------------------------------------
# The step against the tutorial's formulas, on fixed inputs


def tutorial_step(state: dict[str, float], action: int, u: list[float]) -> tuple[dict[str, float], float, bool]:
    """The tutorial's HeartPole.step written out for one person, with given uniforms instead of np.random:
    u[0] alertness, u[1] hypertension, u[2] intoxication (coffee and beer), u[6] waking up, u[7] the coin."""
    st = dict(state)

    def half_hour_passed() -> None:
        st["alertness"] -= logistic((st["time_since_slept"] - 40) / 10)
        st["hypertension"] *= 0.97
        st["intoxication"] *= 0.97
        st["time_since_slept"] += 1
        st["time_elapsed"] += 1

    old = 0.0 if st["time_elapsed"] == 0 else st["work_done"] / st["time_elapsed"]
    if action == 1:
        st["alertness"] += u[0]
        st["hypertension"] += 0.3 * u[1]
    elif action == 2:
        st["alertness"] += -0.5 + 0.5 * u[0]  # U(-0.5, 0): low + width * u
        st["hypertension"] += 0.3 * u[1]
        st["intoxication"] += 0.01 + 0.02 * u[2]
    elif action == 3:
        for _ in range(16):
            half_hour_passed()
        st["alertness"] = 0.7 + 0.6 * u[6]
        st["time_since_slept"] = 0
    a, x = st["alertness"], st["intoxication"]
    st["work_done"] += a * (1 - logistic(a - 3)) * (logistic((0.05 - x) * 50) + 2 * bell(x, 0.135, 0.005))
    half_hour_passed()
    reward = st["work_done"] / st["time_elapsed"] - old
    attack = u[7] < 0.5 * logistic(st["hypertension"] - 6)
    if attack:
        reward -= 100
        st["hypertension"] = 0.0
    return st, reward, bool(attack)


STATES = [
    {
        "alertness": 1.1,
        "hypertension": 0.2,
        "intoxication": 0.0,
        "time_since_slept": 3.0,
        "time_elapsed": 3.0,
        "work_done": 2.5,
    },
    {
        "alertness": 0.3,
        "hypertension": 5.5,
        "intoxication": 0.13,
        "time_since_slept": 45.0,
        "time_elapsed": 300.0,
        "work_done": 95.0,
    },
    {
        "alertness": 2.9,
        "hypertension": 7.0,
        "intoxication": 0.06,
        "time_since_slept": 0.0,
        "time_elapsed": 0.0,
        "work_done": 0.0,
    },
]
UNIFORMS = [[0.25, 0.5, 0.75, 0.1, 0.2, 0.3, 0.9, 0.999], [0.9, 0.1, 0.4, 0.5, 0.5, 0.5, 0.05, 0.0001]]


@pytest.mark.parametrize("action", range(4))
@pytest.mark.parametrize("state", STATES, ids=range(len(STATES)))
@pytest.mark.parametrize("u", UNIFORMS, ids=range(len(UNIFORMS)))
def test_the_step_is_the_tutorials_step(state, action, u) -> None:
    """model.step run by Python and NumPy (in float32, the tables' type) against the tutorial written out in
    float64; sleep's 16 fading half-hours are one power there, so equality is up to float32 rounding."""
    dynamics = Dynamics()
    s = tuple(state.values())
    new, reward, worked, risk, attack, score = model.step(s, dynamics.effects[action], u, dynamics.tables)
    expected, expected_reward, expected_attack = tutorial_step(state, action, u)
    np.testing.assert_allclose(np.array(new, dtype=float), list(expected.values()), rtol=1e-6, atol=1e-6)
    assert reward == pytest.approx(expected_reward, rel=1e-6, abs=1e-6)
    assert bool(attack) == expected_attack
    assert score == pytest.approx(expected["work_done"] / expected["time_elapsed"], rel=1e-6)


@pytest.mark.parametrize("action", range(8))
def test_the_compiled_float32_step_follows_the_python_step(action) -> None:
    """The same code compiled in float32 with the kernel's exp: within float32 precision of float64."""
    dynamics = Dynamics(V1_ACTIONS, variables=V1_VARIABLES)
    f32 = np.float32
    for state, u in zip(STATES * 2, UNIFORMS * 3):
        s = (*state.values(), 0.4)
        u = [*u[:6], 0.3, *u[6:]]
        python = model.step(s, dynamics.effects[action], u, dynamics.tables)
        compiled = kernel.compiled.step(
            tuple(f32(x) for x in s), dynamics.effects[action], tuple(f32(x) for x in u), dynamics.tables
        )
        np.testing.assert_allclose(
            np.array(compiled[0], dtype=float), np.array(python[0], dtype=float), rtol=2e-6, atol=2e-5
        )
        for got, want in zip(compiled[1:], python[1:]):
            assert float(got) == pytest.approx(float(want), rel=2e-6, abs=2e-5)


# ------------------------------------------------------------------------------------------------------
# The random numbers


@njit
def many_uniforms(keys_low, keys_high, steps, draws_per_step):
    out = np.empty((len(keys_low), steps, draws_per_step), dtype=np.float32)
    for i in range(len(keys_low)):
        for c in range(steps):
            for j in range(draws_per_step):
                out[i, c, j] = kernel.uniform(keys_low[i], keys_high[i], c, j)
    return out


def sample(envs: int = 125, steps: int = 1000, draws_per_step: int = 8) -> np.ndarray:
    state = kernel.generator_states(np.random.default_rng(7), envs)
    return many_uniforms(state[kernel.KEY_LOW], state[kernel.KEY_HIGH], steps, draws_per_step)


def test_uniforms_are_uniform_on_the_24_bit_grid() -> None:
    """1,000,000 draws: a chi-square test over 100 bins and the Kolmogorov-Smirnov distance, each at a
    false-alarm rate of about 1e-4 (critical values 157.0 for 99 degrees of freedom, 1.95 / sqrt(n))."""
    u = sample().ravel().astype(np.float64)
    n = u.size
    assert n == 1_000_000 and u.min() >= 0.0 and u.max() < 1.0
    assert np.all(u * 2**24 == np.floor(u * 2**24))
    counts = np.bincount((u * 100).astype(int), minlength=100)
    chi2 = ((counts - n / 100) ** 2 / (n / 100)).sum()
    assert chi2 < 157.0
    ordered = np.sort(u)
    ks = max(np.max(np.arange(1, n + 1) / n - ordered), np.max(ordered - np.arange(n) / n))
    assert ks < 1.95 / math.sqrt(n)


def test_uniforms_are_independent_across_draws_steps_and_envs() -> None:
    """Correlations between the draws of a step, consecutive steps and neighbouring envs, |r| below
    4.5 standard errors (4.5 / sqrt(n)), and the pairs of consecutive steps spread evenly over a 10x10 grid
    (chi-square with 99 degrees of freedom under 157.0)."""
    u = sample()
    bound = lambda n: 4.5 / math.sqrt(n)  # noqa: E731
    for j in range(1, 8):
        assert abs(np.corrcoef(u[:, :, 0].ravel(), u[:, :, j].ravel())[0, 1]) < bound(u[:, :, 0].size)
    now, later = u[:, :-1, :].ravel(), u[:, 1:, :].ravel()
    assert abs(np.corrcoef(now, later)[0, 1]) < bound(now.size)
    assert abs(np.corrcoef(u[:-1].ravel(), u[1:].ravel())[0, 1]) < bound(u[1:].size)
    cells = np.bincount((now * 10).astype(int) * 10 + (later * 10).astype(int), minlength=100)
    assert ((cells - now.size / 100) ** 2 / (now.size / 100)).sum() < 157.0


def test_generator_states_come_from_the_seed_alone() -> None:
    a = kernel.generator_states(np.random.default_rng(3), 5)
    b = kernel.generator_states(np.random.default_rng(3), 5)
    np.testing.assert_array_equal(a, b)
    assert a.dtype == np.uint32 and a.shape == (3, 5) and not a[kernel.COUNTER].any()
    assert len({(lo, hi) for lo, hi in zip(a[0], a[1])}) == 5


# ------------------------------------------------------------------------------------------------------
# The envs on the kernel


@pytest.mark.parametrize("env_id, num_actions", [("HeartPole-v0", 4), ("HeartPole-v1", 8)])
def test_the_single_env_is_env_0_of_the_vector_env_bit_for_bit(env_id, num_actions) -> None:
    import gymnasium as gym

    single = gym.make(env_id).unwrapped
    vector = gym.make_vec(env_id, num_envs=5, vectorization_mode="vector_entry_point")
    obs, _ = single.reset(seed=21)
    vobs, _ = vector.reset(seed=21)
    assert obs.tobytes() == vobs[0].tobytes()
    rng = np.random.default_rng(4)
    for _ in range(400):
        actions = rng.integers(0, num_actions, 5)
        obs, reward, _, _, info = single.step(int(actions[0]))
        vobs, vreward, _, _, vinfo = vector.step(actions)
        assert obs.tobytes() == vobs[0].tobytes()
        assert reward == vreward[0] and info["heart_attack"] == vinfo["heart_attack"][0]
        assert info["heart_attack_risk"] == vinfo["heart_attack_risk"][0]


def test_a_vector_env_continues_exactly_after_deepcopy_and_pickle() -> None:
    env = heartpole.HeartPoleVectorEnv(6, max_steps=40)
    env.reset(seed=2)
    rng = np.random.default_rng(0)
    for actions in rng.integers(0, 4, (50, 6)):
        env.step(actions)
    twins = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    for actions in rng.integers(0, 4, (60, 6)):  # crosses an autoreset
        out = env.step(actions)
        for twin in twins:
            again = twin.step(actions)
            assert out[0].tobytes() == again[0].tobytes() and out[1].tobytes() == again[1].tobytes()


def test_the_dynamics_live_in_model_step_only() -> None:
    """One source: the kernel compiles model's own code objects (only the float literals made float32),
    and no code of the kernel, the envs or the dynamics holds one of the formulas' constants."""
    import ast
    import inspect

    from heartpole import dynamics, env, vector

    for name in ("step", "productivity", "ballmer", "heart_attack_risk", "alertness_decay", "sigmoid"):
        assert getattr(kernel.compiled, name).py_func.__code__.co_code == getattr(model, name).__code__.co_code
    formula_constants = {0.135, 0.005, 0.05, 40.0, 50.0, 0.97}
    for module in (kernel, dynamics, env, vector):
        numbers = {
            node.value
            for node in ast.walk(ast.parse(inspect.getsource(module)))
            if isinstance(node, ast.Constant) and type(node.value) in (int, float)
        }
        assert not numbers & formula_constants, f"{module.__name__} holds {numbers & formula_constants}"


NO_JIT = """
import numpy as np, heartpole
env = heartpole.HeartPole(max_steps=30)
obs, _ = env.reset(seed=5)
for t in range(30):
    obs, reward, terminated, truncated, info = env.step(t % 4)
print(obs.tobytes().hex(), truncated)
"""


def test_everything_runs_without_numba_compiling(tmp_path) -> None:
    """With NUMBA_DISABLE_JIT=1 the same code runs as plain Python, slowly, to the same observations."""

    def run(extra: dict[str, str]) -> str:
        environment = {**os.environ, **extra}
        return subprocess.run(
            [sys.executable, "-c", NO_JIT], capture_output=True, text=True, check=True, env=environment
        ).stdout

    assert run({"NUMBA_DISABLE_JIT": "1"}) == run({}) != ""


@pytest.mark.parametrize("variant", ["v0", "v1"])
def test_the_packed_rows_read_back_as_the_models_tables(variant) -> None:
    """The kernel's layout is derived from the model's table definitions: what pack writes, the generated code
    (kernel.source) reads back exactly, compiled, for every action, with masks (the variant's own spec) and
    gathered (every number of the action rows named as differing, beyond SELECTED_NUMBERS)."""
    dynamics = Dynamics() if variant == "v0" else Dynamics(V1_ACTIONS, variables=V1_VARIABLES)
    packed = dynamics.packed
    assert packed.shape == (len(dynamics.actions) + 1, kernel.row_width(len(dynamics.variables)))
    everything = dataclasses.replace(dynamics.spec, selected=tuple(range(packed.shape[1], packed[:-1].size)))
    assert len(everything.selected) > kernel.SELECTED_NUMBERS

    @njit
    def read(packed, action, spec):
        flat = packed.reshape(packed.size)
        return kernel.numbers(spec, kernel.read(spec, flat), flat, kernel.NO_CELLS, np.int32(action), np.uint64(0))

    for spec in (dynamics.spec, everything):
        for action, effects in enumerate(dynamics.effects):
            zeros, by_spec, tables = read(packed, action, spec.argument)
            assert by_spec == effects and tables == dynamics.tables and zeros == (0.0,) * len(dynamics.variables)


def test_the_selection_names_exactly_the_numbers_that_differ_from_the_first_actions() -> None:
    """v0: coffee's two widths, beer's two lows and three widths, sleep's two fades, rest and waking: 11 masks
    (a mask per action and number would be 33). -0.0 and 0.0 differ, bit for bit."""
    dynamics = Dynamics()
    width = kernel.row_width(len(dynamics.variables))
    rows = dynamics.packed[:4]
    expected = [k * width + c for k in (1, 2, 3) for c in range(width) if rows[k, c] != rows[0, c]]
    assert list(dynamics.spec.selected) == expected and len(expected) == 11
    signed = dynamics.packed.copy()
    signed[2, 3] = -0.0  # beer lowers time_since_slept's effect by -0.0: the same number, other bits
    assert 2 * width + 3 in kernel.selection(signed, 4)
    # no sleep and no fading make sleep's rest and fades equal to doing nothing's: the loop stays v0's all the same
    for params in (parameters.Params(sleep_half_hours=0), parameters.Params(decay_rate=1.0)):
        assert Dynamics(params=params).spec == dynamics.spec


def test_a_loop_spec_is_its_arguments_type_and_refuses_overlays_it_cannot_place() -> None:
    """The spec travels to compiled code as the dtype of an empty array and comes back equal; an overlay needs each
    position once and integers >= 0, and names what it got otherwise."""
    spec = kernel.LoopSpec(6, 0, 4, (28, 29), ((79, 0), (80, 0), (84, 1)))
    assert spec.argument.shape == (0,) and kernel.LoopSpec.of(spec.argument.dtype) == spec and spec.columns == 2
    assert kernel.LoopSpec.of(numba.typeof(spec.argument).dtype) == spec
    for overlay in (((79, 0), (79, 1)), ((79, -1),), ((-1, 0),)):
        with pytest.raises(ValueError, match=re.escape(f"got {list(overlay)}")):
            kernel.LoopSpec(6, 0, 4, (), overlay)


def test_the_source_docstring_shows_what_v0_compiles() -> None:
    """kernel.source's docstring holds v0's generated source exactly, so a reader sees what the loop compiles."""
    assert textwrap.indent(kernel.source(Dynamics().spec), " " * 8) in (kernel.source.__doc__ or "")


@pytest.mark.slow
def test_an_edit_of_the_model_alone_recompiles_the_cached_kernel(tmp_path) -> None:
    """numba keys a cached function on its own file; the kernel inlines model.py's step, so its cache is keyed
    on model.py too (heartpole.jit.cache_keyed_on): an edit of the model alone must not run the old step."""
    import shutil
    from pathlib import Path

    package = Path(heartpole.__file__).parent
    shutil.copytree(package, tmp_path / "heartpole", ignore=shutil.ignore_patterns("__pycache__"))
    code = "import heartpole; e = heartpole.HeartPole(); e.reset(seed=1); print(e.step(0)[4]['productivity'])"
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    run = lambda: float(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,  # noqa: E731
                                       check=True).stdout)  # fmt: skip
    before = run()
    model_file = tmp_path / "heartpole" / "model.py"
    line = "    worked = productivity(state[ALERTNESS], state[INTOXICATION], calm)\n"
    assert line in model_file.read_text()
    model_file.write_text(model_file.read_text().replace(line, line + "    worked = worked * 3.0\n"))
    assert run() == pytest.approx(3 * before, rel=1e-6)


USE_THE_PEOPLE_LOOPS = """
import json
import numpy as np
from numba.core import event
import heartpole

with event.install_recorder("numba:compile") as recorder:
    vector = heartpole.HeartPoleVectorEnv(4, people="default")
    vector.reset(seed=0)
    vector.step(np.zeros(4, dtype=np.int64))
    single = heartpole.HeartPole(people="default")
    single.reset(seed=0)
    single.step(0)
functions = {
    f"{e.data['dispatcher'].py_func.__module__}.{e.data['dispatcher'].py_func.__qualname__}"
    for _, e in recorder.buffer
    if e.is_start
}
print(json.dumps(sorted(f for f in functions if f.startswith("heartpole."))))
"""


@pytest.mark.slow  # two fresh processes, the first compiling every loop of people='default' (tens of seconds)
def test_a_second_process_loads_the_people_loops_from_the_disk_cache(tmp_path) -> None:
    """The loops of people="default" (vector env step and reset, single env step) are compiled by the first
    process that uses them and loaded from numba's disk cache by the next: it compiles nothing of HeartPole's.
    (The people's LoopSpec is in the loops' argument types, which key the cache.)"""
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    environment.pop("NUMBA_DISABLE_JIT", None)

    def compiled() -> list[str]:
        done = subprocess.run(
            [sys.executable, "-c", USE_THE_PEOPLE_LOOPS], capture_output=True, text=True, check=True, env=environment
        )
        return list(json.loads(done.stdout))

    first = [name for name in compiled() if name.startswith("heartpole.kernel.")]
    for loop in ("_loop", "step_envs", "reset_envs", "step_one"):  # the first process compiled each of them
        assert any(name.endswith(loop) for name in first), (loop, first)
    assert compiled() == []
