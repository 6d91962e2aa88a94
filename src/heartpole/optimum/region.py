"""Where the history program ([`heartpole.optimum.whole`][heartpole.optimum.whole]) solves: the typical sleeps so
far at each day start, and the typical work and its spread for each count, fitted on seeded episodes of the
sleep-timing optimum (least squares over their day starts, kept as normal equations)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from heartpole.model import productivity
from heartpole.parameters import Params

from .sleep import _DayModel


def solved_region(
    params: Params, thresholds: np.ndarray, band: int | None, episodes: int
) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
    """Where the program solves: the typical sleeps so far at each day start and, for each count in the band, the
    typical work and its spread, fitted on episodes of the sleep-timing optimum (a fixed seed: the same every time).
    Two passes over the same episodes: the fits of the counts and the work, then the spread about them."""
    steps = params.max_steps
    fits = _Fits()
    for day_starts in _day_starts(params, thresholds, episodes):
        fits.first(day_starts)
    fit_k, fit_w = fits.solve_first()
    for day_starts in _day_starts(params, thresholds, episodes):
        fits.second(day_starts, fit_k, fit_w)
    scale_fit, farthest = fits.solve_second()
    band = farthest + 2 if band is None else band
    m_left = np.arange(steps)
    centre = np.maximum(np.round(fit_k[0] * (steps - m_left) + fit_k[1]).astype(np.int64), 1)
    counts = centre[:, None] - band + np.arange(2 * band + 1)[None, :]
    work_centre = fit_w[0] * (steps - m_left[:, None]) + fit_w[1] * counts + fit_w[2]
    work_scale = np.maximum(scale_fit[0] * np.sqrt(np.maximum(counts, 0)) + scale_fit[1], 0.25)
    return centre, band, work_centre, work_scale


def _day_starts(params: Params, thresholds: np.ndarray, episodes: int) -> Iterator[np.ndarray]:
    """The day starts of seeded episodes of the sleep-timing optimum, a decision at a time: rows of (decisions done,
    sleeps so far, work before the day)."""
    steps = params.max_steps
    awake = thresholds.shape[1]
    drained = _DayModel(params, 1).drained
    low, high = params.wake_alertness
    rng = np.random.default_rng(0)
    work = np.zeros(episodes)
    sleeps = np.zeros(episodes, dtype=np.int64)
    t = np.zeros(episodes, dtype=np.int64)
    w = low + (high - low) * rng.random(episodes)
    for n in range(steps, 0, -1):
        column = np.minimum(t, awake - 1)
        sleep = (t >= awake) | (w - drained[column] < thresholds[min(n, len(thresholds) - 1), column])
        if sleep.any():
            chosen = np.nonzero(sleep)[0]
            yield np.stack([np.full(len(chosen), steps - n + 1.0), sleeps[chosen] + 1.0, work[chosen]], 1)
        sleeps += sleep
        w = np.where(sleep, low + (high - low) * rng.random(episodes), w)
        t = np.where(sleep, 0, t)
        work += productivity(w - drained[np.minimum(t, awake - 1)], 0.0)
        t += 1


class _Fits:
    """Least squares accumulated over day starts (their normal equations), so no day start is kept."""

    def __init__(self) -> None:
        self.k = (np.zeros((2, 2)), np.zeros(2))  # sleeps ~ decisions done
        self.w = (np.zeros((3, 3)), np.zeros(3))  # work ~ decisions done, sleeps
        self.spread = (np.zeros((2, 2)), np.zeros(2))  # |work residual| ~ sqrt(sleeps)
        self.farthest = 0

    @staticmethod
    def _add(normal: tuple[np.ndarray, np.ndarray], design: np.ndarray, target: np.ndarray) -> None:
        normal[0][...] += design.T @ design
        normal[1][...] += design.T @ target

    @staticmethod
    def _solve(normal: tuple[np.ndarray, np.ndarray], fallback: np.ndarray) -> np.ndarray:
        matrix, vector = normal
        return np.linalg.lstsq(matrix, vector, rcond=None)[0] if matrix[-1, -1] > 0 else fallback

    def first(self, rows: np.ndarray) -> None:
        ones = np.ones(len(rows))
        self._add(self.k, np.stack([rows[:, 0], ones], 1), rows[:, 1])
        self._add(self.w, np.stack([rows[:, 0], rows[:, 1], ones], 1), rows[:, 2])

    def solve_first(self) -> tuple[np.ndarray, np.ndarray]:
        return self._solve(self.k, np.array([0.0, 1.0])), self._solve(self.w, np.array([0.3, 0.0, 0.0]))

    def second(self, rows: np.ndarray, fit_k: np.ndarray, fit_w: np.ndarray) -> None:
        ones = np.ones(len(rows))
        residual = rows[:, 2] - np.stack([rows[:, 0], rows[:, 1], ones], 1) @ fit_w
        self._add(self.spread, np.stack([np.sqrt(rows[:, 1]), ones], 1), np.abs(residual) * np.sqrt(np.pi / 2))
        distance = np.abs(rows[:, 1] - np.round(fit_k[0] * rows[:, 0] + fit_k[1]))
        self.farthest = max(self.farthest, int(distance.max()))

    def solve_second(self) -> tuple[np.ndarray, int]:
        return self._solve(self.spread, np.array([0.0, 1.0])), self.farthest
