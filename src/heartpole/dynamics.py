"""One step of HeartPole, written once for a single state and for a batch of states.

:class:`Dynamics` compiles a list of :class:`~heartpole.actions.Action` s, the :class:`~heartpole.model.Params`
and the state :class:`~heartpole.model.Variable` s into per-action lookup columns, then
:meth:`Dynamics.transition` applies the tutorial's step to a state in place:

1. the action's effects (facts 2 and 3), each a uniform draw added to a state variable;
2. rest and sleep: half-hours without work (fact 5 fading, fact 6 decay) and waking up (fact 1);
3. a half-hour of work (facts 7 and 8), after which the half-hour passes (facts 5 and 6);
4. the reward, the change of the score ``work_done / time_elapsed``;
5. the heart-attack coin (fact 4): -100 and hypertension back to 0.

A *single* state is a list of Python floats, the action an ``int`` and the uniforms a list of floats; a
*batch* is a ``(num_variables, num_envs)`` float32 array, an integer array of actions and a
``(num_uniforms, num_envs)`` array of uniforms. The same code runs on both: the formulas of
:mod:`heartpole.model` accept floats and arrays, and the per-action columns come from a tuple of floats
(single) or a float32 table gathered by action (batch).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from heartpole.actions import V0_ACTIONS, Action
from heartpole.model import (
    ALERTNESS,
    HYPERTENSION,
    INTOXICATION,
    TIME_ELAPSED,
    TIME_SINCE_SLEPT,
    V0_VARIABLES,
    WORK_DONE,
    Params,
    Variable,
    alertness_decay,
    heart_attack_risk,
    productivity,
    score,
)


class ActionRecord(NamedTuple):
    """What one action (Python scalars) or a batch of actions (arrays, one value per env) does in a step.

    ``effects`` lists ``(variable, low, width, uniform_column)``: the variable gains ``low + width * u``.
    ``any_rest`` and ``any_wake`` let a step skip what no action of the batch needs. ``wakes`` and
    ``stays_awake`` are 1.0 or 0.0 (one is the other's complement) so that waking up is arithmetic.
    """

    effects: tuple[tuple[int, Any, Any, int], ...]
    any_rest: bool
    rest: Any
    any_wake: bool
    wakes: Any
    stays_awake: Any
    drowsy_rest: Any
    fades: Any


# time_since_slept counts whole half-hours, so the single env reads fact 6's decay from the formula's own
# values; from about 415 on, the float64 sigmoid is exactly 1.0.
DECAY_TABLE_SIZE = 1024
DECAY_TABLE: tuple[float, ...] = tuple(alertness_decay(float(t)) for t in range(DECAY_TABLE_SIZE))

# Variables the step keeps itself; an action may not write to them.
BOOKKEEPING = ("time_since_slept", "time_elapsed", "work_done")


class Dynamics:
    """The compiled model of one HeartPole variant: its variables, its actions and its parameters.

    Args:
        actions: the action set, in action-index order (default: v0's four).
        params: the model's numbers (default: ``Params()``, the tutorial's).
        variables: the state variables in observation order; the first six must be v0's.

    Raises:
        ValueError: on an empty or duplicated action set, or an effect on an unknown or bookkeeping variable.
    """

    def __init__(
        self,
        actions: Sequence[Action] = V0_ACTIONS,
        params: Params | None = None,
        variables: Sequence[Variable] = V0_VARIABLES,
    ) -> None:
        self.actions = tuple(actions)
        self.params = Params() if params is None else params
        self.variables = tuple(variables)
        self.names = tuple(v.name for v in self.variables)
        _check_definitions(self.actions, self.variables)
        self._compile()

    # ----------------------------------------------------------------------------------------------------
    # compilation: what each action does, as a record for one action or a table for a batch
    def _compile(self) -> None:
        index = {name: i for i, name in enumerate(self.names)}
        self.random_variables: tuple[int, ...] = tuple(
            sorted({index[name] for action in self.actions for name in action.effects})
        )
        self._assign_uniform_columns()
        self.fading = tuple(
            (i, factor) for i, v in enumerate(self.variables) if (factor := v.decay_factor(self.params)) is not None
        )
        self.floored = tuple(
            (i, self.variables[i].low)
            for i in self.random_variables
            if math.isfinite(self.variables[i].low)
            and any(a.effects.get(self.names[i], (0.0, 0.0))[0] < 0 for a in self.actions)
        )
        self.max_drowsy_rest = max(action.rest_half_hours for action in self.actions)
        self.calming = tuple((i, float(v.anxiety_relief)) for i, v in enumerate(self.variables) if v.anxiety_relief)
        wake_low, wake_high = self.params.wake_alertness
        self._wake_low, self._wake_width = wake_low, wake_high - wake_low
        self._penalty = self.params.heart_attack_penalty
        self._records = tuple(ActionRecord(*self._fields_of(action)) for action in self.actions)
        self._table = _BatchTable([self._fields_of(action) for action in self.actions])

    def _assign_uniform_columns(self) -> None:
        """One uniform column per randomly changed variable, shared by variables no action changes together.

        Waking up (fact 1) shares a column with variables no sleeping action changes; the heart-attack coin
        (fact 4) has its own. v0 needs four columns: alertness (and waking), hypertension, intoxication, coin.
        """
        waking = -1  # stands for the wake-up draw of a sleeping action
        together = [
            {self.names.index(name) for name in a.effects} | ({waking} if a.sleeps else set()) for a in self.actions
        ]
        column: dict[int, int] = {}
        for variable in (*self.random_variables, waking):
            taken = {column[other] for used in together if variable in used for other in used if other in column}
            column[variable] = next(c for c in range(len(column) + 1) if c not in taken)
        self.uniform_column = {i: column[i] for i in self.random_variables}
        self.wake_uniform = column[waking]
        self.attack_uniform = max(column.values()) + 1
        self.num_uniforms = self.attack_uniform + 1

    def _fields_of(self, action: Action) -> tuple[Any, ...]:
        """The :class:`ActionRecord` of ``action`` for a single state: only the effects it has, as floats."""
        effects = tuple(
            (i, low, high - low, self.uniform_column[i])
            for i in self.random_variables
            for low, high in [action.effects.get(self.names[i], (0.0, 0.0))]
            if (low, high) != (0.0, 0.0)
        )
        rest = action.rest_half_hours + (self.params.sleep_half_hours if action.sleeps else 0)
        drowsy = 0 if action.sleeps else action.rest_half_hours  # no drain if it wakes up fresh after
        fades = tuple(factor**rest for _, factor in self.fading)
        wakes = float(action.sleeps)
        return effects, rest > 0, float(rest), action.sleeps, wakes, 1.0 - wakes, float(drowsy), fades

    def record(self, action: Any) -> ActionRecord:
        """What ``action`` does: precomputed for one action index, looked up per env for an index array."""
        if type(action) is int:
            return self._records[action]
        return self._table.lookup(action)

    # ----------------------------------------------------------------------------------------------------
    # states
    def wake_alertness(self, uniform: Any) -> Any:
        """Fact 1: alertness on waking up, from a uniform draw in [0, 1)."""
        alertness = self._wake_width * uniform
        alertness += self._wake_low
        return alertness

    def initial_state(self, wake_uniform: Any) -> Any:
        """Fact 0 then fact 1: all variables 0, then waking up. A float gives a list, an array a batch."""
        if isinstance(wake_uniform, float):
            state: Any = [0.0] * len(self.variables)
        else:
            state = np.zeros((len(self.variables), len(wake_uniform)), dtype=np.float32)
        state[ALERTNESS] = self.wake_alertness(wake_uniform)
        return state

    # ----------------------------------------------------------------------------------------------------
    # the step
    def transition(self, state: Any, action: Any, uniforms: Any) -> tuple[Any, Any, Any, Any, Any]:
        """Advance ``state`` in place by one decision and its half-hour of work.

        Args:
            state: a list of floats (one state), or a ``(num_variables, num_envs)`` float32 array (a batch).
            action: a valid action index (``int``), or an integer array of them (validated by the caller).
            uniforms: ``num_uniforms`` uniform draws in [0, 1), or a ``(num_uniforms, num_envs)`` array.

        Returns:
            ``(reward, productivity, heart_attack_risk, heart_attack, score)``, floats or arrays.
        """
        if type(state) is list:
            return self.transition_one(state, action, uniforms)
        return self.transition_batch(state, action, uniforms)

    def transition_one(
        self, s: list[float], action: int, u: Sequence[float]
    ) -> tuple[float, float, float, bool, float]:
        """:meth:`transition` for one state: Python floats, branches instead of masks (the single env's path)."""
        act = self.record(action)
        old_score = score(s[WORK_DONE], s[TIME_ELAPSED])
        for i, low, width, k in act.effects:  # facts 2 and 3
            s[i] += low + width * u[k]
        for i, low in self.floored:
            if s[i] < low:
                s[i] = low
        if act.any_rest:
            self._rest(s, act)
            if act.any_wake:  # fact 1: fresh alertness and a new day
                s[ALERTNESS] = self.wake_alertness(u[self.wake_uniform])
                s[TIME_SINCE_SLEPT] = 0.0
        alertness, time_since_slept = s[ALERTNESS], s[TIME_SINCE_SLEPT]
        worked = productivity(alertness, s[INTOXICATION], self._calm(s) if self.calming else None)  # facts 7, 8
        s[WORK_DONE] += worked
        s[ALERTNESS] = alertness - self._alertness_decay(time_since_slept)  # the half-hour passes: facts 5, 6
        for i, factor in self.fading:
            s[i] *= factor
        s[TIME_SINCE_SLEPT] = time_since_slept + 1.0
        s[TIME_ELAPSED] += 1.0
        new_score = score(s[WORK_DONE], s[TIME_ELAPSED])
        risk = heart_attack_risk(s[HYPERTENSION], self.params.heart_attack_proclivity)  # fact 4
        if u[self.attack_uniform] < risk:
            s[HYPERTENSION] = 0.0  # a heart attack resets blood pressure to 0
            return new_score - old_score - self._penalty, worked, risk, True, new_score
        return new_score - old_score, worked, risk, False, new_score

    def transition_batch(
        self, state: np.ndarray | Sequence[np.ndarray], action: np.ndarray, u: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`transition` for a batch: float32 rows updated in place, masks instead of branches."""
        s = list(state)  # the rows: every update below is an augmented assignment, in place
        act = self.record(action)
        old_score = score(s[WORK_DONE], s[TIME_ELAPSED])
        for i, low, width, k in act.effects:  # facts 2 and 3
            width *= u[k]  # this step's own looked-up row
            width += low
            s[i] += width
        for i, low in self.floored:
            np.maximum(s[i], low, out=s[i])
        if act.any_rest:
            self._rest(s, act)
        if act.any_wake:  # fact 1: fresh alertness and a new day, where the action sleeps
            woken = self.wake_alertness(u[self.wake_uniform])
            woken *= act.wakes
            s[ALERTNESS] *= act.stays_awake
            s[ALERTNESS] += woken
            s[TIME_SINCE_SLEPT] *= act.stays_awake
        worked = productivity(s[ALERTNESS], s[INTOXICATION], self._calm(s) if self.calming else None)  # facts 7, 8
        s[WORK_DONE] += worked
        s[ALERTNESS] -= alertness_decay(s[TIME_SINCE_SLEPT])  # the half-hour passes: facts 5 and 6
        for i, factor in self.fading:
            s[i] *= factor
        s[TIME_SINCE_SLEPT] += 1.0
        s[TIME_ELAPSED] += 1.0
        new_score = score(s[WORK_DONE], s[TIME_ELAPSED])
        risk = heart_attack_risk(s[HYPERTENSION], self.params.heart_attack_proclivity)  # fact 4
        coin = u[self.attack_uniform]
        attack = coin < risk
        s[HYPERTENSION] *= coin >= risk  # a heart attack resets blood pressure to 0
        reward = new_score - old_score
        np.subtract(reward, self._penalty, out=reward, where=attack)
        return reward, worked, risk, attack, new_score

    def _alertness_decay(self, time_since_slept: Any) -> Any:
        """Fact 6's decay; for one state, looked up in a table of the formula's values at whole half-hours."""
        if type(time_since_slept) is float and time_since_slept < DECAY_TABLE_SIZE:
            return DECAY_TABLE[int(time_since_slept)]
        return alertness_decay(time_since_slept)

    def _calm(self, s: Any) -> Any:
        """Anxiety relief from the variables that bring it (v1's THC): ``sum(anxiety_relief * value)``."""
        calm: Any = 0.0
        for i, relief in self.calming:
            calm = calm + relief * s[i]
        return calm

    def _rest(self, s: Any, act: ActionRecord) -> None:
        """Half-hours without work (sleep, naps): alertness decays unless waking follows; fading goes on."""
        for k in range(self.max_drowsy_rest):
            drain = self._alertness_decay(s[TIME_SINCE_SLEPT] + k)
            drain *= k < act.drowsy_rest
            s[ALERTNESS] -= drain
        for (i, _), factor in zip(self.fading, act.fades):
            s[i] *= factor
        s[TIME_SINCE_SLEPT] += act.rest
        s[TIME_ELAPSED] += act.rest

    # ----------------------------------------------------------------------------------------------------
    def action_index(self, name: str) -> int:
        """The index of the action called ``name``."""
        for i, action in enumerate(self.actions):
            if action.name == name:
                return i
        raise ValueError(f"unknown action {name!r}; this variant has {[a.name for a in self.actions]}")


class _BatchTable:
    """The actions' :class:`ActionRecord` fields as one float32 table, looked up for a batch in one product.

    Fields equal for every action stay Python floats. The others are rows of a ``(rows, num_actions)``
    table; a batch's values are ``table @ one_hot(actions)``: one matrix product for all of them, which
    costs less than a gather per row. The product is written into buffers kept from step to step (fresh
    arrays this large cost page faults on every step); the step may overwrite them.
    """

    def __init__(self, fields: list[tuple[Any, ...]]) -> None:
        first = fields[0]
        self._effect_keys = sorted({(i, k) for f in fields for i, _, _, k in f[0]})
        columns = [self._flatten(f) for f in fields]
        self._constant = [len(set(values)) == 1 for values in zip(*columns)]
        varying = [values for values, constant in zip(zip(*columns), self._constant) if not constant]
        self._table = np.array(varying, dtype=np.float32).reshape(len(varying), len(fields))
        self._first = self._flatten(first)
        self._num_fades = len(first[7])
        self._action_column = np.arange(len(fields))[:, None]
        self._resting = [a for a, f in enumerate(fields) if f[1]]
        self._waking = [a for a, f in enumerate(fields) if f[3]]
        self._buffers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _flatten(self, f: tuple[Any, ...]) -> list[float]:
        effects = {(i, k): (low, width) for i, low, width, k in f[0]}
        values: list[float] = []
        for key in self._effect_keys:
            values += effects.get(key, (0.0, 0.0))
        return values + [f[2], f[4], f[5], f[6], *f[7]]

    def lookup(self, action: np.ndarray) -> ActionRecord:
        """The record of a batch of (valid) actions: a float or a float32 row of ``len(action)`` per field."""
        is_action, one_hot, rows = self._buffers_for(len(action))
        np.equal(self._action_column, action, out=is_action)
        present = is_action.any(axis=1).tolist()
        if len(rows):
            np.copyto(one_hot, is_action)
            np.matmul(self._table, one_hot, out=rows)
        remaining = iter(rows)
        values = [first if constant else next(remaining) for first, constant in zip(self._first, self._constant)]
        effects = tuple((i, values[2 * j], values[2 * j + 1], k) for j, (i, k) in enumerate(self._effect_keys))
        rest, wakes, stays_awake, drowsy = values[2 * len(self._effect_keys) : 2 * len(self._effect_keys) + 4]
        fades = values[len(values) - self._num_fades :]
        any_rest = any(present[a] for a in self._resting)
        any_wake = any(present[a] for a in self._waking)
        return ActionRecord(effects, any_rest, rest, any_wake, wakes, stays_awake, drowsy, fades)

    def _buffers_for(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._buffers is None or self._buffers[0].shape[1] != n:
            m = len(self._action_column)
            self._buffers = (
                np.empty((m, n), dtype=bool),
                np.empty((m, n), dtype=np.float32),
                np.empty((len(self._table), n), dtype=np.float32),
            )
        return self._buffers


def _check_definitions(actions: tuple[Action, ...], variables: tuple[Variable, ...]) -> None:
    if not actions:
        raise ValueError("a HeartPole variant needs at least one action")
    for a in actions:
        if not isinstance(a, Action):
            raise ValueError(f"actions must be heartpole.Action objects, got {a!r}")
    names = [a.name for a in actions]
    if len(set(names)) != len(names):
        raise ValueError(f"action names must be unique, got {names}")
    var_names = [v.name for v in variables]
    if tuple(var_names[:6]) != tuple(v.name for v in V0_VARIABLES):
        raise ValueError(f"the first six variables must be v0's {[v.name for v in V0_VARIABLES]}, got {var_names[:6]}")
    if len(set(var_names)) != len(var_names):
        raise ValueError(f"variable names must be unique, got {var_names}")
    for a in actions:
        for name in a.effects:
            if name not in var_names:
                raise ValueError(f"action {a.name!r} changes unknown variable {name!r}; variables are {var_names}")
            if name in BOOKKEEPING:
                raise ValueError(f"action {a.name!r} may not change {name!r}, which the step keeps itself")
