"""The one progress bar of HeartPole: a line on stderr for long runs of the library and of ``heartpole``.

Evaluation, training (Stable-Baselines3 and JAX), Ray runs and the commands all draw with
[`Progress`][heartpole.progress.Progress].
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from types import TracebackType
from typing import TextIO

FORCE_VARIABLE = "HEARTPOLE_PROGRESS"
"""Set to ``1`` to show progress bars where stderr is not a terminal."""


class Progress:
    """A one-line progress bar on stderr.

    Args:
        total: the amount of work (at least 1 is assumed).
        description: the bar's label.
        stream: where to draw (default stderr).
        enabled: ``None`` shows the bar when the stream is a terminal or ``HEARTPOLE_PROGRESS=1``; ``True``
            always, ``False`` never.
        unit: with a unit (``"step"``), the bar also shows the rate, e.g. ``12.3k step/s``.

    Also a context manager that closes the bar on leaving.
    """

    def __init__(
        self,
        total: int,
        description: str,
        stream: TextIO | None = None,
        *,
        enabled: bool | None = None,
        unit: str | None = None,
    ) -> None:
        self.total, self.description, self.done, self.unit = max(int(total), 1), description, 0, unit
        self.stream = stream or sys.stderr
        if enabled is None:
            enabled = os.environ.get(FORCE_VARIABLE) == "1" or bool(getattr(self.stream, "isatty", bool)())
        self.enabled = enabled
        self._start = self._last_draw = time.monotonic()

    def update(self, amount: int = 1) -> None:
        """Advance by ``amount`` (never past ``total``) and redraw at most ten times a second."""
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
        rate = f" {_si(self.done / elapsed if elapsed > 0 else 0.0)} {self.unit}/s" if self.unit else ""
        self.stream.write(f"\r{self.description} [{bar}] {100 * share:5.1f}% {elapsed:6.1f}s (eta {eta:5.1f}s){rate}")
        self.stream.flush()

    def clear(self) -> None:
        """Wipe the bar's line, for a line printed in between (the next update draws the bar again)."""
        if self.enabled:
            self.stream.write("\r\x1b[K")
            self.stream.flush()

    def close(self) -> None:
        """End the bar's line."""
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.close()


def _si(value: float) -> str:
    """``value`` with an SI suffix: ``950``, ``12.3k``, ``4.56M``."""
    for factor, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if value >= factor:
            return f"{value / factor:.3g}{suffix}"
    return f"{value:.3g}"


@contextmanager
def progress(total: int, description: str) -> Iterator[Progress]:
    """``with progress(total, "evaluating") as bar: bar.update(n)``."""
    bar = Progress(total, description)
    try:
        yield bar
    finally:
        bar.close()
