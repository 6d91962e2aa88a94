"""What the optimum's solvers share: the refusal, the solver's version and grid, the day's cut, settling."""

from __future__ import annotations

from dataclasses import MISSING, asdict, fields
from typing import Any

import numpy as np

from heartpole.model import alertness_decay, productivity
from heartpole.parameters import Params

SOLVER_VERSION = 5
"""Bumped whenever a saved solution would mean something else; caches of other versions are solved again
(3: the thresholds end where the policy has settled, not at ``max_steps``; 4: the history's worth is solved;
5: the solution plays the history-aware optimum and stores its tables)."""
DEFAULT_GRID = 400
SETTLE_TOLERANCE = 1e-13
"""A backward recursion has settled when its values, less their value at one state, change by at most this
much (relative to their size, plus this much absolute) per decision; see
[`Settling`][heartpole.optimum.common.Settling]."""


class NotCoveredError(ValueError):
    """The variant is outside what the dynamic program solves (extra actions or variables, drinks that may pay)."""


SOLVED_PARAMS = frozenset(
    {"heart_attack_proclivity", "max_steps", "decay_rate", "sleep_half_hours", "heart_attack_penalty", "wake_alertness"}
)
"""The fields of [`Params`][heartpole.parameters.Params] the solvers model. A field added to ``Params`` later reaches
every env backend by itself (model.py and dynamics.py), but not the solvers: its default (the tutorial's
dynamics, which the solvers already are) is covered, any other value refused (`unmodelled`)."""


def unmodelled(params: Params) -> dict[str, Any]:
    """The fields of ``params`` outside `SOLVED_PARAMS` that differ from their defaults: what no solver models."""
    return {
        f.name: getattr(params, f.name)
        for f in fields(params)
        if f.name not in SOLVED_PARAMS and (f.default is MISSING or getattr(params, f.name) != f.default)
    }


def peak_productivity() -> float:
    """The largest work a half-hour can bring without intoxication (alertness about 2.2)."""
    return float(productivity(np.linspace(-5.0, 10.0, 30001), 0.0).max())


def max_awake(params: Params) -> int:
    """Half-hours awake after which continuing loses more work than any sleep costs, even on the last step.

    From there on every half-hour awake earns less than ``-(sleep_half_hours + 2) * peak productivity``, so
    sleeping (which costs ``sleep_half_hours + 1`` half-hours at a rate below the peak) is better.
    """
    bound = -(params.sleep_half_hours + 2) * peak_productivity() - 1.0
    high = params.wake_alertness[1]
    t = np.arange(4096, dtype=np.float64)
    drained = np.concatenate([[0.0], np.cumsum(alertness_decay(t))])
    worst = productivity(high - drained, 0.0)
    below = np.nonzero(worst < bound)[0]
    if not len(below):
        raise NotCoveredError("alertness does not drain far enough within 4096 half-hours")
    return int(below[0]) + 2


def params_dict(params: Params) -> dict[str, Any]:
    """``params`` as JSON-safe data (the waking interval as a list)."""
    out = asdict(params)
    out["wake_alertness"] = list(params.wake_alertness)
    return out


class Settling:
    """Tells when a backward recursion over the decisions left has settled into a stationary policy.

    Far from the episode's end the decisions stop depending on how many are left: the values of all states
    then grow by the same amount per decision (the policy's gain) and their differences converge,
    geometrically, to fixed ones (on v0 to rounding within about 1,200 decisions).
    [`update`][heartpole.optimum.common.Settling.update] is given, after each decision, the arrays that must repeat
    exactly (the decisions, the days' lengths) and the values; it answers ``True`` once the exact arrays have
    repeated for ``needed`` decisions in a row and every value less its first element changed by at most
    [`SETTLE_TOLERANCE`][heartpole.optimum.common.SETTLE_TOLERANCE] times ``1 + max |value|`` over the last decision
    (the differences converge geometrically: a step that small leaves them settled). With ``needed`` longer than a
    day, every day's length has settled too; from there on the recursion would only add the gain, so it can stop and
    the policy can be kept once for all decisions beyond."""

    def __init__(self, needed: int) -> None:
        self.needed = needed
        self.run = 0
        self.exact: list[np.ndarray] = []
        self.values: list[np.ndarray] | None = None

    def update(self, exact: tuple[np.ndarray, ...], values: tuple[np.ndarray, ...]) -> bool:
        """Record one decision's arrays; whether the recursion has settled (see the class docstring)."""
        same = len(self.exact) == len(exact) and all(np.array_equal(a, b) for a, b in zip(self.exact, exact))
        self.run = self.run + 1 if same else 0
        self.exact = [np.array(a, copy=True) for a in exact]
        settled = self.run >= self.needed and self.values is not None
        if settled and self.values is not None:
            for now, before in zip(values, self.values):
                change = float(np.abs((now - now.flat[0]) - (before - before.flat[0])).max())
                if change > SETTLE_TOLERANCE * (1.0 + float(np.abs(now).max())):
                    settled = False
                    break
        # the values are compared only once the decisions have repeated long enough: copies only from there
        self.values = [np.array(a, copy=True) for a in values] if self.run >= self.needed - 1 else None
        return settled
