"""People in the JAX env: a population drawn per episode, and each person's numbers as the step's parameters.

A [`Population`][heartpole.jax.population.Population] is a [`People`][heartpole.people.People] bound to a
variant's [`Dynamics`][heartpole.dynamics.Dynamics]. It draws a person from a key (jittable, ``vmap``-able)
and turns the person's values into the step's tables with
[`step_tables`][heartpole.dynamics.step_tables] itself, run on arrays of values (one per person) instead of
one number each: which entries of the tables depend on the person is read from that run (an entry computed
from the values is an array, every other one a number), so no rule of what a field changes is written here.

Those entries replace the same entries of the ``EnvParams`` the env is given; everything else (the task's
``heart_attack_penalty`` and step limit, the actions' effects, the floors) stays the given params'.
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Callable
from typing import Any, cast

import jax
import jax.numpy as jnp
import numpy as np

from heartpole.dynamics import Dynamics, step_tables
from heartpole.model import ActionEffects, StepTables, table_fields
from heartpole.parameters import Params
from heartpole.people import People, Uniform, field_columns

Tables = tuple[tuple[ActionEffects, ...], StepTables]
"""Each action's [`ActionEffects`][heartpole.model.ActionEffects] and the
[`StepTables`][heartpole.model.StepTables], as [`step_tables`][heartpole.dynamics.step_tables] returns them."""

EFFECTS, TABLES = table_fields(ActionEffects), table_fields(StepTables)


def _element(value: Any) -> Any:
    """step_tables' number type: a person's array stays an array (float32), anything else a float32 number."""
    return value.astype(np.float32) if np.ndim(value) > 0 else np.float32(value)


def _is_person(value: Any) -> bool:
    return bool(np.ndim(value) > 0)


class Population:
    """A population of people bound to a variant: draws people and gives their tables.

    Args:
        people: the population.
        dynamics: the variant; fields a population does not set are its ``params``' (the env's own).

    Attributes:
        people: the population.
        columns: the columns of a person's values ([`People.columns`][heartpole.people.People.columns]).
        traits: the columns observed with ``observe_traits`` ([`People.traits`][heartpole.people.People.traits]).
        trait_index: where the traits are among the columns.
    """

    def __init__(self, people: People, dynamics: Dynamics) -> None:
        self.people, self.dynamics = people, dynamics
        self.columns, self.traits = people.columns, people.traits
        self.trait_index = np.array([self.columns.index(c) for c in self.traits], dtype=np.int32)
        self._cohort_values: jax.Array | None = None
        if people.cohort:
            table = np.array([_values_row(dict(p.traits)) for p in people.cohort], dtype=np.float64)
            self._cohort_values = jnp.asarray(table, dtype=jnp.float32)
            # float64 arithmetic rounded once to float32, as Dynamics does: a person's tables equal an env's
            # made with that person's Params, bit for bit
            self._cohort_tables = _map_person(jnp.asarray, self.tables(table))
            self._personal = _personal_fields(self._cohort_tables)

    @property
    def cohort_values(self) -> jax.Array | None:
        """A cohort's values, ``(len(cohort), len(columns))`` float32, row ``i`` person ``i``'s; ``None`` for a
        distribution."""
        return self._cohort_values

    def tables(self, values: Any) -> Tables:
        """The tables of ``n`` people from their ``(n, len(columns))`` values (NumPy, or JAX to trace):
        entries that depend on the person are ``(n,)`` float32 arrays, the others float32 numbers."""
        params = {f.name: getattr(self.dynamics.params, f.name) for f in dataclasses.fields(Params)}
        at = 0
        for field in dict.fromkeys(column_field(c) for c in self.columns):
            width = len(field_columns(field))
            found = [values[:, at + i] for i in range(width)]
            params[field] = tuple(found) if width > 1 else found[0]
            at += width
        # a Params that holds arrays: step_tables only reads its fields (Params itself checks one person)
        person = cast(Params, types.SimpleNamespace(**params))
        # step_tables calls ``number`` on every number it makes, which is all _element needs of a type
        return step_tables(self.dynamics.actions, self.dynamics.variables, person, number=cast(type, _element))

    def draw(self, key: jax.Array, uniform: jax.Array) -> tuple[jax.Array, jax.Array]:
        """One person: ``(person, values)``, the cohort index (int32, -1 for a distribution) and the
        ``(len(columns),)`` float32 values. A cohort's person is ``floor(uniform * len(cohort))`` (``uniform`` in
        [0, 1) on a grid of ``2 ** -24``: equal chances to 1e-6); a distribution draws each uniform field in its
        range from ``key`` (integers with both ends included) and keeps each fixed one."""
        if self._cohort_values is not None:
            size = len(self.people.cohort)
            person = jnp.minimum((uniform * size).astype(jnp.int32), size - 1)
            return person, self._cohort_values[person]
        keys = jax.random.split(key, len(self.people.fields))
        columns = [_draw_field(k, field, spec) for k, (field, spec) in zip(keys, self.people.fields)]
        return jnp.int32(-1), jnp.concatenate(columns).astype(jnp.float32)

    def params_of(
        self,
        effects: ActionEffects,
        tables: StepTables,
        person: jax.Array,
        values: jax.Array,
        action: jax.Array | None = None,
    ) -> tuple[ActionEffects, StepTables]:
        """One drawn person's ``effects`` and ``tables`` (an ``EnvParams``' arrays; with ``action``, only that
        action's row of ``effects``): the given arrays with the entries ``person``'s values set.

        A cohort member's entries are read by ``[person]`` (``[person, action]``) from the whole cohort merged
        with the given arrays (`merge`), in the fields some member sets alone, so no env builds a table of its
        own. The merged cohort passes an optimization barrier, so that XLA builds it once rather than inside each
        env's fused kernel: on a CPU the people's step ran about 40% faster (docs/jax.md, "People on a GPU").
        A distribution's person's entries are computed from ``values``."""
        if self._cohort_values is None:
            first: Callable[[Any], Any] = lambda x: x[0]  # noqa: E731
            mine = jax.tree_util.tree_map(first, self.merge(effects, tables, self.tables(values[None]), 1))
            if action is None:
                return cast(tuple[ActionEffects, StepTables], mine)
            return jax.tree_util.tree_map(lambda table: table[action], mine[0]), mine[1]
        merged = self.merge(effects, tables, self._cohort_tables, len(self.people.cohort))
        merged_effects, merged_tables = jax.lax.optimization_barrier(merged)
        at = (person,) if action is None else (person, action)
        row = {name: getattr(merged_effects, name)[at] for name in self._personal[0]}
        if action is not None:
            row = {name: getattr(effects, name)[action] for name in effects._fields} | row
        personal = {name: getattr(merged_tables, name)[person] for name in self._personal[1]}
        return effects._replace(**row), tables._replace(**personal)

    @staticmethod
    def merge(effects: ActionEffects, tables: StepTables, person: Tables, n: int) -> tuple[ActionEffects, StepTables]:
        """``effects`` and ``tables`` (an ``EnvParams``' arrays: ``(num_actions, ...)`` and per variable) for
        ``n`` people: each leaf gains a leading ``(n,)`` axis, the person's entries replacing the given ones."""
        person_effects, person_step = person

        def pick(mine: Any, given: jax.Array) -> jax.Array:
            return jnp.asarray(mine) if _is_person(mine) else jnp.broadcast_to(given, (n,))

        def per_action(name: str, per_variable: bool) -> jax.Array:
            given = getattr(effects, name)
            rows = [getattr(e, name) for e in person_effects]
            if per_variable:
                return jnp.stack([jnp.stack([pick(r[v], given[a, v]) for v in range(len(r))], -1)
                                  for a, r in enumerate(rows)], 1)  # fmt: skip
            return jnp.stack([pick(r, given[a]) for a, r in enumerate(rows)], 1)

        def per_variable(name: str) -> jax.Array:
            given = getattr(tables, name)
            return jnp.stack([pick(x, given[v]) for v, x in enumerate(getattr(person_step, name))], -1)

        changed: dict[str, Any] = {name: per_action(name, True) for name in EFFECTS.per_variable}
        changed |= {name: per_action(name, False) for name in EFFECTS.numbers}
        new_effects = effects._replace(**changed)
        changed = {name: per_variable(name) for name in TABLES.per_variable}
        changed |= {name: pick(getattr(person_step, name), getattr(tables, name)) for name in TABLES.numbers}
        return new_effects, tables._replace(**changed)


def column_field(column: str) -> str:
    """The field of [`Params`][heartpole.parameters.Params] a column of values belongs to."""
    for suffix in ("_low", "_high"):
        field = column.removesuffix(suffix)
        if field != column and field_columns(field) != (field,):
            return field
    return column


def _values_row(values: dict[str, Any]) -> list[float]:
    return [float(x) for value in values.values() for x in (value if isinstance(value, tuple) else (value,))]


def _draw_field(key: jax.Array, field: str, spec: Any) -> jax.Array:
    """A field's columns for one person: fixed, or uniform in its range (an integer field's ends included)."""
    if not isinstance(spec, Uniform):
        return jnp.asarray(_values_row({field: spec}), dtype=jnp.float32)
    low, high = (np.atleast_1d(np.asarray(end, dtype=np.float64)) for end in spec.ends())
    if isinstance(getattr(Params(), field), int):
        drawn = jax.random.randint(key, low.shape, low.astype(np.int32), high.astype(np.int32) + 1)
        return drawn.astype(jnp.float32)
    return jax.random.uniform(key, low.shape, jnp.float32, low.astype(np.float32), high.astype(np.float32))


def _personal_fields(tables: Tables) -> tuple[frozenset[str], frozenset[str]]:
    """The fields of ``tables``' ``ActionEffects`` and ``StepTables`` in which some entry is a person's."""
    effects, step = tables

    def sets(table: Any) -> bool:
        return any(_is_person(x) for x in jax.tree_util.tree_leaves(table))

    return (
        frozenset(name for e in effects for name in e._fields if sets(getattr(e, name))),
        frozenset(name for name in step._fields if sets(getattr(step, name))),
    )


def _map_person(function: Callable[[Any], Any], tables: Tables) -> Tables:
    """``tables`` with ``function`` applied to each person entry (the arrays), numbers left as they are."""
    return cast(Tables, jax.tree_util.tree_map(lambda x: function(x) if _is_person(x) else x, tables))
