"""HeartPole's actions as data: what each one does to which state variable, by which random amount.

An [`Action`][heartpole.actions.Action] never runs code of its own;
[`heartpole.dynamics.Dynamics`][heartpole.dynamics.Dynamics] interprets the data, the same way for the single env and
for the vector env. That is how a user adds an action (the tutorial's homework) without touching the physiology::

    tea = Action("drink_tea", {"alertness": (0.0, 0.4), "hypertension": (0.0, 0.1)},
                 fact="Tea holds about half the caffeine of coffee.")
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from heartpole.parameters import V0_VARIABLES, Variable, check_integer, check_pair

MAX_REST_HALF_HOURS = 48
"""The longest rest an action may take (a day): each rest half-hour is computed every step."""

Effects = Mapping[str, tuple[float, float]]


@dataclass(frozen=True)
class Action:
    """One choice the agent can make every half-hour, before the half-hour of work that follows it.

    Attributes:
        name: a short identifier, shown in the text log and by the envs' ``action_names``.
        effects: ``{variable: (low, high)}``: the action adds a uniform random amount in [low, high] to
            each named state variable, drawn afresh every time.
        rest_half_hours: half-hours that pass without work after the effects (a nap, exercise).
            Hypertension and intoxication fade and alertness decays during them, as in any half-hour.
        sleeps: if true, the agent sleeps ``Params.sleep_half_hours`` half-hours and then wakes up
            (fact 1: fresh alertness, ``time_since_slept`` reset), after any rest.
        fact: the one-line fact behind the action, for the manual.
        source: where the fact comes from.

    >>> tea = Action("drink_tea", effects={"alertness": (0.0, 0.5), "hypertension": (0.0, 0.15)})
    >>> tea.is_drink, tea.effects["alertness"]
    (True, (0.0, 0.5))
    >>> Action("drink_tea", effects={"alertness": (0.5, 0.0)})
    Traceback (most recent call last):
    ...
    ValueError: Action 'drink_tea': effect on 'alertness' must be finite numbers with low <= high, got (0.5, 0.0)
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
        check_integer(f"Action {self.name!r}: rest_half_hours", self.rest_half_hours, 0)
        if self.rest_half_hours > MAX_REST_HALF_HOURS:
            raise ValueError(
                f"Action {self.name!r} rests {self.rest_half_hours} half-hours; at most {MAX_REST_HALF_HOURS} (a "
                "day) are accepted. For a night's sleep use sleeps=True and the sleep_half_hours parameter"
            )
        if not isinstance(self.sleeps, bool):
            raise ValueError(f"Action {self.name!r}: sleeps must be True or False, got {self.sleeps!r}")

    @property
    def is_drink(self) -> bool:
        """Whether the action raises intoxication or hypertension (a drink, in the evaluation's counts)."""
        return any(name in ("hypertension", "intoxication") and high > 0 for name, (_, high) in self.effects.items())


def _frozen_effects(action: str, effects: object) -> Mapping[str, tuple[float, float]]:
    if not isinstance(effects, Mapping):
        raise ValueError(
            f"Action {action!r}: effects must be a mapping {{variable: (low, high)}}, got {type(effects).__name__}"
        )
    frozen: dict[str, tuple[float, float]] = {}
    for variable, bounds in effects.items():
        if not isinstance(variable, str):
            raise ValueError(f"Action {action!r}: effect keys must be variable names, got {variable!r}")
        low, high = check_pair(f"Action {action!r}: effect on {variable!r}", bounds)
        if low > high:
            raise ValueError(
                f"Action {action!r}: effect on {variable!r} must be finite numbers with low <= high, got {bounds!r}"
            )
        frozen[variable] = (low, high)
    return _ReadOnlyDict(frozen)


class _ReadOnlyDict(dict):  # type: ignore[type-arg]
    """A dict that cannot change after construction, so a frozen Action stays frozen and hashable."""

    def _refuse(self, *args: object, **kwargs: object) -> None:
        raise TypeError("an Action's effects cannot be changed; build a new Action instead")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _refuse  # type: ignore[assignment]

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted(self.items())))

    def __reduce__(self) -> tuple[Any, tuple[dict[str, tuple[float, float]]]]:
        return (_ReadOnlyDict, (dict(self),))

    def __copy__(self) -> _ReadOnlyDict:
        return self

    def __deepcopy__(self, memo: dict[int, object]) -> _ReadOnlyDict:
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


# --------------------------------------------------------------------------------------------------------
# HeartPole-v1: the tutorial's homework. v0's four actions keep their indices 0-3; four new ones follow.
# Amounts are in HeartPole's units, set against v0's: a coffee, U(0, 0.3) of hypertension, stands for
# caffeine's acute rise of about 8 mm Hg systolic (Mesas et al. 2011), so 0.1 of hypertension is about
# 5 mm Hg; alertness is about 1 on waking (fact 1).

THC = Variable(
    "thc",
    0.0,
    decay=0.7,
    description="THC level: relieves anxiety (anxiety_relief 1); fades 0.7 a half-hour, a half-life of about an hour",
    anxiety_relief=1.0,
)
"""THC in the blood, the state cannabis needs: it moves the onset of crippling anxiety (fact 7) one unit of
alertness higher per unit, and fades by 0.7 a half-hour, since smoked cannabis acts within minutes, peaks
after 15-30 minutes and wears off over 2-3 hours (Grotenhermen F (2003) Pharmacokinetics and
pharmacodynamics of cannabinoids. Clin Pharmacokinet 42(4):327-360): after three hours 0.7 ** 6 = 12% is left."""

V1_VARIABLES: tuple[Variable, ...] = (*V0_VARIABLES, THC)
"""HeartPole-v1's state: v0's six variables, then ``thc`` (index 6)."""

DRINK_TEA = Action(
    "drink_tea",
    {"alertness": (0.0, 0.5), "hypertension": (0.0, 0.15)},
    fact="Tea holds about half the caffeine of coffee (black tea ~47 mg a cup, brewed coffee ~96 mg): half a "
    "coffee's alertness and blood pressure.",
    source="Mayo Clinic, Caffeine content for coffee, tea, soda and more, https://www.mayoclinic.org/"
    "healthy-lifestyle/nutrition-and-healthy-eating/in-depth/caffeine/art-20049372",
)
TAKE_NAP = Action(
    "take_nap",
    {"alertness": (0.3, 0.6)},
    rest_half_hours=1,
    fact="A short nap restores alertness: NASA's planned 40-minute cockpit rest (26 minutes asleep on "
    "average) improved pilots' performance by 34% and physiological alertness by 54%.",
    source="Rosekind MR et al. (1995) Alertness management: strategic naps in operational settings. "
    "J Sleep Res 4(Suppl 2):62-66; NASA Technical Memorandum 108839 (1994)",
)
EXERCISE = Action(
    "exercise",
    {"hypertension": (-0.15, -0.05)},
    rest_half_hours=2,
    fact="An hour of aerobic exercise lowers blood pressure by about 5-7 mm Hg for up to 22 hours, at the "
    "cost of an hour without work in which alertness keeps draining.",
    source="Pescatello LS et al. (2004) American College of Sports Medicine position stand: Exercise and "
    "hypertension. Med Sci Sports Exerc 36(3):533-553",
)
SMOKE_CANNABIS = Action(
    "smoke_cannabis",
    {"thc": (0.5, 1.0), "alertness": (-0.4, 0.0), "hypertension": (0.0, 0.2)},
    fact="Cannabis relieves anxiety but dulls attention, and raises heart rate and blood pressure: the risk "
    "of a heart attack is 4.8 times higher in the hour after smoking.",
    source="Cuttler C, Spradlin A, McLaughlin RJ (2018) A naturalistic examination of the perceived effects "
    "of cannabis on negative affect. J Affect Disord 235:198-205 (58% less anxiety reported); Mittleman MA "
    "et al. (2001) Triggering myocardial infarction by marijuana. Circulation 103(23):2805-2809",
)

V1_NEW_ACTIONS: tuple[Action, ...] = (DRINK_TEA, TAKE_NAP, EXERCISE, SMOKE_CANNABIS)
"""The actions HeartPole-v1 adds to v0's, as indices 4-7."""

V1_ACTIONS: tuple[Action, ...] = (*V0_ACTIONS, *V1_NEW_ACTIONS)
"""HeartPole-v1's action set: v0's four (same indices), then tea, nap, exercise and cannabis."""

ACTION_FIELDS: tuple[str, ...] = ("name", "effects", "rest_half_hours", "sleeps", "fact", "source")
"""The fields of an action definition, in [`Action`][heartpole.actions.Action]'s order."""


def as_action(definition: Action | Mapping[str, Any], position: int | None = None) -> Action:
    """An [`Action`][heartpole.actions.Action] from itself or from a mapping of its fields (say, read from a JSON or
    YAML file).

    ``{"name": "drink_tea", "effects": {"alertness": [0, 0.5]}}`` gives ``Action("drink_tea", {...})``.

    Raises:
        ValueError: not an Action or a mapping, a missing ``name``, an unknown field or a malformed value;
            the message names the action (or its ``position`` in a list) and the accepted fields.
    """
    where = f"action #{position}" if position is not None else "action"
    if isinstance(definition, Action):
        return definition
    if not isinstance(definition, Mapping):
        raise ValueError(
            f"{where} must be a heartpole.Action or a mapping with fields {list(ACTION_FIELDS)}, got "
            f"{type(definition).__name__} {definition!r}"
        )
    unknown = [key for key in definition if key not in ACTION_FIELDS]
    if unknown:
        raise ValueError(f"{where} has unknown field(s) {unknown}; accepted fields are {list(ACTION_FIELDS)}")
    if "name" not in definition:
        raise ValueError(f"{where} is missing its 'name'; accepted fields are {list(ACTION_FIELDS)}")
    return Action(**definition)
