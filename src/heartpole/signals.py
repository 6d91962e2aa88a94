"""The signals that end a ``heartpole`` command, and how a command takes them.

* [`signal_policy`][heartpole.signals.signal_policy]: the ``heartpole`` command's handlers. SIGINT, SIGTERM and SIGHUP
  raise [`Interrupted`][heartpole.signals.Interrupted] (a ``KeyboardInterrupt``) in the main thread, so ``finally``
  blocks and context managers clean up, and the command exits with [`exit_code`][heartpole.signals.exit_code]: 128 +
  the number of the first signal to arrive. A C extension's initialisation is never cut by them: it runs with
  signals deferred (an interrupted one fails with ``ImportError`` and can crash the interpreter at exit;
  matplotlib's ``ft2font`` did).
* [`signals_deferred`][heartpole.signals.signals_deferred]: moves into place and cleanups run to their end; a signal
  that arrives meanwhile takes effect right after.
* [`interruptible`][heartpole.signals.interruptible]: long compiled work (numba's ``nogil`` loops) runs in a worker
  thread while the main thread waits, so a signal takes effect within a fraction of a second.

[`heartpole.files`][heartpole.files], the one writer, uses them (and exports them, as it always has).
"""

from __future__ import annotations

import _thread
import importlib.abc
import importlib.machinery
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from types import FrameType
from typing import Any, TypeVar

T = TypeVar("T")

SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)
"""The signals that end a command cleanly: Ctrl-C, a process manager's stop, a closed terminal."""

_received: list[int] = []  # the first signal to arrive under the policy, for the exit code
_arrivals: list[int] = []  # the read end of the policy's wakeup pipe: every signal's number, as it arrives


class Interrupted(KeyboardInterrupt):
    """A signal that ends the command, raised in the main thread wherever it was (see
    [`signal_policy`][heartpole.signals.signal_policy]).

    A ``KeyboardInterrupt``, so that whatever cleans up after Ctrl-C cleans up after SIGTERM and SIGHUP too.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


# ------------------------------------------------------------------------------------------------------
# signals


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _note(signum: int) -> None:
    """Record the first signal to arrive: Python runs the handlers of those that came since it last looked in the order
    of their numbers (SIGHUP first), the wakeup pipe holds them in the order they came."""
    if not _received:
        try:
            arrived = os.read(_arrivals[0], 4096) if _arrivals else b""
        except BlockingIOError:  # an empty pipe
            arrived = b""
        _received.append(next((n for n in arrived if n in SIGNALS), signum))


def _raise(signum: int, frame: FrameType | None) -> None:
    _note(signum)
    raise Interrupted(signum)


def _forget_arrivals() -> None:  # after a fork, in the child: its signals are never written into the parent's pipe
    if _arrivals:
        _arrivals.clear()
        signal.set_wakeup_fd(-1)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_arrivals)


@contextmanager
def signal_handlers_kept() -> Iterator[None]:
    """Put back the handlers of SIGINT, SIGTERM and SIGHUP when the block ends, for libraries that install
    their own (``ray.init`` makes SIGTERM exit with status 1 at once)."""
    if not _main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            if handler is not None:  # None: installed outside Python, cannot be put back
                signal.signal(s, handler)


@contextmanager
def _handlers(handler: Callable[[int, FrameType | None], Any]) -> Iterator[None]:
    """``handler`` for each of [`SIGNALS`][heartpole.signals.SIGNALS] while the block runs (main thread only), then the
    previous ones."""
    with signal_handlers_kept():
        for s in SIGNALS if _main_thread() else ():
            if signal.getsignal(s) not in (None, signal.SIG_IGN):  # ignored stays ignored (nohup); None: not Python's
                signal.signal(s, handler)
        yield


@contextmanager
def signal_policy() -> Iterator[None]:
    """While the block runs, SIGINT, SIGTERM and SIGHUP raise [`Interrupted`][heartpole.signals.Interrupted] in the main
    thread.

    The ``heartpole`` command runs inside this: every ``finally`` and context manager on the way out runs
    (staging folders and temporary files are removed, Ray is shut down), then the command exits with
    [`exit_code`][heartpole.signals.exit_code] of the first signal to arrive (signals that reach a process together,
    before it runs again, arrive as the system delivers them: SIGHUP, SIGINT, SIGTERM). The handlers from before are
    restored at the end; ignored signals stay ignored. An [`Interrupted`][heartpole.signals.Interrupted] raised where
    Python ignores exceptions (a ``__del__``) is delivered again."""
    _received.clear()
    hook = sys.unraisablehook
    sys.unraisablehook = _redeliver(hook)
    finder = _WholeExtensions()
    sys.meta_path.insert(0, finder)
    read, write = os.pipe()  # the wakeup pipe of `_note`, in the main thread, unless another is set
    try:
        for fd in (read, write):
            os.set_blocking(fd, False)
        if _main_thread() and (previous := signal.set_wakeup_fd(write, warn_on_full_buffer=False)) != -1:
            signal.set_wakeup_fd(previous)  # another's (an asyncio loop's): it stays
        elif _main_thread():
            _arrivals[:] = [read]
        with _handlers(_raise):
            yield
    finally:
        if _arrivals == [read]:
            _arrivals.clear()
            signal.set_wakeup_fd(-1)
        os.close(read)
        os.close(write)
        sys.meta_path.remove(finder)
        sys.unraisablehook = hook


class _WholeExtensionLoader(importlib.machinery.ExtensionFileLoader):
    """Python's loader of a C extension, initialising it with signals deferred: a signal handler that raises
    while an extension's init calls back into Python (pybind11's do) leaves it half made, ``ImportError:
    initialization failed``, and the interpreter may abort at exit ("Fatal Python error: PyThreadState_Get").
    A signal that came meanwhile is delivered once the module is made and initialised."""

    def create_module(self, spec: Any) -> Any:
        self._deferred = ExitStack()  # closed by exec_module, which Python's import calls next
        self._deferred.enter_context(signals_deferred())
        with ExitStack() as on_error:
            on_error.push(self._deferred)
            module = super().create_module(spec)
            on_error.pop_all()
        return module

    def exec_module(self, module: Any) -> None:
        with self._deferred:
            super().exec_module(module)


class _WholeExtensions(importlib.abc.MetaPathFinder):
    """A finder that finds nothing itself: it asks the finders after it and gives a C extension they find
    `_WholeExtensionLoader`."""

    def find_spec(self, name: str, path: Any, target: Any = None) -> Any:
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            if finder is self or find is None:
                continue
            spec = find(name, path, target)
            if spec is None:
                continue
            if type(spec.loader) is importlib.machinery.ExtensionFileLoader:
                spec.loader = _WholeExtensionLoader(spec.loader.name, spec.loader.path)
            return spec
        return None


def _redeliver(hook: Callable[[Any], object]) -> Callable[[Any], None]:
    """An unraisable hook that delivers again a signal whose [`Interrupted`][heartpole.signals.Interrupted] was raised
    where Python ignores exceptions (in a ``__del__`` or a weakref callback, where a signal handler may run), so that
    it is not lost. From another thread, a moment later: delivered at once, it would be raised in this hook,
    where it would be ignored again."""

    def unraisable(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, Interrupted):
            again = signal.Signals(unraisable.exc_value.signum)
            timer = threading.Timer(0.01, _thread.interrupt_main, (again,))
            timer.daemon = True
            timer.start()
        else:
            hook(unraisable)

    return unraisable


def received_signal() -> int | None:
    """The first signal [`signal_policy`][heartpole.signals.signal_policy] received, or ``None``."""
    return _received[0] if _received else None


def exit_code() -> int:
    """128 + the number of the first signal received: 130 (SIGINT, also when none was recorded, as for a
    ``KeyboardInterrupt`` raised by code), 143 (SIGTERM), 129 (SIGHUP)."""
    return 128 + (received_signal() or signal.SIGINT)


def interruption() -> Interrupted:
    """For a library that stopped gracefully on a signal: [`Interrupted`][heartpole.signals.Interrupted] of the first
    one received (SIGINT if none was recorded)."""
    return Interrupted(received_signal() or signal.SIGINT)


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP until the block is done, then deliver the first one that came.

    For the steps that must not stop halfway: moving files into place, removing a staging folder, shutting
    down Ray. The signal then does what it would have done (with
    [`signal_policy`][heartpole.signals.signal_policy]: raise [`Interrupted`][heartpole.signals.Interrupted];
    without, Python's defaults: ``KeyboardInterrupt``, or the end of the process). Only in the main thread
    (signals are handled there); elsewhere the block just runs."""
    pending: list[int] = []

    def hold(signum: int, frame: FrameType | None) -> None:
        pending.append(signum)

    try:
        with _handlers(hold):
            yield
    finally:
        if pending:  # even when the block raised: the signal is never lost
            signal.raise_signal(pending[0])


def interruptible(call: Callable[[], T], poll: float = 0.05) -> T:
    """``call()``, run in a worker thread while the main thread waits for it: its result, or its exception.

    Python runs signal handlers in the main thread between bytecodes, so a long call into compiled code (a
    numba loop over a billion decisions) would hold back SIGINT, SIGTERM and SIGHUP until it returns, minutes or
    hours later. Waiting here instead, the main thread handles a signal within ``poll`` seconds (under
    [`signal_policy`][heartpole.signals.signal_policy]: [`Interrupted`][heartpole.signals.Interrupted] is raised
    from this call) while the worker, a daemon thread, is abandoned: the process exits without waiting for it.
    ``call`` must leave nothing half done if abandoned (write its results, if at all, at its end, in place at
    once). Outside the main thread, ``call()`` runs in the calling thread.
    """
    if not _main_thread():
        return call()
    outcome: list[tuple[bool, Any]] = []

    def work() -> None:
        try:
            outcome.append((True, call()))
        except BaseException as error:  # noqa: BLE001 - handed to the waiting thread, which raises it
            outcome.append((False, error))

    worker = threading.Thread(target=work, name="heartpole-interruptible", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(poll)
    done, value = outcome[0]
    if not done:
        raise value
    return value


@contextmanager
def signals_as_ctrl_c() -> Iterator[None]:
    """While the block runs, SIGTERM and SIGHUP do what Ctrl-C does, for libraries that stop gracefully on
    SIGINT only (Ray Tune stops its trials and saves its state); the signal is noted for
    [`exit_code`][heartpole.signals.exit_code].

    Applies only under [`signal_policy`][heartpole.signals.signal_policy], and once: a second signal, or one while no
    library handles SIGINT, raises [`Interrupted`][heartpole.signals.Interrupted] as usual. All three handlers are
    restored afterwards, since such a library may leave its own SIGINT handler installed."""
    forwarded: list[int] = []

    def forward(signum: int, frame: FrameType | None) -> None:
        handler = signal.getsignal(signal.SIGINT)
        if forwarded or not callable(handler) or handler in (_raise, signal.default_int_handler):
            _raise(signum, frame)
        forwarded.append(signum)
        _note(signum)
        signal.raise_signal(signal.SIGINT)

    with signal_handlers_kept():
        for s in SIGNALS if _main_thread() else ():
            if s != signal.SIGINT and signal.getsignal(s) is _raise:
                signal.signal(s, forward)
        yield
