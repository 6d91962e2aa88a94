"""Files written whole or not at all, and the signals that end a ``heartpole`` command.

Everything HeartPole writes goes through this module, so that an error, Ctrl-C, or the SIGTERM or SIGHUP
of a process manager, a scheduler or a closed terminal never leaves half a file or half a folder behind,
and never costs what was there before:

* [`atomic_files`][heartpole.files.atomic_files] (and [`atomic_write`][heartpole.files.atomic_write],
  [`write_text`][heartpole.files.write_text], [`write_json`][heartpole.files.write_json]): each file is written under a
  hidden temporary name in its own folder and moved into place with ``os.replace`` once all of them are complete.
* [`staged_folder`][heartpole.files.staged_folder]: a whole folder is built in a hidden sibling and moved into place at
  the end; a folder already there is replaced only then. [`scratch_folder`][heartpole.files.scratch_folder] and
  [`replace_folder`][heartpole.files.replace_folder] are its two halves, for writers that must be pointed at a folder of
  their own (Minari).
* [`folder_in_place`][heartpole.files.folder_in_place]: work that saves its own progress in its output folder (a Ray
  Tune search, to resume) runs there, with any earlier folder kept aside until the work is done.
* [`signal_policy`][heartpole.files.signal_policy]: the ``heartpole`` command's handlers. SIGINT, SIGTERM and SIGHUP
  raise [`Interrupted`][heartpole.files.Interrupted] (a ``KeyboardInterrupt``) in the main thread, so ``finally`` blocks
  and context managers clean up, and the command exits with [`exit_code`][heartpole.files.exit_code]: 128 + the signal's
  number. A C extension's initialisation is never cut by them: it runs with signals deferred (an interrupted one
  fails with ``ImportError`` and can crash the interpreter at exit; matplotlib's ``ft2font`` did).
* [`signals_deferred`][heartpole.files.signals_deferred]: moves into place and cleanups run to their end; a signal that
  arrives meanwhile takes effect right after.

An ``OSError`` from a write (a full disk, a read-only file system) names the file or folder being written,
never the temporary name it was written under; what is moved into place is noted for
[`heartpole.paths.outputs_placed`][heartpole.paths.outputs_placed], and [`heartpole.paths`][heartpole.paths] checks
before the work that an output can be written at all.

Files and folders get the modes the umask gives, as ``open`` and ``mkdir`` would. This module imports
only [`heartpole.paths`][heartpole.paths] from HeartPole.
"""

from __future__ import annotations

import _thread
import importlib.abc
import importlib.machinery
import json
import os
import shutil
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from types import FrameType
from typing import Any, TypeAlias

from heartpole.paths import naming_target, note_placed

PathLike: TypeAlias = "str | os.PathLike[str]"

SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)
"""The signals that end a command cleanly: Ctrl-C, a process manager's stop, a closed terminal."""

_received: list[int] = []  # the first signal to arrive under the policy, for the exit code
_arrivals: list[int] = []  # the read end of the policy's wakeup pipe: every signal's number, as it arrives


class Interrupted(KeyboardInterrupt):
    """A signal that ends the command, raised in the main thread wherever it was (see
    [`signal_policy`][heartpole.files.signal_policy]).

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
    """``handler`` for each of [`SIGNALS`][heartpole.files.SIGNALS] while the block runs (main thread only), then the
    previous ones."""
    with signal_handlers_kept():
        for s in SIGNALS if _main_thread() else ():
            if signal.getsignal(s) not in (None, signal.SIG_IGN):  # ignored stays ignored (nohup); None: not Python's
                signal.signal(s, handler)
        yield


@contextmanager
def signal_policy() -> Iterator[None]:
    """While the block runs, SIGINT, SIGTERM and SIGHUP raise [`Interrupted`][heartpole.files.Interrupted] in the main
    thread.

    The ``heartpole`` command runs inside this: every ``finally`` and context manager on the way out runs
    (staging folders and temporary files are removed, Ray is shut down), then the command exits with
    [`exit_code`][heartpole.files.exit_code] of the first signal to arrive (signals that reach a process together,
    before it runs again, arrive as the system delivers them: SIGHUP, SIGINT, SIGTERM). The handlers from before are
    restored at the end; ignored signals stay ignored. An [`Interrupted`][heartpole.files.Interrupted] raised where
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
    """An unraisable hook that delivers again a signal whose [`Interrupted`][heartpole.files.Interrupted] was raised
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
    """The first signal [`signal_policy`][heartpole.files.signal_policy] received, or ``None``."""
    return _received[0] if _received else None


def exit_code() -> int:
    """128 + the number of the first signal received: 130 (SIGINT, also when none was recorded, as for a
    ``KeyboardInterrupt`` raised by code), 143 (SIGTERM), 129 (SIGHUP)."""
    return 128 + (received_signal() or signal.SIGINT)


def interruption() -> Interrupted:
    """For a library that stopped gracefully on a signal: [`Interrupted`][heartpole.files.Interrupted] of the first
    one received (SIGINT if none was recorded)."""
    return Interrupted(received_signal() or signal.SIGINT)


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP until the block is done, then deliver the first one that came.

    For the steps that must not stop halfway: moving files into place, removing a staging folder, shutting
    down Ray. The signal then does what it would have done (with [`signal_policy`][heartpole.files.signal_policy]: raise
    [`Interrupted`][heartpole.files.Interrupted]; without, Python's defaults: ``KeyboardInterrupt``, or the end of
    the process). Only in the main thread (signals are handled there); elsewhere the block just runs."""
    pending: list[int] = []

    def hold(signum: int, frame: FrameType | None) -> None:
        pending.append(signum)

    try:
        with _handlers(hold):
            yield
    finally:
        if pending:  # even when the block raised: the signal is never lost
            signal.raise_signal(pending[0])


@contextmanager
def signals_as_ctrl_c() -> Iterator[None]:
    """While the block runs, SIGTERM and SIGHUP do what Ctrl-C does, for libraries that stop gracefully on
    SIGINT only (Ray Tune stops its trials and saves its state); the signal is noted for
    [`exit_code`][heartpole.files.exit_code].

    Applies only under [`signal_policy`][heartpole.files.signal_policy], and once: a second signal, or one while no
    library handles SIGINT, raises [`Interrupted`][heartpole.files.Interrupted] as usual. All three handlers are
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


# ------------------------------------------------------------------------------------------------------
# files


def umask() -> int:
    """The process's umask (read without changing it for longer than the call)."""
    current = os.umask(0)
    os.umask(current)
    return current


def _make_folder(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; return those created, deepest first."""
    missing = [p for p in [folder, *folder.parents] if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    return missing


def _remove_if_empty(folders: list[Path]) -> None:
    for folder in sorted(set(folders), key=lambda p: len(p.parts), reverse=True):
        try:
            folder.rmdir()
        except OSError:
            pass  # not empty (or gone): kept


def _temporary_file(target: Path) -> Path:
    """A new empty hidden file beside ``target``, named after it; its suffix kept for writers that go by it."""
    handle, name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=target.suffix)
    os.close(handle)
    return Path(name)


@contextmanager
def atomic_files(*paths: PathLike) -> Iterator[list[Path]]:
    """Yield a temporary path to write for each of ``paths``; when the block succeeds, move each into place.

    Each temporary file is hidden (``.NAME.XXXXXXXX.SUFFIX``) in its target's folder, so that moving it is
    one ``os.replace``. The moves run with signals deferred: the targets are replaced all together or not
    at all (barring a crash or a full disk between two renames). Missing folders are created; if the block
    fails or is interrupted (``KeyboardInterrupt`` and ``SystemExit`` included), the temporary files and
    the folders this call created are removed, and the targets are as they were. An ``OSError`` about a
    temporary file (a full disk, a read-only file system) is raised again about its target.
    """
    targets = [Path(p) for p in paths]
    created: list[Path] = []
    temporaries: list[Path] = []
    try:
        with signals_deferred():
            for target in targets:
                created += _make_folder(target.parent)
                temporaries.append(_temporary_file(target))
        yield temporaries
        with signals_deferred():
            for temporary, target in zip(temporaries, targets):
                os.chmod(temporary, 0o666 & ~umask())  # mkstemp makes files private; give the usual mode
                os.replace(temporary, target)
            note_placed(*targets)
    except BaseException as error:
        with signals_deferred():
            for temporary in temporaries:
                temporary.unlink(missing_ok=True)
            _remove_if_empty(created)
        if isinstance(error, OSError):
            raise naming_target(error, targets, temporaries) from error
        raise


def atomic_write(path: PathLike, write: Callable[[Path], object]) -> Path:
    """Call ``write(temporary_path)``, then move the file into place at ``path`` (see
    [`atomic_files`][heartpole.files.atomic_files])."""
    with atomic_files(path) as (temporary,):
        write(temporary)
    return Path(path)


def write_text(path: PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return atomic_write(path, lambda temporary: temporary.write_text(text))


def json_text(data: object) -> str:
    """``data`` as the JSON every HeartPole file holds: indented, a final newline, no NaN or infinity
    (``ValueError``: strict JSON readers refuse them)."""
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def write_json(path: PathLike, data: object) -> Path:
    """Write ``data`` to ``path`` atomically as [`json_text`][heartpole.files.json_text]."""
    return write_text(path, json_text(data))


# ------------------------------------------------------------------------------------------------------
# folders


@contextmanager
def scratch_folder(parent: PathLike, name: str) -> Iterator[Path]:
    """A new hidden folder ``.NAME.XXXXXXXX.partial`` in ``parent`` (created if missing), removed with all it
    holds when the block ends, however it ends; missing parents it created are removed if left empty."""
    created: list[Path] = []
    scratch: Path | None = None
    try:
        with signals_deferred():
            created = _make_folder(Path(parent))
            scratch = Path(tempfile.mkdtemp(prefix=f".{name}.", suffix=".partial", dir=parent))
        os.chmod(scratch, 0o777 & ~umask())  # mkdtemp makes folders private; give the usual mode
        yield scratch
    finally:
        with signals_deferred():
            if scratch is not None:
                shutil.rmtree(scratch, ignore_errors=True)
            _remove_if_empty(created)


def replace_folder(new: PathLike, target: PathLike) -> None:
    """Move the folder ``new`` to ``target``, replacing any folder there, with signals deferred.

    An earlier ``target`` is first moved into a hidden sibling (``.NAME.XXXXXXXX.old``), then deleted once
    ``new`` is in place; if the move fails, it is put back, and the hidden sibling is removed whatever failed.
    An ``OSError`` names ``target``. [`heartpole.paths.check_writable`][heartpole.paths.check_writable] refuses,
    before any work, the targets that cannot be replaced (a mount point).
    """
    new, target = Path(new), Path(target)
    with signals_deferred():
        try:
            if not target.exists():
                os.replace(new, target)
                note_placed(target)
                return
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
            try:
                os.replace(target, old / target.name)  # a mount point: EBUSY, and the hidden folder goes
                try:
                    os.replace(new, target)
                except BaseException:
                    os.replace(old / target.name, target)
                    raise
            finally:
                shutil.rmtree(old, ignore_errors=True)
            note_placed(target)
        except OSError as error:
            if error.errno is None:
                raise
            raise naming_target(error, [target], []) from error


@contextmanager
def staged_folder(target: PathLike) -> Iterator[Path]:
    """Yield an empty hidden sibling of ``target`` to fill; when the block succeeds, it becomes ``target``.

    A folder already at ``target`` is replaced only then ([`replace_folder`][heartpole.files.replace_folder]). If the
    block fails or is interrupted, the staging folder is removed, with any missing parents this call created, and
    ``target`` is as it was."""
    target = Path(target)
    with scratch_folder(target.parent, target.name) as stage:
        yield stage
        replace_folder(stage, target)


@contextmanager
def folder_in_place(target: PathLike, keep: Callable[[Path], bool]) -> Iterator[Path]:
    """Yield ``target`` (created if missing) to work in directly, for work that saves progress there to resume.

    A non-empty folder already at ``target`` is moved into a hidden sibling first, and deleted when the
    block succeeds. If the block fails or is interrupted: an earlier folder is put back (the new work is
    removed); with none, the new work stays only if ``keep(target)`` says it can be resumed, and is
    otherwise removed (``target`` too if this call created it, and missing parents it created).
    """
    target = Path(target)
    created: list[Path] = []
    old: Path | None = None
    try:
        with signals_deferred():
            created = _make_folder(target.parent)
            if target.is_dir() and any(target.iterdir()):
                old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
                os.replace(target, old / target.name)
            if not target.exists():
                target.mkdir()
                created.append(target)
        yield target
    except BaseException:
        with signals_deferred():
            if old is not None or not keep(target):
                _empty(target)
                if old is not None:
                    os.replace(old / target.name, target)
                _remove_if_empty(created)
        raise
    else:
        note_placed(target)
    finally:
        if old is not None:
            with signals_deferred():
                shutil.rmtree(old, ignore_errors=True)


def _empty(folder: Path) -> None:
    for path in folder.iterdir() if folder.is_dir() else ():
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


__all__ = [
    "SIGNALS",
    "Interrupted",
    "atomic_files",
    "atomic_write",
    "exit_code",
    "folder_in_place",
    "interruption",
    "json_text",
    "received_signal",
    "replace_folder",
    "scratch_folder",
    "signal_handlers_kept",
    "signal_policy",
    "signals_as_ctrl_c",
    "signals_deferred",
    "staged_folder",
    "umask",
    "write_json",
    "write_text",
]
