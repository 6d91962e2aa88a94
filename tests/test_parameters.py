"""The parameters and their checks: invalid params refused by name, the tutorial's defaults, one rule for a
number, the variables the step keeps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from heartpole import model, parameters
from heartpole.parameters import Params


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


@pytest.mark.parametrize(
    "value, accepted",
    [(1, True), (np.float32(0.5), True), (True, False), (np.bool_(True), False), ("1", False), (None, False)],
)
def test_one_rule_for_a_number(value, accepted: bool) -> None:
    """A number is a Python or NumPy int or float, never a bool: Params, Variable and Action ask check_number."""
    assert parameters.is_number(value) is accepted
    if not accepted:
        with pytest.raises(ValueError, match="x must be a finite number"):
            parameters.check_number("x", value)
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError, match="x must be a finite number"):
            parameters.check_number("x", bad)
    assert parameters.check_number("x", math.inf, finite=False) == math.inf
    with pytest.raises(ValueError, match=r"x must be a number \(or \+-math.inf\), got nan"):
        parameters.check_number("x", math.nan, finite=False)


def test_the_variables_the_step_keeps_are_named_from_its_own_rule() -> None:
    assert parameters.BOOKKEEPING == ("time_since_slept", "time_elapsed", "work_done")
    names = [v.name for v in parameters.V0_VARIABLES]
    assert [names.index(n) for n in parameters.BOOKKEEPING] == [i for i in range(6) if model.kept_by_the_step(i)]
