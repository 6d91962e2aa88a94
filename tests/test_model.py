"""The model's formulas: known values, floats and arrays alike, no overflow; one step for every backend."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from heartpole import model

finite = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)


def test_known_values() -> None:
    assert model.sigmoid(0.0) == 0.5
    assert model.heart_attack_risk(6.0) == pytest.approx(0.25)
    assert model.heart_attack_risk(0.0) == pytest.approx(0.5 / (1 + math.exp(6)))
    assert model.heart_attack_risk(6.0, proclivity=1.0) == pytest.approx(0.5)
    assert model.alertness_decay(40.0) == pytest.approx(0.5)
    assert model.crippling_anxiety(3.0) == pytest.approx(0.5)
    assert model.gaussian(0.135, 0.135, 0.005) == 1.0
    # The Ballmer peak: about 1 + 2 at blood alcohol 0.135, sober skill sigmoid(2.5).
    assert model.ballmer(0.0) == pytest.approx(1 / (1 + math.exp(-2.5)) + 2 * math.exp(-(0.135**2) / 5e-5))
    assert model.ballmer(0.135) == pytest.approx(2.0 + 1 / (1 + math.exp(4.25)))
    # The tutorial's own example: productivity of its printed state.
    assert model.productivity(0.8270396053524154, 0.012121832164124767) == pytest.approx(0.645391786501011)


@given(finite)
def test_sigmoid_is_a_probability_and_symmetric(x: float) -> None:
    y = model.sigmoid(x)
    assert 0.0 <= y <= 1.0
    assert y + model.sigmoid(-x) == pytest.approx(1.0)


@given(st.lists(finite, min_size=1, max_size=20))
def test_every_formula_gives_the_same_for_floats_and_arrays(values: list[float]) -> None:
    array = np.array(values)
    for formula in (
        model.sigmoid,
        model.heart_attack_risk,
        model.alertness_decay,
        model.crippling_anxiety,
        model.ballmer,
    ):
        vectorized = formula(array)
        assert vectorized.shape == array.shape
        np.testing.assert_allclose(vectorized, [formula(v) for v in values], rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(
        model.productivity(array, array[::-1]),
        [model.productivity(a, b) for a, b in zip(values, values[::-1])],
        rtol=1e-12,
        atol=1e-12,
    )


@given(st.floats(min_value=0, max_value=50), st.floats(min_value=0, max_value=50))
def test_risk_grows_with_hypertension_and_stays_below_proclivity(h1: float, h2: float) -> None:
    low, high = sorted((h1, h2))
    assert model.heart_attack_risk(low) <= model.heart_attack_risk(high) <= 0.5


def test_extreme_values_do_not_overflow() -> None:
    assert model.productivity(-1e6, 0.0) == pytest.approx(-1e6 * model.ballmer(0.0))
    assert model.productivity(1e6, 0.0) == 0.0
    with np.errstate(over="raise", invalid="raise"):
        np.testing.assert_array_equal(model.sigmoid(np.array([-1e6, 1e6])), [0.0, 1.0])


def test_score_is_zero_before_time_passes() -> None:
    assert model.score(0.0, 0.0) == 0.0
    assert model.score(3.0, 2.0) == 1.5
    np.testing.assert_array_equal(model.score(np.array([0.0, 3.0]), np.array([0.0, 2.0])), [0.0, 1.5])


def test_formulas_leave_their_array_arguments_untouched() -> None:
    # The formulas compute in place on their own temporaries; a slip would overwrite the caller's state.
    state = {name: np.linspace(-2.0, 9.0, 50, dtype=np.float32) for name in ("a", "i", "h", "t", "c")}
    before = {name: values.copy() for name, values in state.items()}
    model.productivity(state["a"], state["i"], state["c"])
    model.productivity(state["a"], state["i"])
    model.heart_attack_risk(state["h"], 0.5)
    model.alertness_decay(state["t"])
    model.crippling_anxiety(state["a"])
    model.ballmer(state["i"])
    model.gaussian(state["i"], 0.135, 0.005)
    model.sigmoid(state["a"])
    model.score(state["a"], state["t"])
    for name, values in state.items():
        np.testing.assert_array_equal(values, before[name], err_msg=name)


# ------------------------------------------------------------------------------------------------------
# One definition of the step for every backend


def scratch_model(tmp_path, monkeypatch, name: str, edit) -> object:
    """model.py's own source, changed by ``edit``, imported as a module of its own (for this test only)."""
    import importlib.util
    import inspect
    import sys

    path = tmp_path / f"{name}.py"
    path.write_text(edit(inspect.getsource(model)))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, module)  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_a_helper_called_from_the_step_is_compiled_without_being_listed(tmp_path, monkeypatch) -> None:
    """A helper added to model.py and called from step runs compiled too: the backends' list of functions is
    found from step's code. (With a hand-kept list it ran as plain Python and failed compiled, far away, with
    NameError: name '_half' is not defined.)"""
    from numba import njit

    from heartpole import kernel, lanes

    def add_half(source: str) -> str:
        old = "    worked = productivity(state[ALERTNESS], state[INTOXICATION], calm)\n"
        assert old in source
        helper = 'def _half(x: Number) -> Number:\n    """Half of ``x``."""\n    return x / 2.0\n\n\n'
        source = source.replace("def step(\n", helper + "def step(\n")
        return source.replace(old, old + "    worked = _half(worked)\n")

    changed = scratch_model(tmp_path, monkeypatch, "model_with_a_helper", add_half)
    assert "_half" in changed.FUNCTIONS and "_half" not in model.FUNCTIONS
    compiled = changed.rebind(
        {"exp": lanes.exp32, "where": lanes.where, "replace": kernel.tuple_setitem}, np.float32, njit
    )
    f32 = np.float32
    state = (f32(1.1), f32(0.2), f32(0.0), f32(3.0), f32(3.0), f32(2.5), f32(0.4))
    effects, tables = v1_tables(action=5)  # a nap: v1's rest offsets are not empty (numba iterates no ())
    uniforms = tuple(f32(u) for u in (0.25, 0.5, 0.75, 0.0, 0.0, 0.0, 0.3, 0.9, 0.999))
    _, _, worked, *_ = compiled.step(state, effects, uniforms, tables)
    _, _, unchanged, *_ = kernel.compiled.step(state, effects, uniforms, tables)
    assert worked == unchanged / f32(2.0)


def v1_tables(action: int) -> tuple:
    from heartpole.actions import V1_ACTIONS, V1_VARIABLES
    from heartpole.dynamics import Dynamics

    dynamics = Dynamics(V1_ACTIONS, variables=V1_VARIABLES)
    return dynamics.effects[action], dynamics.tables


def test_the_tables_fields_are_typed_by_kind_in_the_order_backends_build_them() -> None:
    from typing import NamedTuple

    assert model.table_fields(model.ActionEffects) == (
        ("effect_low", "effect_width", "rest_fade"),
        ("rest", "drowsy", "sleeps"),
        (),
    )
    fields = model.table_fields(model.StepTables)
    assert fields.per_variable == ("floor", "fade", "anxiety_relief") and fields.shape == ("rest_offsets",)
    assert set(fields.numbers) >= {"heart_attack_proclivity", "heart_attack_penalty", "wake_low", "wake_width"}

    class Shuffled(NamedTuple):
        rest: model.Number
        effect_low: model.PerVariable

    class Untyped(NamedTuple):
        rest: int

    with pytest.raises(
        TypeError, match=r"Shuffled must declare its PerVariable fields first.*\['rest', 'effect_low'\]"
    ):
        model.table_fields(Shuffled)
    with pytest.raises(TypeError, match="Untyped.rest must be annotated PerVariable, Number or Shape"):
        model.table_fields(Untyped)
