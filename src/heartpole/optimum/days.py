"""The days of a no-drink sleep policy and the expected score of its episodes, in time and memory linear
in the horizon.

Without drinks a day is deterministic once its waking alertness ``w`` is drawn, so an episode is a string of
days. A day starts at a decision with ``n`` decisions left: the episode's first (at ``t = 0``) or the one
after a sleep (at ``t = 1``: the sleep's own step is the new day's first half-hour of work). Given ``w`` it
runs ``L`` decisions without sleeping; then the episode ends (``L == n``) or the next decision sleeps and
the next day starts with ``n - L - 1`` decisions left. A day's *kernel* is the law of ``L`` over the waking
grid and the expected work of the day for each ``L``; [`DayKernels`][heartpole.optimum.days.DayKernels] keeps one per
``n``, each only once while consecutive ones repeat (far from the end they all do: the policy has settled).

[`episode_outcome`][heartpole.optimum.days.episode_outcome] turns them into ``E[work / time]``. An episode's time is ``T
= max_steps + sleep_half_hours * K`` for ``K`` sleeps, which varies with the work, so the score is not a ratio of
expectations. Carrying the law of ``K`` at every day start (the old pass) takes time growing like ``max_steps ** 1.5``
(its spread grows like the root of the days) and memory like ``max_steps ** 2``. Instead, with ``tau = T / max_steps >=
1``, ``1 / tau`` is the integral of ``exp(-u tau)`` over ``u > 0``, and for each ``u`` the expectation ``E[work * exp(-u
tau)]`` takes one pass over the days that multiplies by ``exp(-u * sleep_half_hours / max_steps)`` at each sleep.
[`time_rule`][heartpole.optimum.days.time_rule] gives the integral to rounding for every ``tau`` an episode can have,
whatever the law of ``K``. One compiled (numba) pass carries all its nodes at once, through the decisions from the top,
keeping only the next ``max_awake + 1``
day starts: time linear in the horizon, memory independent of it.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from heartpole.kernel import CACHE

Kernel = tuple[np.ndarray, np.ndarray, np.ndarray]
"""A day's kernel: its lengths ``L`` (ascending), their probabilities and ``E[work of the day; L]``."""


def day_kernel(lengths: np.ndarray, earned: np.ndarray) -> Kernel:
    """The kernel of days whose length and work are ``lengths[i]`` and ``earned[i]`` for the grid's ``w_i``."""
    values, inverse = np.unique(lengths, return_inverse=True)
    size = len(lengths)
    counts = np.bincount(inverse, minlength=len(values))
    work = np.bincount(inverse, weights=earned, minlength=len(values))
    return values.astype(np.int64), counts / size, work / size


class DayKernels:
    """The kernels of the days starting at each ``n`` (after a sleep) and of the episode's first day.

    Built by [`add`][heartpole.optimum.days.DayKernels.add] for ``n = 0, 1, ...`` in turn, then
    [`close`][heartpole.optimum.days.DayKernels.close]; a run of equal kernels is stored once. Days starting beyond
    the last ``n`` added have the last kernel (the policy has settled there)."""

    def __init__(self) -> None:
        self._lengths, self._probs, self._earned = array("q"), array("d"), array("d")
        self._starts = array("q", [0])  # kernel k is entries _starts[k]:_starts[k + 1]
        self._rows = array("q")  # the kernel of each n
        self._last: Kernel | None = None
        self._days: tuple[np.ndarray, np.ndarray] | None = None  # the last lengths and work added
        self.first: Kernel | None = None  # set by close, with the frozen arrays below
        self.lengths = self.probs = self.earned = np.empty(0)
        self.starts = self.rows = np.zeros(1, dtype=np.int64)

    @property
    def stored(self) -> int:
        """The last ``n`` with its own kernel."""
        return len(self._rows) - 1

    def add(self, lengths: np.ndarray, earned: np.ndarray) -> None:
        """Add the kernel of days starting at the next ``n`` (see [`day_kernel`][heartpole.optimum.days.day_kernel])."""
        if self._days is not None and all(np.array_equal(a, b) for a, b in zip(self._days, (lengths, earned))):
            self._rows.append(self._rows[-1])  # the same days as the last n: the same kernel
            return
        self._days = (lengths.copy(), earned.copy())
        kernel = day_kernel(lengths, earned)
        last = self._last
        if last is None or not all(np.array_equal(a, b) for a, b in zip(kernel, last)):
            self._lengths.extend(kernel[0].tolist())
            self._probs.extend(kernel[1].tolist())
            self._earned.extend(kernel[2].tolist())
            self._starts.append(len(self._lengths))
            self._last = kernel
        self._rows.append(len(self._starts) - 2)

    def close(self, first_lengths: np.ndarray, first_earned: np.ndarray) -> DayKernels:
        """Freeze the kernels, with the episode's first day (``t = 0``, at the episode's ``n``)."""
        self.first = day_kernel(first_lengths, first_earned)
        self.lengths = np.frombuffer(self._lengths, dtype=np.int64).copy()
        self.probs = np.frombuffer(self._probs, dtype=np.float64).copy()
        self.earned = np.frombuffer(self._earned, dtype=np.float64).copy()
        self.starts = np.frombuffer(self._starts, dtype=np.int64).copy()
        self.rows = np.frombuffer(self._rows, dtype=np.int64).copy()
        return self

    def kernel(self, n: int) -> Kernel:
        """The kernel of days starting after a sleep with ``n`` decisions left."""
        k = int(self.rows[min(n, self.stored)])
        part = slice(int(self.starts[k]), int(self.starts[k + 1]))
        return self.lengths[part], self.probs[part], self.earned[part]

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, Kernel]:
        """The frozen kernels as `_episode_sums` takes them."""
        if self.first is None:
            raise ValueError("close the DayKernels before using them")
        return self.lengths, self.probs, self.earned, self.starts, self.rows, self.first


@dataclass(frozen=True)
class EpisodeOutcome:
    """Expectations over a policy's episodes: ``E[work / time]`` (the score), sleeps, work and time."""

    score: float
    sleeps: float
    work: float
    time: float


def episode_outcome(days: DayKernels, steps: int, sleep_time: int) -> EpisodeOutcome:
    """``E[work / time]``, sleeps, work and time of the episodes of ``steps`` decisions that ``days`` make.

    Raises:
        RuntimeError: if the days lose probability (a kernel that does not sum to one).
    """
    lengths, probs, earned, starts, rows, (first_lengths, first_probs, first_earned) = days.arrays()
    nodes, weights = time_rule(1.0 + sleep_time)  # tau = T / steps lies in [1, 1 + sleep_time]
    tilts = np.concatenate([[1.0], np.exp(-nodes * sleep_time / steps)])  # the first: plain expectations
    kernels = (lengths, probs, earned, starts, rows, first_lengths, first_probs, first_earned)
    ends = np.asarray(_episode_sums(*kernels, steps, tilts))
    if abs(ends[0, 0] - 1.0) > 1e-9:
        raise RuntimeError(f"the days' probabilities sum to {ends[0, 0]}, not 1")
    work, sleeps = float(ends[1, 0]), float(ends[2, 0])
    # E[W / T] = E[W / tau] / steps, and exp(-u tau) = exp(-u) * exp(-u sleep_time / steps) ** K
    score = float(np.sum(weights * np.exp(-nodes) * ends[1, 1:])) / steps
    return EpisodeOutcome(score, sleeps, work, steps + sleep_time * sleeps)


def time_rule(longest: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes ``u`` and weights of a rule for ``1 / tau = integral of exp(-u tau) du`` over ``u > 0``, for every
    ``tau`` in ``[1, longest]``: the trapezoid rule after ``u = exp(t - exp(-t))``, under which the integrand
    falls double-exponentially at both ends. Relative error below 1e-14 up to ``longest = 10,000`` (69 nodes
    up to 30); the step shrinks slowly with ``longest``, as the theory of the rule wants.
    """
    step = min(0.125, 0.4 / math.log(longest + 1.0))
    t = np.arange(-4.5, math.log(45.0) + 0.25, step)
    u = np.exp(t - np.exp(-t))
    return u, step * u * (1.0 + np.exp(-t))


@njit(cache=CACHE, nogil=True)  # the kernel's choice: on disk where numba can write
def _episode_sums(
    lengths: Any,
    probs: Any,
    earned: Any,
    starts: Any,
    rows: Any,
    first_lengths: Any,
    first_probs: Any,
    first_earned: Any,
    steps: int,
    tilts: Any,
) -> Any:
    """``[E[r ** K], E[W r ** K], E[K r ** K]]`` at the episode's end for each ``r`` in ``tilts``, shape
    ``(3, len(tilts))``, by one pass over the day starts from ``n = steps`` down (see the module docstring);
    a ring of the next ``longest day + 2`` starts holds the sums of the days starting there."""
    nodes = len(tilts)
    depth = max(lengths.max(), first_lengths.max()) + 2
    ring = np.zeros((depth, 3, nodes))  # per day start: E[r ** K], E[W so far r ** K], E[K r ** K]
    ends = np.zeros((3, nodes))
    here = np.zeros((3, nodes))
    stored = len(rows) - 1
    for n in range(steps, -1, -1):
        slot = n % depth
        if n == steps:  # the episode's first day, at t = 0, with no sleep so far
            day_lengths, day_probs, day_earned = first_lengths, first_probs, first_earned
            here[0, :], here[1, :], here[2, :] = 1.0, 0.0, 0.0
        else:
            k = rows[min(n, stored)]
            part = slice(starts[k], starts[k + 1])
            day_lengths, day_probs, day_earned = lengths[part], probs[part], earned[part]
            here[:, :] = ring[slot]
            if here[0].max() == 0.0:
                continue
        ring[slot] = 0.0
        for j in range(len(day_lengths)):
            share, work = day_probs[j], day_earned[j]
            left = n - day_lengths[j]
            if left == 0:  # the episode ends with this day
                for i in range(nodes):
                    ends[0, i] += here[0, i] * share
                    ends[1, i] += here[1, i] * share + here[0, i] * work
                    ends[2, i] += here[2, i] * share
            else:  # decision ``left`` sleeps; the next day starts with ``left - 1`` decisions left, K + 1
                target = ring[(left - 1) % depth]
                for i in range(nodes):
                    tilt = tilts[i]
                    target[0, i] += here[0, i] * share * tilt
                    target[1, i] += (here[1, i] * share + here[0, i] * work) * tilt
                    target[2, i] += (here[2, i] + here[0, i]) * share * tilt
    return ends
