"""The compiled step over envs whose people differ: each env's numbers of the tables are data the loop reads.

A population of people ([`heartpole.people`][heartpole.people]) changes a few numbers of a variant's tables
from one person to the next (the heart-attack proclivity, the fading, the sleep's length, the waking
alertness) and leaves the others alone. [`step_envs`][heartpole.person_kernel.step_envs] is
[`heartpole.kernel`][heartpole.kernel]'s loop over envs (the same step, [`heartpole.model`][heartpole.model]'s,
no formula of its own) with those numbers read per env from two arguments:

* ``cells``, ``(columns, num_envs)`` float32: row ``c`` holds every env's value of column ``c`` (numbers equal
  for every person share a column: HeartPole's two fading variables fade alike). Each varying number costs one
  contiguous load per env (LLVM vectorises them: the loop's arrays are declared not to overlap,
  `heartpole.jit.no_alias`); the shared numbers are read once, as in the v0 loop (what a column costs,
  against gathering each env's numbers by person index: docs/speed.md).
* ``overlay`` ([`overlay_for`][heartpole.person_kernel.overlay_for]): an empty array whose structured dtype says which
  numbers the cells replace: a field ``p{position}`` (the number's index in the raveled packed tables,
  [`pack`][heartpole.kernel.pack]) at byte offset ``4 * column``. numba compiles a loop per argument type, so the
  positions are constants of the compiled code; being part of the arguments' *types*, they also key numba's
  disk cache (`heartpole.jit`): a process loads the loop an earlier one compiled for the same positions.

`heartpole.person_tables` finds the positions and fills the cells from the people drawn.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Sequence
from typing import Any

import numba
import numpy as np
from numba import njit
from numba.core import cgutils
from numba.core import types as nbtypes
from numba.core.errors import TypingError
from numba.extending import intrinsic, overload

from heartpole import jit, kernel, model
from heartpole.jit import INLINE, JIT, cache_keyed_on, no_alias, one, wide_vectors
from heartpole.kernel import ACTIONS, ATTACK, PRODUCTIVITY, REWARD, RISK, SCORE, to_fixed_tuple, tuple_setitem
from heartpole.lanes import F32, U32, U64, add32, where

struct_proxy: Any = cgutils.create_struct_proxy  # untyped in numba
_step, _initial_state = kernel.compiled.step, kernel.compiled.initial_state
_row_width = njit(**JIT, **INLINE)(kernel.row_width)


def overlay_for(positions: Sequence[int], columns: Sequence[int]) -> np.ndarray:
    """The loops' ``overlay`` argument: number ``positions[j]`` of the raveled packed tables is read from row
    ``columns[j]`` of the cells (see the module docstring). Fields may share an offset (numbers sharing a column)."""
    given = [*positions, *columns]
    if len(positions) != len(columns) or len(set(positions)) != len(positions) or min(given, default=0) < 0:
        raise ValueError(
            f"overlay_for needs distinct positions and one column each, all integers >= 0; got positions "
            f"{list(positions)} and columns {list(columns)}"
        )
    dtype = np.dtype(
        {
            "names": [f"p{int(p)}" for p in positions],
            "formats": [np.float32] * len(positions),
            "offsets": [4 * int(c) for c in columns],
            "itemsize": 4 * (max(map(int, columns), default=-1) + 1),
        }
    )
    return np.empty(0, dtype=dtype)


def _positions(fields: Iterable[tuple[str, Any]]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """``(positions, columns)`` from an overlay's fields (``(name, field)``, the field's offset its item 1, in
    NumPy's dtypes as in numba's records), in the order of the positions."""
    pairs = sorted((int(name[1:]), int(field[1]) // 4) for name, field in fields)
    return tuple(p for p, _ in pairs), tuple(c for _, c in pairs)


@intrinsic
def _data_intrinsic(typingctx: Any, array: Any) -> Any:
    """A pointer to the data of the float32 C-contiguous ``array`` (row ``r`` starts ``r * shape[1]`` after it)."""
    if not (isinstance(array, nbtypes.Array) and array.dtype == nbtypes.float32 and array.layout == "C"):
        raise TypingError(f"the cells must be a C-contiguous float32 array, got {array}")

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return struct_proxy(signature.args[0])(context, builder, value=args[0]).data

    pointer: Any = nbtypes.CPointer
    return pointer(nbtypes.float32)(array), codegen


_data: Any = _data_intrinsic
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _data = lambda array: array.ravel()  # noqa: E731


def _setter(table: type[tuple[Any, ...]], fields: model.TableFields, num_variables: int, column: int) -> Any:
    """A compiled ``set(values, value)``: the ``table`` ``values`` with number ``column`` of its packed row
    ([`pack_row`][heartpole.kernel.pack_row]) set to ``value``. Written out field by field, so that the
    indices are constants of the code (numba's ``tuple_setitem`` takes tuples of one type only)."""
    arguments = [f"values[{j}]" for j in range(len(table._fields))]  # type: ignore[attr-defined]
    k, v = kernel.field_at(fields, num_variables, column)
    arguments[k] = "value" if v is None else f"tuple_setitem(values[{k}], {v}, value)"
    source = f"def set_number(values, value):\n    return table({', '.join(arguments)})\n"
    namespace: dict[str, Any] = {"table": table, "tuple_setitem": tuple_setitem}
    exec(source, namespace)  # code made here from field indices, nothing from outside
    return njit(**kernel.PER_POSITIONS, **INLINE)(namespace["set_number"])


def _getter(table: type[tuple[Any, ...]], fields: model.TableFields, num_variables: int, column: int) -> Any:
    """A compiled ``get(values)``: number ``column`` of the ``table`` ``values``' packed row."""
    k, v = kernel.field_at(fields, num_variables, column)
    if v is None:
        return njit(**kernel.PER_POSITIONS, **INLINE)(lambda values: values[k])
    return njit(**kernel.PER_POSITIONS, **INLINE)(lambda values: values[k][v])


@functools.lru_cache(maxsize=256)
def _chain(positions: tuple[int, ...], columns: tuple[int, ...], layout: tuple[int, int, int]) -> Any:
    """A compiled ``own(effects, tables, action, cells, i)``: ``(effects, tables)`` with env ``i``'s numbers at
    ``positions`` (``positions[k]`` from row ``columns[k]`` of the cells, given as ``(data, row_length)``), an
    action's only where it is ``action``. A chain of one function per position, each with its indices as
    constants: nothing for LLVM to unroll. ``layout``: the numbers of variables, the row width, of actions."""
    if not positions:
        return njit(**kernel.PER_POSITIONS, **INLINE)(lambda effects, tables, action, cells, i: (effects, tables))
    rest = _chain(positions[1:], columns[1:], layout)
    num_variables, width, num_actions = layout
    owner, column = divmod(positions[0], width)
    row = U64(columns[0])
    if owner == num_actions:  # the tables' row
        set_table = _setter(model.StepTables, kernel.TABLES, num_variables, column)

        @njit(**kernel.PER_POSITIONS, **INLINE)
        def overlay_tables(effects: Any, tables: Any, action: Any, cells: Any, i: Any) -> Any:
            value = cells[0][row * cells[1] + i]
            return rest(effects, set_table(tables, value), action, cells, i)

        return overlay_tables
    set_effect = _setter(model.ActionEffects, kernel.EFFECTS, num_variables, column)
    shared = _getter(model.ActionEffects, kernel.EFFECTS, num_variables, column)

    @njit(**kernel.PER_POSITIONS, **INLINE)
    def overlay_action(effects: Any, tables: Any, action: Any, cells: Any, i: Any) -> Any:
        value = where(action == owner, cells[0][row * cells[1] + i], shared(effects))
        return rest(set_effect(effects, value), tables, action, cells, i)

    return overlay_action


@functools.lru_cache(maxsize=64)
def _chain_for(layout: Any, dtype: Any) -> Any:
    """`_chain` for a ``layout`` and an overlay's ``dtype``: NumPy's and numba's (their types) alike."""
    num_variables = len(layout[0])
    positions, columns = _positions(dtype.fields.items())
    return _chain(positions, columns, (num_variables, kernel.row_width(num_variables), len(layout[2])))


def own(effects: Any, tables: Any, action: Any, cells: Any, i: Any, layout: Any, overlay: Any) -> Any:
    """``(effects, tables)`` with env ``i``'s own numbers (`_chain`), as ``overlay`` places them. This is the
    plain Python of ``NUMBA_DISABLE_JIT``; compiled code builds the chain from ``overlay``'s type (`_own`)."""
    return _chain_for(layout, overlay.dtype)(effects, tables, action, cells, i)


@overload(own, inline="always")
def _own(effects: Any, tables: Any, action: Any, cells: Any, i: Any, layout: Any, overlay: Any) -> Any:
    """`own` in compiled code: its chain built when compiling, from the types of ``layout`` and ``overlay``,
    and inlined into the loop (compiled into the loop's own code, which numba's disk cache keeps)."""
    chain = _chain_for(layout, overlay.dtype)

    def own_compiled(effects: Any, tables: Any, action: Any, cells: Any, i: Any, layout: Any, overlay: Any) -> Any:
        return chain(effects, tables, action, cells, i)

    return own_compiled


@njit(**JIT)
def _fixed(values: Any, like: Any) -> Any:
    """The first ``len(like)`` items of ``values`` as a tuple (a function of its own: see the kernel's)."""
    return to_fixed_tuple(values[: len(like)], len(like))


@njit(**JIT, **INLINE)
def _shape(layout: Any) -> Any:
    """``(zeros, (rest_offsets,))``: a state of zeros and the rest offsets 0, 1, ... of the layout."""
    zeros = _fixed(np.zeros(len(layout[0]), dtype=np.float32), layout[0])
    rest_offsets = _fixed(np.arange(len(layout[1])).astype(np.float32), layout[1])
    return zeros, (rest_offsets,)


@njit(**JIT, **INLINE)
def _loop(
    envs: Any, results: Any, actions: Any, rng: Any, flat: Any, layout: Any, cells: Any, overlay: Any, selection: Any
) -> None:
    """The loop over envs of `step_envs`, which `step_one` runs over one env."""
    wide_vectors()
    no_alias()
    zeros, shape = _shape(layout)
    width = U64(_row_width(len(zeros)))
    shared = kernel.read_tables(flat, U64(len(layout[2])) * width, zeros, shape)
    values = (_data(cells), U64(cells.shape[1]))
    for index in range(actions.shape[0]):
        i = U64(index)
        state, uniforms = kernel.env_state(envs, rng, i, zeros)
        effects = kernel.action_effects(flat, width, layout, actions[i], zeros, selection)
        effects, tables = own(effects, shared, actions[i], values, i, layout, overlay)
        kernel.store_env(envs, results, rng, i, _step(state, effects, uniforms, tables))


@njit(**JIT)
def step_envs(
    envs: Any, results: Any, actions: Any, rng: Any, flat: Any, layout: Any, cells: Any, overlay: Any, selection: Any
) -> bool:
    """[`step_envs`][heartpole.kernel.step_envs] with each env's own numbers: ``flat`` the packed tables
    raveled, ``cells`` and ``overlay`` as the module docstring says. No two of the arrays may overlap."""
    if not kernel.convert_actions(actions, len(layout[2]), results[ACTIONS]):
        return False
    _loop(envs, results, results[ACTIONS], rng, flat, layout, cells, overlay, selection)
    return True


@njit(**JIT)
def _step_one(
    envs: Any, action: Any, rng: Any, flat: Any, layout: Any, cells: Any, overlay: Any, selection: Any
) -> Any:
    """`step_one`'s compiled part: the loop over one env."""
    zero = F32(0.0)  # one env's results on this function's stack (`one`), its observations the state itself
    out = kernel.StepResults(
        one(zero), one(zero), one(zero), one(False), one(zero), envs, one(kernel.ACTION_DTYPE(action))
    )
    _loop(envs, out, out[ACTIONS], rng, flat, layout, cells, overlay, selection)
    return out[REWARD][0], out[PRODUCTIVITY][0], out[RISK][0], out[ATTACK][0], out[SCORE][0]


def step_one(envs: Any, action: Any, rng: Any, flat: Any, layout: Any, cells: Any, overlay: Any, selection: Any) -> Any:
    """[`step_one`][heartpole.kernel.step_one] with the env's own numbers (``cells`` ``(columns, 1)``): the
    loop of `step_envs`, so a single env is env 0 bit for bit; its results as Python numbers, compiled or not."""
    reward, worked, risk, attack, new_score = _step_one(envs, action, rng, flat, layout, cells, overlay, selection)
    return float(reward), float(worked), float(risk), bool(attack), float(new_score)


@njit(**JIT)
def reset_envs(envs: Any, rng: Any, which: Any, flat: Any, layout: Any, cells: Any, overlay: Any) -> None:
    """[`reset_envs`][heartpole.kernel.reset_envs] with each env's own waking alertness."""
    zeros, shape = _shape(layout)
    tables_at = U64(len(layout[2])) * U64(_row_width(len(zeros)))
    shared = kernel.read_tables(flat, tables_at, zeros, shape)
    effects = kernel.read_effects(flat, U64(0), zeros, ())
    values = (_data(cells), U64(cells.shape[1]))
    wake = len(zeros)  # the wake-up uniform of a draw, as in a step
    for index in range(which.shape[0]):
        if which[index]:
            i = U64(index)
            tables = own(effects, shared, -1, values, i, layout, overlay)[1]
            u = kernel.uniform(rng[kernel.KEY_LOW, i], rng[kernel.KEY_HIGH, i], rng[kernel.COUNTER, i], wake)
            state = _initial_state(zeros, u, tables)
            for v in range(len(zeros)):
                envs[v, i] = state[v]
            rng[kernel.COUNTER, i] = add32(rng[kernel.COUNTER, i], U32(1))


# They inline the kernel's, the model's and jit's code: an edit of any recompiles them.
for _source in (model, kernel, jit):
    cache_keyed_on(_source, step_envs, _step_one, reset_envs)
