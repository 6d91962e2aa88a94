"""``heartpole train --env-kwargs``: training on an env's parameters (a drinking setting such as
``heart_attack_penalty=10``), checked before any work, recorded, and evaluated against that setting's optimum."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

import heartpole  # noqa: E402
from heartpole.cli import build_parser  # noqa: E402
from heartpole.cli.common import CommandError  # noqa: E402
from heartpole.cli.train import build_config  # noqa: E402
from heartpole.training import SHAPED_REWARD, TrainConfig, preset_config, save_preset  # noqa: E402

PENALTY = {"heart_attack_penalty": 10}


def config_of(*argv: str) -> TrainConfig:
    return build_config(build_parser().parse_args(["train", *argv]))


def test_the_env_kwargs_reach_the_config_under_the_people_flags_and_over_a_preset_file_s(tmp_path: Path) -> None:
    assert config_of("--env-kwargs", "heart_attack_penalty=10").env_kwargs == PENALTY
    assert config_of("--env-kwargs", '{"heart_attack_penalty": 10}').env_kwargs == PENALTY
    both = config_of("--env-kwargs", "heart_attack_penalty=10", "--people", "default").env_kwargs
    assert both == {**PENALTY, "people": "default"}
    preset = tmp_path / "p.json"
    save_preset(preset_config(env_kwargs={"max_steps": 40, "heart_attack_penalty": 50}), preset)
    merged = config_of("--preset", str(preset), "--env-kwargs", "heart_attack_penalty=10").env_kwargs
    assert merged == {"max_steps": 40, **PENALTY}


def test_score_rate_with_a_preset_file_is_refused_not_ignored(tmp_path: Path) -> None:
    """The file's reward stays whole (its rate was pinned for its env): --score-rate 0.9 used to be dropped."""
    preset = tmp_path / "p.json"
    save_preset(preset_config(env_kwargs={"max_steps": 40}), preset)
    with pytest.raises(CommandError, match=f"--score-rate applies to the built-in presets; preset file {preset} "):
        config_of("--preset", str(preset), "--score-rate", "0.9")
    assert config_of("--preset", str(preset)).reward == preset_config(env_kwargs={"max_steps": 40}).reward
    assert config_of("--score-rate", "0.3").reward.score_rate == 0.3


def test_the_default_preset_keeps_v0_s_rate_and_names_the_env_s_penalty() -> None:
    """The penalty weighs the risk, not the score: the shaped reward's rate is v0's; its description says 10."""
    config = config_of("--env-kwargs", "heart_attack_penalty=10")
    assert config.reward.score_rate == config_of().reward.score_rate
    assert config.heart_attack_penalty == 10.0 and config_of().heart_attack_penalty == 100.0
    assert config.to_dict()["reward"]["description"].endswith("- 10 x (heart-attack risk - floor)")
    assert SHAPED_REWARD.describe().endswith("- 100 x (heart-attack risk - floor)")
    heartpole.register_variant("PenaltyPole-v0", heartpole.V0_ACTIONS, heart_attack_penalty=7.0, replace=True)
    assert preset_config(env_id="PenaltyPole-v0").heart_attack_penalty == 7.0  # the variant's own, unless given
    assert preset_config(env_id="PenaltyPole-v0", env_kwargs={"heart_attack_penalty": 3}).heart_attack_penalty == 3.0
    refused = TrainConfig(env_kwargs={"heart_attack_penalty": "high"})  # check_config refuses it; it still describes
    assert refused.to_dict()["reward"]["description"].endswith("- nan x (heart-attack risk - floor)")


def test_a_max_episode_steps_is_recorded_as_the_max_steps_it_makes() -> None:
    """A model folder recording max_episode_steps=30 replayed under evaluate's --env-kwargs max_steps=60 ran 30
    steps (a time limit on the 60) and one under max_steps=20 was refused for a keyword the user never gave."""
    assert config_of("--env-kwargs", "max_episode_steps=30").env_kwargs == {"max_steps": 30}
    assert config_of("--env-kwargs", "max_steps=50,max_episode_steps=30").env_kwargs == {"max_steps": 30}


def test_a_config_of_an_unregistered_id_still_describes_itself() -> None:
    """to_dict is data (a Ray worker, or a preset of a variant this process never registered): gym.spec raised."""
    unknown = TrainConfig(env_id="NeverRegisteredPole-v0")
    assert math.isnan(unknown.heart_attack_penalty)
    assert unknown.to_dict()["reward"]["description"].endswith("- nan x (heart-attack risk - floor)")
    given = TrainConfig(env_id="NeverRegisteredPole-v0", env_kwargs=PENALTY)
    assert given.heart_attack_penalty == 10.0


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        ("bogus=1", "env HeartPole-v0 with {'bogus': 1}: .*unexpected keyword argument 'bogus'; it accepts"),
        ("heart_attack_penalty=-1", "heart_attack_penalty must be a finite number in \\[0.0, inf\\], got -1"),
    ],
)
def test_a_keyword_the_env_refuses_is_one_line_before_any_work(value: str, fragment: str) -> None:
    with pytest.raises(CommandError, match=fragment):
        config_of("--env-kwargs", value)


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--env-kwargs", "people=default", "--people", "default"], "gives people and so does --people; give each"),
        (["--env-kwargs", "observe_traits=false", "--people", "default", "--observe-traits"],
         "gives observe_traits and so does --observe-traits; give each once \\(drop observe_traits= from"),
    ],
)  # fmt: skip
def test_a_people_keyword_given_by_env_kwargs_and_a_people_option_is_refused(argv: list[str], fragment: str) -> None:
    """As Python refuses a keyword argument given twice: --people used to replace --env-kwargs' silently."""
    with pytest.raises(CommandError, match=fragment):
        config_of(*argv)
    kept = config_of("--env-kwargs", "observe_traits=true", "--people", "default").env_kwargs
    assert kept == {"observe_traits": True, "people": "default"}  # one keyword each: no conflict


def test_text_that_is_no_keywords_is_refused_by_the_parser(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        config_of("--env-kwargs", "nonsense")
    assert "--env-kwargs takes JSON or NAME=VALUE pairs" in capsys.readouterr().err


@pytest.mark.slow  # solves penalty 10's optimum the first time (a minute or two), then a tiny run
def test_a_run_on_penalty_10_reports_its_regret_against_penalty_10_s_optimum(tmp_path: Path) -> None:
    from heartpole.optimum import optimum

    out = tmp_path / "run"
    argv = ["train", "--env-kwargs", "heart_attack_penalty=10", "--timesteps", "64", "--n-envs", "4",
            "--eval-episodes", "20", "--out", str(out), "--json"]  # fmt: skip
    done = subprocess.run([sys.executable, "-m", "heartpole", *argv], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    run = json.loads(done.stdout)
    assert json.loads((out / "heartpole.json").read_text())["env_kwargs"] == PENALTY
    best = optimum("HeartPole-v0", PENALTY).expected_return  # about -12.04; v0's is -123.30
    assert run["regret"] == pytest.approx(best - run["expected_return"], abs=1e-9)
