"""A run's output folder and files: staged, written atomically, with the umask's modes."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from heartpole import files, paths
from heartpole.policies import SIDECAR_NAME
from heartpole.records import SUMMARY_FILE

# ------------------------------------------------------------------------------------------------------
# output folders and files


def check_output_folder(out: str | os.PathLike[str], force: bool = False) -> Path:
    """Check that training may write to ``out``, before any training starts; return it as a ``Path``.

    ``out`` may be missing or an empty folder; a symbolic link is followed (its target is returned and
    written, as every command's ``--out``; see [`heartpole.paths.followed`][heartpole.paths.followed]). An
    existing non-empty folder needs ``force``, and even then it must be a folder ``heartpole train`` wrote (it
    holds ``heartpole.json`` or ``summary.json``): ``--force`` never deletes anything else.

    Raises:
        FileExistsError: ``out`` is a file, or a non-empty folder without ``force``.
        PermissionError: ``force`` on a folder that ``heartpole train`` did not write.
        OSError: ``out`` cannot be written (a read-only file system, no permission, a mount point: see
            [`heartpole.paths.check_writable`][heartpole.paths.check_writable]).
    """
    out = paths.followed(out)  # a symbolic link: its target is the output, the link stays
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"--out {out} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise FileExistsError(f"--out {out} exists and is not empty; pass --force to replace it")
        if not ((out / SIDECAR_NAME).is_file() or (out / SUMMARY_FILE).is_file()):
            raise PermissionError(
                f"--out {out} was not written by 'heartpole train' (no {SIDECAR_NAME} or {SUMMARY_FILE}); "
                "refusing to replace it even with --force"
            )
    try:
        paths.check_writable(out)
    except OSError as error:
        raise OSError(f"cannot write --out {out}: {error.strerror or error}") from None
    return out


@contextmanager
def staged_output(out: str | os.PathLike[str], force: bool = False) -> Iterator[Path]:
    """Write into a temporary folder beside ``out``; move it to ``out`` only if the block succeeds.

    On any error or interruption (Ctrl-C, and SIGTERM or SIGHUP under the ``heartpole`` command) the
    temporary folder is removed and ``out`` is left as it was, so a failed run never leaves half its files.
    With ``force``, a previous run in ``out`` is replaced, only once the new one is complete (see
    [`heartpole.files.staged_folder`][heartpole.files.staged_folder]).
    """
    out = check_output_folder(out, force)
    with files.staged_folder(out) as staging:
        yield staging
        check_output_folder(out, force)
