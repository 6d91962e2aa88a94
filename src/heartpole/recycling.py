"""Arrays that a step hands out fresh, taken back for the next step once nobody else holds them.

A vector env's step returns new arrays (its observations, rewards and ``info`` values), as Gymnasium's vector envs
do: the caller owns them. Most callers drop them before the next step (they copy what they keep). Allocating
them anew at every step costs more than writing them: at 65,536 envs the C library hands the freed blocks back
to the system and every step faults its pages in again (several hundred page faults a step), and at any size a
new block may lie outside the caches. [`Recycler`][heartpole.recycling.Recycler] reuses the last step's arrays
where the only references left to them are its own, as NumPy itself reuses a temporary whose reference count
says nobody else can see it. A caller that keeps any of them, or a view of one (a view holds its base), a
memoryview or a tensor sharing its memory, keeps them all as they are: the step then makes new ones.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import numpy as np


def _counts(arrays: list[np.ndarray]) -> tuple[int, ...]:
    """The reference counts of ``arrays``, as this very code sees them (its own references included)."""
    return tuple(sys.getrefcount(array) for array in arrays)


class Recycler:
    """Fresh arrays from ``make()`` for each step, or those of an earlier step that only this recycler still holds.

    It keeps the arrays of the last ``keep`` steps: a caller's loop (``obs, reward, ... = env.step(actions)``)
    still holds the last step's while it makes the next, so with two kept, the step before that's come back.
    The reference counts of arrays held by nothing but the recycler are measured on its first arrays, before
    anyone saw them, by the same code that checks the others: what the interpreter itself adds to the counts is
    the same in both, on any CPython version.
    """

    def __init__(self, make: Callable[[], tuple[np.ndarray, ...]], keep: int = 2) -> None:
        self._make, self._keep = make, keep
        self._kept: list[list[np.ndarray]] = []  # oldest first
        self._alone: tuple[int, ...] = ()

    def __call__(self) -> tuple[np.ndarray, ...]:
        """Arrays for this step: an earlier step's if nobody else holds any of them, else new ones."""
        kept = self._kept
        for index, arrays in enumerate(kept):
            if _counts(arrays) == self._alone:
                kept.append(kept.pop(index))
                return tuple(arrays)  # a new tuple each time: whoever holds it holds the arrays
        arrays = list(self._make())
        kept.append(arrays)
        if len(kept) > self._keep:
            del kept[0]
        if not self._alone:  # the first arrays, before anyone saw them: held here alone
            self._alone = _counts(arrays)
        return tuple(arrays)

    def __getstate__(self) -> dict[str, object]:
        """A pickle or copy keeps how to make the arrays, not the arrays (nor counts, which another Python may
        count otherwise)."""
        return {"_make": self._make, "_keep": self._keep}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a pickled or copied recycler, with no arrays kept."""
        self.__init__(state["_make"], state["_keep"])  # type: ignore[misc]
