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
    assign_where,
    heart_attack_risk,
    productivity,
    score,
)


class ActionRecord(NamedTuple):
    """What one action (Python scalars) or a batch of actions (arrays) does in a step.

    ``effects`` lists ``(variable, low, width, uniform_column)``: the variable gains ``low + width * u``.
    ``any_rest`` and ``any_wake`` let a step skip what no action of the batch needs.
    """

    effects: tuple[tuple[int, Any, Any, int], ...]
    any_rest: bool
    rest: Any
    wakes: Any
    any_wake: bool
    drowsy_rest: Any
    fades: Any


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
        affected = sorted({index[name] for action in self.actions for name in action.effects})
        self.random_variables: tuple[int, ...] = tuple(affected)
        self.wake_uniform = len(affected)
        self.attack_uniform = len(affected) + 1
        self.num_uniforms = len(affected) + 2
        self.fading = tuple(
            (i, factor) for i, v in enumerate(self.variables) if (factor := v.decay_factor(self.params)) is not None
        )
        self.floored = tuple(
            (i, self.variables[i].low)
            for i in affected
            if math.isfinite(self.variables[i].low)
            and any(a.effects.get(self.names[i], (0.0, 0.0))[0] < 0 for a in self.actions)
        )
        self.max_drowsy_rest = max(action.rest_half_hours for action in self.actions)
        self.calming = tuple((i, float(v.anxiety_relief)) for i, v in enumerate(self.variables) if v.anxiety_relief)
        wake_low, wake_high = self.params.wake_alertness
        self._wake_low, self._wake_width = wake_low, wake_high - wake_low
        self._records = tuple(self._record_of(action) for action in self.actions)
        self._columns = _BatchColumns(np.array([self._row_of(action) for action in self.actions]).T)

    def _record_of(self, action: Action) -> ActionRecord:
        """The single-state record of ``action``: only the effects it has, rest and sleep as Python scalars."""
        effects = tuple(
            (i, low, high - low, k)
            for k, i in enumerate(self.random_variables)
            for low, high in [action.effects.get(self.names[i], (0.0, 0.0))]
            if (low, high) != (0.0, 0.0)
        )
        rest, drowsy = self._rest_of(action)
        fades = tuple(factor**rest for _, factor in self.fading)
        return ActionRecord(effects, rest > 0, float(rest), action.sleeps, action.sleeps, float(drowsy), fades)

    def _row_of(self, action: Action) -> list[float]:
        """The batch-table column of ``action``: effect (low, width) per random variable, rest, wake, fades."""
        row: list[float] = []
        for i in self.random_variables:
            low, high = action.effects.get(self.names[i], (0.0, 0.0))
            row += [low, high - low]
        rest, drowsy = self._rest_of(action)
        return row + [rest, float(action.sleeps), drowsy] + [factor**rest for _, factor in self.fading]

    def _rest_of(self, action: Action) -> tuple[int, int]:
        """Half-hours without work, and those of them in which alertness decays (none if it then wakes)."""
        rest = action.rest_half_hours + (self.params.sleep_half_hours if action.sleeps else 0)
        return rest, 0 if action.sleeps else action.rest_half_hours

    def record(self, action: Any) -> ActionRecord:
        """What ``action`` does: precomputed for one action index, gathered from the table for an array."""
        if type(action) is int:
            return self._records[action]
        columns = self._columns.gather(action)
        effects = tuple((i, columns[2 * k], columns[2 * k + 1], k) for k, i in enumerate(self.random_variables))
        r = 2 * len(self.random_variables)
        rest, wakes = columns[r], np.not_equal(columns[r + 1], 0)
        any_rest, any_wake = bool(np.any(rest)), bool(np.any(wakes))
        return ActionRecord(effects, any_rest, rest, wakes, any_wake, columns[r + 2], columns[r + 3 :])

    # ----------------------------------------------------------------------------------------------------
    # states
    def wake_alertness(self, uniform: Any) -> Any:
        """Fact 1: alertness on waking up, from a uniform draw in [0, 1)."""
        return self._wake_low + self._wake_width * uniform

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
            state: a list of floats, or a ``(num_variables, num_envs)`` float32 array.
            action: a valid action index (``int``), or an integer array of them (validated by the caller).
            uniforms: ``num_uniforms`` uniform draws in [0, 1), or a ``(num_uniforms, num_envs)`` array.

        Returns:
            ``(reward, productivity, heart_attack_risk, heart_attack, score)``, floats or arrays.
        """
        s, u, act = state, uniforms, self.record(action)
        old_score = score(s[WORK_DONE], s[TIME_ELAPSED])
        for i, low, width, k in act.effects:  # facts 2 and 3
            s[i] += low + width * u[k]
        for i, low in self.floored:
            assign_where(s, i, s[i] < low, low)
        if act.any_rest:
            self._rest(s, act)
        if act.any_wake:  # fact 1
            assign_where(s, ALERTNESS, act.wakes, self.wake_alertness(u[self.wake_uniform]))
            assign_where(s, TIME_SINCE_SLEPT, act.wakes, 0.0)
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
        reward = new_score - old_score - self.params.heart_attack_penalty * attack
        return reward, worked, risk, attack, new_score

    def _calm(self, s: Any) -> Any:
        """Anxiety relief from the variables that bring it (v1's THC): ``sum(anxiety_relief * value)``."""
        calm: Any = 0.0
        for i, relief in self.calming:
            calm = calm + relief * s[i]
        return calm

    def _rest(self, s: Any, act: ActionRecord) -> None:
        """Half-hours without work (sleep, naps): alertness decays unless waking follows; fading goes on."""
        for k in range(self.max_drowsy_rest):
            s[ALERTNESS] -= (k < act.drowsy_rest) * alertness_decay(s[TIME_SINCE_SLEPT] + k)
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


class _BatchColumns:
    """The per-action table for batches, gathering only the rows that differ between actions.

    A gather costs about a nanosecond per env and row, so rows equal for every action stay Python
    floats, and rows equal to each other are gathered once.
    """

    def __init__(self, table: np.ndarray) -> None:
        self._constants: dict[int, float] = {}
        self._unique: list[np.ndarray] = []
        self._source: dict[int, int] = {}
        for r, row in enumerate(table):
            if np.all(row == row[0]):
                self._constants[r] = float(row[0])
                continue
            for j, seen in enumerate(self._unique):
                if np.array_equal(seen, row.astype(np.float32)):
                    self._source[r] = j
                    break
            else:
                self._source[r] = len(self._unique)
                self._unique.append(row.astype(np.float32))
        self._rows = len(table)

    def gather(self, action: np.ndarray) -> list[Any]:
        """Row ``r`` of the result: a float, or the row's value for each env's action."""
        gathered = [row.take(action) for row in self._unique]
        return [self._constants[r] if r in self._constants else gathered[self._source[r]] for r in range(self._rows)]


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
