"""The HeartPole physiology as the tutorial writes it: facts 0-8 and one step of a working day.

Everything here is plain arithmetic on one person's state, in the tutorial's order and with its signs
and constants. The functions take Python or NumPy numbers (a NumPy array gives the curve over many
values, as in the tutorial's plots). Three things are *bound by the backend* that runs them:
``exp``, ``where`` (a branch-free ``a if condition else b``) and ``replace`` (a tuple with one item
changed). [`heartpole.kernel`][heartpole.kernel] compiles this very code with numba, in float32, with its own
``exp``; the JAX env traces it with ``jax.numpy``'s. No formula is written anywhere else.

Time is counted in half-hours. A state is a tuple of floats in observation order (``ALERTNESS`` ...
``WORK_DONE``, then any variant's extra variables).
"""

from __future__ import annotations

import types
from collections.abc import Callable, Sequence
from typing import Annotated, Any, NamedTuple, get_type_hints

import numpy as np
from numpy import where

from heartpole.backend import called_by, rebind_functions

Number = Any
"""A Python float, a NumPy scalar or array, or a backend's number (numba float32, JAX tracer)."""
State = tuple[Number, ...]
"""One person's state: one number per state variable, in observation order."""

# Fact 0: what your productivity and health depend on, in the tutorial's (and the observation's) order.
ALERTNESS, HYPERTENSION, INTOXICATION, TIME_SINCE_SLEPT, TIME_ELAPSED, WORK_DONE = range(6)


def exp(x: Number) -> Number:
    """``e ** x`` with NumPy. Overflow to infinity is expected here (a sigmoid of it is then 0), not warned."""
    with np.errstate(over="ignore"):
        return np.exp(x)


def replace(state: State, index: int, value: Number) -> State:
    """``state`` with item ``index`` set to ``value`` (states are tuples: every backend can trace them)."""
    return state[:index] + (value,) + state[index + 1 :]


def kept_by_the_step(variable: int) -> bool:
    """Whether the step keeps ``variable`` itself (time and work): no action, fading or relief touches it."""
    return TIME_SINCE_SLEPT <= variable <= WORK_DONE


def sigmoid(x: Number) -> Number:
    """The logistic function ``1 / (1 + exp(-x))``."""
    return 1.0 / (1.0 + exp(-x))


def gaussian(x: Number, mu: Number, sigma: Number) -> Number:
    """An unnormalised bell curve ``exp(-(x - mu)**2 / (2 sigma**2))``: 1 at ``x == mu``, width ``sigma``."""
    return exp(-((x - mu) ** 2.0) / (2.0 * sigma**2.0))


def heart_attack_risk(hypertension: Number, proclivity: Number = 0.5) -> Number:
    """Fact 4: the probability of a heart attack in one step, ``proclivity * sigmoid(hypertension - 6)``."""
    return proclivity * sigmoid(hypertension - 6.0)


def alertness_decay(time_since_slept: Number) -> Number:
    """Fact 6: alertness lost in one half-hour awake, ``sigmoid((time_since_slept - 40) / 10)``."""
    return sigmoid((time_since_slept - 40.0) / 10.0)


def crippling_anxiety(alertness: Number) -> Number:
    """Fact 7: the share of work lost to anxiety when too alert, ``sigmoid(alertness - 3)``."""
    return sigmoid(alertness - 3.0)


def ballmer(intoxication: Number) -> Number:
    """Fiction 8: programming skill against blood alcohol, with the Ballmer peak at 0.135:
    ``sigmoid((0.05 - intoxication) * 50) + 2 * gaussian(intoxication, 0.135, 0.005)``."""
    return sigmoid((0.05 - intoxication) * 50.0) + 2.0 * gaussian(intoxication, 0.135, 0.005)


def productivity(alertness: Number, intoxication: Number, calm: Number = 0.0) -> Number:
    """Facts 7 and 8: work done in one half-hour, ``alertness * (1 - crippling_anxiety) * ballmer``.

    ``calm`` is anxiety relief (HeartPole-v1's THC; see `Variable.anxiety_relief`): anxiety sets in
    ``calm`` units of alertness later, ``crippling_anxiety(alertness - calm)``. v0 has none.
    """
    return alertness * (1.0 - crippling_anxiety(alertness - calm)) * ballmer(intoxication)


def score(work_done: Number, time_elapsed: Number) -> Number:
    """The running productivity score ``work_done / time_elapsed``, 0 before any time has passed."""
    return work_done / where(time_elapsed > 1.0, time_elapsed, 1.0)


def wake_alertness(uniform: Number, tables: StepTables) -> Number:
    """Fact 1: after a good night's sleep you wake up quite alert, uniformly in ``Params.wake_alertness``."""
    return tables.wake_low + tables.wake_width * uniform


def initial_state(zeros: State, uniform: Number, tables: StepTables) -> State:
    """Facts 0 and 1: every variable at 0, then waking up (``uniform`` is a draw in [0, 1))."""
    return replace(zeros, ALERTNESS, wake_alertness(uniform, tables))


PerVariable = Annotated[tuple[Number, ...], "one number per state variable"]
"""A field of [`ActionEffects`][heartpole.model.ActionEffects] or [`StepTables`][heartpole.model.StepTables]
with one number per state variable, in observation order."""
Shape = Annotated[tuple[Number, ...], "its length shapes the step's loops"]
"""A field of [`StepTables`][heartpole.model.StepTables] whose length, not its numbers, a backend fixes when it
compiles or traces the step (JAX keeps it out of its parameters)."""


class ActionEffects(NamedTuple):
    """What one action does, as numbers (one per state variable where a tuple).

    The action adds ``effect_low[v] + effect_width[v] * u`` to variable ``v``; then ``rest`` half-hours
    pass without work, the first ``drowsy`` of them awake, after which ``rest_fade[v]`` of ``v`` is left;
    ``sleeps`` (1 or 0) ends the rest by waking up. Built by [`Dynamics`][heartpole.dynamics.Dynamics].

    Its fields are the one definition of these numbers: the kernel's packed rows and the JAX env's
    parameters are laid out from them ([`table_fields`][heartpole.model.table_fields]).
    """

    effect_low: PerVariable
    effect_width: PerVariable
    rest_fade: PerVariable
    rest: Number
    drowsy: Number
    sleeps: Number


class StepTables(NamedTuple):
    """What a variant's variables and parameters mean to [`step`][heartpole.model.step], as numbers.

    Per variable ``v``: its lower bound ``floor[v]``, its share left after a half-hour ``fade[v]`` and
    its ``anxiety_relief[v]``. ``rest_offsets`` are 0, 1, ... up to the longest drowsy rest of the
    variant's actions (none for v0). Built by [`Dynamics`][heartpole.dynamics.Dynamics].

    Its fields are the one definition of these numbers, as [`ActionEffects`][heartpole.model.ActionEffects]'.
    A number the step needs from [`Params`][heartpole.parameters.Params] is a field here, set in
    `heartpole.dynamics.step_tables`: the backends lay it out from here.
    """

    floor: PerVariable
    fade: PerVariable
    anxiety_relief: PerVariable
    heart_attack_proclivity: Number
    heart_attack_penalty: Number
    wake_low: Number
    wake_width: Number
    rest_offsets: Shape


class TableFields(NamedTuple):
    """The fields of a table ([`ActionEffects`][heartpole.model.ActionEffects] or
    [`StepTables`][heartpole.model.StepTables]) by kind, each in definition order."""

    per_variable: tuple[str, ...]
    numbers: tuple[str, ...]
    shape: tuple[str, ...]


def table_fields(table: type[tuple[Any, ...]]) -> TableFields:
    """The fields of ``table`` by their annotation: ``PerVariable``, ``Number`` or ``Shape``.

    The backends build a table from its numbers in this order (``table(*per_variable, *numbers, *shape)``),
    so the fields must be declared in it; ``TypeError`` names a table declared otherwise.
    """
    hints = get_type_hints(table, include_extras=True)
    kinds = {PerVariable: "per_variable", Number: "numbers", Shape: "shape"}
    grouped: dict[str, list[str]] = {kind: [] for kind in kinds.values()}
    order = []
    for name in table._fields:  # type: ignore[attr-defined]
        kind = kinds.get(hints[name])
        if kind is None:
            raise TypeError(f"{table.__name__}.{name} must be annotated PerVariable, Number or Shape")
        grouped[kind].append(name)
        order.append(list(kinds.values()).index(kind))
    if order != sorted(order):
        raise TypeError(
            f"{table.__name__} must declare its PerVariable fields first, then its Number fields, then its Shape "
            f"fields; got {list(table._fields)}"  # type: ignore[attr-defined]
        )
    return TableFields(*(tuple(grouped[kind]) for kind in kinds.values()))


def step(
    state: State, effects: ActionEffects, uniforms: Sequence[Number], tables: StepTables
) -> tuple[State, Number, Number, Number, Any, Number]:
    """One decision and the half-hour of work after it: the tutorial's ``HeartPole.step`` for one person.

    Args:
        state: the state before the step.
        effects: what the chosen action does ([`ActionEffects`][heartpole.model.ActionEffects]).
        uniforms: ``len(state) + 2`` uniform draws in [0, 1): one per variable for the action's effect on
            it, one for waking up, one for the heart-attack coin.
        tables: the variant's variables and parameters ([`StepTables`][heartpole.model.StepTables]).

    Returns:
        ``(state, reward, productivity, heart_attack_risk, heart_attack, score)`` after the step.
    """
    old_score = score(state[WORK_DONE], state[TIME_ELAPSED])
    variables = range(len(state))

    # Facts 2 and 3 (and any variant's actions): each effect adds a uniform amount in [low, high].
    # No variable goes below its lower bound (exercise cannot push blood pressure under 0).
    for v in variables:
        if kept_by_the_step(v):
            continue
        changed = state[v] + effects.effect_low[v] + effects.effect_width[v] * uniforms[v]
        state = replace(state, v, where(changed < tables.floor[v], tables.floor[v], changed))

    # Rest and sleep: half-hours without work. Alertness drains in those spent awake (fact 6);
    # blood pressure and alcohol fade through all of them (fact 5).
    drain: Number = 0.0
    for offset in tables.rest_offsets:
        drain += where(offset < effects.drowsy, alertness_decay(state[TIME_SINCE_SLEPT] + offset), 0.0)
    state = replace(state, ALERTNESS, state[ALERTNESS] - drain)
    for v in variables:
        if not kept_by_the_step(v):
            state = replace(state, v, state[v] * effects.rest_fade[v])
    state = replace(state, TIME_SINCE_SLEPT, state[TIME_SINCE_SLEPT] + effects.rest)
    state = replace(state, TIME_ELAPSED, state[TIME_ELAPSED] + effects.rest)

    # Fact 1: after sleep you wake up quite alert, and the day starts afresh.
    sleeps = effects.sleeps > 0.5
    state = replace(state, ALERTNESS, where(sleeps, wake_alertness(uniforms[len(state)], tables), state[ALERTNESS]))
    state = replace(state, TIME_SINCE_SLEPT, where(sleeps, 0.0, state[TIME_SINCE_SLEPT]))

    # Facts 7 and 8: a half-hour of work.
    calm = 0.0
    for v in variables:
        if not kept_by_the_step(v):
            calm += tables.anxiety_relief[v] * state[v]
    worked = productivity(state[ALERTNESS], state[INTOXICATION], calm)
    state = replace(state, WORK_DONE, state[WORK_DONE] + worked)

    # Facts 5 and 6: the half-hour passes.
    state = replace(state, ALERTNESS, state[ALERTNESS] - alertness_decay(state[TIME_SINCE_SLEPT]))
    for v in variables:
        if not kept_by_the_step(v):
            state = replace(state, v, state[v] * tables.fade[v])
    state = replace(state, TIME_SINCE_SLEPT, state[TIME_SINCE_SLEPT] + 1.0)
    state = replace(state, TIME_ELAPSED, state[TIME_ELAPSED] + 1.0)

    # The reward: the change of the score, and -100 for a heart attack (fact 4), which, like purgatory,
    # is painful but cleansing: blood pressure back to 0.
    new_score = score(state[WORK_DONE], state[TIME_ELAPSED])
    risk = heart_attack_risk(state[HYPERTENSION], tables.heart_attack_proclivity)
    attack = uniforms[len(state) + 1] < risk
    state = replace(state, HYPERTENSION, where(attack, 0.0, state[HYPERTENSION]))
    reward = new_score - old_score - where(attack, tables.heart_attack_penalty, 0.0)
    return state, reward, worked, risk, attack, new_score


# ---------------------------------------------------------------------------------------------------------
# Running this module's code on another backend
BACKEND_BOUND = ("exp", "where", "replace")
"""The operations every backend binds its own way (NumPy's here)."""
STEP_ROOTS = ("step", "initial_state", "kept_by_the_step")
"""The functions a backend runs: the step, the start of an episode and which variables the step keeps."""
FUNCTIONS = called_by(STEP_ROOTS, globals(), BACKEND_BOUND)
"""The functions that make the step, callees first: found from [`step`][heartpole.model.step]'s own code."""


def rebind(
    bindings: dict[str, Any],
    constant: Callable[[Any], Any] = lambda value: value,
    wrap: Callable[[Callable[..., Any]], Any] = lambda function: function,
) -> types.SimpleNamespace:
    """[`FUNCTIONS`][heartpole.model.FUNCTIONS] with this module's very code objects, run against another
    backend.

    Args:
        bindings: replacements for ``exp``, ``where`` and ``replace`` (the backend's operations).
        constant: applied to every float literal of the code (numba: make it float32).
        wrap: applied to every function (numba: compile it).

    Returns:
        The functions by name; each calls the others' rebound versions.
    """
    return rebind_functions(globals(), FUNCTIONS, BACKEND_BOUND, bindings, constant, wrap)
