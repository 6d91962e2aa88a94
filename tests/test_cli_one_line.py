"""Tracebacks where one line is due (issue 43, item 9): each case ends in one line on stderr and exit code 2,
before any work, with nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest

from heartpole.cli import main

pytest.importorskip("stable_baselines3")


def _one_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    return err


@pytest.mark.parametrize(
    ("option", "value"), [("--seed", "4294967296"), ("--seeds", "4294967290-4294967296"), ("--seed", "99999999999999")]
)
def test_train_refuses_seeds_training_cannot_use(capsys, tmp_path: Path, option: str, value: str) -> None:
    err = _one_line(
        capsys, ["train", option, value, "--timesteps", "64", "--n-envs", "2", "--out", str(tmp_path / "o")]
    )
    assert f"{option}: a training seed is a whole number from 0 to 4,294,967,295" in err
    assert not (tmp_path / "o").exists()


def test_the_largest_training_seed_is_taken() -> None:
    from heartpole.training import TrainConfig

    assert TrainConfig(seed=2**32 - 1).seed == 2**32 - 1
    with pytest.raises(ValueError, match="seed must be at most 4294967295"):
        TrainConfig(seed=2**32)
