"""A HeartPole variant as the numbers its step reads: [`Dynamics`][heartpole.dynamics.Dynamics].

[`Dynamics`][heartpole.dynamics.Dynamics] turns a list of [`Action`][heartpole.actions.Action] s, the state
[`Variable`][heartpole.parameters.Variable] s and the [`Params`][heartpole.parameters.Params] into the
[`StepTables`][heartpole.model.StepTables] of [`step`][heartpole.model.step] (what each action does to each
variable, how each variable fades), and into the packed form [`heartpole.kernel`][heartpole.kernel] runs. It holds no
state of an episode and no formula: the envs hold the state, [`heartpole.model`][heartpole.model] the formulas.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from heartpole import kernel
from heartpole.actions import V0_ACTIONS, Action
from heartpole.model import ActionEffects, StepTables
from heartpole.parameters import BOOKKEEPING, V0_VARIABLES, Params, Variable


class Dynamics:
    """The tables of one HeartPole variant: its variables, its actions and its parameters.

    Args:
        actions: the action set, in action-index order (default: v0's four).
        params: the model's numbers (default: ``Params()``, the tutorial's).
        variables: the state variables in observation order; the first six must be v0's.

    Attributes:
        effects: each action's [`ActionEffects`][heartpole.model.ActionEffects], in action-index order.
        tables: the variables' and parameters' [`StepTables`][heartpole.model.StepTables].
        packed: the same as one float32 array, as [`step_envs`][heartpole.kernel.step_envs] takes them.
        spec: what the compiled loop is specialised on ([`LoopSpec`][heartpole.kernel.LoopSpec]): the variant's
            shape and which numbers of the action rows differ between actions.

    Raises:
        ValueError: a definition that is not an Action or Variable; no action; duplicate names; variables that
            do not start with v0's six; an effect on a variable the variant lacks, that the step keeps itself
            or that has a finite high bound (the step does not cap variables). Each Action, Variable and
            Params checks its own fields when it is made; these are the rules of a variant as a whole.
    """

    def __init__(
        self,
        actions: Sequence[Action] = V0_ACTIONS,
        params: Params | None = None,
        variables: Sequence[Variable] = V0_VARIABLES,
    ) -> None:
        self.actions = _sequence("actions", actions, Action)
        self.params = Params() if params is None else params
        self.variables = _sequence("variables", variables, Variable)
        _check_definitions(self.actions, self.variables)
        self.names = tuple(v.name for v in self.variables)
        with np.errstate(over="ignore"):  # a number beyond float32 is refused just below, with its name
            self.effects, self.tables = step_tables(self.actions, self.variables, self.params)
        _check_float32(self.effects, self.tables)
        self.packed = kernel.pack(self.effects, self.tables)
        # the numbers that differ between actions with these parameters or the defaults: loops shared by parameters
        defaults = []
        if self.params != Params():
            defaults.append(kernel.pack(*step_tables(self.actions, self.variables, Params())))
        selected = kernel.selection(self.packed, len(self.actions), *defaults)
        shape = (len(self.variables), len(self.tables.rest_offsets), len(self.actions))
        self.spec = kernel.LoopSpec(*shape, selected)

    def action_index(self, name: str) -> int:
        """The index of the action called ``name``."""
        for i, action in enumerate(self.actions):
            if action.name == name:
                return i
        raise ValueError(f"unknown action {name!r}; this variant has {[a.name for a in self.actions]}")


def step_tables(
    actions: Sequence[Action], variables: Sequence[Variable], params: Params, number: type = np.float32
) -> tuple[tuple[ActionEffects, ...], StepTables]:
    """Each action's [`ActionEffects`][heartpole.model.ActionEffects] and the variant's
    [`StepTables`][heartpole.model.StepTables], every number of type ``number`` (the envs' float32, or ``float``
    to run [`step`][heartpole.model.step] in float64)."""
    f32 = number
    names = [v.name for v in variables]
    fade = [_fade(v, params) for v in variables]
    effects = []
    for action in actions:
        low, high = [0.0] * len(names), [0.0] * len(names)
        for name, (lo, hi) in action.effects.items():
            low[names.index(name)], high[names.index(name)] = lo, hi
        rest = action.rest_half_hours + (params.sleep_half_hours if action.sleeps else 0)
        effects.append(
            ActionEffects(
                effect_low=tuple(f32(x) for x in low),
                effect_width=tuple(f32(h - lo) for lo, h in zip(low, high)),
                rest_fade=tuple(f32(f**rest) for f in fade),
                rest=f32(rest),
                drowsy=f32(0 if action.sleeps else action.rest_half_hours),  # sleep ends in waking up fresh
                sleeps=f32(action.sleeps),
            )
        )
    longest_drowsy = max(int(e.drowsy) for e in effects)
    wake_low, wake_high = params.wake_alertness
    tables = StepTables(
        floor=tuple(f32(v.low) for v in variables),
        fade=tuple(f32(f) for f in fade),
        anxiety_relief=tuple(f32(v.anxiety_relief) for v in variables),
        rest_offsets=tuple(f32(k) for k in range(longest_drowsy)),
        heart_attack_proclivity=f32(params.heart_attack_proclivity),
        heart_attack_penalty=f32(params.heart_attack_penalty),
        wake_low=f32(wake_low),
        wake_width=f32(wake_high - wake_low),
    )
    return tuple(effects), tables


def _check_float32(effects: Sequence[ActionEffects], tables: StepTables) -> None:
    """Refuse numbers that float32, the step's arithmetic, cannot hold (a variable's floor may be -inf)."""
    named = [(f"action {i}'s {key}", value) for i, e in enumerate(effects) for key, value in e._asdict().items()]
    named += [(key, value) for key, value in tables._asdict().items() if key != "floor"]
    for name, value in named:
        if not np.all(np.isfinite(np.asarray(value, dtype=np.float32))):
            raise ValueError(
                f"{name} is {value!r} in float32, the step's arithmetic: effects, their widths (high - low) and "
                "parameters must be finite numbers below 3.4e38 in size"
            )


def _fade(variable: Variable, params: Params) -> float:
    factor = variable.decay_factor(params)
    # not float(factor): heartpole.jax and heartpole.person_tables run step_tables on arrays of people's decay rates
    return 1.0 if factor is None else factor


def _sequence(name: str, value: object, kind: type) -> tuple[Any, ...]:
    """``value`` as a tuple; ``TypeError`` naming ``name`` when it is not a sequence (a number, a string)."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Iterable):
        raise TypeError(
            f"{name} must be a sequence of heartpole.{kind.__name__} objects, got {type(value).__name__} {value!r}"
        )
    return tuple(value)


def _check_definitions(actions: tuple[Action, ...], variables: tuple[Variable, ...]) -> None:
    """The rules of a variant as a whole (each action, variable and parameter checks itself when made)."""
    if not actions:
        raise ValueError("a HeartPole variant needs at least one action")
    for kind, definitions in ((Action, actions), (Variable, variables)):
        for definition in definitions:
            if not isinstance(definition, kind):
                raise ValueError(f"expected heartpole.{kind.__name__} objects, got {definition!r}")
    _check_unique("action", [a.name for a in actions])
    if variables[: len(V0_VARIABLES)] != V0_VARIABLES:
        raise ValueError(
            f"the first six variables must be v0's exactly, {[v.name for v in V0_VARIABLES]} "
            f"(heartpole.V0_VARIABLES), since the step itself reads and writes them; got "
            f"{[v.name for v in variables[: len(V0_VARIABLES)]]}. Add yours after them: "
            "variables=(*heartpole.V0_VARIABLES, my_variable)"
        )
    _check_unique("variable", [v.name for v in variables])
    by_name = {v.name: v for v in variables}
    for action in actions:
        for name, (_, high) in action.effects.items():
            if name in BOOKKEEPING:
                raise ValueError(
                    f"action {action.name!r} may not change {name!r}, which the step keeps itself; actions may "
                    f"change {[v for v in by_name if v not in BOOKKEEPING]}"
                )
            if name not in by_name:
                raise ValueError(
                    f"action {action.name!r} changes {name!r}, which is not a state variable of this variant "
                    f"({list(by_name)}); add it, e.g. variables=(*heartpole.V0_VARIABLES, "
                    f"heartpole.Variable({name!r}, 0.0, decay=0.9))"
                )
            if high > 0 and math.isfinite(by_name[name].high):
                raise ValueError(
                    f"action {action.name!r} raises {name!r}, whose high bound is {by_name[name].high}: the step "
                    "keeps variables above their low bound but does not cap them, so use high=math.inf"
                )


def _check_unique(kind: str, names: list[str]) -> None:
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise ValueError(f"{kind} names must be unique; {duplicates} appear more than once in {names}")
