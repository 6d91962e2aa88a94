"""The HeartPole step compiled with numba: [`step`][heartpole.model.step] over many people at once.

No formula lives here. [`heartpole.model`][heartpole.model]'s functions are compiled *as written*, with three
bindings of this module's: a float32 ``exp`` that LLVM can vectorise, ``where`` as a branch-free
select and ``replace`` as numba's in-register tuple update. Their float literals become float32
constants, so that the whole step computes in float32 (a Python float would make numba compute in
float64, at half the vector width). What this module adds is the machinery around the step:

* a counter-based random number generator: the ``j``-th uniform of an env's ``c``-th draw is a keyed
  hash of ``(key, c, j)``. An env's state is its key and its counter, so copies and pickles continue
  exactly, and two envs (or two policies evaluated alike) with the same key see the same draws.
* the tables packed in one array, laid out from the model's own definitions of them;
* [`step_envs`][heartpole.kernel.step_envs] and [`reset_envs`][heartpole.kernel.reset_envs], the loops over
  envs; the single env runs one env of them ([`step_one`][heartpole.kernel.step_one], the same loop), so the
  two agree bit for bit.

Compiled code is cached on disk where numba can write (`heartpole.jit`). With ``NUMBA_DISABLE_JIT=1``
everything runs as plain Python.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numba
import numpy as np
from numba import njit
from numba.core import cgutils
from numba.core import types as nbtypes
from numba.cpython.unsafe.tuple import tuple_setitem as _tuple_setitem
from numba.extending import intrinsic
from numba.np.numpy_support import carray as _carray
from numba.np.unsafe.ndarray import to_fixed_tuple as _to_fixed_tuple

from heartpole import jit, model
from heartpole import rng as random_numbers  # the module; ``rng`` names envs' generator states here
from heartpole.jit import CACHE as CACHE  # numba's disk cache, for the package's other compiled code
from heartpole.jit import INLINE, JIT, cache_keyed_on, one, wide_vectors

# The compiled functions take and return ``Any``: numba specialises them on the types of their arguments
# (float32 scalars, tuples of any length, arrays), which no single annotation describes. numba's stubs type an
# intrinsic's call as its typing function's (``typingctx`` first) and as never returning, which holds only
# outside compiled code; this module calls the intrinsics from compiled code, so it holds them as ``Any``.
tuple_setitem: Any = _tuple_setitem
to_fixed_tuple: Any = _to_fixed_tuple
carray: Any = _carray
alloca_once: Any = cgutils.alloca_once


F32, U64 = np.float32, np.uint64
LOG2E, LN2_HIGH, LN2_LOW = F32(1.4426950408889634), F32(0.693359375), F32(-2.12194440e-4)
EXP_LOW, EXP_HIGH = F32(-87.0), F32(87.0)


@intrinsic
def _int32_as_float32_intrinsic(typingctx: Any, bits: Any) -> Any:
    """The float32 whose IEEE-754 bits are the int32 ``bits`` (a bit cast, no conversion)."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.bitcast(args[0], context.get_value_type(nbtypes.float32))

    return nbtypes.float32(nbtypes.int32), codegen


_int32_as_float32: Any = _int32_as_float32_intrinsic


@njit(**JIT, **INLINE)
def exp32(x: Any) -> Any:
    """``e ** x`` in float32 without branches or calls, so that LLVM vectorises it.

    ``x`` is clamped to [-87, 87], where float32 ``exp`` and ``1 / (1 + exp)`` are finite and normal (the
    formulas need nothing beyond: their sigmoids are 0 or 1 there to float32 precision; past 87, ``1 / (1 +
    exp)`` would be a subnormal, which CPUs compute many times slower). Then ``e ** x = 2 ** n * e ** r`` with
    ``|r| <= ln(2) / 2``; ``e ** r`` is its Taylor polynomial to degree 6 (relative error below 2e-7).
    """
    x = min(max(F32(x), EXP_LOW), EXP_HIGH)
    n = np.floor(x * LOG2E + F32(0.5))
    r = x - n * LN2_HIGH - n * LN2_LOW
    p = F32(1.0 / 720.0)
    p = p * r + F32(1.0 / 120.0)
    p = p * r + F32(1.0 / 24.0)
    p = p * r + F32(1.0 / 6.0)
    p = p * r + F32(0.5)
    p = p * r + F32(1.0)
    p = p * r + F32(1.0)
    return p * _int32_as_float32((np.int32(n) + np.int32(127)) << np.int32(23))


@njit(**JIT, **INLINE)
def where(condition: Any, a: Any, b: Any) -> Any:
    """``a if condition else b``; LLVM turns it into a select, not a branch."""
    return a if condition else b


@njit(**JIT, **INLINE)
def stored(variable: Any, x: Any) -> Any:
    """``x`` as the state keeps it for ``variable``: a subnormal float32 (below ~1.2e-38) becomes 0. Fading
    values (blood pressure, alcohol, THC) would otherwise stick at a subnormal for ever (times 0.97 rounds
    back to itself) and make every later step several times slower; CPUs compute subnormals in microcode.
    The variables the step keeps itself (time and work) never fade and are kept as they are."""
    return x if _kept_by_the_step(variable) else where(abs(x) < SMALLEST_NORMAL, F32(0.0), x)


# ---------------------------------------------------------------------------------------------------------
# The random numbers are heartpole.rng's, compiled with these four 32-bit operations: LLVM's own, since numba
# would widen uint32 arithmetic to 64 bits (half the vector lanes).
def _uint32_operation(name: str) -> Any:
    @intrinsic
    def operation(typingctx: Any, a: Any, b: Any) -> Any:
        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            return getattr(builder, name)(args[0], args[1])

        return nbtypes.uint32(nbtypes.uint32, nbtypes.uint32), codegen

    operation.__doc__ = f"``a {name} b`` on 32-bit unsigned integers, wrapping around."
    return operation


mul32, add32, xor32, shr32 = (_uint32_operation(name) for name in ("mul", "add", "xor", "lshr"))

# Intrinsics run only in compiled code: plain Python stands in for them (numba.config has no static type).
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _int32_as_float32 = lambda bits: np.int32(bits).view(np.float32)  # noqa: E731
    mul32 = lambda a, b: np.uint32((int(a) * int(b)) & 0xFFFFFFFF)  # noqa: E731
    add32 = lambda a, b: np.uint32((int(a) + int(b)) & 0xFFFFFFFF)  # noqa: E731
    xor32 = lambda a, b: np.uint32(int(a) ^ int(b))  # noqa: E731
    shr32 = lambda a, b: np.uint32(int(a) >> int(b))  # noqa: E731
    tuple_setitem = model.replace  # noqa: F811
    to_fixed_tuple = lambda values, length: tuple(values[:length])  # noqa: E731

compiled = model.rebind({"exp": exp32, "where": where, "replace": tuple_setitem}, F32, njit(**JIT, **INLINE))
"""[`heartpole.model`][heartpole.model]'s functions, compiled: ``compiled.step`` is the step every env runs. Float
literals become float32 constants: numba would compute in float64 otherwise, at half the vector width."""
_step, _initial_state, _kept_by_the_step = compiled.step, compiled.initial_state, compiled.kept_by_the_step

U32 = np.uint32
SMALLEST_NORMAL = F32(np.finfo(np.float32).tiny)
KEY_LOW, KEY_HIGH, COUNTER = random_numbers.KEY_LOW, random_numbers.KEY_HIGH, random_numbers.COUNTER
generator_states = random_numbers.generator_states

compiled_rng = random_numbers.rebind(
    {
        "u32": U32,
        "mul32": mul32,
        "add32": add32,
        "xor32": xor32,
        "shr32": shr32,
        "to_float": F32,
        "where": where,
        "replace": tuple_setitem,
        "kept_by_the_step": _kept_by_the_step,
    },
    F32,
    njit(**JIT, **INLINE),
)
"""[`heartpole.rng`][heartpole.rng]'s generator, compiled: its 32-bit integer operations are LLVM's own (numba
would widen uint32 arithmetic to 64 bits, half the vector lanes)."""
mix32, uniform, draws = compiled_rng.mix32, compiled_rng.uniform, compiled_rng.draws


# ---------------------------------------------------------------------------------------------------------
# The tables, packed into one float32 array: a call from Python unboxes one array, not dozens of numbers.
# Their layout is derived from the model's own definitions: a table's row holds its PerVariable fields,
# ``n`` numbers each, then its Number fields, one each (model.table_fields); its Shape fields are not packed.
EFFECTS = model.table_fields(model.ActionEffects)
"""The fields of an action's row of [`pack`][heartpole.kernel.pack]'s array, by kind."""
TABLES = model.table_fields(model.StepTables)
"""The fields of the variant's row of [`pack`][heartpole.kernel.pack]'s array (its last), by kind."""
ACTION_DTYPE = np.int32
"""The dtype of [`step_envs`][heartpole.kernel.step_envs]'s actions: with 32-bit integers in the loop, LLVM
vectorises it eight floats wide, with 64-bit ones four wide."""
OUTPUTS = {
    "reward": np.float32,
    "productivity": np.float32,
    "heart_attack_risk": np.float32,
    "heart_attack": np.bool_,
    "score": np.float32,
}
"""The results of a step, in [`step_envs`][heartpole.kernel.step_envs]'s order, with their dtypes."""


def new_results(count: int) -> tuple[np.ndarray, ...]:
    """Fresh arrays for [`step_envs`][heartpole.kernel.step_envs]'s results of ``count`` envs (`OUTPUTS`)."""
    return tuple(np.empty(count, dtype=dtype) for dtype in OUTPUTS.values())


WIDTHS = tuple((len(fields.per_variable), len(fields.numbers)) for fields in (EFFECTS, TABLES))
"""Per table (`EFFECTS`, `TABLES`): how many numbers its row holds per variable, and besides."""


def row_width(num_variables: int) -> int:
    """The width of [`pack`][heartpole.kernel.pack]'s rows for ``num_variables`` variables: the wider of the
    two tables' rows."""
    (effects, effect_numbers), (tables, table_numbers) = WIDTHS
    return max(effects * num_variables + effect_numbers, tables * num_variables + table_numbers)


_row_width = njit(**JIT, **INLINE)(row_width)


def pack_row(table: tuple[Any, ...], fields: model.TableFields) -> list[Any]:
    """``table``'s numbers in its row's order: its PerVariable fields one after the other, then its Numbers."""
    return [x for name in fields.per_variable for x in getattr(table, name)] + [
        getattr(table, k) for k in fields.numbers
    ]


def field_at(fields: model.TableFields, num_variables: int, column: int) -> tuple[int, int | None]:
    """Where number ``column`` of a packed row (`pack_row`) lives in its table: ``(field, variable)`` for a
    PerVariable field, ``(field, None)`` for a Number (``field`` its index among the table's fields)."""
    per_variable = len(fields.per_variable)
    if column < per_variable * num_variables:
        return divmod(column, num_variables)
    return per_variable + column - per_variable * num_variables, None


def padded_rows(effects: Sequence[model.ActionEffects], tables: model.StepTables) -> list[list[Any]]:
    """[`pack`][heartpole.kernel.pack]'s rows before they become an array: numbers of any type (arrays too)."""
    width = row_width(len(tables.floor))
    rows = [pack_row(e, EFFECTS) for e in effects] + [pack_row(tables, TABLES)]
    return [row + [0.0] * (width - len(row)) for row in rows]


def pack(effects: Sequence[model.ActionEffects], tables: model.StepTables) -> np.ndarray:
    """``effects`` and ``tables`` as one float32 array of `row_width` columns: a row per action (`EFFECTS`),
    then a row for ``tables`` (`TABLES`), each padded with zeros. The rest offsets are 0, 1, ... and
    need only their number ([`layout`][heartpole.kernel.layout])."""
    return np.array(padded_rows(effects, tables), dtype=np.float32)


def layout(num_variables: int, num_rest_offsets: int, num_actions: int) -> tuple[tuple[None, ...], ...]:
    """The ``layout`` argument of the kernels: tuples of ``None`` whose lengths are the numbers of
    variables, rest offsets and actions. Compiled code is specialised on them, so its loops over variables
    and actions have known lengths (LLVM unrolls them); ``None`` costs nothing to pass."""
    return ((None,) * num_variables, (None,) * num_rest_offsets, (None,) * num_actions)


def _repeat(count: int) -> Any:
    """A compiled ``repeat(value)``: the tuple of ``count`` copies of ``value`` (numba has no ``tuple * int``)."""
    if count == 0:
        return njit(**JIT, **INLINE)(lambda value: ())
    rest = _repeat(count - 1)
    return njit(**JIT, **INLINE)(lambda value: (value,) + rest(value))


def reader(table: type[tuple[Any, ...]], fields: model.TableFields, cell: Any) -> Any:
    """A compiled ``read(source, start, zeros, shape)``: the ``table`` whose row (`pack_row`) starts at
    ``start`` (unsigned), number ``j`` being ``cell(source, start + j)``, with ``shape`` as its Shape fields."""
    per_variable, numbers = len(fields.per_variable), len(fields.numbers)
    groups, scalars = _repeat(per_variable), _repeat(numbers)

    @njit(**JIT, **INLINE)
    def read(source: Any, start: Any, zeros: Any, shape: Any) -> Any:
        n = U64(len(zeros))
        rows = groups(zeros)
        for k in range(per_variable):
            row = zeros
            for v in range(len(zeros)):
                row = tuple_setitem(row, v, cell(source, start + U64(k) * n + U64(v)))
            rows = tuple_setitem(rows, k, row)
        values = scalars(zeros[0])
        for k in range(numbers):
            values = tuple_setitem(values, k, cell(source, start + U64(per_variable) * n + U64(k)))
        return table(*(rows + values + shape))

    return read


@njit(**JIT, **INLINE)
def _at(values: Any, index: Any) -> Any:
    """``values[index]``: a table's numbers read from a row of `pack`'s array, or the action table."""
    return values[index]


@njit(**JIT, **INLINE)
def _chosen(source: Any, column: Any) -> Any:
    """The ``column`` of env's action's row of the action table, selected with masks (no gather).
    ``source`` is ``(table, width, actions, action)``: the table, its row width, the layout's actions."""
    table, width, actions, action = source
    value = table[column]
    for k in range(1, len(actions)):
        value = where(action == k, table[U64(k) * width + column], value)
    return value


read_effects = reader(model.ActionEffects, EFFECTS, _at)
"""The [`ActionEffects`][heartpole.model.ActionEffects] in a row of `pack`'s array (or the action table)."""
chosen_effects = reader(model.ActionEffects, EFFECTS, _chosen)
"""The [`ActionEffects`][heartpole.model.ActionEffects] of an env's action, selected with masks (`_chosen`)."""
read_tables = reader(model.StepTables, TABLES, _at)
"""The [`StepTables`][heartpole.model.StepTables] in [`pack`][heartpole.kernel.pack]'s last row."""


@njit(**JIT)
def _fixed(values: Any, like: Any) -> Any:
    """The first ``len(like)`` items of the array ``values`` as a tuple (numba needs ``len`` of an
    argument itself to know the tuple's length, hence a function of its own, never inlined)."""
    return to_fixed_tuple(values[: len(like)], len(like))


@njit(**JIT, **INLINE)
def _unpack(packed: Any, layout: Any) -> Any:
    """``(zeros, tables)`` from [`pack`][heartpole.kernel.pack]'s array: a state of zeros and the
    [`StepTables`][heartpole.model.StepTables] (its rest offsets 0, 1, ... from the layout)."""
    zeros = _fixed(np.zeros(len(layout[0]), dtype=np.float32), layout[0])
    rest_offsets = _fixed(np.arange(len(layout[1])).astype(np.float32), layout[1])
    return zeros, read_tables(packed[packed.shape[0] - 1], U64(0), zeros, (rest_offsets,))


STACK_TABLE_LIMIT = 4096
"""Action tables of up to this many numbers (16 kB; HeartPole-v1's has 224) go on the stack."""


@intrinsic
def _stack_floats_intrinsic(typingctx: Any, actions: Any, zeros: Any) -> Any:
    """A pointer to an action table's float32 (`_action_table`) on the stack of the compiled function
    that calls it: ``len(actions)`` rows of `row_width`."""
    count = len(actions) * row_width(len(zeros))

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return alloca_once(builder, context.get_value_type(nbtypes.float32), size=count)

    pointer: Any = nbtypes.CPointer
    return pointer(nbtypes.float32)(actions, zeros), codegen


stack_floats: Any = _stack_floats_intrinsic


@njit(**JIT, **INLINE)
def _action_table(packed: Any, layout: Any, zeros: Any) -> Any:
    """[`pack`][heartpole.kernel.pack]'s action rows, one after the other, copied to a flat array on the caller's stack.

    The loop over envs reads each env's action effects from it. LLVM vectorises those reads only from
    memory it knows no written array overlaps, which the caller's stack is, and ``packed`` is not. A table
    too large for the stack (`STACK_TABLE_LIMIT`) goes on the heap: correct, slower.
    """
    width = _row_width(len(zeros))  # known when compiling, as the branch below
    if len(layout[2]) * width <= STACK_TABLE_LIMIT:  # known when compiling: one branch stays
        table = carray(stack_floats(layout[2], zeros), len(layout[2]) * width)
    else:
        table = np.empty(len(layout[2]) * width, dtype=np.float32)
    for a in range(len(layout[2])):
        for c in range(width):
            table[a * width + c] = packed[a, c]
    return table


if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _action_table = lambda packed, layout, zeros: np.ascontiguousarray(packed[:-1]).ravel()  # type: ignore[assignment]  # noqa: E731


SELECTED_ACTIONS = 4
"""Up to this many actions, the loop over envs selects each env's action effects with masks; with more, it
reads them from the action table with gathers (the masks grow with the actions, and outgrow the registers).
At 16,384 envs on our Xeon: v0 about 78 us a step with masks, 86 us with gathers; v1 (8 actions) 125 us
with gathers, 5,000 us with masks (LLVM gives up vectorising)."""


# ---------------------------------------------------------------------------------------------------------
# The loops over envs. Array indices are unsigned: numba then skips its negative-index wraparound, which
# hides the addresses from LLVM's vectoriser. The single env is env 0 of a loop over one env: one compiled
# definition, so the two agree bit for bit. One env's turn in a loop is `env_state`, `action_effects`, the
# step, `store_env` (heartpole.person_kernel's loop takes the same turn, with each env's own numbers).
@njit(**JIT, **INLINE)
def env_state(envs: Any, rng: Any, i: Any, zeros: Any) -> Any:
    """``(state, uniforms)``: env ``i``'s state ``envs[:, i]`` as a tuple like ``zeros``, and its draw for this
    step from its generator state ``rng[:, i]``."""
    state = zeros
    for v in range(len(zeros)):
        state = tuple_setitem(state, v, envs[U64(v), i])
    return state, draws(rng[U64(KEY_LOW), i], rng[U64(KEY_HIGH), i], rng[U64(COUNTER), i], zeros)


@njit(**JIT, **INLINE)
def action_effects(table: Any, width: Any, layout: Any, action: Any, zeros: Any) -> Any:
    """The effects of ``action`` from the action rows at the start of ``table`` (rows of ``width``): selected
    with masks up to `SELECTED_ACTIONS` actions, gathered beyond (known when compiling: one branch stays)."""
    if len(layout[2]) <= SELECTED_ACTIONS:
        return chosen_effects((table, width, layout[2], action), U64(0), zeros, ())
    return read_effects(table, U64(action) * width, zeros, ())


@njit(**JIT, **INLINE)
def store_env(envs: Any, results: Any, rng: Any, i: Any, outcome: Any) -> None:
    """Env ``i``'s step ``outcome`` (the model's step's tuple) into place: its new state into ``envs[:, i]``,
    its draw counted in ``rng``, its results into ``results[k][i]``."""
    state, reward, worked, risk, attack, new_score = outcome
    for v in range(len(state)):
        envs[U64(v), i] = stored(v, state[v])
    rng[U64(COUNTER), i] = add32(rng[U64(COUNTER), i], U32(1))
    results[0][i] = reward
    results[1][i] = worked
    results[2][i] = risk
    results[3][i] = attack
    results[4][i] = new_score


@njit(**JIT, **INLINE)
def _step_envs(envs: Any, results: Any, actions: Any, rng: Any, packed: Any, layout: Any) -> None:
    """The loop over envs of `step_envs`, which `step_one` runs over one env."""
    wide_vectors()
    zeros, tables = _unpack(packed, layout)
    table, width = _action_table(packed, layout, zeros), U64(_row_width(len(zeros)))
    for index in range(actions.shape[0]):
        i = U64(index)
        state, uniforms = env_state(envs, rng, i, zeros)
        effects = action_effects(table, width, layout, actions[i], zeros)
        store_env(envs, results, rng, i, _step(state, effects, uniforms, tables))


@njit(**JIT)
def step_envs(envs: Any, results: Any, actions: Any, rng: Any, packed: Any, layout: Any) -> None:
    """Step every env ``i`` with ``actions[i]``: its state ``envs[:, i]`` in place, its results to
    ``results[k][i]``, a tuple of arrays in `OUTPUTS` order (`new_results`).

    The results are arrays apart from the state so that fresh ones can go out as they are, without a copy.
    Each env draws its uniforms with its generator state ``rng[:, i]`` and then counts the draw.
    ``packed`` and ``layout`` are [`pack`][heartpole.kernel.pack]'s and [`layout`][heartpole.kernel.layout]'s.
    """
    _step_envs(envs, results, actions, rng, packed, layout)


@njit(**JIT)
def step_one(envs: Any, action: Any, rng: Any, packed: Any, layout: Any) -> Any:
    """[`step_envs`][heartpole.kernel.step_envs] over one env (the single env's path): ``envs`` is
    ``(num_variables, 1)``, ``rng`` ``(3, 1)``; returns its results as numbers, in `OUTPUTS` order. The same
    loop as the vector env's, so the single env is env 0 of a vector env bit for bit."""
    results = (one(F32(0.0)), one(F32(0.0)), one(F32(0.0)), one(False), one(F32(0.0)))
    _step_envs(envs, results, one(ACTION_DTYPE(action)), rng, packed, layout)
    return results[0][0], results[1][0], results[2][0], results[3][0], results[4][0]


@njit(**JIT)
def reset_envs(envs: Any, rng: Any, which: Any, packed: Any, layout: Any) -> None:
    """Start env ``i`` afresh wherever ``which[i]``: every variable 0, then waking up with one draw."""
    zeros, tables = _unpack(packed, layout)
    wake = len(zeros)  # the wake-up uniform of a draw, as in a step
    for i in range(which.shape[0]):
        if which[i]:
            u = uniform(rng[KEY_LOW, i], rng[KEY_HIGH, i], rng[COUNTER, i], wake)
            state = _initial_state(zeros, u, tables)
            for v in range(len(zeros)):
                envs[v, i] = state[v]
            rng[COUNTER, i] = add32(rng[COUNTER, i], U32(1))


# They inline model's step and jit's tools: an edit of either recompiles them.
cache_keyed_on(model, step_envs, step_one, reset_envs)
cache_keyed_on(jit, step_envs, step_one, reset_envs)
cache_keyed_on(random_numbers, step_envs, step_one, reset_envs)
# Plain Python would return NumPy scalars where compiled code returns Python ones.
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _python_step_one = step_one

    def step_one(envs: Any, action: Any, rng: Any, packed: Any, layout: Any) -> Any:  # type: ignore[misc]  # noqa: F811
        """[`step_one`][heartpole.kernel.step_one] run as plain Python, its results as Python numbers."""
        reward, worked, risk, attack, new_score = _python_step_one(envs, action, rng, packed, layout)
        return float(reward), float(worked), float(risk), bool(attack), float(new_score)
