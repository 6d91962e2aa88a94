"""The HeartPole step compiled with numba: [`step`][heartpole.model.step] over many people at once.

No formula lives here. [`heartpole.model`][heartpole.model]'s functions are compiled *as written*, with three
bindings: a float32 ``exp`` that LLVM can vectorise and ``where`` as a branch-free select
([`heartpole.lanes`][heartpole.lanes]), and ``replace`` as numba's in-register tuple update. Their float
literals become float32 constants, so that the whole step computes in float32 (a Python float would make
numba compute in float64, at half the vector width). What this module adds is the machinery around the step:

* [`heartpole.rng`][heartpole.rng]'s counter-based generator, compiled: the ``j``-th uniform of an env's
  ``c``-th draw is a keyed hash of ``(key, c, j)``. An env's state is its key and its counter, so copies and
  pickles continue exactly, and two envs (or two policies evaluated alike) with the same key see the same draws.
* the tables packed in one array, laid out from the model's own definitions of them, and each env's action
  effects selected from them with a mask only where the actions' numbers differ
  ([`selection_for`][heartpole.kernel.selection_for]);
* [`step_envs`][heartpole.kernel.step_envs] and [`reset_envs`][heartpole.kernel.reset_envs], the loops over
  envs; the single env runs one env of them ([`step_one`][heartpole.kernel.step_one], the same loop), so the
  two agree bit for bit.

Compiled code is cached on disk where numba can write (`heartpole.jit`). With ``NUMBA_DISABLE_JIT=1``
everything runs as plain Python.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any, NamedTuple

import numba
import numpy as np
from numba import njit
from numba.core import cgutils
from numba.core import types as nbtypes
from numba.cpython.unsafe.tuple import tuple_setitem as _tuple_setitem
from numba.extending import intrinsic, overload
from numba.np.numpy_support import carray as _carray
from numba.np.unsafe.ndarray import to_fixed_tuple as _to_fixed_tuple

from heartpole import jit, lanes, model
from heartpole import rng as random_numbers  # the module; ``rng`` names envs' generator states here
from heartpole.jit import CACHE as CACHE  # numba's disk cache, for the package's other compiled code
from heartpole.jit import INLINE, JIT, JitOptions, cache_keyed_on, no_alias, one, wide_vectors
from heartpole.lanes import F32, U32, U64, add32, exp32, mul32, shr32, where, xor32

# The compiled functions take and return ``Any``: numba specialises them on the types of their arguments
# (float32 scalars, tuples of any length, arrays), which no single annotation describes. numba's stubs type an
# intrinsic's call as its typing function's (``typingctx`` first) and as never returning, which holds only
# outside compiled code; this module calls the intrinsics from compiled code, so it holds them as ``Any``.
tuple_setitem: Any = _tuple_setitem
to_fixed_tuple: Any = _to_fixed_tuple
carray: Any = _carray
alloca_once: Any = cgutils.alloca_once
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]  # intrinsics run only in compiled code
    tuple_setitem = model.replace
    to_fixed_tuple = lambda values, length: tuple(values[:length])  # noqa: E731


@njit(**JIT, **INLINE)
def stored(variable: Any, x: Any) -> Any:
    """``x`` as the state keeps it for ``variable``: a subnormal float32 (below ~1.2e-38) becomes 0. Fading
    values (blood pressure, alcohol, THC) would otherwise stick at a subnormal for ever (times 0.97 rounds
    back to itself) and make every later step several times slower; CPUs compute subnormals in microcode.
    The variables the step keeps itself (time and work) never fade and are kept as they are."""
    return x if _kept_by_the_step(variable) else where(abs(x) < SMALLEST_NORMAL, F32(0.0), x)


compiled = model.rebind({"exp": exp32, "where": where, "replace": tuple_setitem}, F32, njit(**JIT, **INLINE))
"""[`heartpole.model`][heartpole.model]'s functions, compiled: ``compiled.step`` is the step every env runs. Float
literals become float32 constants: numba would compute in float64 otherwise, at half the vector width."""
_step, _initial_state, _kept_by_the_step = compiled.step, compiled.initial_state, compiled.kept_by_the_step

SMALLEST_NORMAL = F32(np.finfo(np.float32).tiny)
KEY_LOW, KEY_HIGH, COUNTER = random_numbers.KEY_LOW, random_numbers.KEY_HIGH, random_numbers.COUNTER
generator_states = random_numbers.generator_states

_INTEGERS = {"u32": U32, "mul32": mul32, "add32": add32, "xor32": xor32, "shr32": shr32, "to_float": F32}
_SHARED = {"where": where, "replace": tuple_setitem, "kept_by_the_step": _kept_by_the_step}
compiled_rng = random_numbers.rebind({**_INTEGERS, **_SHARED}, F32, njit(**JIT, **INLINE))
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
OUTPUTS = {"reward": F32, "productivity": F32, "heart_attack_risk": F32, "heart_attack": np.bool_, "score": F32}
"""The results of a step, in [`step_envs`][heartpole.kernel.step_envs]'s order, with their dtypes."""


class StepResults(NamedTuple):
    """The arrays a loop over envs writes, item ``i`` (column ``i``) env ``i``'s: the `OUTPUTS` (their dtypes),
    a copy of the new states (``(num_variables, num_envs)`` float32) and the actions as `ACTION_DTYPE`."""

    reward: np.ndarray
    productivity: np.ndarray
    heart_attack_risk: np.ndarray
    heart_attack: np.ndarray
    score: np.ndarray
    observations: np.ndarray
    actions: np.ndarray


REWARD, PRODUCTIVITY, RISK, ATTACK, SCORE, OBSERVATIONS, ACTIONS = range(len(StepResults._fields))
"""The positions of `StepResults`' fields, by which compiled code reads them: numba 0.68 loses the writes made
by name (``results.reward[i] = ...``) in a function inlined into the one that built the tuple (the single env's
step read 0 for all its results); by position they hold."""


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


read_effects = reader(model.ActionEffects, EFFECTS, _at)
"""The [`ActionEffects`][heartpole.model.ActionEffects] in a row of `pack`'s array (or the action table)."""
read_tables = reader(model.StepTables, TABLES, _at)
"""The [`StepTables`][heartpole.model.StepTables] in [`pack`][heartpole.kernel.pack]'s last row."""

PER_POSITIONS: JitOptions = {**JIT, "cache": False}
"""The options of the small functions made per set of positions (closures over them): never cached themselves,
they are inlined into the loops, which are."""


def selection_for(packed: np.ndarray, num_actions: int, *also: np.ndarray) -> np.ndarray:
    """The loops' ``selection`` for [`pack`][heartpole.kernel.pack]'s array ``packed``: an empty array whose
    structured dtype names, as fields ``p{position}``, the numbers of its action rows (raveled) that differ, bit
    for bit, from the first action's number in the same column (and a field ``first``, so that it has one); and
    those that differ in any of the arrays ``also`` (selecting a number equal to the first action's changes
    nothing, so variants that differ in parameters only can share one compiled loop).

    Being part of the argument's *type*, the positions are constants of the compiled loop, and key numba's disk
    cache: the loop selects an env's action effects with one mask for each position (`select`), and none where
    every action has the same number (v0: 11 masks, where a mask per action and number would take 33)."""
    differ = np.zeros(packed[1:num_actions].shape, dtype=bool)
    for table in (packed, *also):
        bits = np.ascontiguousarray(table[:num_actions], dtype=np.float32).view(np.uint32)
        differ |= bits[1:] != bits[0]
    positions = np.flatnonzero(differ.ravel()) + packed.shape[1]
    names = ["first"] + [f"p{int(p)}" for p in positions]
    fields = {"names": names, "formats": [np.uint8] * len(names), "offsets": [0] * len(names)}
    return np.empty(0, dtype=np.dtype(fields))  # type: ignore[call-overload]


@functools.lru_cache(maxsize=256)
def _selector(positions: tuple[int, ...], num_variables: int) -> Any:
    """A compiled ``select(effects, table, action)``: the first action's ``effects`` with, at each of
    ``positions`` of the action ``table`` (rows of `row_width`), the number of the action it belongs to where that
    is ``action``. Written out as one expression per number, its indices constants of the code: one function
    for numba to compile, not one per position (slower to compile: docs/speed.md)."""
    width = row_width(num_variables)
    owners: dict[int, list[int]] = {}  # column -> the positions of the actions whose number differs there
    for position in positions:
        owners.setdefault(position % width, []).append(position)

    def number(column: int) -> str:
        field, variable = field_at(EFFECTS, num_variables, column)
        expression = f"effects[{field}]" + ("" if variable is None else f"[{variable}]")
        for position in owners.get(column, []):  # its number read before: a select, not a load behind a branch
            expression = f"(n{position} if action == {position // width} else {expression})"
        return expression

    per_variable = len(EFFECTS.per_variable)
    fields = [
        "(" + "".join(f"{number(k * num_variables + v)}, " for v in range(num_variables)) + ")"
        for k in range(per_variable)
    ] + [number(per_variable * num_variables + j) for j in range(len(EFFECTS.numbers))]
    reads = "".join(f"    n{position} = table[U64({position})]\n" for position in positions)
    source = f"def select_all(effects, table, action):\n{reads}    return ActionEffects({', '.join(fields)})\n"
    namespace: dict[str, Any] = {"ActionEffects": model.ActionEffects, "U64": U64}
    exec(source, namespace)  # code made here from table positions, nothing from outside
    return njit(**PER_POSITIONS, **INLINE)(namespace["select_all"])


def _positions(dtype: Any) -> tuple[int, ...]:
    """The positions a ``selection``'s ``dtype`` names (`selection_for`), in order: NumPy's and numba's alike."""
    return tuple(sorted(int(name[1:]) for name in dtype.fields if name != "first"))


def _selector_for(dtype: Any, num_variables: int) -> Any:
    """`_selector` for a ``selection``'s ``dtype``."""
    return _selector(_positions(dtype), num_variables)


def select(effects: Any, table: Any, action: Any, selection: Any) -> Any:
    """The effects of ``action``: the first action's ``effects`` with the numbers `selection_for` names taken from
    the action ``table`` where they are ``action``'s. This is the plain Python of ``NUMBA_DISABLE_JIT``; compiled
    code builds the chain from ``selection``'s type (`_select`)."""
    return _selector_for(selection.dtype, len(effects.effect_low))(effects, table, action)


@overload(select, inline="always")
def _select(effects: Any, table: Any, action: Any, selection: Any) -> Any:
    """`select` in compiled code: its chain built when compiling, from the type of ``selection``."""
    chain = _selector_for(selection.dtype, len(effects[0]))

    def select_compiled(effects: Any, table: Any, action: Any, selection: Any) -> Any:
        return chain(effects, table, action)

    return select_compiled


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


SELECTED_NUMBERS = 64
"""Up to this many numbers named by the selection (`selection_for`), the loop over envs selects each env's action
effects with masks (`select`); with more, with gathers (masks outgrow the registers). The figures that set it:
docs/speed.md, "What each mechanism of the loop earned"."""


def masked(selection: Any) -> bool:
    """Whether the loop selects the action effects of ``selection`` with masks (`SELECTED_NUMBERS`). Plain Python;
    compiled code knows the answer when compiling (`_masked`), so only one way is compiled into the loop."""
    return len(_positions(selection.dtype)) <= SELECTED_NUMBERS


@overload(masked, inline="always")
def _masked(selection: Any) -> Any:
    """`masked` in compiled code: a constant of the code, from the type of ``selection``."""
    answer = len(_positions(selection.dtype)) <= SELECTED_NUMBERS

    def masked_compiled(selection: Any) -> bool:
        return answer

    return masked_compiled


@njit(**JIT)
def convert_actions(actions: Any, count: Any, out: Any) -> bool:
    """Whether every one of the integers ``actions`` is at least 0 and below ``count`` (compared as unsigned:
    negatives become huge), converting them into ``out`` as `ACTION_DTYPE` meanwhile: one pass, where NumPy's
    check and conversion take two. ``out`` is of no use where they are not."""
    largest = U64(0)
    for i in range(actions.shape[0]):
        largest = max(largest, U64(actions[i]))
        out[i] = ACTION_DTYPE(actions[i])
    return largest < U64(count)


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
def action_effects(table: Any, width: Any, layout: Any, action: Any, zeros: Any, selection: Any) -> Any:
    """The effects of ``action`` from the action rows at the start of ``table`` (rows of ``width``): selected
    with masks (`select`) up to `SELECTED_NUMBERS` numbers, gathered beyond (known when compiling: one branch
    stays)."""
    if masked(selection):
        return select(read_effects(table, U64(0), zeros, ()), table, action, selection)
    return read_effects(table, U64(action) * width, zeros, ())


@njit(**JIT, **INLINE)
def store_env(envs: Any, results: Any, rng: Any, i: Any, outcome: Any) -> None:
    """Env ``i``'s step ``outcome`` (the model's step's tuple) into place: its new state into ``envs[:, i]`` and
    ``results``' observations ``[:, i]``, its draw counted in ``rng``, its results into `StepResults`' ``[i]``."""
    state, reward, worked, risk, attack, new_score = outcome
    for v in range(len(state)):
        x = stored(v, state[v])
        envs[U64(v), i] = x
        results[OBSERVATIONS][U64(v), i] = x
    rng[U64(COUNTER), i] = add32(rng[U64(COUNTER), i], U32(1))
    results[REWARD][i] = reward
    results[PRODUCTIVITY][i] = worked
    results[RISK][i] = risk
    results[ATTACK][i] = attack
    results[SCORE][i] = new_score


@njit(**JIT, **INLINE)
def _step_envs(envs: Any, results: Any, actions: Any, rng: Any, packed: Any, layout: Any, selection: Any) -> None:
    """The loop over envs of `step_envs`, which `step_one` runs over one env."""
    wide_vectors()
    no_alias()
    zeros, tables = _unpack(packed, layout)
    table, width = _action_table(packed, layout, zeros), U64(_row_width(len(zeros)))
    for index in range(actions.shape[0]):
        i = U64(index)
        state, uniforms = env_state(envs, rng, i, zeros)
        effects = action_effects(table, width, layout, actions[i], zeros, selection)
        store_env(envs, results, rng, i, _step(state, effects, uniforms, tables))


@njit(**JIT)
def step_envs(envs: Any, results: Any, actions: Any, rng: Any, packed: Any, layout: Any, selection: Any) -> bool:
    """Step every env ``i`` with ``actions[i]``: its state ``envs[:, i]`` in place, its results to ``results``, a
    [`StepResults`][heartpole.kernel.StepResults] ([`new_results`][heartpole.arrays.new_results]). First the
    actions (integers of any type) are checked and converted into ``results.actions`` (`convert_actions`): where
    one is not an action, nothing changes and the answer is False.

    The results are arrays apart from the state so that fresh ones can go out as they are, without a copy.
    Each env draws its uniforms with its generator state ``rng[:, i]`` and then counts the draw.
    ``packed``, ``layout`` and ``selection`` are [`pack`][heartpole.kernel.pack]'s,
    [`layout`][heartpole.kernel.layout]'s and [`selection_for`][heartpole.kernel.selection_for]'s.
    """
    if not convert_actions(actions, len(layout[2]), results[ACTIONS]):
        return False
    _step_envs(envs, results, results[ACTIONS], rng, packed, layout, selection)
    return True


@njit(**JIT)
def step_one(envs: Any, action: Any, rng: Any, packed: Any, layout: Any, selection: Any) -> Any:
    """[`step_envs`][heartpole.kernel.step_envs] over one env (the single env's path): ``envs`` is
    ``(num_variables, 1)``, ``rng`` ``(3, 1)``; returns its results as numbers, in `OUTPUTS` order. The same
    loop as the vector env's, so the single env is env 0 of a vector env bit for bit."""
    zero = F32(0.0)  # one env's results on this function's stack (`one`), its observations the state itself
    out = StepResults(one(zero), one(zero), one(zero), one(False), one(zero), envs, one(ACTION_DTYPE(action)))
    _step_envs(envs, out, out[ACTIONS], rng, packed, layout, selection)
    return out[REWARD][0], out[PRODUCTIVITY][0], out[RISK][0], out[ATTACK][0], out[SCORE][0]


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


# They inline the model's step, jit's tools, the generator and the lanes: an edit of any recompiles them.
for _source in (model, jit, random_numbers, lanes):
    cache_keyed_on(_source, step_envs, step_one, reset_envs)
# Plain Python would return NumPy scalars where compiled code returns Python ones.
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _python_step_one = step_one

    def step_one(envs: Any, action: Any, rng: Any, packed: Any, layout: Any, selection: Any) -> Any:  # type: ignore[misc]  # noqa: F811
        """[`step_one`][heartpole.kernel.step_one] run as plain Python, its results as Python numbers."""
        reward, worked, risk, attack, new_score = _python_step_one(envs, action, rng, packed, layout, selection)
        return float(reward), float(worked), float(risk), bool(attack), float(new_score)
