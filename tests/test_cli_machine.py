"""Sizes a user asks for, checked against the machine before the work starts, and what training leaves behind
(issue 43, item 10)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.test_cli_one_line import one_line

pytest.importorskip("stable_baselines3")


@pytest.mark.parametrize("command", ["train", "tune"])
def test_more_cpus_per_trial_than_the_machine_has_is_refused(capsys, monkeypatch, tmp_path: Path, command: str) -> None:
    pytest.importorskip("ray")
    pytest.importorskip("optuna")
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    out = str(tmp_path / "o")
    extra = ["--seeds", "0-1", "--ray"] if command == "train" else ["--trials", "1"]
    err = one_line(capsys, [command, *extra, "--cpus-per-trial", "1000", "--timesteps", "64", "--out", out])
    assert "--cpus-per-trial 1000: this machine has 2 CPUs" in err and "give at most 2" in err
    assert not (tmp_path / "o").exists()


def test_training_leaves_no_sb3_folder_in_the_temporary_folder(tmp_path: Path, monkeypatch) -> None:
    import tempfile

    from heartpole.training import preset_config, train_model

    temporary = tmp_path / "tmp"
    temporary.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temporary))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    train_model(preset_config(timesteps=64, n_envs=2))
    assert [p.name for p in temporary.iterdir() if p.name.startswith("SB3-")] == []


def test_a_network_larger_than_the_memory_is_refused_before_it_is_built(capsys, tmp_path: Path) -> None:
    from dataclasses import replace

    from heartpole.training import preset_config
    from heartpole.training.presets import save_preset

    preset = tmp_path / "p.json"
    save_preset(replace(preset_config(), net_arch=(10**9,), timesteps=64, n_envs=2), preset)
    err = one_line(capsys, ["train", "--preset", str(preset), "--out", str(tmp_path / "o"), "--eval-episodes", "2"])
    assert "net_arch [1000000000] has 12,000,000,005 parameters per network" in err and "GiB of memory" in err
    assert not (tmp_path / "o").exists()


def test_network_memory_is_counted_against_half_the_memory(monkeypatch) -> None:
    from heartpole import paths
    from heartpole.training import checks

    needed = checks.check_network_memory((64, 64), 6, 4)
    assert needed == (6 * 64 + 64 + 64 * 64 + 64 + 64 * 5 + 5) * checks.NETWORK_BYTES_PER_PARAMETER
    monkeypatch.setattr(paths, "physical_memory", lambda: 2 * needed)
    checks.check_network_memory((64, 64), 6, 4)
    monkeypatch.setattr(paths, "physical_memory", lambda: 2 * needed - 1)
    with pytest.raises(ValueError, match=r"net_arch \[64, 64\] has 4,933 parameters per network"):
        checks.check_network_memory((64, 64), 6, 4)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"hyperparameters": {"n_steps": 10**12}}, "n_steps x n_envs = 2,000,000,000,000 steps a rollout"),
        ({"n_envs": 10**9}, "n_steps x n_envs = 128,000,000,000 steps a rollout and n_envs 1,000,000,000"),
        ({"algo": "dqn", "hyperparameters": {"buffer_size": 10**12}}, "buffer_size 1,000,000,000,000"),
    ],
    ids=["n_steps", "n_envs", "buffer_size"],
)
def test_a_buffer_larger_than_the_memory_is_refused_before_training(
    capsys, tmp_path: Path, changes: dict, message: str
) -> None:
    from dataclasses import replace

    from heartpole.training import preset_config
    from heartpole.training.presets import save_preset

    preset = tmp_path / "p.json"
    config = replace(preset_config(), timesteps=64, n_envs=2, net_arch=(8,))
    save_preset(replace(config, **changes), preset)
    err = one_line(capsys, ["train", "--preset", str(preset), "--out", str(tmp_path / "o"), "--eval-episodes", "2"])
    assert message in err and "GiB of memory; this machine has" in err
    assert not (tmp_path / "o").exists()


def test_buffer_memory_is_counted_against_half_the_memory(monkeypatch) -> None:
    from dataclasses import replace

    from heartpole import paths
    from heartpole.training import checks, preset_config

    config = replace(preset_config(), n_envs=4, hyperparameters={"n_steps": 128})
    needed = checks.check_buffer_memory(config, 6)
    assert needed == 4 * 128 * (6 + checks.BUFFER_NUMBERS_PER_STEP) * 4 + 4 * checks.ENV_BYTES
    monkeypatch.setattr(paths, "physical_memory", lambda: 2 * needed)
    checks.check_buffer_memory(config, 6)
    monkeypatch.setattr(paths, "physical_memory", lambda: 2 * needed - 1)
    with pytest.raises(ValueError, match="n_steps x n_envs = 512 steps a rollout and n_envs 4"):
        checks.check_buffer_memory(config, 6)


def test_more_episodes_than_the_memory_holds_are_refused_before_they_run(capsys, tmp_path: Path) -> None:
    err = one_line(capsys, ["evaluate", "--policy", "expert", "--episodes", str(10**13)])
    assert "evaluating 10,000,000,000,000 episodes needs about" in err and "GiB of memory" in err
    pytest.importorskip("minari")
    from heartpole.offline import truth

    with pytest.raises(ValueError, match=r"a truth of 100,000,000,000 episodes \(run side by side\) needs about"):
        truth.true_value("expert", episodes=10**11)
