"""``heartpole dataset`` on a full disk: one line, exit code 2, nothing left behind (HDF5, which Minari writes
with, does not survive a failed write: hundreds of tracebacks, then a segmentation fault)."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from collections import namedtuple
from pathlib import Path

import pytest

import heartpole

pytest.importorskip("minari")

from heartpole.offline import datasets, folder  # noqa: E402


def _small_files(limit: int) -> None:
    """In the child: files of at most ``limit`` bytes, and a write past it fails (EFBIG) instead of killing."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


def test_a_dataset_larger_than_the_process_may_write_is_one_line(tmp_path: Path) -> None:
    root = tmp_path / "minari"
    env = {**os.environ, "MINARI_DATASETS_PATH": str(root), "PYTHONPATH": str(Path(heartpole.__file__).parents[1])}
    result = subprocess.run(
        [sys.executable, "-m", "heartpole", "dataset", "--policy", "expert", "--episodes", "300"],
        env=env, capture_output=True, text=True, timeout=300, preexec_fn=lambda: _small_files(3_000_000),
    )  # fmt: skip
    assert result.returncode == 2, result.stderr[-2000:]
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr[-2000:]
    assert "needs a file of about" in result.stderr and "ulimit -f" in result.stderr
    assert not root.exists()  # nothing left behind, not even Minari's folder


Usage = namedtuple("Usage", "total used free")


def test_a_disk_that_fills_while_recording_stops_before_hdf5_fails(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    checks: list[int] = []

    def usage(path: object) -> Usage:
        checks.append(1)  # room at first (the check before recording, the first chunk), then none
        return Usage(10**12, 0, 10**12 if len(checks) <= 2 else 1000)

    monkeypatch.setattr(folder.shutil, "disk_usage", usage)
    with pytest.raises(OSError, match=r"needs about .* KiB and .*minari has 1 KiB free"):
        datasets.record_dataset("expert", 0.0, 4, num_envs=2)
    assert len(checks) == 3
    root = tmp_path / "minari"
    assert not root.exists() or not any(root.iterdir())  # no .heartpole-datasets.*.partial/ left


def test_the_estimate_covers_what_a_dataset_takes(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    datasets.record_dataset("expert", 0.1, 5, dataset_id="heartpole/v0/size-v0")
    taken = sum(p.stat().st_size for p in tmp_path.rglob("*") if p.is_file())
    estimate = folder.dataset_bytes(5, 1000, 6 + 8, 4)
    assert taken < estimate < 4 * taken
