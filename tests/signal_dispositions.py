"""The signal dispositions that the tests sending SIGINT, SIGTERM or SIGHUP rely on, set by the tests themselves.

A test run inherits its dispositions from whatever started it: ``nohup`` starts it with SIGHUP ignored, a background
job of a non-interactive shell with SIGINT ignored, and an ignored signal stays ignored in every child (the
``heartpole`` command keeps an inherited SIG_IGN on purpose). A test that expects a signal to end a command sets the
terminal's dispositions where it sends it: `as_in_a_terminal` for a child (``preexec_fn``), the
``terminal_signals`` fixture (tests/conftest.py) for the test process itself.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from pathlib import Path

SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
"""The signals that end a ``heartpole`` command."""


def as_in_a_terminal() -> None:
    """A child's ``preexec_fn``: SIGINT, SIGTERM and SIGHUP at their defaults and unblocked, as in a terminal."""
    for signum in SIGNALS:
        signal.signal(signum, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)


def ignoring(signum: int) -> Callable[[], None]:
    """A child's ``preexec_fn``: as in a terminal, but ``signum`` ignored, as ``nohup`` (SIGHUP) or a background job
    (SIGINT) starts a command."""

    def preexec() -> None:
        as_in_a_terminal()
        signal.signal(signum, signal.SIG_IGN)

    return preexec


def pending(pid: int) -> int:
    """The signals the kernel holds for ``pid``, not yet handed to it (a bit mask; 0 without /proc)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text().splitlines()
    except OSError:
        return 0
    return sum(int(line.split()[1], 16) for line in status if line.startswith(("ShdPnd:", "SigPnd:")))
