"""heartpole.launch: what ``heartpole train`` runs, called directly."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from heartpole import launch, training  # noqa: E402
from heartpole.training import preset_config  # noqa: E402


def tiny(**overrides: object) -> training.TrainConfig:
    settings: dict[str, object] = {"timesteps": 512, "n_envs": 2, "env_kwargs": {"max_steps": 16}, **overrides}
    return preset_config("default", **settings)  # type: ignore[arg-type]


def test_default_out_names_the_preset_the_algorithm_and_the_backend() -> None:
    assert launch.default_out(preset_config()) == "runs/ppo"
    assert launch.default_out(preset_config("tutorial", "a2c")) == "runs/tutorial-a2c"
    assert launch.default_out(preset_config(), "jax") == "runs/ppo-jax"
    from_file = training.TrainConfig(preset="runs/tune-ppo/best_preset.json")
    assert launch.default_out(from_file) == "runs/best_preset-ppo"


def test_check_run_refuses_before_any_training(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="Nope-v0"):
        launch.check_run(tiny(env_id="Nope-v0"), tmp_path / "out")
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="is a file"):
        launch.check_run(tiny(), tmp_path / "file")
    assert launch.check_run(tiny(), str(tmp_path / "new")) == tmp_path / "new"
    assert not (tmp_path / "new").exists()  # checking writes nothing


def test_train_one_seed_writes_the_run_into_out(tmp_path: Path) -> None:
    out = tmp_path / "run"
    result = launch.train(tiny(seed=3), out, eval_episodes=4, progress=False)
    assert result["seed"] == 3
    assert json.loads((out / training.EVALUATION_FILE).read_text())["episodes"] == 4
    assert {"model.zip", "heartpole.json", "learning_curve.csv"} <= set(os.listdir(out))
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no staging folder left beside it


def test_train_seeds_calls_back_per_seed_and_aggregates(tmp_path: Path) -> None:
    seen: list[int] = []
    result = launch.train(
        tiny(),
        tmp_path / "seeds",
        seeds=[1, 0],
        eval_episodes=4,
        progress=False,
        on_run=lambda r: seen.append(r["seed"]),
    )
    assert seen == [1, 0] and [run["seed"] for run in result["runs"]] == [1, 0]
    assert (tmp_path / "seeds" / training.SUMMARY_FILE).is_file()
    assert sorted(os.listdir(tmp_path / "seeds")) == ["seed_0", "seed_1", training.SUMMARY_FILE]


def test_a_failed_run_leaves_out_as_it_was(tmp_path: Path) -> None:
    def interrupt(run: dict[str, object]) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        launch.train(tiny(), tmp_path / "run", seeds=[0, 1], eval_episodes=4, progress=False, on_run=interrupt)
    assert list(tmp_path.iterdir()) == []


def test_ray_needs_seeds_and_the_sb3_backend(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="ray runs the seeds"):
        launch.train(tiny(), tmp_path / "x", ray=True)
    with pytest.raises(ValueError, match="ray runs the seeds"):
        launch.train(tiny(), tmp_path / "x", seeds=[0], backend="jax", ray=True)
    assert list(tmp_path.iterdir()) == []
