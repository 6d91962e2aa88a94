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
from typing import Any, Sequence

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
    select,
)

# Variables the step keeps itself; an action may not write to them.
BOOKKEEPING = ("time_since_slept", "time_elapsed", "work_done")


class Dynamics:
    """The compiled model of one HeartPole variant: its variables, its actions and its parameters.

    Args:
        actions: the action set, in action-index order (default: v0's four).
        params: the model's numbers (default: the tutorial's).
        variables: the state variables in observation order; the first six must be v0's.

    Raises:
        ValueError: on an empty or duplicated action set, or an effect on an unknown or bookkeeping variable.
    """

    def __init__(
        self,
        actions: Sequence[Action] = V0_ACTIONS,
        params: Params = Params(),
        variables: Sequence[Variable] = V0_VARIABLES,
    ) -> None:
        self.actions = tuple(actions)
        self.params = params
        self.variables = tuple(variables)
        self.names = tuple(v.name for v in self.variables)
        _check_definitions(self.actions, self.variables)
        self._compile()

    # ----------------------------------------------------------------------------------------------------
    # compilation: per-action columns
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
        rows = [self._columns_of(action) for action in self.actions]
        self._single_columns = tuple(rows)
        self._batch_table = np.array(rows, dtype=np.float32).T.copy()  # (columns, actions)
        self.max_drowsy_rest = max(action.rest_half_hours for action in self.actions)
        wake_low, wake_high = self.params.wake_alertness
        self._wake_low, self._wake_width = wake_low, wake_high - wake_low

    def _columns_of(self, action: Action) -> tuple[Any, ...]:
        """The action's columns: effect (low, width) per random variable, rest, wake, drowsy rest, fades."""
        columns: list[Any] = []
        for i in self.random_variables:
            low, high = action.effects.get(self.names[i], (0.0, 0.0))
            columns += [low, high - low]
        rest = action.rest_half_hours + (self.params.sleep_half_hours if action.sleeps else 0)
        drowsy = 0 if action.sleeps else action.rest_half_hours  # alertness is reset on waking anyway
        columns += [float(rest), action.sleeps, float(drowsy)]
        columns += [factor**rest for _, factor in self.fading]
        return tuple(columns)

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

    def columns(self, action: Any) -> Any:
        """The per-action columns for one action index (a tuple) or a batch of them (a 2-D array)."""
        if isinstance(action, int):
            return self._single_columns[action]
        return self._batch_table.take(action, axis=1)

    # ----------------------------------------------------------------------------------------------------
    # the step
    def transition(self, state: Any, action: Any, uniforms: Any) -> tuple[Any, Any, Any, Any, Any]:
        """Advance ``state`` in place by one decision and its half-hour of work.

        Args:
            state: a list of floats, or a ``(num_variables, num_envs)`` float32 array.
            action: a valid action index, or an integer array of them (validated by the caller).
            uniforms: ``num_uniforms`` uniform draws in [0, 1), or a ``(num_uniforms, num_envs)`` array.

        Returns:
            ``(reward, productivity, heart_attack_risk, heart_attack, score)``, floats or arrays.
        """
        s, u, c = state, uniforms, self.columns(action)
        old_score = score(s[WORK_DONE], s[TIME_ELAPSED])
        self._apply_effects(s, u, c)
        self._rest(s, u, c)
        worked = productivity(s[ALERTNESS], s[INTOXICATION])
        s[WORK_DONE] += worked
        self._half_hour_passes(s)
        new_score = score(s[WORK_DONE], s[TIME_ELAPSED])
        risk = heart_attack_risk(s[HYPERTENSION], self.params.heart_attack_proclivity)
        attack = u[self.attack_uniform] < risk
        s[HYPERTENSION] *= u[self.attack_uniform] >= risk  # the attack resets blood pressure to 0
        reward = new_score - old_score - self.params.heart_attack_penalty * attack
        return reward, worked, risk, attack, new_score

    def _apply_effects(self, s: Any, u: Any, c: Any) -> None:
        for k, i in enumerate(self.random_variables):
            s[i] += c[2 * k] + c[2 * k + 1] * u[k]
        for i, low in self.floored:
            s[i] = select(s[i] < low, low, s[i])

    def _rest(self, s: Any, u: Any, c: Any) -> None:
        rest_column = 2 * len(self.random_variables)
        rest, wakes, drowsy = c[rest_column], c[rest_column + 1], c[rest_column + 2]
        for k in range(self.max_drowsy_rest):
            s[ALERTNESS] -= (k < drowsy) * alertness_decay(s[TIME_SINCE_SLEPT] + k)
        for j, (i, _) in enumerate(self.fading):
            s[i] *= c[rest_column + 3 + j]
        s[TIME_SINCE_SLEPT] += rest
        s[TIME_ELAPSED] += rest
        if not isinstance(wakes, bool):  # a batch: the wake column is 0.0 / 1.0
            wakes = wakes != 0
        s[ALERTNESS] = select(wakes, self.wake_alertness(u[self.wake_uniform]), s[ALERTNESS])
        s[TIME_SINCE_SLEPT] = select(wakes, 0.0, s[TIME_SINCE_SLEPT])

    def _half_hour_passes(self, s: Any) -> None:
        s[ALERTNESS] -= alertness_decay(s[TIME_SINCE_SLEPT])
        for i, factor in self.fading:
            s[i] *= factor
        s[TIME_SINCE_SLEPT] += 1.0
        s[TIME_ELAPSED] += 1.0

    # ----------------------------------------------------------------------------------------------------
    def action_index(self, name: str) -> int:
        """The index of the action called ``name``."""
        for i, action in enumerate(self.actions):
            if action.name == name:
                return i
        raise ValueError(f"unknown action {name!r}; this variant has {[a.name for a in self.actions]}")


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
