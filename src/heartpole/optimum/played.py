"""The history-aware optimum an [`OptimumSolution`][heartpole.optimum.solution.OptimumSolution] plays: solved on
fixed grids, with its grid error, and stored beside the solution.

[`solve_played`][heartpole.optimum.played.solve_played] solves [`solve_history`][heartpole.optimum.whole.solve_history]
with its policy on `HISTORY_GRID` waking points and `HISTORY_POINTS` work points. What it adds to the sleep-timing
optimum, ``gain = lower - markov`` (both on that waking grid), is added to the sleep-timing optimum's fine-grid score.
The gain's grid error is bounded as the sleep-timing program's is: by how much it moves when the waking grid is
halved (a second solve, without the policy). Up to [`HISTORY_HORIZON`][heartpole.optimum.whole.HISTORY_HORIZON]
decisions; beyond, the solution plays the sleep-timing policy and states the history's worth
([`history_worth`][heartpole.optimum.whole.history_worth]).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from heartpole.parameters import Params

from .whole import HISTORY_HORIZON, HistoryOptimum, solve_history

HISTORY_GRID = 50
"""Waking-alertness points of the played history program (its gain's grid error is measured against half)."""
HISTORY_POINTS = 37
"""Work grid points per (decisions left, sleeps so far) of the played history program: its gap ``upper - lower``
falls like the square of their spacing (1.4e-6 with 25 points, 6e-7 with 37 for the cohort's Cleo at 400)."""
_ARRAYS = ("centre", "work_centre", "work_scale", "offsets", "line_values", "line_slopes")
_SCALARS = ("grid", "points", "band", "lower", "upper", "markov")


def solve_played(params: Params) -> tuple[HistoryOptimum, float] | None:
    """The history program ``params``' solution plays, with its policy, and its gain's grid error (the change of
    ``lower - markov`` from `HISTORY_GRID` to half of it); ``None`` beyond
    [`HISTORY_HORIZON`][heartpole.optimum.whole.HISTORY_HORIZON] decisions."""
    if params.max_steps > HISTORY_HORIZON:
        return None
    solved = solve_history(params, grid=HISTORY_GRID, points=HISTORY_POINTS)
    half = solve_history(params, grid=HISTORY_GRID // 2, points=HISTORY_POINTS, policy=False)
    return solved, abs(solved.gain - half.gain)


def history_arrays(solved: HistoryOptimum) -> dict[str, np.ndarray]:
    """The arrays of ``solved``'s policy, named for an ``.npz`` beside the solution's thresholds."""
    return {f"history_{name}": getattr(solved, name) for name in _ARRAYS}


def history_meta(solved: HistoryOptimum) -> dict[str, Any]:
    """The figures of ``solved``, JSON-safe."""
    return {name: getattr(solved, name) for name in _SCALARS}


def history_from(params: Params, meta: dict[str, Any], arrays: Any) -> HistoryOptimum:
    """The [`HistoryOptimum`][heartpole.optimum.whole.HistoryOptimum] saved by `history_arrays` and `history_meta`."""
    return HistoryOptimum(
        params=params,
        grid=int(meta["grid"]),
        points=int(meta["points"]),
        lower=float(meta["lower"]),
        upper=float(meta["upper"]),
        markov=float(meta["markov"]),
        band=int(meta["band"]),
        **{name: np.asarray(arrays[f"history_{name}"]) for name in _ARRAYS},
    )
