"""The arrays the vector env's compiled loop reads and writes: placed apart in the caches, and a step's taken back
when nobody holds them.

**Placed apart** ([`staggered`][heartpole.arrays.staggered]). The loop over envs reads and writes about twenty
rows of memory side by side (the states' variables, the generator states, each result, the observations) at
the same index. The C library hands out large blocks at the same offset from a 4,096-byte boundary, and rows of
16,384 float32 are 64 kB apart, so every row's ``i``-th value fell into the same set of the L1 cache (64 sets of
64 bytes, 8 ways): more rows than ways, and the cache evicted at every step of the loop. Carved from one block
at offsets chosen a few cache lines apart, each array's rows fall into a set of their own (what it earns:
docs/speed.md).

**Taken back** ([`Recycler`][heartpole.arrays.Recycler]). A step returns new arrays (its observations, rewards
and ``info`` values), as Gymnasium's vector envs do: the caller owns them. Most callers drop them before long
(they copy what they keep). Allocating them anew at every step costs more than writing them: at large sizes the
C library hands the freed blocks back to the system and every step faults their pages in again (docs/speed.md
counts them), and a new block may lie outside the caches. The recycler reuses an earlier step's
arrays where the only references left to them are its own, as NumPy itself reuses a temporary whose reference
count says nobody else can see it. A caller that keeps any of them, a view of one (a view holds the block it
was carved from), a memoryview or a tensor sharing its memory keeps them all as they are: the step then makes
new ones.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from heartpole import kernel

LINE, PAGE = 64, 4096
"""A cache line and the span of the L1 cache's sets (64 sets of a line), in bytes."""
SLOTS = {"states": 0, "generators": 7, "cells": 14, "observations": 21, "results": 28}
"""Where each of the loop's arrays starts, in cache lines past a `PAGE` boundary (its rows, for 16,384 envs,
all in that set); the results' arrays follow one another `SPACING` lines apart."""
SPACING = 7
"""Lines between one array and the next among those `staggered` carves at once."""


def staggered(specs: Sequence[tuple[tuple[int, ...], Any]], first: int) -> list[np.ndarray]:
    """New C-contiguous arrays of ``specs`` (``(shape, dtype)`` each), carved from one block of memory (their base:
    a view of one of them holds it too), array ``k`` starting ``first + k * SPACING`` cache lines (modulo a
    `PAGE`) past a `PAGE` boundary."""
    counts = [math.prod(shape) for shape, _ in specs]
    sizes = [count * np.dtype(dtype).itemsize for count, (_, dtype) in zip(counts, specs)]
    shares = [-(-size // PAGE) * PAGE + PAGE for size in sizes]  # each array's room: a page more than its size
    block = np.empty(sum(shares) + PAGE, dtype=np.uint8)  # and a page to reach the first boundary
    start = -block.ctypes.data % PAGE  # the first boundary (``ctypes`` costs a microsecond: once a block)
    arrays = []
    for k, ((shape, dtype), count, share) in enumerate(zip(specs, counts, shares)):
        array = np.frombuffer(block, dtype, count, start + (first + k * SPACING) * LINE % PAGE)
        arrays.append(array if len(shape) == 1 else array.reshape(shape))
        start += share
    return arrays


def placed(array: np.ndarray, slot: str) -> np.ndarray:
    """A C-contiguous copy of ``array`` starting at `SLOTS`' ``slot`` (``"states"``, ``"generators"``, ``"cells"``)."""
    copy = staggered([(array.shape, array.dtype)], SLOTS[slot])[0]
    copy[...] = array
    return copy


def new_results(count: int, num_variables: int) -> kernel.StepResults:
    """Fresh arrays for [`step_envs`][heartpole.kernel.step_envs]'s [`StepResults`][heartpole.kernel.StepResults]
    of ``count`` envs: its [`OUTPUTS`][heartpole.kernel.OUTPUTS], the loop's copy of the new states (the
    observations), ``(num_variables, count)`` float32, and the actions as
    [`ACTION_DTYPE`][heartpole.kernel.ACTION_DTYPE]."""
    vectors = [((count,), dtype) for dtype in (*kernel.OUTPUTS.values(), kernel.ACTION_DTYPE)]
    reward, productivity, risk, attack, score, actions = staggered(vectors, SLOTS["results"])
    (observations,) = staggered([((num_variables, count), np.float32)], SLOTS["observations"])
    # two blocks: a caller who keeps the observations keeps no more
    return kernel.StepResults(reward, productivity, risk, attack, score, observations, actions)


COUNTED = sys.implementation.name == "cpython" and getattr(sys, "_is_gil_enabled", lambda: True)()
"""Whether reference counts say who holds an array: on CPython with its GIL. Elsewhere (PyPy, a free-threaded
build, whose counts are deferred and split between threads) a [`Recycler`][heartpole.arrays.Recycler] never
reuses arrays."""


def _counts(held: list[Any]) -> tuple[int, ...]:
    """The reference counts of ``held``, as this very code sees them (its own references included)."""
    return tuple(map(sys.getrefcount, held))


class Recycler:
    """The tuple of arrays ``make()`` gives, new for a step, or an earlier step's (the very tuple) where only this
    recycler still holds it and its arrays (it checks the blocks they were carved from too: a view of one holds
    its block, not the array).

    It keeps the arrays of the last ``keep`` steps: a caller's loop (``obs, reward, ... = env.step(actions)``)
    still holds the last step's while it makes the next, so with two kept, the step before that's come back;
    a caller that drops them at once gets the same arrays back at every step.
    The reference counts of arrays held by nothing but the recycler are measured on its first arrays, before
    anyone saw them, by the same code that checks the others: what the interpreter itself adds to the counts is
    the same in both, on any CPython version.
    """

    def __init__(self, make: Callable[[], tuple[np.ndarray, ...]], keep: int = 2) -> None:
        self._make, self._keep = make, keep
        self._kept: list[list[Any]] = []  # oldest first: each a tuple ``make()`` gave, its arrays, their blocks
        self._alone: tuple[int, ...] = ()

    def __call__(self) -> Any:
        """The arrays for this step: an earlier step's tuple if nobody else holds it or any of its arrays, else a
        new one. Handing back the very tuple, not a new one, costs nothing; whoever holds it holds its arrays."""
        kept = self._kept
        newest = len(kept) - 1 if COUNTED else -1  # the newest first: the likeliest to be in the caches still
        for index in range(newest, -1, -1):
            if _counts(kept[index]) == self._alone:
                kept.append(kept.pop(index))
                return kept[-1][0]
        held: list[Any] = [self._make()]
        held += held[0]
        held += {id(a.base): a.base for a in held[1:] if isinstance(a.base, np.ndarray)}.values()  # their blocks
        kept.append(held)
        if len(kept) > self._keep:
            del kept[0]
        if not self._alone:  # the first arrays, before anyone saw them: held here alone
            self._alone = _counts(held)
        return held[0]

    def __getstate__(self) -> dict[str, object]:
        """A pickle or copy keeps how to make the arrays, not the arrays (nor counts, which another Python may
        count otherwise)."""
        return {"_make": self._make, "_keep": self._keep}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a pickled or copied recycler, with no arrays kept."""
        self.__init__(state["_make"], state["_keep"])  # type: ignore[misc]
