"""Each env's person as the numbers the compiled loop ([`heartpole.kernel`][heartpole.kernel]) reads from ``cells``.

[`PersonTables`][heartpole.person_tables.PersonTables] binds a population
([`People`][heartpole.people.People]) to a variant ([`Dynamics`][heartpole.dynamics.Dynamics]): which numbers
of the packed tables differ between people (the *slots*), and, for people drawn
([`Sample`][heartpole.people.Sample]), each env's values of them. The numbers come from
[`step_tables`][heartpole.dynamics.step_tables], the one place that turns [`Params`][heartpole.parameters.Params]
into tables: a cohort's members one by one (so an env of the cohort's person is an env made with that person's
``Params`` bit for bit), a distribution's people all at once (NumPy arrays in place of the parameters).
"""

from __future__ import annotations

import dataclasses
import types

import numpy as np

from heartpole import kernel
from heartpole.dynamics import Dynamics, step_tables
from heartpole.parameters import Params
from heartpole.people import People, Sample, field_columns


class PersonTables:
    """A population's numbers for a variant's kernel.

    Attributes:
        people: the population.
        positions: ``(k,)`` the numbers (indices into the variant's packed tables raveled) that differ between people.
        spec: the variant's [`LoopSpec`][heartpole.kernel.LoopSpec] with those positions as its overlay: which row
            of the cells ([`cells`][heartpole.person_tables.PersonTables.cells]) each is read from.
    """

    def __init__(self, dynamics: Dynamics, people: People) -> None:
        self.people, self.dynamics = people, dynamics
        self._base = dynamics.packed
        if people.cohort:
            members = [dataclasses.replace(dynamics.params, **p.values()) for p in people.cohort]  # type: ignore[arg-type]
            self._cohort = np.stack([self._packed_one(params) for params in members]).reshape(len(members), -1)
            probes = self._cohort
        else:
            probes = self._packed_many(self._probes())
        self.positions = np.flatnonzero(np.any(probes != self._base.ravel(), axis=0))
        columns = np.arange(len(self.positions))
        if people.cohort:  # numbers equal for every member share a column (hypertension and alcohol fade alike)
            values = self._cohort[:, self.positions]
            _, first, columns = np.unique(values, axis=1, return_index=True, return_inverse=True)
            columns = np.argsort(np.argsort(first))[columns.ravel()]
            # the members' numbers, a column of the cells per row: an env's are its member's column of these
            self._members = np.ascontiguousarray(self._cohort[:, np.sort(self.positions[first])].T, dtype=np.float32)
        overlay = tuple(zip(self.positions.tolist(), columns.tolist()))
        self.spec = dataclasses.replace(dynamics.spec, overlay=overlay)

    def cells(self, n: int) -> np.ndarray:
        """The loops' ``cells`` for ``n`` envs before any draw (zeros): ``(columns, n)`` float32, row ``c`` each
        env's value of the numbers the `spec`'s overlay reads from column ``c``."""
        return np.zeros((self.spec.columns, n), dtype=np.float32)

    def assign(self, cells: np.ndarray, which: np.ndarray, sample: Sample) -> None:
        """Give the envs ``which`` (a mask, or indices) the people of ``sample`` (in env order), in place."""
        if self.people.cohort:
            cells[:, which] = self._members[:, sample.person]
            return
        full = self._packed_many({c: sample.column(c, self.dynamics.params) for c in self.people.columns})
        shared = np.delete(full, self.positions, axis=1)
        if not np.array_equal(shared, np.broadcast_to(np.delete(self._base.ravel(), self.positions), shared.shape)):
            raise RuntimeError("a person changed a number no probe of the population changed")  # never, by design
        cells[:, which] = full[:, self.positions].T

    def table_values(self, cells: np.ndarray, name: str) -> np.ndarray:
        """Each env's float32 value of the variant's table number ``name`` (a Number field of
        [`StepTables`][heartpole.model.StepTables], ``"heart_attack_proclivity"`` say) as the loops read it: its
        column of ``cells`` where people differ in it, else the variant's own; ``(n,)``, a new array."""
        packed = self._base
        column = len(kernel.TABLES.per_variable) * len(self.dynamics.variables) + kernel.TABLES.numbers.index(name)
        row = dict(self.spec.overlay).get((packed.shape[0] - 1) * packed.shape[1] + column)
        if row is None:
            return np.full(cells.shape[1], packed[-1, column], dtype=np.float32)
        return cells[row].copy()

    # ----------------------------------------------------------------------------------------------------
    def _packed_one(self, params: Params) -> np.ndarray:
        """One person's packed tables, built as an env made with ``params`` builds them."""
        return Dynamics(self.dynamics.actions, params, self.dynamics.variables).packed

    def _probes(self) -> dict[str, np.ndarray]:
        """Values of a distribution's columns that move every number a person can move: every column at its low
        end, at its high end, and each alone at its high end (a width ``high - low`` moves with one end)."""
        fixed = self.people.sample(np.random.default_rng(0), 1)  # its fixed columns; the traits are set below
        low, high = self.people.trait_bounds()
        traits = list(self.people.traits)
        rows = [low, high] + [np.where(np.arange(len(traits)) == j, high, low) for j in range(len(traits))]
        probes = {c: np.full(len(rows), fixed.values[0, k]) for k, c in enumerate(self.people.columns)}
        for j, column in enumerate(traits):
            probes[column] = np.array([row[j] for row in rows], dtype=np.float64)
        return probes

    def _packed_many(self, columns: dict[str, np.ndarray]) -> np.ndarray:
        """``(n, size)`` float32: the packed tables of ``n`` people at once, their columns given as arrays."""
        n = len(next(iter(columns.values())))
        values: dict[str, object] = {}
        for field in dataclasses.fields(Params):
            found = [columns.get(c) for c in field_columns(field.name)]
            if any(column is None for column in found):
                values[field.name] = getattr(self.dynamics.params, field.name)
            else:
                values[field.name] = tuple(found) if len(found) == 2 else found[0]
        params = types.SimpleNamespace(**values)  # Params' fields, arrays for the drawn ones
        effects, tables = step_tables(self.dynamics.actions, self.dynamics.variables, params)  # type: ignore[arg-type]
        cells = [np.broadcast_to(np.float32(x), (n,)) for row in kernel.padded_rows(effects, tables) for x in row]
        return np.stack(cells, axis=1)
