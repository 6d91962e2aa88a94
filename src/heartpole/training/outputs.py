"""A run's output folder and files: staged, written atomically, with the umask's modes."""

from __future__ import annotations

import csv
import os
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

import gymnasium as gym
import numpy as np

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole import files
from heartpole.policies import (  # the run's file names and the algorithms, each defined once, there
    CURVE_COLUMNS,
    SIDECAR_NAME,
)

EVALUATION_FILE = "evaluation.json"
SUMMARY_FILE = "summary.json"

# ------------------------------------------------------------------------------------------------------
# output folders and files


def check_output_folder(out: str | os.PathLike[str], force: bool = False) -> Path:
    """Check that training may write to ``out``, before any training starts; return it as a ``Path``.

    ``out`` may be missing or an empty folder. An existing non-empty folder needs ``force``, and even then
    it must be a folder ``heartpole train`` wrote (it holds ``heartpole.json`` or ``summary.json``):
    ``--force`` never deletes anything else.

    Raises:
        FileExistsError: ``out`` is a file, or a non-empty folder without ``force``.
        PermissionError: ``force`` on a folder that ``heartpole train`` did not write.
    """
    out = Path(out)
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
    return out


@contextmanager
def staged_output(out: str | os.PathLike[str], force: bool = False) -> Iterator[Path]:
    """Write into a temporary folder beside ``out``; move it to ``out`` only if the block succeeds.

    On any error or interruption (Ctrl-C, and SIGTERM or SIGHUP under the ``heartpole`` command) the
    temporary folder is removed and ``out`` is left as it was, so a failed run never leaves half its files.
    With ``force``, a previous run in ``out`` is replaced, only once the new one is complete (see
    :func:`heartpole.files.staged_folder`).
    """
    out = check_output_folder(out, force)
    with files.staged_folder(out) as staging:
        yield staging
        check_output_folder(out, force)


def write_curve(path: Path, rows: Sequence[Mapping[str, float]]) -> None:
    """Write the learning curve as CSV with :data:`CURVE_COLUMNS`."""
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=CURVE_COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({key: row[key] for key in CURVE_COLUMNS})


def _versions() -> dict[str, str]:
    import stable_baselines3
    import torch

    return {
        "heartpole": heartpole.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "gymnasium": gym.__version__,
        "numpy": np.__version__,
    }
