"""``heartpole optimum`` answers signals within a second, even in the solver's long compiled loops, and refuses a
grid the machine's memory cannot hold before it starts."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from heartpole.cli import main
from tests.signal_dispositions import SIGNALS, as_in_a_terminal

SRC = Path(__file__).resolve().parents[1] / "src"


@pytest.mark.parametrize(
    "signum",
    # SIGTERM in the default suite; the others (the same path, seconds each) with the slow tests
    [s if s == signal.SIGTERM else pytest.param(s, marks=pytest.mark.slow) for s in SIGNALS],
    ids=[s.name for s in SIGNALS],
)
def test_a_long_solve_ends_within_a_second_of_a_signal(tmp_path: Path, signum: signal.Signals) -> None:
    """A billion-decision horizon spends minutes in numba's loop over the episode's decisions (13 minutes
    deaf to SIGTERM before): the signal ends it with 128 + n at once, leaving the cache as it was."""
    cache = tmp_path / "cache"
    cache.mkdir()
    env = {**os.environ, "HEARTPOLE_CACHE_DIR": str(cache),
           "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}  # fmt: skip
    command = [sys.executable, "-m", "heartpole", "optimum", "--param", "max_steps=100000000000", "--check", "0"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                               preexec_fn=as_in_a_terminal)  # fmt: skip
    assert process.stderr is not None
    assert process.stderr.readline().startswith("solving HeartPole-v0")
    time.sleep(2)  # into the solve (minutes long)
    assert process.poll() is None
    sent = time.monotonic()
    process.send_signal(signum)
    try:
        _, err = process.communicate(timeout=30)
    finally:
        process.kill()
    took = time.monotonic() - sent
    assert process.returncode == 128 + signum, err
    assert took < 1.5, f"{took:.1f} s after {signum.name}"
    assert list(cache.iterdir()) == []


def test_a_grid_beyond_the_machines_memory_is_refused_before_solving(capsys: pytest.CaptureFixture[str]) -> None:
    started = time.monotonic()
    assert main(["optimum", "--grid", str(10**11), "--check", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--grid 100000000000: the solver would need about" in err[0], err
    assert "more than this machine's" in err[0] and time.monotonic() - started < 30
