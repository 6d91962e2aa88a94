"""People differ: a population of people, each with their own numbers of the model, drawn per episode.

A [`People`][heartpole.people.People] says how each of the person's fields of
[`Params`][heartpole.parameters.Params] varies between people, in one of two ways:

- **a distribution**: each field given is fixed (a value) or [`Uniform`][heartpole.people.Uniform] in a
  range (integers with both ends included for an integer field; for the ``(low, high)`` pair
  ``wake_alertness``, each end uniform in its own range);
- **a finite cohort** of named people ([`Person`][heartpole.people.Person]), drawn with equal chances.

``max_steps`` and ``heart_attack_penalty`` are the task's, not the person's: every env of a vector env is
truncated at the same step and every episode is scored on the same scale, so they stay the env's own
keyword arguments (passing them here is a ``TypeError`` saying so). Fields a population does not set are
the env's too.

Sampling is vectorized: [`People.sample`][heartpole.people.People.sample] draws ``n`` people from a
``numpy.random.Generator`` at once and gives one row per env, one column per set field (a pair field gives
two: ``wake_alertness_low`` and ``wake_alertness_high``), plus the cohort index of each. The traits (the
columns that differ between people) and their bounds make the observation of a contextual env.

>>> import numpy as np
>>> people = People(heart_attack_proclivity=Uniform(0.3, 0.7), sleep_half_hours=Uniform(12, 20))
>>> drawn = people.sample(np.random.default_rng(0), 4)
>>> drawn.values.shape, people.traits
((4, 2), ('heart_attack_proclivity', 'sleep_half_hours'))
>>> len(People.default().cohort), People.resolve("default") == People.default()
(24, True)
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from heartpole.parameters import Params, check_integer, check_keywords, check_number, check_pair

TASK_FIELDS = ("max_steps", "heart_attack_penalty")
"""The fields of [`Params`][heartpole.parameters.Params] that belong to the task, not to a person."""
PERSON_FIELDS = tuple(f.name for f in dataclasses.fields(Params) if f.name not in TASK_FIELDS)
"""The fields of [`Params`][heartpole.parameters.Params] a population may vary (every other field)."""

Value = float | tuple[float, float]
"""A field's value: a number, or a ``(low, high)`` pair for ``wake_alertness``."""


@functools.cache  # asked at every step of a single env with people (its traits)
def _is_pair(field: str) -> bool:
    return isinstance(getattr(Params(), field), tuple)


@functools.cache
def _is_integer(field: str) -> bool:
    return isinstance(getattr(Params(), field), int)


def field_columns(field: str) -> tuple[str, ...]:
    """The columns of ``field`` in a sample: its name, or ``<name>_low`` and ``<name>_high`` for a pair."""
    return (f"{field}_low", f"{field}_high") if _is_pair(field) else (field,)


def _check_fields(function: str, given: Sequence[str], also: tuple[str, ...] = ()) -> None:
    """Python's ``TypeError`` for a keyword that is not a person's field (and why the task's are not)."""
    for name in given:
        if name in TASK_FIELDS:
            raise TypeError(
                f"{function}() got an unexpected keyword argument {name!r}: {' and '.join(TASK_FIELDS)} are the "
                f"task's, the same for everyone (pass them to the env); a person's fields are {list(PERSON_FIELDS)}"
            )
    check_keywords(function, given, PERSON_FIELDS + also)


def _as_value(field: str, value: object) -> object:
    """A list for a pair field becomes a tuple (as JSON gives it); anything else is left for Params to judge."""
    return tuple(value) if _is_pair(field) and isinstance(value, list) else value


def _checked_params(where: str, values: Mapping[str, object]) -> Params:
    """``Params(**values)``: the one validator of every field's rule, its error prefixed with ``where``."""
    try:
        return Params(**values)  # type: ignore[arg-type]
    except ValueError as error:
        raise ValueError(f"{where}: {error}") from None


@dataclass(frozen=True)
class Uniform:
    """A field uniform between ``low`` and ``high`` (both included for an integer field).

    For the pair field ``wake_alertness``, ``low`` and ``high`` are pairs and each end is drawn on its own:
    ``Uniform((0.6, 1.2), (0.8, 1.4))`` wakes a person between ``U(0.6, 0.8)`` and ``U(1.2, 1.4)``.

    Raises:
        ValueError: ends that are not numbers (or pairs of numbers), or ``low > high``.
    """

    low: Value
    high: Value

    def __post_init__(self) -> None:
        lows, highs = np.atleast_1d(_end(self.low)), np.atleast_1d(_end(self.high))
        if lows.shape != highs.shape or not bool(np.all(lows <= highs)):
            raise ValueError(f"Uniform(low, high) needs low <= high (elementwise for pairs), got {self!r}")

    def ends(self) -> tuple[Value, Value]:
        """``(low, high)`` with pairs as tuples."""
        return _end(self.low), _end(self.high)


def _end(end: object) -> Value:
    """A range's end: a finite number or a pair of them (a tuple), else ``ValueError``."""
    if isinstance(end, (tuple, list)):
        check_pair("a pair end of Uniform", end)
        return cast(tuple[float, float], tuple(end))
    check_number("Uniform's end (a finite number or a (low, high) pair of them)", end)
    return cast(float, end)


@dataclass(frozen=True, init=False)
class Person:
    """A named person: their values of some of [`PERSON_FIELDS`][heartpole.people.PERSON_FIELDS].

    ``Person("Ada", heart_attack_proclivity=0.5, sleep_half_hours=16)``; fields not given are the env's.

    Raises:
        TypeError: a keyword that is not a person's field (``max_steps``, ``heart_attack_penalty`` are the
            task's).
        ValueError: an empty name, no field, or a value [`Params`][heartpole.parameters.Params] refuses.
    """

    name: str
    traits: tuple[tuple[str, Value], ...]
    """The fields given, in [`Params`][heartpole.parameters.Params]' order, as ``(field, value)`` pairs."""

    def __init__(self, name: str, **traits: Value) -> None:
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"a person's name must be a non-empty string, got {name!r}")
        _check_fields("Person", list(traits))
        if not traits:
            raise ValueError(f"person {name!r}: give at least one of {list(PERSON_FIELDS)}")
        values = {field: _as_value(field, value) for field, value in traits.items()}
        _checked_params(f"person {name!r}", values)
        object.__setattr__(self, "name", name)
        ordered = tuple((field, values[field]) for field in PERSON_FIELDS if field in values)
        object.__setattr__(self, "traits", ordered)

    def values(self) -> dict[str, Value]:
        """The fields given, as a dict."""
        return dict(self.traits)

    def params(self, base: Params | None = None) -> Params:
        """``base`` (default: v0's [`Params`][heartpole.parameters.Params]) with this person's fields."""
        return dataclasses.replace(base or Params(), **self.values())  # type: ignore[arg-type]


@dataclass(frozen=True, init=False)
class People:
    """A population of people: per-field distributions, or a finite cohort (see the module docstring).

    ``People(heart_attack_proclivity=Uniform(0.3, 0.7), decay_rate=0.95)`` or ``People(cohort=[Person(...),
    ...])``; [`People.default`][heartpole.people.People.default] is a cohort the optimum solves.

    Raises:
        TypeError: a field that is not a person's (see [`PERSON_FIELDS`][heartpole.people.PERSON_FIELDS]), or
            a cohort member that is not a [`Person`][heartpole.people.Person].
        ValueError: nothing given, a cohort and fields together, repeated names, cohort members that give
            different fields, or a range with a value [`Params`][heartpole.parameters.Params] refuses (every
            corner of the ranges is checked by constructing ``Params``: its rules are intervals and
            ``low <= high``, so a valid box of corners holds only valid people).
    """

    fields: tuple[tuple[str, Value | Uniform], ...]
    """Each field of a distribution, in [`Params`][heartpole.parameters.Params]' order: a fixed value or a
    [`Uniform`][heartpole.people.Uniform] (empty for a cohort)."""
    cohort: tuple[Person, ...]
    """The named people of a finite cohort (empty for a distribution)."""

    def __init__(self, *, cohort: Sequence[Person] = (), **fields: Value | Uniform) -> None:
        _check_fields("People", list(fields), also=("cohort",))
        cohort = tuple(cohort)
        if cohort and fields:
            raise ValueError("give a cohort or per-field distributions, not both (a Person may set any field)")
        if not cohort and not fields:
            raise ValueError(f"a population needs a cohort or at least one of {list(PERSON_FIELDS)}")
        if cohort:
            _check_cohort(cohort)
        else:
            fields = {field: _as_value(field, value) for field, value in fields.items()}  # type: ignore[misc]
            _check_corners(fields)
        object.__setattr__(self, "cohort", cohort)
        ordered = tuple((field, fields[field]) for field in PERSON_FIELDS if field in fields)
        object.__setattr__(self, "fields", ordered)

    @classmethod
    def default(cls) -> People:
        """The default population: 24 named people whose every optimum the solver covers (see
        [`DEFAULT_COHORT`][heartpole.people.DEFAULT_COHORT])."""
        return _default()

    @classmethod
    def resolve(cls, people: People | str | None) -> People | None:
        """``people`` as a population: a [`People`][heartpole.people.People], a name (``"default"``) or ``None``.

        Raises:
            ValueError: an unknown name (the message lists the names).
            TypeError: anything else.
        """
        if people is None or isinstance(people, People):
            return people
        if isinstance(people, str):
            if people not in POPULATIONS:
                raise ValueError(f"unknown population {people!r}; named populations: {sorted(POPULATIONS)}")
            return POPULATIONS[people]()
        raise TypeError(f"people must be a People, one of {sorted(POPULATIONS)} or None, got {people!r}")

    @functools.cached_property
    def columns(self) -> tuple[str, ...]:
        """The columns of a sample: every field set, a pair field as two (see
        [`field_columns`][heartpole.people.field_columns])."""
        given = [f for f, _ in self.cohort[0].traits] if self.cohort else [f for f, _ in self.fields]
        return tuple(column for field in given for column in field_columns(field))

    @functools.cached_property
    def traits(self) -> tuple[str, ...]:
        """The columns that differ between people (a cohort's all, a distribution's uniform ones): what an
        env with ``observe_traits=True`` appends to the observation."""
        if self.cohort:
            return self.columns
        return tuple(c for f, spec in self.fields if isinstance(spec, Uniform) for c in field_columns(f))

    def trait_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` float32 arrays bounding [`traits`][heartpole.people.People.traits]: a Box's bounds."""
        index = [self.columns.index(column) for column in self.traits]
        low, high = self._bounds
        return low[index].astype(np.float32), high[index].astype(np.float32)

    @property
    def finite(self) -> bool:
        """Whether the population is a finite cohort (so each person's optimum can be solved once)."""
        return bool(self.cohort)

    def sample(self, rng: np.random.Generator, n: int) -> Sample:
        """Draw ``n`` people (one per env) from ``rng``, vectorized: the same generator state gives the same people.

        A cohort draws ``rng.integers(0, len(cohort), n)``; a distribution draws ``rng.random((n, k))`` for
        its ``k`` uniform columns (row by row: env ``i``'s people are the same whatever ``n``, so a single env
        draws what env 0 of a vector env draws) and maps column ``j`` to ``low + (high - low) * u`` (an
        integer field: ``low + floor((high - low + 1) * u)``, both ends included); a fixed one draws nothing.
        """
        n = check_integer("n", n, 0)
        if self.cohort:
            person = rng.integers(0, len(self.cohort), size=int(n))
            return Sample(self, person, self._table[person])
        uniforms = rng.random((int(n), len(self.traits)))
        columns, used = [], 0
        for field, spec in self.fields:
            width = len(field_columns(field)) if isinstance(spec, Uniform) else 0
            columns.append(self._draw(uniforms[:, used : used + width], field, spec, int(n)))
            used += width
        values = np.concatenate(columns, axis=1) if columns else np.zeros((int(n), 0))
        return Sample(self, np.full(int(n), -1, dtype=np.int64), values)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description (for ``info``, datasets' metadata and reports)."""
        if self.cohort:
            return {"cohort": [{"name": p.name, **_json(p.values())} for p in self.cohort]}

        def spec(value: Value | Uniform) -> Any:
            return {"uniform": [_json_value(v) for v in value.ends()]} if isinstance(value, Uniform) else value

        return {"fields": {field: _json_value(spec(value)) for field, value in self.fields}}

    @functools.cached_property
    def _table(self) -> np.ndarray:
        """A cohort's values: one row per person, one column per [`columns`][heartpole.people.People.columns]."""
        return np.array([_row(p.values()) for p in self.cohort], dtype=np.float64).reshape(len(self.cohort), -1)

    @functools.cached_property
    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.cohort:
            return self._table.min(axis=0), self._table.max(axis=0)
        low = {f: v.ends()[0] if isinstance(v, Uniform) else v for f, v in self.fields}
        high = {f: v.ends()[1] if isinstance(v, Uniform) else v for f, v in self.fields}
        return np.array(_row(low), dtype=np.float64), np.array(_row(high), dtype=np.float64)

    @staticmethod
    def _draw(uniforms: np.ndarray, field: str, spec: Value | Uniform, n: int) -> np.ndarray:
        """``field``'s columns for ``n`` people from ``uniforms`` in [0, 1), one column per column of it."""
        if not isinstance(spec, Uniform):
            return np.tile(np.array(_row({field: spec}), dtype=np.float64), (n, 1))
        low, high = (np.atleast_1d(np.asarray(end, dtype=np.float64)) for end in spec.ends())
        if _is_integer(field):
            return np.minimum(low + np.floor((high - low + 1.0) * uniforms), high)  # u < 1, but rounding
        return low + (high - low) * uniforms


@dataclass(frozen=True, eq=False)
class Sample:
    """People drawn for ``n`` envs by [`People.sample`][heartpole.people.People.sample].

    Attributes:
        people: the population drawn from.
        person: ``(n,)`` int64 cohort index of each env's person (-1 for a distribution).
        values: ``(n, len(people.columns))`` float64: each env's value of each column.
    """

    people: People
    person: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return len(self.person)

    @property
    def names(self) -> list[str]:
        """Each env's person's name (``""`` for a distribution's anonymous people)."""
        if not self.people.cohort:
            return [""] * len(self)
        names = np.array([p.name for p in self.people.cohort], dtype=object)
        return list(names[self.person])

    def traits(self) -> np.ndarray:
        """``(n, len(people.traits))`` float32: the observed traits (columns in
        [`People.traits`][heartpole.people.People.traits]' order)."""
        index = [self.people.columns.index(column) for column in self.people.traits]
        return self.values[:, index].astype(np.float32)

    def column(self, name: str, base: Params | None = None) -> np.ndarray:
        """``(n,)`` float64 values of any column of [`Params`][heartpole.parameters.Params] (``decay_rate``,
        ``wake_alertness_low``, ``max_steps`` ...): the drawn ones, else ``base``'s (default v0's) for all."""
        if name in self.people.columns:
            return self.values[:, self.people.columns.index(name)]
        known = {column: value for field in dataclasses.fields(Params) for column, value in _base(base, field.name)}
        if name not in known:
            raise ValueError(f"unknown column {name!r}; columns: {sorted(known)}")
        return np.full(len(self), known[name], dtype=np.float64)

    def params(self, index: int, base: Params | None = None) -> Params:
        """Env ``index``'s person as [`Params`][heartpole.parameters.Params]: ``base`` (default v0's) with the drawn
        fields (one env at a time: for reports and the solver, not for stepping)."""
        row = self.values[index]
        values: dict[str, Any] = {}
        for field, _ in self.people.cohort[0].traits if self.people.cohort else self.people.fields:
            found = [float(row[self.people.columns.index(c)]) for c in field_columns(field)]
            values[field] = tuple(found) if _is_pair(field) else int(found[0]) if _is_integer(field) else found[0]
        return dataclasses.replace(base or Params(), **values)


def _base(base: Params | None, field: str) -> list[tuple[str, float]]:
    value = getattr(base or Params(), field)
    return list(zip(field_columns(field), value)) if _is_pair(field) else [(field, float(value))]


def _row(values: Mapping[str, object]) -> list[float]:
    """The values of ``values``' fields, in [`PERSON_FIELDS`][heartpole.people.PERSON_FIELDS] order, pairs
    flattened (the columns of a sample)."""
    row: list[float] = []
    for field in PERSON_FIELDS:
        if field in values:
            value = values[field]
            row.extend(float(x) for x in (value if isinstance(value, tuple) else (value,)))
    return row


def _json_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def _json(values: Mapping[str, Value]) -> dict[str, Any]:
    return {field: _json_value(value) for field, value in values.items()}


def _check_cohort(cohort: tuple[Person, ...]) -> None:
    for member in cohort:
        if not isinstance(member, Person):
            raise TypeError(f"a cohort holds heartpole.people.Person values, got {member!r}")
    names = [p.name for p in cohort]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise ValueError(f"a cohort's names must differ; repeated: {repeated}")
    first = [f for f, _ in cohort[0].traits]
    for member in cohort[1:]:
        if [f for f, _ in member.traits] != first:
            raise ValueError(
                f"every person of a cohort gives the same fields: {cohort[0].name!r} gives {first}, "
                f"{member.name!r} gives {[f for f, _ in member.traits]}"
            )


def _check_corners(fields: Mapping[str, object]) -> None:
    """Construct [`Params`][heartpole.parameters.Params] at every corner of the ranges (its rules are convex)."""
    options: list[list[tuple[str, object]]] = []
    for field, spec in fields.items():
        if isinstance(spec, Uniform):
            low, high = spec.ends()
            if _is_pair(field):  # each end of the pair between its own low and high
                ends = [(a, b) for a in (low[0], high[0]) for b in (low[1], high[1])]  # type: ignore[index]
                options.append([(field, end) for end in ends])
            else:
                options.append([(field, low), (field, high)])
        else:
            options.append([(field, spec)])
    for corner in itertools.product(*options):
        _checked_params(f"People({', '.join(f'{k}={v!r}' for k, v in fields.items())})", dict(corner))


DEFAULT_COHORT: tuple[tuple[str, float, float, int, tuple[float, float]], ...] = (
    # name, heart_attack_proclivity, decay_rate, sleep_half_hours, wake_alertness
    ("Ada", 0.50, 0.97, 16, (0.70, 1.30)),
    ("Ben", 0.55, 0.93, 15, (0.85, 1.55)),
    ("Cleo", 0.75, 0.95, 19, (0.55, 1.35)),
    ("Dev", 0.40, 0.96, 16, (0.80, 1.50)),
    ("Eli", 0.45, 0.96, 13, (0.85, 1.55)),
    ("Fay", 0.45, 0.96, 20, (0.70, 1.50)),
    ("Gus", 0.80, 0.95, 14, (0.80, 1.50)),
    ("Hana", 0.50, 0.94, 16, (0.60, 1.10)),
    ("Ivo", 0.40, 0.96, 20, (0.75, 1.45)),
    ("Jun", 0.55, 0.95, 17, (0.70, 1.30)),
    ("Kai", 0.75, 0.93, 19, (0.50, 1.10)),
    ("Lea", 0.70, 0.94, 16, (0.90, 1.30)),
    ("Milo", 0.50, 0.93, 15, (0.85, 1.25)),
    ("Nia", 0.30, 0.95, 18, (0.65, 1.15)),
    ("Omar", 0.60, 0.94, 13, (0.50, 1.00)),
    ("Pia", 0.35, 0.95, 19, (0.80, 1.40)),
    ("Quinn", 0.65, 0.96, 13, (0.55, 1.15)),
    ("Rui", 0.35, 0.94, 17, (0.75, 1.55)),
    ("Sara", 0.60, 0.94, 13, (0.65, 1.15)),
    ("Theo", 0.65, 0.96, 18, (0.60, 1.20)),
    ("Uma", 0.75, 0.94, 17, (0.70, 1.40)),
    ("Vik", 0.55, 0.97, 14, (0.60, 1.10)),
    ("Wen", 0.65, 0.97, 12, (0.75, 1.35)),
    ("Xena", 0.40, 0.95, 15, (0.65, 1.05)),
)
"""The default cohort: 24 people. Ada is the tutorial's own (v0's defaults); the other 23 are a Latin
hypercube drawn once with ``numpy.random.default_rng(26)`` (one stratified permutation per column, in the
order proclivity, sleep, waking low, waking width, decay) and rounded: heart_attack_proclivity in
[0.3, 0.8] (to 0.05), sleep_half_hours in 12..20 (6 to 10 hours), wake_alertness starting in [0.5, 0.9]
and 0.4 to 0.8 wide (to 0.05 and 0.1), decay_rate in [0.93, 0.97] (to 0.01; at most 0.95 below
proclivity 0.4, where the optimum's proof that drinks never pay needs it). The optimum covers every one of
them (tested). Why 24: a solve takes 2-4 s alone and about 5 s with two at once on a busy two-core machine,
so the first solve of all of them stays well under two minutes (``benchmarks/people_solve.py``), then loads
from the cache in well under a second. Proclivity and decay_rate do not change the optimal sleep timing (an
optimal policy never drinks), only the heart-attack floor and what a drink costs;
sleep_half_hours and wake_alertness change the timing."""


@functools.lru_cache(maxsize=1)
def _default() -> People:
    cohort = [
        Person(name, heart_attack_proclivity=p, decay_rate=d, sleep_half_hours=s, wake_alertness=w)
        for name, p, d, s, w in DEFAULT_COHORT
    ]
    return People(cohort=cohort)


POPULATIONS: Mapping[str, Callable[[], People]] = {"default": _default}
"""The named populations [`People.resolve`][heartpole.people.People.resolve] knows."""


def check_observe_traits(observe_traits: Any, people: People | None) -> bool:
    """``observe_traits`` as a bool: ``TypeError`` unless it is one (NumPy's too), ``ValueError`` if it is true
    without a population (``people``) whose traits to observe. The one rule of every env, NumPy's and JAX's."""
    if not isinstance(observe_traits, (bool, np.bool_)):
        raise TypeError(f"observe_traits must be True or False, got {observe_traits!r}")
    if observe_traits and people is None:
        raise ValueError("observe_traits=True needs a population: pass people= (e.g. people='default')")
    return bool(observe_traits)
