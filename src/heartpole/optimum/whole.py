"""The optimum over every policy that sees the observation, work done and time so far included, with bounds.

The sleep-timing program ([`heartpole.optimum.sleep`][heartpole.optimum.sleep]) finds the best policy that sees
``(decisions left, alertness, time awake)``. The score is a ratio, ``work / time``, so the work done and the sleeps so
far are worth a little more: an episode that has gone well has a higher score to protect. This module solves the
whole problem of a no-drink episode by a dynamic program over day starts.

State. A day starts right after a sleep: ``m`` decisions are left, ``K`` sleeps have been taken (so the episode's time
will be ``max_steps + sleep_half_hours * (K + more sleeps)``), ``W`` units of work were done before the day. Given the
day's waking alertness ``w`` the day is deterministic, so the only choice is how many decisions ``j`` to work before
the next sleep (or to work to the end). Its value ``V(m, K, W)`` is the best expected final score.

Why the bounds hold. For a fixed plan of the future (which day lengths follow which waking draws) the final score is
``(W + X) / (c_K + 16 Y)`` with ``X``, ``Y`` independent of ``W``: affine in ``W``. So ``V(m, K, .)`` is the upper
envelope of lines, convex in ``W``, and the program keeps, on a grid of ``W`` for each ``(m, K)``:

* an **upper value**: chords of a convex function lie above it, so interpolating upper values linearly gives upper
  values between the grid's points (outside the grid the edge chord is extended: an approximation, see below);
* a **lower line**: the value and slope of one concrete plan, exact at every ``W`` (a plan's value is affine). The
  policy that at each decision takes the best of these lines (`HistoryOptimum.sleeps`, by their upper envelope) earns
  at least every line's value, so ``lower`` is the value of a policy one can play.

Both are exact on the waking-alertness grid (a midpoint rule over ``grid`` points, as the sleep-timing program's).
What they assume: the sleeps so far stay within ``band`` of their typical count and the work within ``spread``
standard deviations of its typical value for that count (the region is measured by following the sleep-timing
optimum on seeded episodes); a policy leaving it is not counted in ``upper``. `solve_history` reports how the
figures move when the region or the grids are widened, as the sleep-timing program reports its grid's error.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numba import njit

from heartpole.kernel import CACHE
from heartpole.model import ballmer, productivity
from heartpole.parameters import Params

from .common import max_awake
from .region import solved_region
from .sleep import _DayModel, solve_params


@dataclass(frozen=True)
class HistoryOptimum:
    """The optimum over all no-drink policies of one [`Params`][heartpole.parameters.Params], bounded on a grid.

    Attributes:
        params: what was solved.
        grid: midpoint points of the waking alertness.
        points: grid points of the work before a day, for each ``(decisions left, sleeps so far)``.
        lower: the expected score of the history-aware policy (`sleeps`), exact on the waking grid.
        upper: what no policy that stays in the solved region scores more than, on the waking grid.
        markov: the sleep-timing optimum's expected score on the same waking grid (it sees no history).
    """

    params: Params
    grid: int
    points: int
    lower: float
    upper: float
    markov: float
    centre: np.ndarray = field(repr=False)  # (max_steps,) typical sleeps so far at a day start with m left
    band: int = field(repr=False)
    work_centre: np.ndarray = field(repr=False)  # (max_steps, 2 band + 1): the work grid's centre and scale
    work_scale: np.ndarray = field(repr=False)
    offsets: np.ndarray = field(repr=False)  # (points,) the work grid in units of work_scale
    line_values: np.ndarray = field(repr=False)  # (max_steps, 2 band + 1, points): the lower lines
    line_slopes: np.ndarray = field(repr=False)

    @property
    def gain(self) -> float:
        """What the history is worth at least: ``lower - markov``."""
        return self.lower - self.markov

    @property
    def gap(self) -> float:
        """``upper - lower``: how far the played policy may be from the optimum (on the grid, in the region)."""
        return self.upper - self.lower

    def sleeps(self, obs: np.ndarray, decisions_left: np.ndarray) -> np.ndarray:
        """Whether the history-aware policy sleeps, for no-drink observations ``(envs, 6)`` (float) and the
        decisions left (1 on the last decision). It reads alertness, time awake, time elapsed and work done."""
        if len(self.line_values) != self.params.max_steps:
            raise ValueError("this solution kept no policy: solve it with solve_history(..., policy=True)")
        obs = np.asarray(obs, dtype=np.float64)
        n = np.asarray(decisions_left, dtype=np.int64)
        params = self.params
        awake, drained = self._day
        t = np.minimum(obs[:, 3].round().astype(np.int64), awake - 1)
        sleeps = self._sleeps_so_far(obs, n)
        w = obs[:, 0] + drained[t]
        day = (w, obs[:, 5], drained, float(ballmer(0.0)), awake)
        return _greedy(*day, t, n, sleeps, params.max_steps, params.sleep_half_hours, self._tables())

    def inside(self, obs: np.ndarray, decisions_left: np.ndarray) -> np.ndarray:
        """Whether each observation lies in the solved region: at the day start a sleep now would begin, its sleeps so
        far within the band about their typical count and its work within the work grid. Outside (another person's
        episode, say) the lines are extrapolated far from where they were solved, and `sleeps` means little."""
        obs = np.asarray(obs, dtype=np.float64)
        n = np.asarray(decisions_left, dtype=np.int64)
        sleeps = self._sleeps_so_far(obs, n)
        if not self.params.sleep_half_hours:
            return np.ones(len(obs), dtype=bool)
        after = np.clip(n - 1, 0, len(self.centre) - 1)
        b = sleeps + 1 - self.centre[after] + self.band
        row = np.clip(b, 0, 2 * self.band)
        low = self.work_centre[after, row] + self.work_scale[after, row] * self.offsets[0]
        high = self.work_centre[after, row] + self.work_scale[after, row] * self.offsets[-1]
        return (b >= 0) & (b <= 2 * self.band) & (obs[:, 5] >= low) & (obs[:, 5] <= high)

    def _sleeps_so_far(self, obs: np.ndarray, n: np.ndarray) -> np.ndarray:
        """The sleeps so far that the time elapsed and the decisions left tell; -1 where sleeps take no time (the
        time does not tell them, and they do not matter: every count has the centre's values)."""
        params = self.params
        if not params.sleep_half_hours:
            return np.full(len(obs), -1, dtype=np.int64)
        return np.round((obs[:, 4] - (params.max_steps - n)) / params.sleep_half_hours).astype(np.int64)

    @functools.cached_property
    def _day(self) -> tuple[int, np.ndarray]:
        """Half-hours awake after which a day always sleeps, and the alertness drained after each: worked out once,
        not at every decision."""
        return max_awake(self.params), _DayModel(self.params, 1).drained

    @functools.cached_property
    def _hull(self) -> tuple[np.ndarray, np.ndarray]:
        """Each day start's upper envelope of its lower lines, so play finds the best line by a binary search."""
        return _hulls(self.work_centre, self.work_scale, self.offsets, self.line_values, self.line_slopes)

    def _tables(self) -> tuple[Any, ...]:
        return (
            self.centre,
            self.band,
            self.work_centre,
            self.work_scale,
            self.offsets,
            self.line_values,
            self.line_slopes,
            *self._hull,
        )


HISTORY_HORIZON = 3000
"""The longest horizon whose history-aware optimum a solution plays, and that
[`history_worth`][heartpole.optimum.whole.history_worth] solves; longer ones play the sleep-timing policy and take the
history's worth at this horizon (it falls with the horizon: 4.3e-5 at 300 decisions, 1.2e-5 at 1,000, 0.3e-5 at 3,000
on v0). A longer program would take time and memory growing with the horizon (about 3 x 40 MB of tables here)."""


def history_worth(params: Params) -> float:
    """What a policy that also sees the work done and the sleeps so far can add to the sleep-timing optimum's expected
    score: the program's upper value less the sleep-timing optimum's on the same grid, on a coarse grid (25 waking
    points, 13 work points: it states the worth higher than finer grids do, see docs/optimum.md), at most
    [`HISTORY_HORIZON`][heartpole.optimum.whole.HISTORY_HORIZON] decisions."""
    short = replace(params, max_steps=min(params.max_steps, HISTORY_HORIZON))
    solved = solve_history(short, grid=25, points=13, policy=False)
    return max(solved.upper - solved.markov, 0.0)


def solve_history(
    params: Params,
    *,
    grid: int = 50,
    points: int = 25,
    band: int | None = None,
    spread: float = 6.0,
    episodes: int = 4000,
    policy: bool = True,
) -> HistoryOptimum:
    """Solve the optimum over every no-drink policy of ``params`` (module docstring), with its bounds.

    Args:
        params: the variant (no drinks: the sleep-timing program's cases).
        grid: midpoint points of the waking alertness.
        points: grid points of the work before a day, ``spread`` typical deviations either side of its typical value.
        band: sleeps so far either side of the typical count; ``None``: two more than the farthest seen on
            ``episodes`` seeded episodes of the sleep-timing optimum.
        policy: keep the lines of every day start, for `HistoryOptimum.sleeps`; without, only the bounds are
            solved, in memory that does not grow with the horizon.
    """
    steps = params.max_steps
    markov = solve_params(params, grid)
    centre, band, work_centre, work_scale = solved_region(params, markov.thresholds, band, episodes)
    offsets = np.linspace(-spread, spread, points)
    days = _day_work(params, grid)
    geometry = np.stack(
        [
            work_centre + work_scale * offsets[0],
            work_scale * (offsets[1] - offsets[0]),
            np.full_like(work_scale, points),
        ],
        axis=-1,
    )
    _, lines, slopes, upper, lower = _program(
        steps,
        params.sleep_half_hours,
        np.ascontiguousarray(days.T),
        centre,
        band,
        geometry,
        steps if policy else days.shape[1] + 1,
    )
    return HistoryOptimum(
        params,
        grid,
        points,
        float(lower),
        float(upper),
        markov.expected_score,
        centre,
        band,
        work_centre,
        work_scale,
        offsets,
        lines,
        slopes,
    )


def _day_work(params: Params, grid: int) -> np.ndarray:
    """``(grid, max_awake + 1)``: the work of a day of each waking alertness after ``j`` half-hours."""
    awake = max_awake(params)
    low, high = params.wake_alertness
    wake = low + (high - low) * (np.arange(grid) + 0.5) / grid
    drained = _DayModel(params, 1).drained
    worked = productivity(wake[:, None] - drained[None, :awake], 0.0)
    return np.concatenate([np.zeros((grid, 1)), np.cumsum(worked, axis=1)], axis=1)


@njit(cache=CACHE)
def _best_days(
    upper: Any,
    lines: Any,
    slopes: Any,
    geometry: Any,
    centre: Any,
    band: int,
    steps: int,
    rest: int,
    by_length: Any,
    m: int,
    count: int,
    works: Any,
    start: int,
    rows: int,
) -> Any:
    """The best choice of a day at position ``start`` with ``m`` decisions left and ``count`` sleeps, for each work
    before the day in ``works`` (rows) and each waking alertness (columns): the upper value, and the best lower line's
    value and slope.

    The choices are: sleep after ``j`` more half-hours (the next day starts with ``m - j - 1`` left, one more sleep,
    the day's work added), or work to the end. The upper value is the chord of the next day start's grid, extended
    past its ends; the lower line the better of the two nearest lines (the edge line past the ends)."""
    columns, grid = by_length.shape
    awake = columns - 1
    points = upper.shape[2]
    best_up = np.full((len(works), grid), -np.inf)
    best_low = np.full((len(works), grid), -np.inf)
    best_slope = np.zeros((len(works), grid))
    time = steps + rest * count
    if m == 0 or m + start <= awake - 1:  # work to the end
        for i in range(len(works)):
            for g in range(grid):
                best_up[i, g] = best_low[i, g] = (works[i] + by_length[start + m, g]) / time
                best_slope[i, g] = 1.0 / time
    for j in range(min(m - 1, awake - 1 - start) + 1):
        after = m - j - 1
        b = count + 1 - centre[after] + band
        if b < 0 or b > 2 * band:
            continue
        first_x, spacing = geometry[after, b, 0], geometry[after, b, 1]
        up_row, line_row, slope_row = upper[after % rows, b], lines[after % rows, b], slopes[after % rows, b]
        for i in range(len(works)):
            for g in range(grid):
                x = works[i] + by_length[start + j, g]
                f = (x - first_x) / spacing
                k = 0 if f < 0.0 else (points - 2 if f >= points - 1 else int(f))
                frac = f - k
                up = up_row[k] + (up_row[k + 1] - up_row[k]) * frac
                first = line_row[k] + slope_row[k] * (x - first_x - spacing * k)
                second = line_row[k + 1] + slope_row[k + 1] * (x - first_x - spacing * (k + 1))
                if f < 0.0 or (f < points - 1 and first >= second):
                    low, slope = first, slope_row[k]
                else:
                    low, slope = second, slope_row[k + 1]
                if up > best_up[i, g]:
                    best_up[i, g] = up
                if low > best_low[i, g]:
                    best_low[i, g], best_slope[i, g] = low, slope
    return best_up, best_low, best_slope


@njit(cache=CACHE)
def _program(steps: int, rest: int, by_length: Any, centre: Any, band: int, geometry: Any, rows: int) -> Any:
    """The backward program over day starts ``(m, sleeps so far, work)``; the upper and lower values at the start.
    ``geometry[m, b]`` is the first work grid point and the spacing of day starts ``(m, b)``. The values of ``m`` are
    kept in row ``m % rows``: ``rows = steps`` keeps them all (for the policy), a day's length plus one only those the
    next day starts need."""
    grid = by_length.shape[1]
    width, points = 2 * band + 1, 0
    points = int(geometry[0, 0, 2])
    upper = np.full((rows, width, points), -1e9)
    lines = np.full((rows, width, points), -1e9)
    slopes = np.zeros((rows, width, points))
    for m in range(steps):
        for b in range(width):
            count = centre[m] - band + b
            row = m % rows
            upper[row, b], lines[row, b], slopes[row, b] = -1e9, -1e9, 0.0
            if count < 1:
                continue
            works = geometry[m, b, 0] + geometry[m, b, 1] * np.arange(points)
            up, low, slope = _best_days(
                upper, lines, slopes, geometry, centre, band, steps, rest, by_length, m, count, works, 1, rows
            )
            for i in range(points):
                upper[row, b, i] = up[i].sum() / grid
                lines[row, b, i] = low[i].sum() / grid
                slopes[row, b, i] = slope[i].sum() / grid
    # the episode's first day: t = 0, no sleep and no work so far
    up, low, _ = _best_days(
        upper, lines, slopes, geometry, centre, band, steps, rest, by_length, steps, 0, np.zeros(1), 0, rows
    )
    return upper, lines, slopes, up[0].sum() / grid, low[0].sum() / grid


@njit(cache=CACHE)
def _sober_work(alertness: float, sober: float) -> float:
    """`heartpole.model.productivity` without intoxication (``sober`` is ``ballmer(0)``), term by term as there."""
    return alertness * (1.0 - 1.0 / (1.0 + np.exp(-(alertness - 0.0 - 3.0)))) * sober


@njit(cache=CACHE)
def _greedy(
    w: Any,
    work: Any,
    drained: Any,
    sober: float,
    awake: int,
    t: Any,
    n: Any,
    sleeps: Any,
    steps: Any,
    rest: Any,
    tables: Any,
) -> Any:
    """Sleep where sleeping now is worth at least as much as the best later sleep of the same day (or working to the
    end), by the upper envelope of the lower lines. Env ``e`` woke at alertness ``w[e]`` (``drained`` since), has
    ``work[e]`` done; its work after ``j`` more half-hours adds the productivity of each. ``tables``: those of
    `_line_envelope`."""
    decide = np.zeros(len(t), dtype=np.bool_)
    for e in range(len(t)):
        if t[e] >= awake - 1:
            decide[e] = True
            continue
        best_later = -np.inf
        if n[e] + t[e] <= awake - 1:  # working to the end is a choice
            total = work[e]
            for j in range(n[e]):
                total += _sober_work(w[e] - drained[t[e] + j], sober)
            best_later = total / (steps + rest * sleeps[e])
        later = work[e]
        now = _line_envelope(later, n[e] - 1, sleeps[e], tables)
        decide[e] = now >= best_later
        # a later sleep that beats sleeping now settles it (the first one found: most decisions are "work on")
        for j in range(1, min(n[e] - 1, awake - 1 - t[e]) + 1):
            if not decide[e]:
                break
            later += _sober_work(w[e] - drained[t[e] + j - 1], sober)
            decide[e] = now >= _line_envelope(later, n[e] - j - 1, sleeps[e], tables)
    return decide


@njit(cache=CACHE)
def _line_envelope(x: float, after: int, sleeps: int, tables: Any) -> float:
    """The best lower line at the day start ``after`` decisions left with ``x`` work done (``-inf`` outside the band
    of sleeps so far; ``sleeps < 0``: the centre's): the hull's line whose stretch holds ``x`` (`_hulls`). ``tables``
    is `HistoryOptimum._tables`' ``(centre, band, work_centre, work_scale, offsets, lines, slopes, hull, breaks)``."""
    centre, band, work_centre, work_scale, offsets, lines, slopes, hull, breaks = tables
    b = band if sleeps < 0 else sleeps + 1 - centre[after] + band
    if b < 0 or b > 2 * band:
        return -np.inf
    low, high = 0, len(offsets) - 1  # breaks past the hull's last line are +inf
    while low < high:
        middle = (low + high) // 2
        if breaks[after, b, middle] <= x:
            low = middle + 1
        else:
            high = middle
    i = hull[after, b, low]
    return lines[after, b, i] + slopes[after, b, i] * (x - (work_centre[after, b] + work_scale[after, b] * offsets[i]))


@njit(cache=CACHE)
def _hulls(work_centre: Any, work_scale: Any, offsets: Any, lines: Any, slopes: Any) -> Any:
    """The upper envelope of each day start's lines ``lines[m, b, i] + slopes[m, b, i] * (x - x_i)``: ``hull[m, b]``
    lists the lines that are the best somewhere, left to right, and ``breaks[m, b, k]`` is where line ``k + 1`` of the
    list overtakes line ``k`` (``+inf`` after the last). The convex hull trick: lines by increasing slope, each one
    dropping those it and the one before cover."""
    steps, width, points = lines.shape
    hull = np.zeros((steps, width, points), dtype=np.int64)
    breaks = np.full((steps, width, points), np.inf)
    cross = np.empty(points)
    for m in range(steps):
        for b in range(width):
            slope = slopes[m, b]
            at_zero = lines[m, b] - slope * (work_centre[m, b] + work_scale[m, b] * offsets)
            top = -1
            for i in np.argsort(slope, kind="mergesort"):
                if top >= 0 and slope[hull[m, b, top]] == slope[i]:
                    if at_zero[hull[m, b, top]] >= at_zero[i]:
                        continue
                    top -= 1
                while top >= 0:
                    j = hull[m, b, top]
                    x = (at_zero[j] - at_zero[i]) / (slope[i] - slope[j])
                    if top >= 1 and x <= cross[top - 1]:
                        top -= 1
                        continue
                    cross[top] = x
                    break
                top += 1
                hull[m, b, top] = i
            breaks[m, b, :top] = cross[:top]
    return hull, breaks
