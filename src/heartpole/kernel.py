"""The HeartPole step compiled with numba: [`step`][heartpole.model.step] over many envs at once, for every variant
and every population of people.

No formula lives here. [`heartpole.model`][heartpole.model]'s functions are compiled *as written*, with three
bindings: a float32 ``exp`` that LLVM can vectorise and ``where`` as a branch-free select
([`heartpole.lanes`][heartpole.lanes]), and ``replace`` as numba's in-register tuple update. Their float
literals become float32 constants, so that the whole step computes in float32. What this module adds:

* [`heartpole.rng`][heartpole.rng]'s counter-based generator, compiled: an env's state is its key and its counter;
* the tables packed in one float32 array ([`pack`][heartpole.kernel.pack]: a row per action, then the variant's);
* one loop over envs ([`step_envs`][heartpole.kernel.step_envs], [`reset_envs`][heartpole.kernel.reset_envs]; the
  single env's [`step_one`][heartpole.kernel.step_one] runs it over one env: the two agree bit for bit), specialised
  by one [`LoopSpec`][heartpole.kernel.LoopSpec] into generated Python a reader can print
  ([`source`][heartpole.kernel.source]). With ``NUMBA_DISABLE_JIT=1`` everything runs as plain Python.
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
from numba.core import types as nbtypes
from numba.cpython.unsafe.tuple import tuple_setitem as _tuple_setitem
from numba.extending import intrinsic, overload

from heartpole import jit, lanes, model
from heartpole import rng as random_numbers  # the module; ``rng`` names envs' generator states here
from heartpole.jit import CACHE as CACHE  # numba's disk cache, for the package's other compiled code
from heartpole.jit import INLINE, JIT, JitOptions, cache_keyed_on, column, no_alias, one, wide_vectors
from heartpole.lanes import F32, U32, U64, add32, exp32, mul32, shr32, where, xor32

# The compiled functions take and return ``Any``: numba specialises them on the types of their arguments.
# numba's stubs type an intrinsic's call as never returning, which holds only outside compiled code.
tuple_setitem: Any = _tuple_setitem
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]  # intrinsics run only in compiled code
    tuple_setitem = model.replace


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
    def columns(self) -> int:
        """The number of rows of ``cells`` the loop reads."""
        return max((c + 1 for _, c in self.overlay), default=0)


NO_CELLS = np.zeros((0, 0), dtype=np.float32)
"""The loops' ``cells`` where no number is an env's own (a `LoopSpec` without overlay)."""


def source(spec: LoopSpec) -> str:
    """The Python source the loops compile for ``spec`` (`read`, `numbers`): ``read(flat)``, once a loop, reads every
    number of the packed tables ``flat`` (raveled) that the step takes; ``numbers(known, flat, cells, action, i)``,
    for env ``i``, makes from them the zero state, [`ActionEffects`][heartpole.model.ActionEffects] and
    [`StepTables`][heartpole.model.StepTables] of its step with ``action``.

    Every index is a constant of the code. A number that differs between actions (``spec.selected``) is chosen by
    the action (``n50 if action == 2 else n6``: a select between values read before the loop; read in the loop,
    LLVM merged the choice into a gather, docs/speed.md); beyond `SELECTED_NUMBERS` of them it is gathered from
    the action's row. An env's own number (``spec.overlay``) comes from its column of ``cells`` (``cell0 =
    cells[0, i]``). For v0, ``print(heartpole.kernel.source(heartpole.Dynamics().spec))``::

        def read(flat):
            return (flat[0], flat[1], flat[2], flat[3], flat[4], flat[5], flat[6], flat[7], flat[8], flat[9],
                    flat[10], flat[11], flat[12], flat[13], flat[14], flat[15], flat[16], flat[17], flat[18],
                    flat[19], flat[20], flat[28], flat[29], flat[44], flat[46], flat[50], flat[51], flat[52],
                    flat[79], flat[80], flat[84], flat[86], flat[88], flat[89], flat[90], flat[91], flat[92],
                    flat[93], flat[94], flat[95], flat[96], flat[97], flat[98], flat[99], flat[100], flat[101],
                    flat[102], flat[103], flat[104], flat[105], flat[106], flat[107], flat[108], flat[109])


        def numbers(known, flat, cells, action, i):
            (n0, n1, n2, n3, n4, n5, n6, n7, n8, n9, n10, n11, n12, n13, n14, n15, n16, n17, n18, n19, n20, n28,
             n29, n44, n46, n50, n51, n52, n79, n80, n84, n86, n88, n89, n90, n91, n92, n93, n94, n95, n96, n97,
             n98, n99, n100, n101, n102, n103, n104, n105, n106, n107, n108, n109) = known
            e0 = n44 if action == 2 else n0
            e2 = n46 if action == 2 else n2
            e6 = n50 if action == 2 else n28 if action == 1 else n6
            e7 = n51 if action == 2 else n29 if action == 1 else n7
            e8 = n52 if action == 2 else n8
            e13 = n79 if action == 3 else n13
            e14 = n80 if action == 3 else n14
            e18 = n84 if action == 3 else n18
            e20 = n86 if action == 3 else n20
            zeros = (F32(0.0), F32(0.0), F32(0.0), F32(0.0), F32(0.0), F32(0.0))
            effects = ActionEffects(
                effect_low=(e0, n1, e2, n3, n4, n5),
                effect_width=(e6, e7, e8, n9, n10, n11),
                rest_fade=(n12, e13, e14, n15, n16, n17),
                rest=e18,
                drowsy=n19,
                sleeps=e20,
            )
            tables = StepTables(
                floor=(n88, n89, n90, n91, n92, n93),
                fade=(n94, n95, n96, n97, n98, n99),
                anxiety_relief=(n100, n101, n102, n103, n104, n105),
                heart_attack_proclivity=n106,
                heart_attack_penalty=n107,
                wake_low=n108,
                wake_width=n109,
                rest_offsets=no_floats(),
            )
            return zeros, effects, tables
    """
    width, n = row_width(spec.variables), spec.variables
    owners = {column: [p for p in spec.selected if p % width == column] for column in range(width)}
    own = {p: c for p, c in spec.overlay}
    gather = len(spec.selected) > SELECTED_NUMBERS
    known: set[int] = set()  # the positions read before the loop
    cells = sorted(set(own.values()))
    lines = [f"    {_tuple(f'cell{c}' for c in cells)} = {_tuple(f'cells[{c}, i]' for c in cells)}"] if cells else []

    def number(position: int) -> str:
        column = position % width
        if position >= spec.actions * width:  # the variant's row
            return f"cell{own[position]}" if position in own else _known(known, position)
        changed = [p for p in range(column, spec.actions * width, width) if p in own]
        if not owners[column] and not changed:
            return _known(known, column)
        if gather and owners[column]:
            lines.append(f"    e{column} = flat[U64(action) * U64({width}) + U64({column})]")
        else:
            expression = _known(known, column)
            for p in [] if gather else owners[column]:
                expression = f"{_known(known, p)} if action == {p // width} else {expression}"
            lines.append(f"    e{column} = {expression}")
        lines.extend(f"    e{column} = cell{own[p]} if action == {p // width} else e{column}" for p in changed)
        return f"e{column}"

    def fields(table: model.TableFields, row: int) -> list[str]:
        per, names = len(table.per_variable), enumerate(table.per_variable)
        groups = [f"{name}=({_tuple(number(row + k * n + v) for v in range(n))})" for k, name in names]
        return [
            f"        {f},"
            for f in groups + [f"{name}={number(row + per * n + j)}" for j, name in enumerate(table.numbers)]
        ]

    offsets = f"({_tuple(f'F32({k}.0)' for k in range(spec.rest_offsets))})" if spec.rest_offsets else "no_floats()"
    body = [f"    zeros = ({_tuple(['F32(0.0)'] * n)})", "    effects = ActionEffects(", *fields(EFFECTS, 0), "    )"]
    body += [
        "    tables = StepTables(",
        *fields(TABLES, spec.actions * width),
        f"        rest_offsets={offsets},",
        "    )",
    ]
    order = sorted(known)
    reads = textwrap.wrap(
        f"return ({_tuple(f'flat[{p}]' for p in order)})", 108, initial_indent="    ", subsequent_indent=" " * 12
    )
    names = textwrap.wrap(
        f"({_tuple(f'n{p}' for p in order)}) = known", 108, initial_indent="    ", subsequent_indent=" " * 5
    )
    head = ["def read(flat):", *reads, "", "", "def numbers(known, flat, cells, action, i):", *names, *lines]
    return "\n".join([*head, *body, "    return zeros, effects, tables"]) + "\n"


def _known(known: set[int], position: int) -> str:
    """The name in `source` of the number at ``position``, which its ``read`` reads (added to ``known``)."""
    known.add(position)
    return f"n{position}"


unituple: Any = nbtypes.UniTuple  # untyped in numba


@intrinsic
def _no_floats_intrinsic(typingctx: Any) -> Any:
    """An empty tuple of float32 (numba types ``()`` as a tuple of nothing, which it cannot iterate)."""
    empty = unituple(nbtypes.float32, 0)
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
    """The numbers of the packed tables ``flat`` (raveled) that the step takes, read once before a loop over envs,
    as `source`'s ``read`` reads them for the `LoopSpec` whose `argument` is ``spec``. Plain Python here
    (``NUMBA_DISABLE_JIT``); compiled code compiles `source` when it compiles the loop, from ``spec``'s type."""
    return _compiled(LoopSpec.of(spec.dtype))["read"](flat)


def numbers(spec: Any, known: Any, flat: Any, cells: Any, action: Any, i: Any) -> Any:
    """``(zeros, effects, tables)`` of env ``i`` taking ``action``, as `source`'s ``numbers`` makes them (``known``
    what `read` gave). Plain Python here; compiled code compiles it as `read`."""
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
