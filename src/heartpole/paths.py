"""Where a command's output goes: checked before the work, named in errors, known to be in place.

* [`check_writable`][heartpole.paths.check_writable]: before any work, whether a file or folder can be written (and
  replaced) where it would go: its folder is writable and not on a read-only file system, the name fits, the
  target is not a mount point or a symbolic link that leads nowhere. Training for an hour and then failing to
  write is the failure this prevents.
* [`naming_target`][heartpole.paths.naming_target]: an ``OSError`` about a hidden temporary name raised again about
  the output it stood for (a full disk reads ``runs/x: No space left on device``);
  [`describe_error`][heartpole.paths.describe_error] says it in one line.
* [`expect_output`][heartpole.paths.expect_output], [`note_placed`][heartpole.paths.note_placed] and
  [`outputs_placed`][heartpole.paths.outputs_placed]: whether a command's output is in place, so that a signal
  arriving after that ends it as a success (its exit status says what happened to the output).

[`heartpole.files`][heartpole.files] writes through these. This module imports nothing from HeartPole.
"""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path
from typing import TypeAlias

PathLike: TypeAlias = "str | os.PathLike[str]"

TEMPORARY_ROOM = 20
"""Bytes of a file name taken by the hidden temporary name it is written under (``.NAME.XXXXXXXX.old``)."""

_expected: list[Path] = []  # the outputs a command announced (expect_output)
_placed: list[Path] = []  # the files and folders moved into place since forget_outputs
_new_only: set[Path] = set()  # announced outputs that must not replace a file (no --force)


def check_writable(target: PathLike) -> Path:
    """Check, before any work, that a file or folder can be written at ``target``; return it as a ``Path``.

    Makes a hidden probe folder where ``target`` would go (in the nearest folder that exists) and removes it,
    so that what the operating system would refuse at the end (a read-only file system, no permission, a
    full disk) is refused at the start. ``target`` itself is not touched.

    Raises:
        OSError: naming ``target``, with the reason: ``EROFS``, ``EACCES``, ``ENOSPC``...; ``ENAMETOOLONG`` for a
            name longer than the file system takes; ``ENOTDIR`` when a file stands where a folder would be;
            ``EBUSY`` for a mount point, which cannot be moved aside to be replaced (a folder inside it can);
            ``ELOOP`` for a symbolic link that leads nowhere (a loop, or a missing target).
    """
    target = Path(target)
    name = str(target)
    for path in (target, *target.parents):
        if path.is_symlink() and not path.exists():
            reason = f"{path} is a symbolic link that leads nowhere (a loop or a missing target)"
            raise OSError(errno.ELOOP, reason, name)
        if path.exists():
            break
    if target.exists() and os.path.ismount(target):
        raise OSError(errno.EBUSY, "a mount point cannot be replaced; give a folder inside it", name)
    folder = _nearest_folder(target)
    if not folder.is_dir():
        raise OSError(errno.ENOTDIR, f"{folder} is not a folder", name)
    missing = target.parts[len(folder.parts) :] if target.parts[: len(folder.parts)] == folder.parts else ()
    for n, part in enumerate(missing or (target.name,)):
        longest = _name_max(folder) - (TEMPORARY_ROOM if n == len(missing) - 1 or not missing else 0)
        if len(os.fsencode(part)) > longest:
            reason = f"a name too long ({len(os.fsencode(part))} bytes; at most {longest} here)"
            raise OSError(errno.ENAMETOOLONG, reason, name)
    try:
        probe = tempfile.mkdtemp(prefix=".heartpole-probe.", dir=folder)
    except OSError as error:
        code = error.errno or errno.EACCES
        raise OSError(code, os.strerror(code), name) from None
    os.rmdir(probe)
    return target


def _nearest_folder(target: Path) -> Path:
    """The nearest of ``target``'s parents that exists (or is a link), where a probe can be made."""
    folder = target.parent if str(target.parent) else Path(".")
    while not folder.exists() and not folder.is_symlink() and folder != folder.parent:
        folder = folder.parent
    return folder


def _name_max(folder: Path) -> int:
    """The longest file name the file system of ``folder`` takes (255 where it cannot be asked)."""
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def naming_target(error: OSError, targets: list[Path], temporaries: list[Path]) -> OSError:
    """``error`` raised again about the output it concerns, when it names one of ``temporaries`` or a hidden
    name made for one of ``targets`` (``.NAME.XXXXXXXX...``): that name means nothing to a user, and is gone.
    With several targets and no way to tell which, their common folder is named. An error about any other
    file is returned as it is."""
    named = {str(temporary): target for temporary, target in zip(temporaries, targets)}
    filename = None if error.filename is None else str(error.filename)
    if error.errno is None or (filename is not None and filename not in named and not _hidden_for(filename, targets)):
        return error
    target = named.get(filename or "", targets[0] if len(targets) == 1 else None)
    if target is None:
        target = Path(os.path.commonpath([str(t) for t in targets]))
    return type(error)(error.errno, error.strerror or os.strerror(error.errno), str(target))


def _hidden_for(filename: str, targets: list[Path]) -> bool:
    return any(filename.startswith(str(t.parent / f".{t.name}.")) for t in targets)


def describe_error(error: OSError) -> str:
    """An ``OSError`` in one line for a user: ``PATH: reason``, or the reason alone when no path is known."""
    reason = error.strerror or str(error)
    return reason if error.filename is None else f"{error.filename}: {reason}"


def forget_outputs() -> None:
    """Start afresh: no output expected, none placed (each ``heartpole`` command begins so)."""
    _expected.clear()
    _placed.clear()
    _new_only.clear()


def expect_output(*paths: PathLike, replace: bool = True) -> None:
    """Note ``paths`` as the output a command is about to write (see
    [`outputs_placed`][heartpole.paths.outputs_placed]); with ``replace=False``, a file that appears at one of
    them meanwhile (another run writing the same output) is not replaced
    ([`new_only`][heartpole.paths.new_only])."""
    _expected.extend(Path(p) for p in paths)
    if not replace:
        _new_only.update(Path(p) for p in paths)


def new_only(path: PathLike) -> bool:
    """Whether ``path`` was announced with ``replace=False``: it is placed only where nothing is."""
    return Path(path) in _new_only


def note_placed(*paths: PathLike) -> None:
    """Note that ``paths`` are in place, whole ([`heartpole.files`][heartpole.files] calls it after each move)."""
    _placed.extend(Path(p) for p in paths)


def outputs_placed() -> bool:
    """Whether every output noted by [`expect_output`][heartpole.paths.expect_output] is in place (it, or a folder
    holding it, was noted by [`note_placed`][heartpole.paths.note_placed]); ``False`` when none was expected.

    A command interrupted after that point has done its work: its new output is complete and in place, so it
    ends as a success, not with 128 + the signal's number, which says that the output is as it was."""
    if not _expected:
        return False
    placed = {os.path.abspath(p) for p in _placed}
    return all(any(os.path.abspath(q) in placed for q in (path, *path.parents)) for path in _expected)


__all__ = [
    "check_writable",
    "describe_error",
    "expect_output",
    "followed",
    "forget_outputs",
    "naming_target",
    "note_placed",
    "outputs_placed",
    "physical_memory",
    "check_memory",
]


def followed(target: PathLike) -> Path:
    """``target``, or where it leads if it is a symbolic link (followed to its end): every command writes through
    a link given as its output, to the file or folder it names, and never replaces the link itself (a link is
    how a user keeps outputs on another disk). A link that leads nowhere stays as it is, for
    [`check_writable`][heartpole.paths.check_writable] to refuse."""
    path = Path(target)
    if path.is_symlink() and path.exists():
        return Path(os.path.realpath(path))
    return path


def physical_memory() -> int | None:
    """The machine's physical memory in bytes, where the platform says (``None`` elsewhere): what a size a user
    asks for (a grid, a network, a buffer) is checked against before the work starts."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def check_memory(needed: int, what: str) -> None:
    """``ValueError`` when ``what`` (a sentence's subject: ``"--episodes 10,000,000,000,000"``) needs ``needed``
    bytes, more than half the machine's memory ([`physical_memory`][heartpole.paths.physical_memory]); nothing
    where the platform does not say."""
    memory = physical_memory()
    if memory is not None and needed > memory // 2:
        raise ValueError(
            f"{what} needs about {needed / 2**30:,.1f} GiB of memory; this machine has {memory / 2**30:,.1f} GiB "
            "(at most half of it may go to it)"
        )
