"""Preset files: what `heartpole tune` writes and `heartpole train --preset FILE` reads."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("torch")

from heartpole import training  # noqa: E402
from heartpole.cli import main  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore:.*is out of date.*:DeprecationWarning")


@pytest.mark.parametrize("preset", ["default", "tutorial"])
def test_a_preset_file_round_trips_every_field_but_the_seed(tmp_path: Path, preset: str) -> None:
    config = training.preset_config(preset, seed=7, net_arch=(8, 4), env_kwargs={"max_steps": 50})
    path = training.save_preset(config, tmp_path / "p.json", source="test")
    data = json.loads(path.read_text())
    assert data["format"] == training.PRESET_FORMAT and "seed" not in data["config"]
    assert data["notes"] == {"source": "test"}
    assert training.load_preset(path) == training.TrainConfig(**{**config.__dict__, "seed": 0})
    assert os.listdir(tmp_path) == ["p.json"]


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("not json", "is not JSON"),
        ("\udcff{}", "preset.json is not JSON text: 'utf-8' codec can't decode byte 0xff"),  # named the file not
        ('{"format": "heartpole-preset/2", "config": {}}', "format 'heartpole-preset/2', made by another version"),
        ('{"algo": "ppo"}', "is not a preset file"),
        ('{"format": "heartpole-preset/1", "config": {"algo": "ppo", "learning_rate": 1}}', "unknown configuration"),
        ('{"format": "heartpole-preset/1", "config": {"algo": "sac"}}', "unknown algorithm 'sac'"),
    ],
)
def test_bad_preset_files_give_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, fragment: str
) -> None:
    path = tmp_path / "preset.json"
    path.write_bytes(text.encode("utf-8", "surrogateescape"))  # \udcff: the byte 0xff, not UTF-8
    with pytest.raises(ValueError, match=re.escape(fragment)):
        training.load_preset(path)
    assert main(["train", "--preset", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("heartpole train: error:") and fragment in err[0], err
    assert not (tmp_path / "out").exists()


def test_train_takes_a_preset_file_and_its_overrides(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = training.preset_config("default", "a2c", timesteps=999, n_envs=3, net_arch=(12,))
    path = training.save_preset(training.TrainConfig(**{**config.__dict__, "preset": "tuned"}), tmp_path / "p.json")
    out = tmp_path / "run"
    args = ["train", "--preset", str(path), "--timesteps", "96", "--eval-episodes", "4", "--out", str(out), "--json"]
    assert main(args) == 0
    capsys.readouterr()
    sidecar = json.loads((out / "heartpole.json").read_text())
    assert sidecar["algo"] == "a2c" and sidecar["timesteps"] == 96 and sidecar["config"]["net_arch"] == [12]
    assert sidecar["config"]["n_envs"] == 3 and sidecar["preset"] == "tuned"
    assert main(["train", "--preset", str(path), "--algo", "ppo", "--out", str(tmp_path / "x")]) == 2
    assert "differs from the preset file's a2c" in capsys.readouterr().err
    assert main(["train", "--preset", str(tmp_path / "missing.json"), "--out", str(tmp_path / "y")]) == 2
    assert "No such file" in capsys.readouterr().err
