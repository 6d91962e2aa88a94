"""HeartPole's actions as data: what each one does to which state variable, by which random amount.

An :class:`Action` never runs code of its own; :class:`heartpole.dynamics.Dynamics` interprets the
data, the same way for the single env and for the vector env. That is how a user adds an action (the
tutorial's homework) without touching the physiology::

    tea = Action("drink_tea", {"alertness": (0.0, 0.4), "hypertension": (0.0, 0.1)},
                 fact="Tea holds about half the caffeine of coffee.")
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

Effects = Mapping[str, tuple[float, float]]


@dataclass(frozen=True)
class Action:
    """One choice the agent can make every half-hour, before the half-hour of work that follows it.

    Attributes:
        name: a short identifier, shown in ``info["action"]`` and in the text log.
        effects: ``{variable: (low, high)}``: the action adds a uniform random amount in [low, high] to
            each named state variable, drawn afresh every time.
        rest_half_hours: half-hours that pass without work after the effects (a nap, exercise).
            Hypertension and intoxication fade and alertness decays during them, as in any half-hour.
        sleeps: if true, the agent sleeps ``Params.sleep_half_hours`` half-hours and then wakes up
            (fact 1: fresh alertness, ``time_since_slept`` reset), after any rest.
        fact: the one-line fact behind the action, for the manual.
        source: where the fact comes from.
    """

    name: str
    effects: Effects = field(default_factory=dict)
    rest_half_hours: int = 0
    sleeps: bool = False
    fact: str = ""
    source: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"Action name must be a non-empty identifier such as 'drink_tea', got {self.name!r}")
        object.__setattr__(self, "effects", _frozen_effects(self.name, self.effects))
        rest = self.rest_half_hours
        if isinstance(rest, bool) or not isinstance(rest, (int, np.integer)) or rest < 0:
            raise ValueError(f"Action {self.name!r}: rest_half_hours must be an integer >= 0, got {rest!r}")
        if not isinstance(self.sleeps, bool):
            raise ValueError(f"Action {self.name!r}: sleeps must be True or False, got {self.sleeps!r}")

    @property
    def is_drink(self) -> bool:
        """Whether the action raises intoxication or hypertension (a drink, in the evaluation's counts)."""
        return any(name in ("hypertension", "intoxication") and high > 0 for name, (_, high) in self.effects.items())


def _frozen_effects(action: str, effects: Any) -> Mapping[str, tuple[float, float]]:
    if not isinstance(effects, Mapping):
        raise ValueError(
            f"Action {action!r}: effects must be a mapping {{variable: (low, high)}}, got {type(effects).__name__}"
        )
    frozen: dict[str, tuple[float, float]] = {}
    for variable, bounds in effects.items():
        if not isinstance(variable, str):
            raise ValueError(f"Action {action!r}: effect keys must be variable names, got {variable!r}")
        if not (isinstance(bounds, (tuple, list)) and len(bounds) == 2):
            raise ValueError(f"Action {action!r}: effect on {variable!r} must be a (low, high) pair, got {bounds!r}")
        low, high = bounds
        numbers = all(
            isinstance(b, (int, float, np.integer, np.floating)) and not isinstance(b, bool) and math.isfinite(b)
            for b in bounds
        )
        if not numbers or low > high:
            raise ValueError(
                f"Action {action!r}: effect on {variable!r} must be finite numbers with low <= high, got {bounds!r}"
            )
        frozen[variable] = (float(low), float(high))
    return _ReadOnlyDict(frozen)


class _ReadOnlyDict(dict):  # type: ignore[type-arg]
    """A dict that cannot change after construction, so a frozen Action stays frozen and hashable."""

    def _refuse(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("an Action's effects cannot be changed; build a new Action instead")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _refuse  # type: ignore[assignment]

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted(self.items())))

    def __reduce__(self) -> tuple[Any, tuple[dict[str, tuple[float, float]]]]:
        return (_ReadOnlyDict, (dict(self),))

    def __copy__(self) -> _ReadOnlyDict:
        return self

    def __deepcopy__(self, memo: dict[int, Any]) -> _ReadOnlyDict:
        return self


DO_NOTHING = Action("do_nothing", fact="Fact 0: keep working as you are.")
DRINK_COFFEE = Action(
    "drink_coffee",
    {"alertness": (0.0, 1.0), "hypertension": (0.0, 0.3)},
    fact="Fact 2: caffeine increases alertness and blood pressure.",
)
DRINK_BEER = Action(
    "drink_beer",
    {"alertness": (-0.5, 0.0), "hypertension": (0.0, 0.3), "intoxication": (0.01, 0.03)},
    fact="Fact 3: alcohol decreases alertness, increases intoxication and blood pressure.",
    source="https://attorneydwi.com/b-a-c-per-drink/ (blood alcohol per drink)",
)
SLEEP = Action("sleep", sleeps=True, fact="Sleep 16 half-hours, then wake up quite alert (fact 1).")

V0_ACTIONS: tuple[Action, ...] = (DO_NOTHING, DRINK_COFFEE, DRINK_BEER, SLEEP)
