"""Hostile preset files and training options (issue 35, rows A7, A8, A9, B7, B17): refused before any
training, by one check, naming the file, the key, the value and what is accepted."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from heartpole.cli import main
from heartpole.training import load_preset, preset_config


def preset(tmp_path: Path, algo: str = "ppo", **config: Any) -> Path:
    path = tmp_path / "f.json"
    path.write_text(json.dumps({"format": "heartpole-preset/1", "config": {"algo": algo, **config}}))
    return path


@pytest.mark.parametrize(
    ("config", "said"),
    [
        ({"net_arch": "64"}, "net_arch must be a non-empty list of layer sizes (whole numbers >= 1), got '64'"),
        ({"net_arch": [1.7]}, "net_arch must list layer sizes that are whole numbers >= 1, got [1.7]"),
        ({"net_arch": []}, "net_arch must be a non-empty list"),
        ({"hyperparameters": {"learning_rate": "fast"}}, "hyperparameters.learning_rate must be a finite number > 0"),
        ({"hyperparameters": {"learning_rate": -1}}, "hyperparameters.learning_rate must be a finite number > 0"),
        ({"hyperparameters": {"nosuch": 1}}, "hyperparameters: ppo has no 'nosuch'; it takes ["),
        ({"hyperparameters": {"gamma": 2}}, "hyperparameters.gamma must be a finite number in (0, 1], got 2"),
        ({"hyperparameters": {"batch_size": 1e9}}, "hyperparameters.batch_size must be a whole number >= 2"),
        ({"hyperparameters": "x"}, "hyperparameters must be an object"),
        ({"env_kwargs": None}, "env_kwargs must be an object"),
        ({"env_kwargs": {"nosuch": 1}}, "env_kwargs {'nosuch': 1}: env 'HeartPole-v0': "),
        ({"env_kwargs": {"decay_rate": math.nan}}, "decay_rate must be a finite number in (0.0, 1.0], got nan"),
        ({"reward": {"score_rate": 1e308}}, "reward.score_rate must be 'best', 'auto' or a number in (0, "),
        ({"reward": {"score_rate": -1}}, "reward.score_rate must be"),
        ({"reward": {"nosuch": 1}}, "reward has no 'nosuch'"),
        ({"normalize_rewards": "yes"}, "normalize_rewards must be true or false, got 'yes'"),
    ],
)
def test_a_bad_preset_names_the_file_the_key_and_what_is_accepted(
    tmp_path: Path, config: dict[str, Any], said: str
) -> None:
    path = preset(tmp_path, **config)
    with pytest.raises(ValueError) as raised:
        load_preset(path)
    assert str(raised.value).startswith(f"preset file {path}: "), raised.value
    assert said in str(raised.value), raised.value


def test_a_dqn_minibatch_larger_than_its_buffer_is_refused(tmp_path: Path) -> None:
    path = preset(tmp_path, "dqn", hyperparameters={"batch_size": 10_000, "buffer_size": 1_000})
    with pytest.raises(ValueError, match=r"batch_size \(10000\) must be at most the replay buffer's size"):
        load_preset(path)


def test_every_built_in_preset_passes(tmp_path: Path) -> None:
    from heartpole.training.checks import check_config

    for name in ("default", "tutorial"):
        for algo in ("ppo", "a2c", "dqn"):
            check_config(preset_config(name, algo))
    check_config(preset_config("default", backend="jax"))
    path = tmp_path / "saved.json"
    from heartpole.training import save_preset

    save_preset(preset_config("default"), path)
    assert load_preset(path) == preset_config("default")  # a file HeartPole wrote loads as it was


@pytest.mark.parametrize("rate", ["-1", "0", "1e308", "2"])
def test_score_rates_no_policy_can_earn_are_refused_before_training(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, rate: str
) -> None:
    pytest.importorskip("stable_baselines3")
    code = main(["train", "--score-rate", rate, "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and "--score-rate must be 'best', 'auto' or a number in (0, 1.43]" in err, err
    assert not (tmp_path / "run").exists()


def test_the_cli_names_the_preset_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    path = preset(tmp_path, net_arch="64")
    code = main(["train", "--preset", str(path), "--timesteps", "100", "--n-envs", "1", "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith(f"heartpole train: error: preset file {path}: net_arch"), err
    assert "Traceback" not in err
