"""The compiled step over envs whose people differ: each env's numbers of the tables are data the loop reads.

A population of people ([`heartpole.people`][heartpole.people]) changes a few numbers of a variant's tables
from one person to the next (the heart-attack proclivity, the fading, the sleep's length, the waking
alertness) and leaves the others alone. [`kernels`][heartpole.person_kernel.kernels] compiles
[`step_envs`][heartpole.kernel.step_envs]'s loop for one set of such numbers (their *positions* in the raveled
packed tables, [`pack`][heartpole.kernel.pack]): number ``positions[k]`` is read from row ``k + 1`` of a
``(len(positions) + 1, num_envs)`` float32 array of per-env values (``cells``; row 0 unused), every other
number from the variant's own table. The positions are constants of the compiled code, so each varying number
costs one contiguous load per env and the shared ones nothing new: one compiled loop, no Python per env, no
formula (the step is [`heartpole.model`][heartpole.model]'s, compiled by [`heartpole.kernel`][heartpole.kernel]).
`heartpole.person_tables` finds the positions and fills the cells from the people drawn.
"""

from __future__ import annotations

import functools
from typing import Any

import numba
import numpy as np
from numba import njit
from numba.core import cgutils
from numba.core import types as nbtypes
from numba.extending import intrinsic

from heartpole import kernel, model
from heartpole.jit import INLINE, JIT, JitOptions
from heartpole.kernel import F32, U32, U64, add32, carray, draws, stored, to_fixed_tuple, tuple_setitem, where

struct_proxy: Any = cgutils.create_struct_proxy  # untyped in numba
_step, _initial_state = kernel.compiled.step, kernel.compiled.initial_state
_row_width = njit(**JIT, **INLINE)(kernel.row_width)
STACK_PEOPLE = 4096
"""A population's numbers up to this many (16 kB; the default cohort's are 24 people times 8) go on the stack."""
COMPILED: JitOptions = {**JIT, "cache": False}
"""The options of the loops compiled per set of positions (closures over them, which numba's disk cache
does not keep apart)."""


@njit(**JIT)
def _fixed(values: Any, like: Any) -> Any:
    """The first ``len(like)`` items of ``values`` as a tuple (a function of its own: see the kernel's)."""
    return to_fixed_tuple(values[: len(like)], len(like))


@intrinsic
def _data_intrinsic(typingctx: Any, array: Any) -> Any:
    """A pointer to the float32 data of ``array``."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return struct_proxy(signature.args[0])(context, builder, value=args[0]).data

    pointer: Any = nbtypes.CPointer
    return pointer(nbtypes.float32)(array), codegen


@intrinsic
def _int_data_intrinsic(typingctx: Any, array: Any) -> Any:
    """A pointer to the int32 data of ``array``."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return struct_proxy(signature.args[0])(context, builder, value=args[0]).data

    pointer: Any = nbtypes.CPointer
    return pointer(nbtypes.int32)(array), codegen


@intrinsic
def _stack_buffer_intrinsic(typingctx: Any) -> Any:
    """A pointer to room for `STACK_PEOPLE` float32 on the stack of the compiled function that calls it."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return kernel.alloca_once(builder, context.get_value_type(nbtypes.float32), size=STACK_PEOPLE)

    pointer: Any = nbtypes.CPointer
    return pointer(nbtypes.float32)(), codegen


_data: Any = _data_intrinsic
_int_data: Any = _int_data_intrinsic
_stack_buffer: Any = _stack_buffer_intrinsic
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _data = _int_data = lambda array: array.ravel()  # noqa: E731


@njit(**JIT, **INLINE)
def _stack_people(people: Any) -> Any:
    """The people's numbers ``(P, k)`` (at most `STACK_PEOPLE`) copied to the caller's stack: each env's are
    then gathered from memory no written array overlaps, which LLVM vectorises without checks at run time.
    (Larger tables, a distribution's with one row per env, are read where they are: slower, the same.)"""
    table = carray(_stack_buffer(), people.shape)
    for p in range(people.shape[0]):
        for k in range(people.shape[1]):
            table[p, k] = people[p, k]
    return table


if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _stack_people = lambda people: people  # type: ignore[assignment]  # noqa: E731


def _setter(table: type[tuple[Any, ...]], fields: model.TableFields, num_variables: int, column: int) -> Any:
    """A compiled ``set(values, value)``: the ``table`` ``values`` with number ``column`` of its packed row
    ([`pack_row`][heartpole.kernel.pack_row]) set to ``value``. Written out field by field, so that the
    indices are constants of the code (numba's ``tuple_setitem`` takes tuples of one type only)."""
    per_variable = len(fields.per_variable)
    arguments = [f"values[{j}]" for j in range(len(table._fields))]  # type: ignore[attr-defined]
    if column < per_variable * num_variables:
        k, v = divmod(column, num_variables)
        arguments[k] = f"tuple_setitem(values[{k}], {v}, value)"
    else:
        arguments[per_variable + column - per_variable * num_variables] = "value"
    source = f"def set_number(values, value):\n    return table({', '.join(arguments)})\n"
    namespace: dict[str, Any] = {"table": table, "tuple_setitem": tuple_setitem}
    exec(source, namespace)  # code made here from field indices, nothing from outside
    return njit(**COMPILED, **INLINE)(namespace["set_number"])


def _overlay(positions: tuple[int, ...], columns: tuple[int, ...], layout: tuple[int, int, int]) -> Any:
    """A compiled ``own(effects, tables, action, cells, i)``: ``(effects, tables)`` with the env's own numbers
    at ``positions`` (``cells[row + k][i]`` for ``positions[k]``), the action's only where it is ``action``.
    A chain of one function per position, each with its indices as constants: nothing for LLVM to unroll."""
    if not positions:
        return njit(**COMPILED, **INLINE)(lambda effects, tables, action, cells, i: (effects, tables))
    rest = _overlay(positions[1:], columns[1:], layout)
    num_variables, width, num_actions = layout
    owner, column = divmod(positions[0], width)
    own, count = U64(columns[0]), U64(max(columns) + 1)
    if owner == num_actions:  # the tables' row
        set_table = _setter(model.StepTables, kernel.TABLES, num_variables, column)

        @njit(**COMPILED, **INLINE)
        def overlay(effects: Any, tables: Any, action: Any, cells: Any, i: Any) -> Any:
            values = cells
            return rest(effects, set_table(tables, values[0][U64(values[1][i]) * count + own]), action, cells, i)

        return overlay
    set_effect = _setter(model.ActionEffects, kernel.EFFECTS, num_variables, column)
    shared = _getter(model.ActionEffects, kernel.EFFECTS, num_variables, column)

    @njit(**COMPILED, **INLINE)
    def overlay_action(effects: Any, tables: Any, action: Any, cells: Any, i: Any) -> Any:
        values = cells
        value = where(action == owner, values[0][U64(values[1][i]) * count + own], shared(effects))
        return rest(set_effect(effects, value), tables, action, cells, i)

    return overlay_action


def _getter(table: type[tuple[Any, ...]], fields: model.TableFields, num_variables: int, column: int) -> Any:
    """A compiled ``get(values)``: number ``column`` of the ``table`` ``values``' packed row."""
    per_variable = len(fields.per_variable)
    if column < per_variable * num_variables:
        k, v = divmod(column, num_variables)
        return njit(**COMPILED, **INLINE)(lambda values: values[k][v])
    j = per_variable + column - per_variable * num_variables
    return njit(**COMPILED, **INLINE)(lambda values: values[j])


@njit(**JIT, **INLINE)
def _shape(layout: Any) -> Any:
    """``(zeros, (rest_offsets,))``: a state of zeros and the rest offsets 0, 1, ... of the layout."""
    zeros = _fixed(np.zeros(len(layout[0]), dtype=np.float32), layout[0])
    rest_offsets = _fixed(np.arange(len(layout[1])).astype(np.float32), layout[1])
    return zeros, (rest_offsets,)


@njit(**JIT, **INLINE)
def _stack_table(flat: Any, layout: Any, zeros: Any) -> Any:
    """``flat`` (the packed tables, raveled) copied to the caller's stack, as the kernel's action table is:
    LLVM vectorises reads only from memory no written array overlaps. On the heap when too large."""
    rows = layout[2] + (None,)  # the action rows and the tables' row
    size = len(rows) * _row_width(len(zeros))
    if size <= kernel.STACK_TABLE_LIMIT:  # known when compiling: one branch stays
        table = carray(kernel.stack_floats(rows, zeros), size)
    else:
        table = np.empty(size, dtype=np.float32)
    for c in range(size):
        table[c] = flat[c]
    return table


if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _stack_table = lambda flat, layout, zeros: flat  # type: ignore[assignment]  # noqa: E731


class Kernels:
    """The loops over envs for one set of positions (see the module docstring); made by `kernels`.

    Attributes:
        step_envs: ``step_envs(envs, results, actions, rng, flat, layout, cells)``: as
            [`step_envs`][heartpole.kernel.step_envs] (``flat`` the packed tables raveled) with each env's
            own numbers.
        step_one: ``step_one(envs, action, rng, flat, layout, cells)``: as
            [`step_one`][heartpole.kernel.step_one]; the same loop, so a single env is env 0 bit for bit.
        reset_envs: ``reset_envs(envs, rng, which, flat, layout, cells)``: as
            [`reset_envs`][heartpole.kernel.reset_envs], with each env's own waking alertness.
    """

    def __init__(
        self, positions: tuple[int, ...], columns: tuple[int, ...], num_variables: int, num_actions: int
    ) -> None:
        own = _overlay(positions, columns, (num_variables, kernel.row_width(num_variables), num_actions))

        @njit(**COMPILED, **INLINE)
        def loop(
            envs: Any, results: Any, actions: Any, rng: Any, flat: Any, layout: Any, people: Any, person: Any
        ) -> None:
            kernel.wide_vectors()
            zeros, shape = _shape(layout)
            width = U64(_row_width(len(zeros)))
            table = _stack_table(flat, layout, zeros)
            shared = kernel.read_tables(table, U64(len(layout[2])) * width, zeros, shape)
            values = (_data(people), _int_data(person))
            selected = len(layout[2]) <= kernel.SELECTED_ACTIONS  # known when compiling: one branch stays
            for index in range(actions.shape[0]):
                i = U64(index)
                state = zeros
                for v in range(len(zeros)):
                    state = tuple_setitem(state, v, envs[U64(v), i])
                key_low, key_high = rng[U64(kernel.KEY_LOW), i], rng[U64(kernel.KEY_HIGH), i]
                uniforms = draws(key_low, key_high, rng[U64(kernel.COUNTER), i], zeros)
                if selected:
                    effects = kernel.chosen_effects((table, width, layout[2], actions[i]), U64(0), zeros, ())
                else:
                    effects = kernel.read_effects(table, U64(actions[i]) * width, zeros, ())
                effects, tables = own(effects, shared, actions[i], values, i)
                state, reward, worked, risk, attack, new_score = _step(state, effects, uniforms, tables)
                for v in range(len(zeros)):
                    envs[U64(v), i] = stored(v, state[v])
                rng[U64(kernel.COUNTER), i] = add32(rng[U64(kernel.COUNTER), i], U32(1))
                results[0][i] = reward
                results[1][i] = worked
                results[2][i] = risk
                results[3][i] = attack
                results[4][i] = new_score

        @njit(**COMPILED)
        def step_envs(
            envs: Any, results: Any, actions: Any, rng: Any, flat: Any, layout: Any, people: Any, person: Any
        ) -> None:
            if people.size <= STACK_PEOPLE:  # two copies of the loop, each knowing where its table is
                loop(envs, results, actions, rng, flat, layout, _stack_people(people), person)
            else:
                loop(envs, results, actions, rng, flat, layout, people, person)

        @njit(**COMPILED)
        def step_one(envs: Any, action: Any, rng: Any, flat: Any, layout: Any, people: Any, person: Any) -> Any:
            one = kernel.one
            results = (one(F32(0.0)), one(F32(0.0)), one(F32(0.0)), one(False), one(F32(0.0)))
            loop(envs, results, one(kernel.ACTION_DTYPE(action)), rng, flat, layout, people, person)
            return results[0][0], results[1][0], results[2][0], results[3][0], results[4][0]

        @njit(**COMPILED)
        def reset_envs(envs: Any, rng: Any, which: Any, flat: Any, layout: Any, people: Any, person: Any) -> None:
            zeros, shape = _shape(layout)
            tables_at = U64(len(layout[2])) * U64(_row_width(len(zeros)))
            shared = kernel.read_tables(flat, tables_at, zeros, shape)
            effects = kernel.read_effects(flat, U64(0), zeros, ())
            values = (_data(people), _int_data(person))
            wake = len(zeros)  # the wake-up uniform of a draw, as in a step
            for index in range(which.shape[0]):
                if which[index]:
                    i = U64(index)
                    tables = own(effects, shared, -1, values, i)[1]
                    u = kernel.uniform(rng[kernel.KEY_LOW, i], rng[kernel.KEY_HIGH, i], rng[kernel.COUNTER, i], wake)
                    state = _initial_state(zeros, u, tables)
                    for v in range(len(zeros)):
                        envs[v, i] = state[v]
                    rng[kernel.COUNTER, i] = add32(rng[kernel.COUNTER, i], U32(1))

        self.step_envs, self.reset_envs = step_envs, reset_envs
        self._step_one = step_one

    def step_one(self, envs: Any, action: Any, rng: Any, flat: Any, layout: Any, people: Any, person: Any) -> Any:
        """One env's step (see the class docstring); its results as Python numbers, compiled or not."""
        reward, worked, risk, attack, new_score = self._step_one(envs, action, rng, flat, layout, people, person)
        return float(reward), float(worked), float(risk), bool(attack), float(new_score)


@functools.lru_cache(maxsize=32)
def kernels(positions: tuple[int, ...], columns: tuple[int, ...], num_variables: int, num_actions: int) -> Kernels:
    """The loops for ``positions`` of a variant's packed tables (``num_variables`` and ``num_actions`` give their
    layout), number ``positions[j]`` read from column ``columns[j]`` of the people's table (numbers equal for
    every person share one: HeartPole's two fading variables fade alike), compiled on their first call, once
    per process and set of positions."""
    return Kernels(tuple(map(int, positions)), tuple(map(int, columns)), num_variables, num_actions)
