"""The HeartPole physiology: parameters, state variables and the formulas of the tutorial's facts 0-8.

Every formula here is written once and works on Python floats (fast, exact ``math`` calls, used by the
single env) and on NumPy arrays (used by the vector env and by plots) alike. Time is counted in
half-hours.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

ArrayOrFloat = Any  # a Python float or a NumPy array; the formulas accept either


def _exp_(x: ArrayOrFloat) -> ArrayOrFloat:
    """``exp(x)``; a float array is overwritten with the result, so pass only a temporary you own.

    Floats go through ``math`` (fast, exact, clamped so it never overflows); arrays are computed in place,
    which halves the memory traffic of a batch step.
    """
    if type(x) is float:
        return math.exp(x if x < 700.0 else 700.0)
    with np.errstate(over="ignore"):  # exp() may overflow to inf on purpose: 1 / (1 + inf) is 0
        if type(x) is np.ndarray and x.dtype.kind == "f":
            return np.exp(x, out=x)
        return np.exp(x)


def _logistic_(x: ArrayOrFloat) -> ArrayOrFloat:
    """``1 / (1 + exp(x))``, overwriting a float array ``x`` (a temporary) with the result."""
    if type(x) is float:  # the single env's path, kept short: it runs five times a step
        return 1.0 / (1.0 + math.exp(x if x < 700.0 else 700.0))
    x = _exp_(x)
    x += 1.0
    if type(x) is np.ndarray:
        return np.reciprocal(x, out=x)
    return 1.0 / x


def sigmoid(x: ArrayOrFloat) -> ArrayOrFloat:
    """The logistic function ``1 / (1 + exp(-x))``."""
    return _logistic_(-x)


def gaussian(x: ArrayOrFloat, mu: float, sigma: float) -> ArrayOrFloat:
    """An unnormalised bell curve ``exp(-(x - mu)**2 / (2 sigma**2))``: 1 at ``x == mu``, width ``sigma``."""
    exponent = x - mu
    exponent *= exponent
    exponent *= -0.5 / sigma**2
    # Far from mu, exp() would give subnormal float32 numbers, which CPUs compute about ten times slower;
    # flooring the exponent at -87 keeps them normal and changes the bell by less than 1.7e-38.
    if type(exponent) is float:
        return math.exp(exponent if exponent > -87.0 else -87.0)
    return _exp_(np.maximum(exponent, -87.0, out=exponent if type(exponent) is np.ndarray else None))


def heart_attack_risk(hypertension: ArrayOrFloat, proclivity: float = 0.5) -> ArrayOrFloat:
    """Fact 4: the probability of a heart attack in one step, ``proclivity * sigmoid(hypertension - 6)``."""
    risk = _logistic_(6.0 - hypertension)
    risk *= proclivity
    return risk


def alertness_decay(time_since_slept: ArrayOrFloat) -> ArrayOrFloat:
    """Fact 6: alertness lost in one half-hour awake, ``sigmoid((time_since_slept - 40) / 10)``."""
    exponent = 40.0 - time_since_slept
    exponent /= 10.0
    return _logistic_(exponent)


def crippling_anxiety(alertness: ArrayOrFloat) -> ArrayOrFloat:
    """Fact 7: the share of work lost to anxiety when too alert, ``sigmoid(alertness - 3)``."""
    return _logistic_(3.0 - alertness)


def ballmer(intoxication: ArrayOrFloat) -> ArrayOrFloat:
    """Fiction 8: programming skill against blood alcohol, with the Ballmer peak at 0.135:
    ``sigmoid((0.05 - intoxication) * 50) + 2 * gaussian(intoxication, 0.135, 0.005)``."""
    exponent = intoxication - 0.05
    exponent *= 50.0
    skill = _logistic_(exponent)
    peak = gaussian(intoxication, 0.135, 0.005)
    peak *= 2.0
    skill += peak
    return skill


def productivity(alertness: ArrayOrFloat, intoxication: ArrayOrFloat, calm: ArrayOrFloat | None = None) -> ArrayOrFloat:
    """Fact 7 and fiction 8: work done in one half-hour, ``alertness * (1 - anxiety) * ballmer``.

    ``calm`` is anxiety relief (HeartPole-v1's THC; see :attr:`Variable.anxiety_relief`): anxiety sets in
    ``calm`` units of alertness later, ``crippling_anxiety(alertness - calm)``. ``None``, v0's case, is none.
    """
    anxious = alertness if calm is None else alertness - calm
    work = 1.0 - crippling_anxiety(anxious)
    work *= alertness
    return work * ballmer(intoxication)  # not in place: the two may broadcast to a larger shape


@dataclass(frozen=True)
class Params:
    """The numbers of the model that a variant may change; the defaults are the tutorial's.

    Attributes:
        heart_attack_proclivity: scales the heart-attack risk (fact 4), in [0, 1].
        max_steps: decisions per episode; the episode is truncated after this many steps.
        decay_rate: share of hypertension and intoxication left after a half-hour (fact 5), in (0, 1].
        sleep_half_hours: how long the sleep action sleeps before waking up.
        heart_attack_penalty: reward lost per heart attack.
        wake_alertness: alertness on waking is uniform on this (low, high) interval (fact 1).
    """

    heart_attack_proclivity: float = 0.5
    max_steps: int = 1000
    decay_rate: float = 0.97
    sleep_half_hours: int = 16
    heart_attack_penalty: float = 100.0
    wake_alertness: tuple[float, float] = (0.7, 1.3)

    def __post_init__(self) -> None:
        _check_number("heart_attack_proclivity", self.heart_attack_proclivity, 0.0, 1.0)
        _check_integer("max_steps", self.max_steps, 1)
        _check_number("decay_rate", self.decay_rate, 0.0, 1.0, low_open=True)
        _check_integer("sleep_half_hours", self.sleep_half_hours, 0)
        _check_number("heart_attack_penalty", self.heart_attack_penalty, 0.0, math.inf)
        low, high = _pair("wake_alertness", self.wake_alertness)
        if not low <= high:
            raise ValueError(f"wake_alertness must be (low, high) with low <= high, got {self.wake_alertness!r}")


def _check_number(name: str, value: Any, low: float, high: float, low_open: bool = False) -> None:
    is_number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    in_range = is_number and math.isfinite(value) and (low < value if low_open else low <= value) and value <= high
    if not in_range:
        bracket = "(" if low_open else "["
        raise ValueError(f"{name} must be a finite number in {bracket}{low}, {high}], got {value!r}")


def _check_integer(name: str, value: Any, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def _pair(name: str, value: Any) -> tuple[float, float]:
    if not (isinstance(value, (tuple, list)) and len(value) == 2):
        raise ValueError(f"{name} must be a (low, high) pair of numbers, got {value!r}")
    for item in value:
        _check_number(name, item, -math.inf, math.inf)
    return float(value[0]), float(value[1])


@dataclass(frozen=True)
class Variable:
    """One state variable: its name, its bounds in the observation space and how it fades.

    Attributes:
        name: the key used in observations' documentation, ``info`` and action effects.
        low, high: bounds of the observation space for this variable.
        decay: share left after each half-hour (``None``: it does not fade). The string ``"params"``
            means ``Params.decay_rate``, which is how hypertension and intoxication fade (fact 5).
        description: one line for the manual.
        anxiety_relief: each unit of this variable moves the onset of crippling anxiety (fact 7) this
            many units of alertness higher: the work of a half-hour is
            ``productivity(alertness, intoxication, calm=sum(anxiety_relief * value))``. 0 (v0's six
            variables) means the variable does not touch productivity; HeartPole-v1's ``thc`` has 1.
    """

    name: str
    low: float = -math.inf
    high: float = math.inf
    decay: float | str | None = None
    description: str = ""
    anxiety_relief: float = 0.0

    def decay_factor(self, params: Params) -> float | None:
        """The per-half-hour factor of this variable under ``params``, or ``None`` if it does not fade."""
        return params.decay_rate if self.decay == "params" else self.decay


ALERTNESS, HYPERTENSION, INTOXICATION, TIME_SINCE_SLEPT, TIME_ELAPSED, WORK_DONE = range(6)

V0_VARIABLES: tuple[Variable, ...] = (
    Variable("alertness", description="sleepy (low) vs alert (high); wakes up near 1"),
    Variable("hypertension", 0.0, decay="params", description="blood pressure above normal"),
    Variable("intoxication", 0.0, decay="params", description="blood alcohol content"),
    Variable("time_since_slept", 0.0, description="half-hours since waking up"),
    Variable("time_elapsed", 0.0, description="half-hours since the episode began, sleep included"),
    Variable("work_done", description="total productivity so far"),
)


def score(work_done: ArrayOrFloat, time_elapsed: ArrayOrFloat) -> ArrayOrFloat:
    """The running productivity score ``work_done / time_elapsed`` (0 before any time has passed).

    ``time_elapsed`` counts whole half-hours, so dividing by at least 1 only changes the start, where both are 0.
    """
    if type(time_elapsed) is float:
        return work_done / (time_elapsed if time_elapsed > 1.0 else 1.0)
    return work_done / np.maximum(time_elapsed, 1.0)


def variable_names(variables: Sequence[Variable]) -> tuple[str, ...]:
    """The names of ``variables``, in observation order."""
    return tuple(v.name for v in variables)
