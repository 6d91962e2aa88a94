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
  [`folder_lock`][heartpole.files.folder_lock] keeps a second process from writing the same folder meanwhile.
* [`signal_policy`][heartpole.signals.signal_policy] and [`signals_deferred`][heartpole.signals.signals_deferred]
  ([`heartpole.signals`][heartpole.signals], exported here too): the ``heartpole`` command's handlers, under which
  a signal unwinds through every cleanup; moves into place and cleanups run to their end.

An ``OSError`` from a write (a full disk, a read-only file system) names the file or folder being written,
never the temporary name it was written under; what is moved into place is noted for
[`heartpole.paths.outputs_placed`][heartpole.paths.outputs_placed], and [`heartpole.paths`][heartpole.paths] checks
before the work that an output can be written at all.

Files and folders get the modes the umask gives, as ``open`` and ``mkdir`` would. This module imports
only [`heartpole.paths`][heartpole.paths] and [`heartpole.signals`][heartpole.signals] from HeartPole.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TypeAlias

from heartpole.paths import naming_target, new_only, note_placed
from heartpole.signals import (
    SIGNALS,
    Interrupted,
    exit_code,
    interruption,
    received_signal,
    signal_handlers_kept,
    signal_policy,
    signals_as_ctrl_c,
    signals_deferred,
)

try:
    import fcntl
except ImportError:  # Windows: folder_lock locks nothing
    fcntl = None  # type: ignore[assignment]

PathLike: TypeAlias = "str | os.PathLike[str]"

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
            for temporary in temporaries:
                os.chmod(temporary, 0o666 & ~umask())  # mkstemp makes files private; give the usual mode
            _place(temporaries, targets)
            note_placed(*targets)
    except BaseException as error:
        with signals_deferred():
            for temporary in temporaries:
                temporary.unlink(missing_ok=True)
            _remove_if_empty(created)
        if isinstance(error, OSError):
            raise naming_target(error, targets, temporaries) from error
        raise


def _place(temporaries: list[Path], targets: list[Path]) -> None:
    """Move each temporary file to its target. A target announced as new only (`heartpole.paths.new_only`) is
    linked, which fails where a file appeared meanwhile: then the ones linked are taken back and
    ``FileExistsError`` names the target."""
    linked: list[Path] = []
    try:
        for temporary, target in zip(temporaries, targets):
            if new_only(target) and _linked(temporary, target):
                linked.append(target)
    except FileExistsError:
        for placed in linked:
            placed.unlink(missing_ok=True)
        reason = "it appeared while this command ran (another run writing it?); pass --force to replace it"
        raise FileExistsError(errno.EEXIST, reason, str(target)) from None
    for temporary, target in zip(temporaries, targets):
        if target in linked:
            temporary.unlink()
        else:
            os.replace(temporary, target)


def _linked(temporary: Path, target: Path) -> bool:
    """Hard-link ``temporary`` at ``target``; ``False`` on a file system without hard links (then the target is
    checked and replaced, which a concurrent writer can still race)."""
    try:
        os.link(temporary, target)
    except OSError as error:
        if error.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK, errno.EXDEV):
            raise
        if target.exists():
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(target)) from None
        return False
    return True


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


class FolderInUseError(OSError):
    """Another process holds [`folder_lock`][heartpole.files.folder_lock] on the folder."""


@contextmanager
def folder_lock(target: PathLike) -> Iterator[None]:
    """Hold an exclusive lock on ``target`` while the block runs, for work that writes in the folder itself.

    The lock is the hidden file ``.NAME.lock`` beside ``target`` (missing parents are created), locked with
    ``flock`` and removed when the block ends; missing parents it created are removed if left empty. The
    operating system drops the lock of a process that dies, so a lock file a killed process left holds nobody
    back. Where Python has no ``fcntl`` (Windows), the block runs without a lock.

    Raises:
        FolderInUseError: another process (or another ``folder_lock`` in this one) holds the lock; nothing was
            changed.
    """
    target = Path(target)
    lock = target.parent / f".{target.name}.lock"
    created: list[Path] = []
    handle: int | None = None  # None: not ours (another holds it), nothing to remove
    try:
        with signals_deferred():
            created = _make_folder(target.parent)
            handle = _locked(lock, target)
        yield
    finally:
        with signals_deferred():
            if handle is not None:
                lock.unlink(missing_ok=True)  # while locked: a process that opened it meanwhile sees it gone
                os.close(handle)
            _remove_if_empty(created)


def _locked(lock: Path, target: Path) -> int:
    """A descriptor of ``lock``, locked. A lock file its holder removed after we opened it is no longer the lock:
    it is made again."""
    while True:
        try:
            handle = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as error:
            raise naming_target(error, [target], [lock]) from error
        try:
            if fcntl is not None:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(handle)
            raise FolderInUseError(
                f"{target} is being written by another process (it holds {lock}); wait for it to end or choose "
                "another folder"
            ) from None
        try:
            if os.path.samestat(os.fstat(handle), os.stat(lock)):
                return handle
        except FileNotFoundError:
            pass
        os.close(handle)


def _empty(folder: Path) -> None:
    for path in folder.iterdir() if folder.is_dir() else ():
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


__all__ = [
    "SIGNALS",
    "FolderInUseError",
    "Interrupted",
    "atomic_files",
    "atomic_write",
    "exit_code",
    "folder_in_place",
    "folder_lock",
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
