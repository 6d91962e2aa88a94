"""The model's formulas: known values, floats and arrays alike, no overflow, parameter checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from heartpole import model
from heartpole.model import Params

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


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"heart_attack_proclivity": -0.1}, "heart_attack_proclivity"),
        ({"heart_attack_proclivity": 1.5}, "heart_attack_proclivity"),
        ({"heart_attack_proclivity": float("nan")}, "heart_attack_proclivity"),
        ({"heart_attack_proclivity": "0.5"}, "heart_attack_proclivity"),
        ({"max_steps": 0}, "max_steps"),
        ({"max_steps": 10.5}, "max_steps"),
        ({"max_steps": True}, "max_steps"),
        ({"decay_rate": 0.0}, "decay_rate"),
        ({"decay_rate": 1.1}, "decay_rate"),
        ({"sleep_half_hours": -1}, "sleep_half_hours"),
        ({"heart_attack_penalty": -1}, "heart_attack_penalty"),
        ({"wake_alertness": (1.3, 0.7)}, "wake_alertness"),
        ({"wake_alertness": 1.0}, "wake_alertness"),
    ],
)
def test_invalid_params_are_refused_with_their_name(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Params(**kwargs)


def test_default_params_are_the_tutorials() -> None:
    p = Params()
    assert (p.heart_attack_proclivity, p.max_steps, p.decay_rate, p.sleep_half_hours) == (0.5, 1000, 0.97, 16)
    assert (p.heart_attack_penalty, p.wake_alertness) == (100.0, (0.7, 1.3))
