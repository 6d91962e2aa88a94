"""Tracebacks where one line is due (issue 43, item 9): each case ends in one line on stderr and exit code 2,
before any work, with nothing written."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import heartpole
from heartpole.cli import main

pytest.importorskip("stable_baselines3")


def one_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    """Run the CLI with ``argv``: exit 2 and exactly one line on stderr, which is returned."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    return err


@pytest.mark.parametrize(
    ("option", "value"), [("--seed", "4294967296"), ("--seeds", "4294967290-4294967296"), ("--seed", "99999999999999")]
)
def test_train_refuses_seeds_training_cannot_use(capsys, tmp_path: Path, option: str, value: str) -> None:
    err = one_line(capsys, ["train", option, value, "--timesteps", "64", "--n-envs", "2", "--out", str(tmp_path / "o")])
    assert f"{option}: a training seed is a whole number from 0 to 4,294,967,295" in err
    assert not (tmp_path / "o").exists()


def test_the_largest_training_seed_is_taken() -> None:
    from heartpole.training import TrainConfig

    assert TrainConfig(seed=2**32 - 1).seed == 2**32 - 1
    with pytest.raises(ValueError, match="seed must be at most 4294967295"):
        TrainConfig(seed=2**32)


def _small_files(limit: int) -> None:
    """In the child: files of at most ``limit`` bytes; a write past it fails (EFBIG) instead of killing."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


def test_a_long_mp4_that_cannot_be_written_isone_line(tmp_path: Path) -> None:
    pytest.importorskip("imageio_ffmpeg")
    target = tmp_path / "out" / "x.mp4"
    result = subprocess.run(
        [sys.executable, "-m", "heartpole", "record", "--policy", "expert", "--out", str(target)],
        env={**os.environ, "PYTHONPATH": str(Path(heartpole.__file__).parents[1])},
        capture_output=True, text=True, timeout=300, preexec_fn=lambda: _small_files(200_000),
    )  # fmt: skip
    assert result.returncode == 2, result.stderr[-2000:]
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr[-2000:]
    assert f"{target}: ffmpeg did not write a whole video (ffmpeg stopped after" in result.stderr
    assert not (tmp_path / "out").exists()  # no temporary file, and the folder it made is gone


@pytest.mark.parametrize("mode", ["human", "ansi", "bogus"])
def test_a_preset_render_mode_training_cannot_use_is_refused_up_front(capsys, tmp_path: Path, mode: str) -> None:
    from dataclasses import replace

    from heartpole.training import preset_config
    from heartpole.training.presets import save_preset

    preset = tmp_path / "p.json"
    save_preset(replace(preset_config(), env_kwargs={"render_mode": mode}, timesteps=64, n_envs=2), preset)
    err = one_line(capsys, ["train", "--preset", str(preset), "--out", str(tmp_path / "o"), "--eval-episodes", "2"])
    assert f"env_kwargs {{'render_mode': '{mode}'}}" in err and "render_mode must be None or one of" in err
    assert not (tmp_path / "o").exists()
