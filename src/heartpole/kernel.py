"""The HeartPole step compiled with numba: [`step`][heartpole.model.step] over many envs at once, for every variant
and every population of people.

No formula lives here. [`heartpole.model`][heartpole.model]'s functions are compiled *as written*, with three
bindings: a float32 ``exp`` that LLVM can vectorise and ``where`` as a branch-free select
([`heartpole.lanes`][heartpole.lanes]), and ``replace`` as numba's in-register tuple update. Their float
literals become float32 constants, so that the whole step computes in float32. What this module adds:

* [`heartpole.rng`][heartpole.rng]'s counter-based generator, compiled: an env's state is its key and its counter;
* the tables packed in one float32 array ([`pack`][heartpole.kernel.pack]: a row per action, then the variant's);
* one loop over envs ([`step_envs`][heartpole.kernel.step_envs], [`reset_envs`][heartpole.kernel.reset_envs]; the
  single env's [`step_one`][heartpole.kernel.step_one] runs it over one env, so the two agree bit for bit),
  specialised by one [`LoopSpec`][heartpole.kernel.LoopSpec]: which numbers differ between actions, and which
  are each env's own (a person's). The numbers an env's step reads are generated Python,
  [`source`][heartpole.kernel.source], which a reader can print.

Compiled code is cached on disk where numba can write (`heartpole.jit`). With ``NUMBA_DISABLE_JIT=1``
everything runs as plain Python.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import textwrap
from collections.abc import Sequence
from typing import Any, NamedTuple

import numba
import numpy as np
from numba import njit
from numba.cpython.unsafe.tuple import tuple_setitem as _tuple_setitem
from numba.core import types as nbtypes
from numba.extending import intrinsic, overload
from numba.core import cgutils
from numba.np.numpy_support import carray as _carray
from numba.np.unsafe.ndarray import to_fixed_tuple as _to_fixed_tuple

from heartpole import jit, lanes, model
from heartpole import rng as random_numbers  # the module; ``rng`` names envs' generator states here
from heartpole.jit import CACHE as CACHE  # numba's disk cache, for the package's other compiled code
from heartpole.jit import INLINE, JIT, JitOptions, cache_keyed_on, column, no_alias, one, wide_vectors
from heartpole.lanes import F32, U32, U64, add32, exp32, mul32, shr32, where, xor32

# The compiled functions take and return ``Any``: numba specialises them on the types of their arguments.
# numba's stubs type an intrinsic's call as never returning, which holds only outside compiled code.
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
# A table's row holds its PerVariable fields, ``n`` numbers each, then its Number fields, one each
# (model.table_fields); its Shape fields (the rest offsets 0, 1, ...) are not packed.
EFFECTS = model.table_fields(model.ActionEffects)
"""The fields of an action's row of [`pack`][heartpole.kernel.pack]'s array, by kind."""
TABLES = model.table_fields(model.StepTables)
"""The fields of the variant's row of [`pack`][heartpole.kernel.pack]'s array (its last), by kind."""
ACTION_DTYPE = np.int32
"""The dtype of the loop's actions: with 32-bit integers, LLVM vectorises it eight floats wide, not four."""
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


def row_width(num_variables: int) -> int:
    """The width of [`pack`][heartpole.kernel.pack]'s rows for ``num_variables`` variables: the wider of the
    two tables' rows."""
    return max(len(t.per_variable) * num_variables + len(t.numbers) for t in (EFFECTS, TABLES))


def pack_row(table: tuple[Any, ...], fields: model.TableFields) -> list[Any]:
    """``table``'s numbers in its row's order: its PerVariable fields one after the other, then its Numbers."""
    return [x for name in fields.per_variable for x in getattr(table, name)] + [
        getattr(table, k) for k in fields.numbers
    ]


def padded_rows(effects: Sequence[model.ActionEffects], tables: model.StepTables) -> list[list[Any]]:
    """[`pack`][heartpole.kernel.pack]'s rows before they become an array: numbers of any type (arrays too)."""
    width = row_width(len(tables.floor))
    rows = [pack_row(e, EFFECTS) for e in effects] + [pack_row(tables, TABLES)]
    return [row + [0.0] * (width - len(row)) for row in rows]


def pack(effects: Sequence[model.ActionEffects], tables: model.StepTables) -> np.ndarray:
    """``effects`` and ``tables`` as one float32 array of `row_width` columns: a row per action (`EFFECTS`),
    then a row for ``tables`` (`TABLES`), each padded with zeros."""
    return np.array(padded_rows(effects, tables), dtype=np.float32)


def selection(packed: np.ndarray, num_actions: int, *also: np.ndarray) -> tuple[int, ...]:
    """The positions (in ``packed`` raveled) of the action rows' numbers that differ, bit for bit, from the first
    action's number in the same column, in ``packed`` or in any of the arrays ``also`` (selecting a number equal
    to the first action's changes nothing, so variants that differ in parameters only can share one loop)."""
    differ = np.zeros(packed[1:num_actions].shape, dtype=bool)
    for table in (packed, *also):
        bits = np.ascontiguousarray(table[:num_actions], dtype=np.float32).view(np.uint32)
        differ |= bits[1:] != bits[0]
    return tuple(int(p) for p in np.flatnonzero(differ.ravel()) + packed.shape[1])


SELECTED_NUMBERS = 64
"""Up to this many numbers that differ between actions, an env's are selected with masks; with more, gathered
from its action's row (masks outgrow the registers). The figures that set it: docs/speed.md."""


@dataclasses.dataclass(frozen=True)
class LoopSpec:
    """What one compiled loop over envs is specialised on: the variant's shape, the numbers that differ between
    actions and the numbers each env reads from its own column of ``cells`` (its person's).

    The loops take it as [`argument`][heartpole.kernel.LoopSpec.argument], an empty array whose dtype's one field
    is named after the spec: numba compiles a loop per argument type, so the spec's numbers are constants of the
    compiled code and key numba's disk cache. [`source`][heartpole.kernel.source] is what it compiles.

    Attributes:
        variables: the number of state variables.
        rest_offsets: the number of rest offsets (the longest drowsy rest of the actions).
        actions: the number of actions.
        selected: positions in the packed tables raveled ([`pack`][heartpole.kernel.pack]) of the action rows'
            numbers that differ from the first action's ([`selection`][heartpole.kernel.selection]).
        overlay: ``(position, column)`` pairs: number ``position`` of the packed tables raveled is each env's
            value in row ``column`` of the loop's ``cells`` (positions distinct; numbers may share a column).
    """

    variables: int
    rest_offsets: int
    actions: int
    selected: tuple[int, ...] = ()
    overlay: tuple[tuple[int, int], ...] = ()

    def __post_init__(self) -> None:
        positions = [p for p, _ in self.overlay]
        if len(set(positions)) != len(positions) or min(sum(self.overlay, ()), default=0) < 0:
            raise ValueError(
                f"a LoopSpec's overlay needs (position, column) pairs of integers >= 0, each position once; got "
                f"{list(self.overlay)}"
            )

    @functools.cached_property
    def argument(self) -> np.ndarray:
        """The spec as the loops take it: an empty array whose dtype's one field is named after it."""
        return np.empty(0, dtype=np.dtype([(repr(dataclasses.astuple(self)), np.uint8)]))

    @classmethod
    def of(cls, dtype: Any) -> LoopSpec:
        """The spec an `argument`'s ``dtype`` names: NumPy's dtype or numba's record type alike."""
        (name,) = dtype.fields
        return cls(*ast.literal_eval(name))

    @property
    def size(self) -> int:
        """The number of numbers of the packed tables ([`pack`][heartpole.kernel.pack]): a row per action and one."""
        return (self.actions + 1) * row_width(self.variables)

    @property
    def columns(self) -> int:
        """The number of rows of ``cells`` the loop reads."""
        return max((c + 1 for _, c in self.overlay), default=0)


NO_CELLS = np.zeros((0, 0), dtype=np.float32)
"""The loops' ``cells`` where no number is an env's own (a `LoopSpec` without overlay)."""


def source(spec: LoopSpec) -> str:
    """The Python source of ``numbers(packed, cells, action, i)`` for ``spec``: ``(zeros, effects, tables)``, the
    zero state, [`ActionEffects`][heartpole.model.ActionEffects] and [`StepTables`][heartpole.model.StepTables] env
    ``i`` steps with when it takes ``action``. The loops compile it (`numbers`), inlined, for their spec.

    Every index is a constant of the code. A number that differs between actions (``spec.selected``) is read
    from each action's row before it is selected (``n1_13 if action == 1 else n0_13``: a select, not a load
    behind a branch, so that LLVM vectorises it); beyond `SELECTED_NUMBERS` of them it is gathered from the
    action's row. An env's own number (``spec.overlay``) is read from its column of ``cells``. For v0
    (``print(heartpole.kernel.source(heartpole.Dynamics().spec))``; a person's numbers would add
    ``cell0, cell1 = cells[0, i], cells[1, i]`` and use them in place of the variant's)::

        def numbers(packed, cells, action, i):
            n0_0, n2_0 = packed[0, 0], packed[2, 0]
            e0 = n2_0 if action == 2 else n0_0
            n0_2, n2_2 = packed[0, 2], packed[2, 2]
            e2 = n2_2 if action == 2 else n0_2
            n0_6, n1_6, n2_6 = packed[0, 6], packed[1, 6], packed[2, 6]
            e6 = n2_6 if action == 2 else n1_6 if action == 1 else n0_6
            n0_7, n1_7, n2_7 = packed[0, 7], packed[1, 7], packed[2, 7]
            e7 = n2_7 if action == 2 else n1_7 if action == 1 else n0_7
            n0_8, n2_8 = packed[0, 8], packed[2, 8]
            e8 = n2_8 if action == 2 else n0_8
            n0_13, n3_13 = packed[0, 13], packed[3, 13]
            e13 = n3_13 if action == 3 else n0_13
            n0_14, n3_14 = packed[0, 14], packed[3, 14]
            e14 = n3_14 if action == 3 else n0_14
            n0_18, n3_18 = packed[0, 18], packed[3, 18]
            e18 = n3_18 if action == 3 else n0_18
            n0_20, n3_20 = packed[0, 20], packed[3, 20]
            e20 = n3_20 if action == 3 else n0_20
            zeros = (F32(0.0), F32(0.0), F32(0.0), F32(0.0), F32(0.0), F32(0.0))
            effects = ActionEffects(
                effect_low=(e0, packed[0, 1], e2, packed[0, 3], packed[0, 4], packed[0, 5]),
                effect_width=(e6, e7, e8, packed[0, 9], packed[0, 10], packed[0, 11]),
                rest_fade=(packed[0, 12], e13, e14, packed[0, 15], packed[0, 16], packed[0, 17]),
                rest=e18,
                drowsy=packed[0, 19],
                sleeps=e20,
            )
            tables = StepTables(
                floor=(packed[4, 0], packed[4, 1], packed[4, 2], packed[4, 3], packed[4, 4], packed[4, 5]),
                fade=(packed[4, 6], packed[4, 7], packed[4, 8], packed[4, 9], packed[4, 10], packed[4, 11]),
                anxiety_relief=(packed[4, 12], packed[4, 13], packed[4, 14], packed[4, 15], packed[4, 16], packed[4, 17]),
                heart_attack_proclivity=packed[4, 18],
                heart_attack_penalty=packed[4, 19],
                wake_low=packed[4, 20],
                wake_width=packed[4, 21],
                rest_offsets=no_floats(),
            )
            return zeros, effects, tables
    """
    width, n = row_width(spec.variables), spec.variables
    gather = len(spec.selected) > SELECTED_NUMBERS
    owners = {column: [p // width for p in spec.selected if p % width == column] for column in range(width)}
    own = {divmod(p, width): c for p, c in spec.overlay}
    cells = sorted(set(own.values()))
    lines = [f"    {_tuple(f'cell{c}' for c in cells)} = {_tuple(f'cells[{c}, i]' for c in cells)}"] if cells else []
    known: list[int] = []  # the positions of the numbers read before the loop, in order

    def constant(position: int) -> str:
        if position not in known:
            known.append(position)
        return f"n{position}"

    def effect(column: int) -> str:
        changed = [a for a in range(spec.actions) if (a, column) in own]
        if not owners[column] and not changed:
            return constant(column)
        if gather and owners[column]:
            lines.append(f"    e{column} = flat[U64(action) * U64({width}) + U64({column})]")
        else:
            rows = [a * width + column for a in [0, *([] if gather else owners[column])]]
            expression = constant(column)
            for p in rows[1:]:
                expression = f"{constant(p)} if action == {p // width} else {expression}"
            lines.append(f"    e{column} = {expression}")
        lines.extend(f"    e{column} = cell{own[a, column]} if action == {a} else e{column}" for a in changed)
        return f"e{column}"

    def table(column: int) -> str:
        c = own.get((spec.actions, column))
        return constant(spec.actions * width + column) if c is None else f"cell{c}"

    def fields(table_fields: model.TableFields, number: Any) -> list[str]:
        per = len(table_fields.per_variable)
        groups = [(name, [number(k * n + v) for v in range(n)]) for k, name in enumerate(table_fields.per_variable)]
        return [f"        {name}=({_tuple(values)})," for name, values in groups] + [
            f"        {name}={number(per * n + j)}," for j, name in enumerate(table_fields.numbers)
        ]

    effects = fields(EFFECTS, effect)
    tables = fields(TABLES, table)
    offsets = f"({_tuple(f'F32({k}.0)' for k in range(spec.rest_offsets))})"
    tables.append(f"        rest_offsets={offsets if spec.rest_offsets else 'no_floats()'},")
    lines += [f"    zeros = ({_tuple(['F32(0.0)'] * n)})", "    effects = ActionEffects(", *effects, "    )"]
    lines += ["    tables = StepTables(", *tables, "    )", "    return zeros, effects, tables"]
    known.sort()
    reads = textwrap.wrap(_tuple(f"flat[{p}]" for p in known), 104, initial_indent="    return (", subsequent_indent=" " * 12)
    names = textwrap.wrap(_tuple(f"n{p}" for p in known), 104, initial_indent="    (", subsequent_indent=" " * 5)
    names[-1] += ") = known" if known else "() = known"
    lines = ["def read(flat):", *reads[:-1], reads[-1] + ")", "", "", "def numbers(known, flat, cells, action, i):", *names, *lines]
    return "\n".join(lines) + "\n"


@intrinsic
def _no_floats_intrinsic(typingctx: Any) -> Any:
    """An empty tuple of float32 (numba types ``()`` as a tuple of nothing, which it cannot iterate)."""
    empty = nbtypes.UniTuple(nbtypes.float32, 0)
    return empty(), lambda context, builder, signature, args: context.get_constant_undef(empty)


no_floats: Any = _no_floats_intrinsic
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    no_floats = tuple


def _tuple(items: Any) -> str:
    """``items`` (strings) as the inside of a tuple's parentheses in Python source."""
    items = list(items)
    return ", ".join(items) + ("," if len(items) == 1 else "")


PER_SPEC: JitOptions = {**JIT, "cache": False}
"""The options of the function made per spec: never cached itself, it is inlined into the loops, which are."""


@functools.lru_cache(maxsize=256)
def _compiled(spec: LoopSpec) -> dict[str, Any]:
    """`source` of ``spec``'s functions, compiled (to be inlined), by name."""
    namespace: dict[str, Any] = {"F32": F32, "U64": U64, "no_floats": no_floats}
    namespace.update(ActionEffects=model.ActionEffects, StepTables=model.StepTables)
    exec(source(spec), namespace)  # code made here from the spec's integers, nothing from outside
    return {name: njit(**PER_SPEC, **INLINE)(namespace[name]) for name in ("read", "numbers")}


def read(spec: Any, flat: Any) -> Any:
    """The numbers that actions choose between, read from the packed tables ``flat`` (raveled) before a loop over
    envs as `source`'s ``read`` reads them for the `LoopSpec` whose `argument` is ``spec``. Plain Python here
    (``NUMBA_DISABLE_JIT``); compiled code compiles `source` when it compiles the loop, from ``spec``'s type."""
    return _compiled(LoopSpec.of(spec.dtype))["read"](flat)


def numbers(spec: Any, known: Any, flat: Any, cells: Any, action: Any, i: Any) -> Any:
    """``(zeros, effects, tables)`` of env ``i`` taking ``action``, as `source`'s ``numbers`` makes them (``chosen``
    what `read` gave). Plain Python here, compiled code compiles it as `read`."""
    return _compiled(LoopSpec.of(spec.dtype))["numbers"](known, flat, cells, action, i)


@overload(read, inline="always")
def _read(spec: Any, flat: Any) -> Any:
    """`read` in compiled code: `source`'s, for the spec ``spec``'s type names, compiled and inlined."""
    generated = _compiled(LoopSpec.of(spec.dtype))["read"]

    def read_compiled(spec: Any, flat: Any) -> Any:
        return generated(flat)

    return read_compiled


@overload(numbers, inline="always")
def _numbers(spec: Any, known: Any, flat: Any, cells: Any, action: Any, i: Any) -> Any:
    """`numbers` in compiled code, as `_read`."""
    generated = _compiled(LoopSpec.of(spec.dtype))["numbers"]

    def numbers_compiled(spec: Any, known: Any, flat: Any, cells: Any, action: Any, i: Any) -> Any:
        return generated(known, flat, cells, action, i)

    return numbers_compiled


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
# The loop over envs. Array indices are unsigned: numba then skips its negative-index wraparound, which
# hides the addresses from LLVM's vectoriser. One env's turn is `numbers`, `env_state`, the step, `store_env`.
@njit(**JIT, **INLINE)
def env_state(envs: Any, rng: Any, i: Any, zeros: Any) -> Any:
    """``(state, uniforms)``: env ``i``'s state ``envs[:, i]`` as a tuple like ``zeros``, and its draw for this
    step from its generator state ``rng[:, i]``."""
    state = zeros
    for v in range(len(zeros)):
        state = tuple_setitem(state, v, envs[U64(v), i])
    return state, draws(rng[U64(KEY_LOW), i], rng[U64(KEY_HIGH), i], rng[U64(COUNTER), i], zeros)


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


@njit(**JIT)
def _loop(envs: Any, results: Any, rng: Any, packed: Any, cells: Any, spec: Any) -> None:
    """The loop over envs of `step_envs` and `step_one`, one compiled function for both: env ``i`` takes
    ``results.actions[i]``. No two of the arrays may overlap (`no_alias`: LLVM vectorises the loop then)."""
    wide_vectors()
    no_alias()
    actions, flat = results[ACTIONS], packed.reshape(packed.size)
    known = read(spec, flat)
    for index in range(actions.shape[0]):
        i = U64(index)
        zeros, effects, tables = numbers(spec, known, flat, cells, actions[i], i)
        state, uniforms = env_state(envs, rng, i, zeros)
        store_env(envs, results, rng, i, _step(state, effects, uniforms, tables))


@njit(**JIT)
def step_envs(envs: Any, results: Any, actions: Any, rng: Any, packed: Any, cells: Any, spec: Any) -> bool:
    """Step every env ``i`` with ``actions[i]``: its state ``envs[:, i]`` in place, its results to ``results``, a
    [`StepResults`][heartpole.kernel.StepResults] ([`new_results`][heartpole.arrays.new_results]). First the
    actions (integers of any type) are checked and converted into ``results.actions`` (`convert_actions`): where
    one is not an action, nothing changes and the answer is False.

    Each env draws its uniforms with its generator state ``rng[:, i]`` and then counts the draw. ``packed`` is
    [`pack`][heartpole.kernel.pack]'s, ``spec`` a [`LoopSpec`][heartpole.kernel.LoopSpec]'s ``argument``, ``cells``
    ``(spec.columns, num_envs)`` float32 (`NO_CELLS` without overlay). No two of the arrays may overlap.
    """
    if not convert_actions(actions, packed.shape[0] - 1, results[ACTIONS]):
        return False
    _loop(envs, results, rng, packed, cells, spec)
    return True


@njit(**JIT)
def step_one(envs: Any, action: Any, rng: Any, packed: Any, cells: Any, spec: Any) -> Any:
    """[`step_envs`][heartpole.kernel.step_envs] over one env (the single env's path): ``envs`` is
    ``(num_variables, 1)``, ``rng`` ``(3, 1)``; returns its results as numbers, in `OUTPUTS` order. The same
    compiled loop as the vector env's, so the single env is env 0 of a vector env bit for bit."""
    flat = packed.reshape(packed.size)
    zero, zeros = F32(0.0), numbers(spec, read(spec, flat), flat, cells, ACTION_DTYPE(0), U64(0))[0]
    # one env's results on this function's stack (`one`, `column`), not on the heap
    out = StepResults(one(zero), one(zero), one(zero), one(False), one(zero), column(zeros), one(ACTION_DTYPE(action)))
    _loop(envs, out, rng, packed, cells, spec)
    return out[REWARD][0], out[PRODUCTIVITY][0], out[RISK][0], out[ATTACK][0], out[SCORE][0]


@njit(**JIT)
def reset_envs(envs: Any, rng: Any, which: Any, packed: Any, cells: Any, spec: Any) -> None:
    """Start env ``i`` afresh wherever ``which[i]``: every variable 0, then waking up with one draw (its own waking
    alertness where the spec's overlay says so)."""
    flat = packed.reshape(packed.size)
    known = read(spec, flat)
    for index in range(which.shape[0]):
        if which[index]:
            i = U64(index)
            zeros, _, tables = numbers(spec, known, flat, cells, ACTION_DTYPE(0), i)
            u = uniform(rng[U64(KEY_LOW), i], rng[U64(KEY_HIGH), i], rng[U64(COUNTER), i], len(zeros))
            state = _initial_state(zeros, u, tables)
            for v in range(len(zeros)):
                envs[U64(v), i] = state[v]
            rng[U64(COUNTER), i] = add32(rng[U64(COUNTER), i], U32(1))


# They inline the model's step, jit's tools, the generator and the lanes: an edit of any recompiles them.
for _source in (model, jit, random_numbers, lanes):
    cache_keyed_on(_source, _loop, step_envs, step_one, reset_envs)
# Plain Python would return NumPy scalars where compiled code returns Python ones.
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _python_step_one = step_one

    def step_one(envs: Any, action: Any, rng: Any, packed: Any, cells: Any, spec: Any) -> Any:  # type: ignore[misc]  # noqa: F811
        """[`step_one`][heartpole.kernel.step_one] run as plain Python, its results as Python numbers."""
        reward, worked, risk, attack, new_score = _python_step_one(envs, action, rng, packed, cells, spec)
        return float(reward), float(worked), float(risk), bool(attack), float(new_score)
