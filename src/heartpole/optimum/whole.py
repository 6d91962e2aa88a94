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
  policy that at each decision takes the best of these lines (`HistoryOptimum.sleeps`) earns at least
  every line's value, so ``lower`` is the value of a policy one can play.

Both are exact on the waking-alertness grid (a midpoint rule over ``grid`` points, as the sleep-timing program's).
What they assume: the sleeps so far stay within ``band`` of their typical count and the work within ``spread``
standard deviations of its typical value for that count (the region is measured by following the sleep-timing
optimum on seeded episodes); a policy leaving it is not counted in ``upper``. `solve_history` reports how the
figures move when the region or the grids are widened, as the sleep-timing program reports its grid's error.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from heartpole.kernel import CACHE
from heartpole.model import Params, productivity

from .common import max_awake
from .sleep import _DayModel, solve_params


@dataclass(frozen=True)
class HistoryOptimum:
    """The optimum over all no-drink policies of one [`Params`][heartpole.model.Params], bounded on a grid.

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
        obs = np.asarray(obs, dtype=np.float64)
        n = np.asarray(decisions_left, dtype=np.int64)
        params = self.params
        awake = max_awake(params)
        drained = _DayModel(params, 1).drained
        t = np.minimum(obs[:, 3].round().astype(np.int64), awake - 1)
        sleeps = np.round((obs[:, 4] - (params.max_steps - n)) / params.sleep_half_hours).astype(np.int64)
        w = obs[:, 0] + drained[t]
        work = obs[:, 5].astype(np.float64)
        return _greedy_sleeps(
            w, t, n, sleeps, work, drained, params.max_steps, params.sleep_half_hours, awake, *self._tables()
        )

    def _tables(self) -> tuple[Any, ...]:
        return (
            self.centre,
            self.band,
            self.work_centre,
            self.work_scale,
            self.offsets,
            self.line_values,
            self.line_slopes,
        )


def solve_history(
    params: Params, *, grid: int = 50, points: int = 25, band: int = 4, spread: float = 6.0, episodes: int = 4000
) -> HistoryOptimum:
    """Solve the optimum over every no-drink policy of ``params`` (module docstring), with its bounds."""
    steps = params.max_steps
    markov = solve_params(params, grid)
    centre, work_centre, work_scale = _region(params, markov.thresholds, band, episodes)
    offsets = np.linspace(-spread, spread, points)
    days = _day_work(params, grid)
    _, lines, slopes, upper, lower = _program(
        steps, params.sleep_half_hours, days, centre, band, work_centre, work_scale, offsets
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


def _region(
    params: Params, thresholds: np.ndarray, band: int, episodes: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the program solves: the typical sleeps so far at each day start and, for each count in the band, the
    typical work and its spread, fitted on episodes of the sleep-timing optimum (a fixed seed: the same every time)."""
    steps = params.max_steps
    awake = thresholds.shape[1]
    drained = _DayModel(params, 1).drained
    low, high = params.wake_alertness
    rng = np.random.default_rng(0)
    size = episodes
    work = np.zeros(size)
    sleeps = np.zeros(size, dtype=np.int64)
    t = np.zeros(size, dtype=np.int64)
    w = low + (high - low) * rng.random(size)
    starts = []
    for n in range(steps, 0, -1):
        column = np.minimum(t, awake - 1)
        sleep = (t >= awake) | (w - drained[column] < thresholds[min(n, len(thresholds) - 1), column])
        if sleep.any():
            chosen = np.nonzero(sleep)[0]
            starts.append(np.stack([np.full(len(chosen), n - 1.0), sleeps[chosen] + 1.0, work[chosen]], 1))
        sleeps += sleep
        w = np.where(sleep, low + (high - low) * rng.random(size), w)
        t = np.where(sleep, 0, t)
        work += productivity(w - drained[np.minimum(t, awake - 1)], 0.0)
        t += 1
    m_left = np.arange(steps)
    if starts:
        seen = np.concatenate(starts)
        done = steps - seen[:, 0]
        fit_k = np.linalg.lstsq(np.stack([done, np.ones(len(seen))], 1), seen[:, 1], rcond=None)[0]
        design = np.stack([done, seen[:, 1], np.ones(len(seen))], 1)
        fit_w = np.linalg.lstsq(design, seen[:, 2], rcond=None)[0]
        residual = seen[:, 2] - design @ fit_w
        scale_fit = np.linalg.lstsq(
            np.stack([np.sqrt(seen[:, 1]), np.ones(len(seen))], 1), np.abs(residual) * np.sqrt(np.pi / 2), rcond=None
        )[0]
    else:  # no episode sleeps: any day start is off the optimum's path
        fit_k, fit_w, scale_fit = np.array([0.0, 1.0]), np.array([0.3, 0.0, 0.0]), np.array([0.0, 1.0])
    centre = np.maximum(np.round(fit_k[0] * (steps - m_left) + fit_k[1]).astype(np.int64), 1)
    counts = centre[:, None] - band + np.arange(2 * band + 1)[None, :]
    work_centre = fit_w[0] * (steps - m_left[:, None]) + fit_w[1] * counts + fit_w[2]
    work_scale = np.maximum(scale_fit[0] * np.sqrt(np.maximum(counts, 0)) + scale_fit[1], 0.25)
    return centre, work_centre, work_scale


@njit(cache=CACHE, inline="always")
def _look(
    upper: Any, lines: Any, slopes: Any, work_centre: Any, work_scale: Any, offsets: Any, m: Any, b: Any, x: Any
) -> Any:
    """The upper value and the best lower line (value, slope) at work ``x`` for day starts ``(m, b)``: the chord
    (extended past the grid's ends) and the better of the two nearest lines (the edge line past the ends)."""
    points = len(offsets)
    f = ((x - work_centre[m, b]) / work_scale[m, b] - offsets[0]) / (offsets[1] - offsets[0])
    k = 0 if f < 0.0 else (points - 2 if f >= points - 1 else int(f))
    frac = f - k
    up = upper[m, b, k] * (1.0 - frac) + upper[m, b, k + 1] * frac
    first = lines[m, b, k] + slopes[m, b, k] * (x - work_centre[m, b] - work_scale[m, b] * offsets[k])
    second = lines[m, b, k + 1] + slopes[m, b, k + 1] * (x - work_centre[m, b] - work_scale[m, b] * offsets[k + 1])
    if f < 0.0 or (f < points - 1 and first >= second):
        return up, first, slopes[m, b, k]
    return up, second, slopes[m, b, k + 1]


@njit(cache=CACHE)
def _day(
    upper: Any,
    lines: Any,
    slopes: Any,
    work_centre: Any,
    work_scale: Any,
    offsets: Any,
    centre: Any,
    band: Any,
    steps: Any,
    rest: Any,
    days: Any,
    g: Any,
    m: Any,
    count: Any,
    work: Any,
    start: Any,
    awake: Any,
) -> Any:
    """The best choice of a day at position ``start`` with ``m`` decisions left: the upper value, and the best lower
    line's value and slope."""
    best_up, best_low, best_slope = -np.inf, -np.inf, 0.0
    time = steps + rest * count
    if m == 0 or m + start <= awake - 1:  # work to the end
        best_up = best_low = (work + days[g, start + m]) / time
        best_slope = 1.0 / time
    for j in range(min(m - 1, awake - 1 - start) + 1):
        after = m - j - 1
        b = count + 1 - centre[after] + band
        if b < 0 or b > 2 * band:
            continue
        up, low, slope = _look(
            upper, lines, slopes, work_centre, work_scale, offsets, after, b, work + days[g, start + j]
        )
        if up > best_up:
            best_up = up
        if low > best_low:
            best_low, best_slope = low, slope
    return best_up, best_low, best_slope


@njit(cache=CACHE)
def _program(
    steps: Any, rest: Any, days: Any, centre: Any, band: Any, work_centre: Any, work_scale: Any, offsets: Any
) -> Any:
    """The backward program over day starts ``(m, sleeps so far, work)``; the upper and lower values at the start."""
    grid, columns = days.shape
    awake = columns - 1
    width, points = 2 * band + 1, len(offsets)
    upper = np.full((steps, width, points), -1e9)
    lines = np.full((steps, width, points), -1e9)
    slopes = np.zeros((steps, width, points))
    for m in range(steps):
        for b in range(width):
            count = centre[m] - band + b
            if count < 1:
                continue
            for i in range(points):
                work = work_centre[m, b] + work_scale[m, b] * offsets[i]
                up = low = slope = 0.0
                for g in range(grid):
                    u, v, s = _day(
                        upper,
                        lines,
                        slopes,
                        work_centre,
                        work_scale,
                        offsets,
                        centre,
                        band,
                        steps,
                        rest,
                        days,
                        g,
                        m,
                        count,
                        work,
                        1,
                        awake,
                    )
                    up += u
                    low += v
                    slope += s
                upper[m, b, i], lines[m, b, i], slopes[m, b, i] = up / grid, low / grid, slope / grid
    up = low = 0.0
    for g in range(grid):  # the episode's first day: t = 0, no sleep and no work so far
        u, v, _ = _day(
            upper,
            lines,
            slopes,
            work_centre,
            work_scale,
            offsets,
            centre,
            band,
            steps,
            rest,
            days,
            g,
            steps,
            0,
            0.0,
            0,
            awake,
        )
        up += u
        low += v
    return upper, lines, slopes, up / grid, low / grid


def _greedy_sleeps(
    w: Any,
    t: Any,
    n: Any,
    sleeps: Any,
    work: Any,
    drained: Any,
    steps: Any,
    rest: Any,
    awake: Any,
    centre: Any,
    band: Any,
    work_centre: Any,
    work_scale: Any,
    offsets: Any,
    lines: Any,
    slopes: Any,
) -> Any:
    """Sleep where sleeping now is worth at least as much as the best later sleep of the same day (or working to the
    end), by the upper envelope of the lower lines."""
    columns = np.minimum(t[:, None] + np.arange(awake)[None, :], awake - 1)
    worked = productivity(w[:, None] - drained[columns], 0.0)
    later = work[:, None] + np.concatenate([np.zeros((len(w), 1)), np.cumsum(worked, axis=1)], axis=1)
    return _greedy(
        later, t, n, sleeps, steps, rest, awake, centre, band, work_centre, work_scale, offsets, lines, slopes
    )


@njit(cache=CACHE)
def _greedy(
    later: Any,
    t: Any,
    n: Any,
    sleeps: Any,
    steps: Any,
    rest: Any,
    awake: Any,
    centre: Any,
    band: Any,
    work_centre: Any,
    work_scale: Any,
    offsets: Any,
    lines: Any,
    slopes: Any,
) -> Any:
    """`_greedy_sleeps`' loop: ``later[e, j]`` is env ``e``'s work after ``j`` more half-hours of its day."""
    decide = np.zeros(len(t), dtype=np.bool_)
    for e in range(len(t)):
        if t[e] >= awake - 1:
            decide[e] = True
            continue
        time = steps + rest * sleeps[e]
        best_later = later[e, n[e]] / time if n[e] + t[e] <= awake - 1 else -np.inf
        now = -np.inf
        for j in range(min(n[e] - 1, awake - 1 - t[e]) + 1):
            after = n[e] - j - 1
            b = sleeps[e] + 1 - centre[after] + band
            if b < 0 or b > 2 * band:
                continue
            value = -np.inf
            for i in range(len(offsets)):
                x_i = work_centre[after, b] + work_scale[after, b] * offsets[i]
                value = max(value, lines[after, b, i] + slopes[after, b, i] * (later[e, j] - x_i))
            if j == 0:
                now = value
            elif value > best_later:
                best_later = value
        decide[e] = now >= best_later
    return decide
