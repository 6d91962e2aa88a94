"""The numbers of the model a variant may change, its state variables, and the checks every input goes through.

[`Params`][heartpole.parameters.Params] and [`Variable`][heartpole.parameters.Variable] describe a variant;
[`heartpole.dynamics`][heartpole.dynamics] turns them into the tables that [`heartpole.model`][heartpole.model]'s
step reads. The checks (``check_number``, ``check_integer`` ...) are the one rule for a number, used by every
module that takes one from a user. Nothing here is compiled: editing a message recompiles no loop.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from heartpole.model import kept_by_the_step

MAX_STEPS = 2**53
"""The longest episode ``max_steps`` may ask for: the largest count a float64 holds exactly (the solver and the
rates count time in float64; the step counters are 64-bit integers)."""


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
        check_number("heart_attack_proclivity", self.heart_attack_proclivity, 0.0, 1.0)
        check_integer("max_steps", self.max_steps, 1, MAX_STEPS)
        check_number("decay_rate", self.decay_rate, 0.0, 1.0, low_open=True)
        check_integer("sleep_half_hours", self.sleep_half_hours, 0)
        check_number("heart_attack_penalty", self.heart_attack_penalty, 0.0, math.inf)
        low, high = check_pair("wake_alertness", self.wake_alertness)
        if not low <= high:
            raise ValueError(f"wake_alertness must be (low, high) with low <= high, got {self.wake_alertness!r}")


def is_number(value: object) -> bool:
    """Whether ``value`` is a real number: a Python or NumPy int or float, not a bool."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_number(
    name: str,
    value: Any,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    finite: bool = True,
) -> float:
    """``value`` as a float, or ``ValueError`` naming ``name`` unless it is a number (not a bool), finite unless
    ``finite`` is false (NaN never passes), in [low, high] (``(low, high]`` with ``low_open``)."""
    in_range = is_number(value) and (low < value if low_open else low <= value) and value <= high
    if not in_range or (finite and not math.isfinite(value)):
        kind = "a finite number" if finite else "a number (or +-math.inf)"
        bracket = "(" if low_open else "["
        interval = f" in {bracket}{low}, {high}]" if math.isfinite(low) or math.isfinite(high) else ""
        raise ValueError(f"{name} must be {kind}{interval}, got {value!r}")
    return float(value)


def check_pair(name: str, value: Any) -> tuple[float, float]:
    """``value`` as a ``(low, high)`` pair of finite numbers, or ``ValueError`` naming ``name``."""
    if not (isinstance(value, (tuple, list)) and len(value) == 2):
        raise ValueError(f"{name} must be a (low, high) pair of numbers, got {value!r}")
    return check_number(name, value[0]), check_number(name, value[1])


def check_keywords(function: str, given: Iterable[str], accepted: Iterable[str]) -> None:
    """Raise Python's ``TypeError`` for keyword arguments of ``function`` outside ``accepted``, naming those.

    The message starts as Python's own (``f() got an unexpected keyword argument 'x'``): libraries branch on
    it (TorchRL retries an env without ``frameskip`` on exactly that error).
    """
    known = list(accepted)
    unexpected = [name for name in given if name not in known]
    if unexpected:
        also = f" (and {', '.join(map(repr, unexpected[1:]))})" if unexpected[1:] else ""
        raise TypeError(
            f"{function}() got an unexpected keyword argument {unexpected[0]!r}{also}; it accepts {sorted(known)}"
        )


def check_integer(name: str, value: Any, minimum: int, maximum: int | None = None) -> int:
    """``value`` as an int, or ``ValueError`` naming ``name`` unless it is an integer (not a bool) >= ``minimum``
    (and <= ``maximum`` where given)."""
    integer = is_number(value) and isinstance(value, (int, np.integer))
    if not (integer and value >= minimum and (maximum is None or value <= maximum)):
        bounds = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum:,}]"
        raise ValueError(f"{name} must be an integer {bounds}, got {value!r}")
    return int(value)


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
    decay: float | Literal["params"] | None = None
    description: str = ""
    anxiety_relief: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"a variable name must be an identifier such as 'stress', got {self.name!r}")
        where = f"variable {self.name!r}"
        for bound in ("low", "high"):
            check_number(f"{where}: {bound}", getattr(self, bound), finite=False)
        if not self.low <= 0.0 <= self.high:
            raise ValueError(
                f"{where}: every variable starts at 0, so low <= 0 <= high is needed; got [{self.low}, {self.high}]"
            )
        decay_ok = self.decay is None or self.decay == "params" or (is_number(self.decay) and 0.0 < self.decay <= 1.0)
        if not decay_ok:
            raise ValueError(
                f"{where}: decay must be None (no fading), 'params' (fades like hypertension) or the share left "
                f"after a half-hour, in (0, 1]; got {self.decay!r}"
            )
        check_number(f"{where}: anxiety_relief", self.anxiety_relief)
        if not isinstance(self.description, str):
            raise ValueError(f"{where}: description must be a string, got {self.description!r}")

    def decay_factor(self, params: Params) -> float | None:
        """The per-half-hour factor of this variable under ``params``, or ``None`` if it does not fade."""
        return params.decay_rate if self.decay == "params" else self.decay


V0_VARIABLES: tuple[Variable, ...] = (
    Variable("alertness", description="sleepy (low) vs alert (high); wakes up near 1"),
    Variable("hypertension", 0.0, decay="params", description="blood pressure above normal"),
    Variable("intoxication", 0.0, decay="params", description="blood alcohol content"),
    Variable("time_since_slept", 0.0, description="half-hours since waking up"),
    Variable("time_elapsed", 0.0, description="half-hours since the episode began, sleep included"),
    Variable("work_done", description="total productivity so far"),
)


BOOKKEEPING: tuple[str, ...] = tuple(v.name for i, v in enumerate(V0_VARIABLES) if kept_by_the_step(i))
"""The names of the variables the step keeps itself ([`kept_by_the_step`][heartpole.model.kept_by_the_step]):
no action may write to them."""


def variable_names(variables: Sequence[Variable]) -> tuple[str, ...]:
    """The names of ``variables``, in observation order."""
    return tuple(v.name for v in variables)
