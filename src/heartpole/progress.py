"""A one-line progress bar on stderr, for long runs of the library and of the ``heartpole`` command."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO


class Progress:
    """A one-line progress bar on stderr, shown when stderr is a terminal (or HEARTPOLE_PROGRESS=1)."""

    def __init__(self, total: int, description: str, stream: TextIO | None = None) -> None:
        self.total, self.description, self.done = max(int(total), 1), description, 0
        self.stream = stream or sys.stderr
        self.enabled = os.environ.get("HEARTPOLE_PROGRESS") == "1" or bool(getattr(self.stream, "isatty", bool)())
        self._start = self._last_draw = time.monotonic()

    def update(self, amount: int = 1) -> None:
        """Advance by ``amount`` and redraw at most ten times a second."""
        self.done = min(self.done + amount, self.total)
        now = time.monotonic()
        if self.enabled and (now - self._last_draw >= 0.1 or self.done == self.total):
            self._last_draw = now
            self._draw(now)

    def _draw(self, now: float) -> None:
        share = self.done / self.total
        bar = "#" * int(30 * share) + "." * (30 - int(30 * share))
        elapsed = now - self._start
        eta = elapsed / share - elapsed if share > 0 else 0.0
        self.stream.write(f"\r{self.description} [{bar}] {100 * share:5.1f}% {elapsed:6.1f}s (eta {eta:5.1f}s)")
        self.stream.flush()

    def close(self) -> None:
        """End the bar's line."""
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()


@contextmanager
def progress(total: int, description: str) -> Iterator[Progress]:
    """``with progress(total, "evaluating") as bar: bar.update(n)``."""
    bar = Progress(total, description)
    try:
        yield bar
    finally:
        bar.close()
