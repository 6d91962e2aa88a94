"""The best long-run score known for a HeartPole env: the rate of the ``expert`` policy's sleep rule.

`best_known_rate` is what the solved bar
(`solved_bar`) and the shaped training reward measure scores against; the
``expert`` policy (`ExpertPolicy`) sleeps once the coming half-hour would
earn less than it. It is computed from the dynamics alone, so registering a variant solves nothing else.
"""

from __future__ import annotations

import functools

import numpy as np

from heartpole.actions import TAKE_NAP
from heartpole.dynamics import Dynamics
from heartpole.model import alertness_decay, productivity
from heartpole.parameters import Params

RATE_WITH_NAPS = 0.69
"""The long-run rate of the expert's nap rule in a variant with v1's ``take_nap`` (see
`ExpertPolicy`)."""


def best_known_rate(dynamics: Dynamics) -> float | None:
    """The best long-run score known for ``dynamics``: the ``expert`` policy's rate (0.327 for v0, 0.69 for
    v1), or ``None`` for a variant without the ``do_nothing`` and ``sleep`` actions the expert needs."""
    names = {action.name for action in dynamics.actions}
    if not {"do_nothing", "sleep"} <= names:
        return None
    return RATE_WITH_NAPS if TAKE_NAP in dynamics.actions else expert_rate(dynamics.params)


@functools.lru_cache(maxsize=32)
def expert_rate(params: Params, grid: int = 400) -> float:
    """The long-run score of "sleep when the coming half-hour earns less than the score", as a fixed point.

    A day starts with waking alertness ``w`` uniform on ``params.wake_alertness``; its ``s``-th half-hour of
    work earns ``productivity(w - sum(alertness_decay(j) for j < s), 0)``. For a threshold ``rate`` a day
    lasts ``L(w)`` decisions and earns ``W(w)``. An episode of ``D = max_steps`` decisions holds ``D / E[L]``
    days and ``D / E[L] - 1`` sleeps, so its score is ``(D / E[L]) E[W] / (D + sleep (D / E[L] - 1))``.
    Iterating ``rate <- score(rate)`` from 0 converges to the best threshold (Dinkelbach's method), since a
    threshold equal to the score it achieves cannot be improved on. ``w`` is integrated on a midpoint grid.

    Memory does not grow with ``max_steps``: the rate is never negative, and a day's work turns negative
    (and so stops) once alertness is below 0, so only the half-hours up to then are computed.
    """
    low, high = params.wake_alertness
    wake = low + (high - low) * (np.arange(grid) + 0.5) / grid
    horizon = params.max_steps
    earned = productivity(_waking_alertness(wake, horizon), 0.0)
    columns = earned.shape[1]  # < horizon: every day has ended by the last column
    rate = 0.0
    for _ in range(200):
        working = earned >= rate
        working[:, 0] = True  # the decision to sleep comes with the first half-hour of the new day
        whole = working.all(axis=1)
        length = np.where(whole, horizon, np.argmin(working, axis=1))
        work = np.where(np.arange(columns)[None, :] < length[:, None], earned, 0.0).sum(axis=1)
        days = horizon / length.mean()
        new_rate = days * work.mean() / (horizon + params.sleep_half_hours * max(days - 1.0, 0.0))
        if abs(new_rate - rate) < 1e-12:
            break
        rate = new_rate
    return float(rate)


def _waking_alertness(wake: np.ndarray, horizon: int, block: int = 64) -> np.ndarray:
    """Alertness over a day for each waking alertness in ``wake``: ``(len(wake), columns)``.

    ``columns`` is ``horizon``, or fewer: up to the first half-hour after waking at which every day's
    alertness is below 0 (productivity is negative from there on, and alertness only falls).
    """
    decay: list[np.ndarray] = [np.zeros(1)]
    total, start = 0.0, 0
    while start < horizon - 1 and (start == 0 or total <= wake.max()):
        steps = np.arange(start, min(start + block, horizon - 1), dtype=np.float64)
        part = total + np.cumsum(alertness_decay(steps))
        decay.append(part)
        total, start = float(part[-1]), start + len(steps)
        block *= 2
    cumulative = np.concatenate(decay)
    if total > wake.max():  # cut just after the first half-hour at which every day is below 0
        cumulative = cumulative[: max(int(np.argmax(cumulative > wake.max())) + 1, 2)]
    return wake[:, None] - cumulative[None, :]
