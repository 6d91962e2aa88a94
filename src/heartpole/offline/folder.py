"""Minari's datasets folder, written atomically, the room a dataset needs, checked before and while it is
written, and a dataset's files, checked before they are read ([`check_stored`][heartpole.offline.folder.check_stored]).

A dataset is written into a hidden scratch folder in Minari's datasets folder and moved into place when complete
([`write_atomically`][heartpole.offline.folder.write_atomically]). HDF5 (through h5py, which Minari writes with) does
not survive a write that fails: every object it deallocates afterwards prints a traceback, and the process may end
in a segmentation fault. So a dataset's size is estimated ([`dataset_bytes`][heartpole.offline.folder.dataset_bytes],
generously) and checked against the free space of the folder and the largest file the process may write
(``RLIMIT_FSIZE``) before anything is recorded, and the free space again before each chunk of episodes is written
([`check_room`][heartpole.offline.folder.check_room]): a full disk is a one-line ``OSError`` that leaves nothing
behind.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import warnings
from collections.abc import Callable, Iterator, Mapping
from functools import partial
from pathlib import Path

from heartpole import files, paths

EPISODE_BYTES = 32 * 1024
"""Room an episode takes in a dataset's HDF5 file beyond its steps (its groups and their metadata), rounded up."""
FOLDER_BYTES = 256 * 1024
"""Room a dataset takes beyond its episodes (its metadata, the namespace files), rounded up."""


def root() -> Path:
    """Minari's datasets folder, as Minari itself finds it: ``MINARI_DATASETS_PATH`` if set, else
    ``~/.minari/datasets``."""
    configured = os.environ.get("MINARI_DATASETS_PATH")
    return Path(configured) if configured is not None else Path.home() / ".minari" / "datasets"


def dataset_bytes(episodes: int, steps: int, observation_size: int, num_actions: int) -> int:
    """A generous estimate of the bytes ``episodes`` episodes of ``steps`` steps take in a dataset: per step, the
    observation twice (Minari stores ``T + 1`` per episode, and HDF5 chunks round up), the action probabilities,
    the action, reward, flags and the four scalar infos, all as 8 bytes; per episode
    [`EPISODE_BYTES`][heartpole.offline.folder.EPISODE_BYTES]; [`FOLDER_BYTES`][heartpole.offline.folder.FOLDER_BYTES]
    once. HeartPole-v0's datasets take about 60% of it."""
    per_step = 8 * (2 * observation_size + num_actions + 8)
    return episodes * (steps * per_step + EPISODE_BYTES) + FOLDER_BYTES


def check_room(folder: Path, needed: int, what: str) -> None:
    """Check that ``needed`` bytes fit in ``folder`` (or its nearest existing parent): its file system's free space
    and the largest file this process may write (``RLIMIT_FSIZE``, where the platform has it).

    Raises:
        OSError: a one-line message naming ``what``, the folder, the bytes needed and the bytes there are.
    """
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    try:
        free = shutil.disk_usage(existing).free
    except OSError:
        return  # a folder whose free space cannot be read: writing it will say what is wrong
    if needed > free:
        raise OSError(f"{what} needs about {_size(needed)} and {existing} has {_size(free)} free; free some space "
                      "or point MINARI_DATASETS_PATH elsewhere")  # fmt: skip
    limit = _file_size_limit()
    if limit is not None and needed > limit:
        raise OSError(f"{what} needs a file of about {_size(needed)} and this process may write files of at most "
                      f"{_size(limit)} (ulimit -f)")  # fmt: skip


def _file_size_limit() -> int | None:
    try:
        import resource
    except ImportError:  # Windows
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _size(count: int) -> str:
    for unit, power in (("TiB", 40), ("GiB", 30), ("MiB", 20)):
        if count >= 2**power:
            return f"{count / 2**power:,.1f} {unit}"
    return f"{count / 1024:.0f} KiB"


def check_stored(target_id: str, stored: Path) -> None:
    """``ValueError`` naming ``stored``, a file of the dataset ``target_id``, unless it is a regular file and, where
    its name says HDF5, an HDF5 file (h5py's own error names no file)."""
    if not stored.is_file():  # a FIFO or a device would block the HDF5 reader or feed it forever
        raise ValueError(f"dataset {target_id!r}: {stored} is not a regular file")
    if stored.suffix == ".hdf5" and not _is_hdf5(stored):
        empty = " (it is empty)" if stored.stat().st_size == 0 else ""
        raise ValueError(f"dataset {target_id!r}: {stored} is not an HDF5 file{empty}; record the dataset again")


def _is_hdf5(path: Path) -> bool:
    """Whether ``path`` is an HDF5 file (h5py's check); ``True`` without h5py, whose absence Minari reports."""
    try:
        import h5py
    except ImportError:
        return True
    return bool(h5py.is_hdf5(path))


def write_atomically(creates: Mapping[str, Callable[[], None]], force: bool) -> None:
    """Run each dataset's ``create`` with Minari pointed at a hidden scratch folder in its datasets folder,
    then move the datasets into place together, signals deferred ([`heartpole.files`][heartpole.files]): an error
    or an interruption leaves Minari's folder as it was; once they are all in place, a command ends as a success.
    h5py's tracebacks from objects it frees after a failed write are kept off stderr (the error itself is raised)."""
    folder = root()
    paths.expect_output(*(folder / target_id for target_id in creates))
    with files.scratch_folder(folder, "heartpole-datasets") as scratch:
        with _minari_root(scratch), _quiet_h5py_deallocation():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # Minari's notices about optional metadata
                for create in creates.values():
                    create()
        with files.signals_deferred():
            existing = [target_id for target_id in creates if (folder / target_id).exists()]
            if existing and not force:
                raise FileExistsError(f"dataset {existing[0]!r} already exists in {folder}; pass force=True (--force)")
            for target_id in creates:
                (folder / target_id).parent.mkdir(parents=True, exist_ok=True)
                _copy_namespace_metadata(scratch, folder, target_id)
                files.replace_folder(scratch / target_id, folder / target_id)


def _copy_namespace_metadata(temporary: Path, folder: Path, target_id: str) -> None:
    """Give the real namespaces (``heartpole``, ``heartpole/v0``) the metadata files Minari made for them."""
    parts = target_id.split("/")[:-1]
    for depth in range(1, len(parts) + 1):
        namespace = Path(*parts[:depth])
        for source in (temporary / namespace).glob("*.json"):
            destination = folder / namespace / source.name
            if not destination.exists():
                files.atomic_write(destination, partial(shutil.copyfile, source))


@contextlib.contextmanager
def _minari_root(path: Path) -> Iterator[None]:
    previous = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(path)
    try:
        yield
    finally:
        if previous is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = previous


@contextlib.contextmanager
def _quiet_h5py_deallocation() -> Iterator[None]:
    """Within the block, the exceptions h5py's objects raise while being freed (after a failed write, one per
    object) are dropped instead of printed; every other unraisable exception is printed as before."""
    previous = sys.unraisablehook

    def hook(unraisable: sys.UnraisableHookArgs) -> None:
        if "h5py" not in f"{unraisable.err_msg} {unraisable.object!r}":
            previous(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous
