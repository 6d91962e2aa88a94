"""Training under people: ``heartpole train --people`` reaches the env, the run's summary reports the oracle
regret and is solved by it, and a trait-seeing model observes the traits (and only loads where they are).

The fast tests use the three-person cohort of tests/people_cohorts.py (three solves, cached) or no solve at
all; the tiny CLI runs over the default cohort (24 solves the first time) are marked slow.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from heartpole import records, solved  # noqa: E402
from heartpole.cli import build_parser  # noqa: E402
from heartpole.cli.common import CommandError  # noqa: E402
from heartpole.cli.train import build_config  # noqa: E402
from heartpole.evaluation import evaluate  # noqa: E402
from heartpole.people import People  # noqa: E402
from heartpole.policies import load_policy  # noqa: E402
from heartpole.training import TrainConfig, preset_config  # noqa: E402
from tests.people_cohorts import TRIO  # noqa: E402

pytestmark = pytest.mark.slow  # training under people solves a cohort and compiles the people's loop: minutes

V0_WIDTH = 6


def config_of(*argv: str) -> TrainConfig:
    return build_config(build_parser().parse_args(["train", *argv]))


def test_the_people_flags_reach_the_envs_keyword_arguments(tmp_path: Path) -> None:
    assert config_of().env_kwargs == {}
    assert config_of("--people", "default").env_kwargs == {"people": "default"}
    seeing = config_of("--people", "default", "--observe-traits", "--backend", "jax")
    assert seeing.env_kwargs == {"people": "default", "observe_traits": True}
    preset = tmp_path / "p.json"
    from heartpole.training import save_preset

    save_preset(preset_config(env_kwargs={"max_steps": 40}), preset)
    merged = config_of("--preset", str(preset), "--people", "default").env_kwargs
    assert merged == {"max_steps": 40, "people": "default"}


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--observe-traits"], "--observe-traits needs --people"),
        (["--people", "everyone"], "unknown population 'everyone' for --people; named populations: ['default']"),
    ],
)
def test_bad_people_flags_say_what_is_accepted(argv: list[str], fragment: str) -> None:
    with pytest.raises(CommandError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        config_of(*argv)


def test_a_run_under_people_reports_and_is_solved_by_its_oracle_regret() -> None:
    """The expert's oracle regret on the trio is about 0.001 (tests/test_truth.py): solved at the oracle bar;
    ``coffee`` is far from it. Neither has a regret against one optimum."""
    config = preset_config(env_kwargs={"people": TRIO})
    for policy, is_solved in (("expert", True), ("coffee", False)):
        evaluation = evaluate(policy, episodes=400, seed=0, env_kwargs={"people": TRIO}).to_dict()
        line = records.run_summary(config, evaluation, 1.0, 2.0)
        assert line["oracle_regret"] == evaluation["oracle_regret"]
        assert line["oracle_regret_ci95"] == evaluation["oracle_regret_ci95"]
        assert line["regret"] is None
        assert line["solved"] is is_solved
        assert line["solved_bar"] == {"oracle_regret_at_most": solved.SOLVED_REGRET}
    plain = records.run_summary(preset_config(), evaluate("expert", episodes=20, seed=0).to_dict(), 1.0, 2.0)
    assert "oracle_regret" not in plain and plain["solved_bar"] == {"regret_at_most": solved.SOLVED_REGRET}


def test_the_aggregate_across_seeds_has_the_oracle_regret() -> None:
    runs = [{"oracle_regret": value, "mean_return": -1.0} for value in (0.1, 0.2, 0.3, 0.4)]
    figures = dict(records.aggregate_figures(records.aggregate(runs)))
    assert figures["oracle regret"].startswith("0.2500 [")  # the interquartile mean of the four


def test_a_trait_seeing_model_observes_the_traits_and_loads_only_where_they_are(tmp_path: Path) -> None:
    from heartpole.jax.export import sb3_ppo

    seeing = {"people": "default", "observe_traits": True}
    model, _ = sb3_ppo(preset_config(env_kwargs=seeing))
    width = V0_WIDTH + len(People.default().traits)
    assert model.observation_space.shape == (width,)
    model.save(tmp_path / "model.zip")
    policy = load_policy(str(tmp_path / "model.zip"), env_kwargs=seeing)
    assert policy.model.observation_space.shape == (width,)  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=rf"expects observations \({width},\).*this env has observations \(6,\)"):
        load_policy(str(tmp_path / "model.zip"), env_kwargs={"people": "default"})


def heartpole(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "heartpole", *args], capture_output=True, text=True, timeout=900)


@pytest.mark.slow  # the default cohort's 24 solves the first time (a minute or two), then a tiny run per backend
@pytest.mark.parametrize("backend", ["sb3", "jax"])
def test_a_tiny_training_run_under_people_writes_the_oracle_keys(tmp_path: Path, backend: str) -> None:
    if backend == "jax":
        pytest.importorskip("jax")
    out = tmp_path / "run"
    flags = ["--people", "default", "--observe-traits", "--timesteps", "2048", "--n-envs", "4"]
    flags += ["--eval-episodes", "50", "--seeds", "0-1", "--out", str(out), "--json"]
    result = heartpole("train", "--backend", backend, *flags)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["config"]["env_kwargs"] == {"people": "default", "observe_traits": True}
    assert summary["solved_bar"] == {"oracle_regret_at_most": solved.SOLVED_REGRET}
    assert "oracle_regret" in summary["aggregate"]
    for run in summary["runs"]:
        assert run["oracle_regret"] > 0 and run["oracle_regret_ci95"][0] <= run["oracle_regret_ci95"][1]
        evaluation = json.loads((out / f"seed_{run['seed']}" / records.EVALUATION_FILE).read_text())
        assert evaluation["oracle_regret"] == run["oracle_regret"] and evaluation["regret"] is None
