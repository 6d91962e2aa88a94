"""Training with Stable-Baselines3: the training reward, presets, runs and the CLI (the VecEnv adapter:
test_training_adapter.py).

Every training here is a smoke run of a few thousand steps: it checks that the outputs exist, load back
and act, not that the agent learns (benchmarks/solve.py measures that, see README).
"""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from stable_baselines3.common.vec_env import VecNormalize  # noqa: E402

import heartpole  # noqa: E402
from heartpole import policies, training  # noqa: E402
from heartpole.cli import main  # noqa: E402
from heartpole.model import TIME_ELAPSED  # noqa: E402
from heartpole.training import (  # noqa: E402
    ENV_REWARD,
    SHAPED_REWARD,
    HeartPoleSB3VecEnv,
    TrainConfig,
    TrainingReward,
    preset_config,
)

torch.set_num_threads(1)
pytestmark = pytest.mark.filterwarnings("ignore:.*is out of date.*:DeprecationWarning")
FLOOR = 0.5 / (1.0 + np.exp(6.0))  # heart-attack risk at zero blood pressure
RUN_FILES = ("model.zip", "vecnormalize.pkl", "heartpole.json", "learning_curve.csv", "evaluation.json")


def tiny(algo: str = "ppo", **overrides: object) -> TrainConfig:
    """The default preset's settings, shrunk to a smoke run."""
    settings: dict[str, object] = {"timesteps": 2048, "n_envs": 4, **overrides}
    if algo == "dqn":
        settings["hyperparameters"] = {
            **training.DEFAULT_HYPERPARAMETERS["dqn"],
            "learning_starts": 200,
            "buffer_size": 5000,
        }
    return preset_config("default", algo, **settings)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------------------------------
# the training reward


def rewards_and_infos(reward: TrainingReward, seed: int = 1, steps: int = 300) -> list[tuple]:
    """(training reward, infos, observation before, observation after) per step of a coffee-heavy policy."""
    venv = HeartPoleSB3VecEnv(num_envs=64, reward=reward, env_kwargs={"max_steps": 100})
    venv.seed(seed)
    obs = venv.reset()
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(steps):
        before = obs
        obs, trained, _, infos = venv.step(rng.choice(4, size=64, p=[0.3, 0.5, 0.1, 0.1]))
        after = np.array([info.get("terminal_observation", o) for info, o in zip(infos, obs)])
        out.append((trained, infos, before, after))
    return out


def test_env_reward_is_passed_through_unchanged() -> None:
    venv = HeartPoleSB3VecEnv(num_envs=8)
    native = gym.make_vec("HeartPole-v0", num_envs=8, vectorization_mode="vector_entry_point")
    venv.seed(9)
    venv.reset()
    native.reset(seed=9)
    for a in np.random.default_rng(2).integers(0, 4, (40, 8)):
        _, reward, _, _ = venv.step(a)
        _, expected, _, _, _ = native.step(a)
        np.testing.assert_array_equal(reward, expected)


def test_shaped_reward_is_the_documented_formula() -> None:
    rate, horizon = 0.32, 2000.0
    for trained, infos, before, after in rewards_and_infos(SHAPED_REWARD, steps=150):
        risk = np.array([info["heart_attack_risk"] for info in infos])
        worked = np.array([info["productivity"] for info in infos])
        half_hours = after[:, TIME_ELAPSED].astype(np.float64) - before[:, TIME_ELAPSED]
        assert set(np.unique(half_hours)) <= {1.0, 17.0}  # a half-hour of work, after 16 of sleep or not
        expected = (worked - rate * half_hours) / horizon - 100 * (risk - FLOOR)
        np.testing.assert_allclose(trained, expected, rtol=1e-5, atol=1e-6)


def test_expected_risk_penalty_is_unbiased() -> None:
    """The summed risk has the realised attacks' expectation (tolerance: 4.5 standard errors)."""
    risk_part, attack_part = [], []
    for _, infos, _, _ in rewards_and_infos(ENV_REWARD, seed=2, steps=400):
        risk_part.append([info["heart_attack_risk"] for info in infos])
        attack_part.append([info["heart_attack"] for info in infos])
    risks, attacks = np.array(risk_part).sum(axis=0), np.array(attack_part, dtype=float).sum(axis=0)
    difference = attacks - risks  # per env; a martingale's end value, mean 0
    assert risks.mean() > 2 * 400 * FLOOR  # coffee-heavy: well above the floor
    assert abs(difference.mean()) < 4.5 * difference.std(ddof=1) / np.sqrt(len(difference))


def test_training_reward_validates_its_fields() -> None:
    with pytest.raises(ValueError, match="score_rate"):
        TrainingReward(score_rate=float("nan"))
    with pytest.raises(ValueError, match="horizon"):
        TrainingReward(horizon=0)
    assert ENV_REWARD.is_env_reward and not SHAPED_REWARD.is_env_reward
    assert "heart-attack risk" in SHAPED_REWARD.describe()


def test_auto_rate_tracks_the_running_score() -> None:
    reward = TrainingReward(expected_risk=True, score_rate="auto", rate_window=50)
    venv = HeartPoleSB3VecEnv(num_envs=16, reward=reward)
    venv.seed(0)
    obs = venv.reset()
    for _ in range(300):  # never drink, sleep when tired: the score settles near 0.32
        obs, *_ = venv.step(np.where(obs[:, 0] < 0.35, 3, 0))
    assert 0.25 < venv.rate < 0.40


# ------------------------------------------------------------------------------------------------------
# presets and configurations


def test_tutorial_preset_is_the_tutorial_setup() -> None:
    config = preset_config("tutorial", timesteps=100)
    assert (config.algo, config.net_arch, dict(config.hyperparameters)) == ("dqn", (16, 16), {})
    assert config.reward.is_env_reward and not config.normalize_observations and config.n_envs == 1
    assert preset_config("tutorial").timesteps == 500_000
    model, env = training.build_model(config)
    from stable_baselines3 import DQN

    reference = DQN("MlpPolicy", gym.make("HeartPole-v0"), policy_kwargs={"net_arch": [16, 16]}, device="cpu")
    for name in ("learning_rate", "gamma", "buffer_size", "batch_size", "target_update_interval", "train_freq"):
        assert getattr(model, name) == getattr(reference, name), name
    layers = [m for m in model.q_net.q_net if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in layers] == [(6, 16), (16, 16), (16, 4)]
    assert not isinstance(env, VecNormalize)


def test_default_preset_is_ppo_on_the_shaped_reward() -> None:
    config = preset_config()
    assert config.algo == "ppo" and config.reward == SHAPED_REWARD and config.n_envs == 16
    assert config.normalize_observations and config.normalize_rewards and config.gamma == 0.95
    assert preset_config(algo="dqn").hyperparameters["gamma"] == 0.95


def test_default_preset_on_a_variant_uses_the_variants_rate() -> None:
    assert preset_config(env_id="HeartPole-v1").reward.score_rate == 0.68  # 98% of v1's best, 0.69
    assert preset_config(env_id="HeartPole-v1", score_rate="auto").reward.score_rate == "auto"
    assert preset_config(env_id="HeartPole-v1", score_rate=0.5).reward.score_rate == 0.5
    assert preset_config(score_rate="best").reward == SHAPED_REWARD  # v0: its tuned 0.32
    heartpole.register_variant("AwakeTrainPole-v0", actions=heartpole.V0_ACTIONS[:3])
    try:  # no sleep: no known best, so the rate is estimated while training
        assert preset_config(env_id="AwakeTrainPole-v0").reward.score_rate == "auto"
    finally:
        gym.registry.pop("AwakeTrainPole-v0")
        heartpole.registry._variants.discard("AwakeTrainPole-v0")
    with pytest.raises(ValueError, match="no score rate"):
        preset_config("tutorial", score_rate="auto")


def test_runs_are_judged_against_their_own_envs_bar() -> None:
    evaluation = {"mean_return": -124.5, "ci95": [-130.0, -119.0], "expected_return": -124.5,
                  "expected_ci95": [-124.6, -124.4], "heart_attacks_per_episode": 1.25, "score": 0.45,
                  "drinks_per_episode": 0.0, "sleeps_per_episode": 60.0}  # fmt: skip
    v0 = training.run_summary(preset_config(), evaluation, 1.0, 1.0)
    v1 = training.run_summary(preset_config(env_id="HeartPole-v1"), evaluation, 1.0, 1.0)
    assert v0["solved"] and v0["solved_bar"]["score_at_least"] == 0.30
    assert not v1["solved"] and v1["solved_bar"]["score_at_least"] == 0.63  # v1's best score is 0.69


def test_train_command_exposes_the_score_rate(tmp_path: Path) -> None:
    import argparse

    from heartpole.cli.common import CommandError
    from heartpole.cli.train import build_config

    def args(**kw) -> argparse.Namespace:
        base = {"preset": "default", "algo": None, "env": "HeartPole-v1", "timesteps": None, "n_envs": None,
                "seed": "0", "score_rate": "best"}  # fmt: skip
        return argparse.Namespace(**{**base, **kw})

    assert build_config(args()).reward.score_rate == 0.68
    assert build_config(args(score_rate="auto")).reward.score_rate == "auto"
    assert build_config(args(score_rate="0.4")).reward.score_rate == 0.4
    with pytest.raises(CommandError, match="--score-rate takes best, auto or a number"):
        build_config(args(score_rate="fast"))
    with pytest.raises(CommandError, match="applies to the default preset"):
        build_config(args(preset="tutorial", score_rate="auto"))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"preset": "fancy"}, "unknown preset"),
        ({"algo": "sac"}, "unknown algorithm"),
        ({"timesteps": 0}, "timesteps"),
        ({"n_envs": -1}, "n_envs"),
        ({"seed": -3}, "seed"),
    ],
)
def test_bad_configurations_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        preset_config(**kwargs)


def test_training_is_reproducible_from_the_seed() -> None:
    def parameters(seed: int) -> list[np.ndarray]:
        trained = training.train_model(tiny(timesteps=1024, seed=seed))
        return [p.detach().numpy().copy() for p in trained.model.policy.parameters()]

    first, again, other = parameters(1), parameters(1), parameters(2)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert not all(np.array_equal(a, b) for a, b in zip(first, other))


def test_learning_curve_rows_average_the_ended_episodes() -> None:
    trained = training.train_model(tiny(timesteps=1024, n_envs=4, env_kwargs={"max_steps": 8}))
    rows = trained.curve
    assert len(rows) == 1024 // 8 // 16  # 128 episodes of 8 steps, 16 per row
    assert [r["timesteps"] for r in rows] == sorted(r["timesteps"] for r in rows)
    for row in rows:  # the return telescopes: score - 100 x heart attacks, averaged alike
        assert row["mean_return"] == pytest.approx(row["score"] - 100 * row["heart_attacks"], abs=1e-3)


# ------------------------------------------------------------------------------------------------------
# runs: files that exist, load and act


@pytest.mark.parametrize("algo", ["ppo", "a2c", "dqn"])
def test_train_run_writes_files_that_load_and_act(tmp_path: Path, algo: str) -> None:
    from heartpole.policies import load_policy

    summary = training.train_run(tiny(algo, seed=3), tmp_path / "run", eval_episodes=10)
    folder = tmp_path / "run"
    for name in RUN_FILES:
        assert (folder / name).is_file(), name
    sidecar = json.loads((folder / "heartpole.json").read_text())
    from heartpole.policies.saved import file_sha256

    assert sidecar["model"] == "model.zip" and sidecar["model_sha256"] == file_sha256(folder / "model.zip")
    assert sidecar["vecnormalize"] == "vecnormalize.pkl"
    assert sidecar["vecnormalize_sha256"] == file_sha256(folder / "vecnormalize.pkl")
    assert load_policy(str(folder / "model.zip")).normalizer_path == folder / "vecnormalize.json"
    assert (sidecar["algo"], sidecar["env_id"], sidecar["seed"], sidecar["timesteps"]) == (
        algo,
        "HeartPole-v0",
        3,
        2048,
    )
    assert sidecar["config"]["hyperparameters"]["gamma"] == 0.95
    evaluation = json.loads((folder / "evaluation.json").read_text())
    assert evaluation["episodes"] == 10 and evaluation["policy"] == str(folder / "model.zip")
    assert summary["score"] == evaluation["score"] and summary["seed"] == 3
    with (folder / "learning_curve.csv").open() as handle:
        reader = csv.DictReader(handle)
        assert tuple(reader.fieldnames or ()) == policies.CURVE_COLUMNS
        assert all(np.isfinite(float(row["mean_return"])) for row in reader)
    policy = load_policy(str(folder / "model.zip"), "HeartPole-v0")
    venv = gym.make_vec("HeartPole-v0", num_envs=32, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    for _ in range(20):
        actions = policy(obs)
        assert actions.shape == (32,) and actions.dtype.kind == "i" and ((0 <= actions) & (actions < 4)).all()
        obs, *_ = venv.step(actions)


def test_loaded_policy_matches_the_trained_model(tmp_path: Path) -> None:
    """load_policy reproduces the policy as trained: VecNormalize's statistics, then a deterministic act."""
    from heartpole.policies import load_policy

    config = tiny(seed=4)
    trained = training.train_model(config)
    trained.model.save(tmp_path / "model.zip")
    trained.normalizer.save(str(tmp_path / "vecnormalize.pkl"))  # type: ignore[union-attr]
    (tmp_path / "heartpole.json").write_text(json.dumps({"algo": "ppo", "vecnormalize": "vecnormalize.pkl"}))
    obs = np.random.default_rng(0).uniform(0, [2, 3, 0.1, 40, 1500, 400], size=(256, 6)).astype(np.float32)
    expected, _ = trained.model.predict(trained.normalizer.normalize_obs(obs), deterministic=True)  # type: ignore[union-attr]
    np.testing.assert_array_equal(load_policy(str(tmp_path / "model.zip"))(obs), expected)


def test_train_seeds_writes_one_folder_per_seed_and_a_summary(tmp_path: Path) -> None:
    seen: list[int] = []
    summary = training.train_seeds(
        tiny(timesteps=1024), [2, 0], tmp_path, eval_episodes=10, on_run=lambda run: seen.append(run["seed"])
    )
    assert seen == [2, 0]
    for seed in (2, 0):
        assert all((tmp_path / f"seed_{seed}" / name).is_file() for name in RUN_FILES)
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk == json.loads(json.dumps(summary))
    assert on_disk["seeds"] == [2, 0] and [run["seed"] for run in on_disk["runs"]] == [2, 0]
    score = on_disk["aggregate"]["score"]
    low, high = score["iqm_ci95"]
    assert score["min"] <= low <= score["iqm"] <= high <= score["max"]
    assert on_disk["solved_seeds"] == sum(run["solved"] for run in on_disk["runs"])
    cpu = [run["cpu_seconds"] for run in on_disk["runs"]]
    assert all(0 < seconds for seconds in cpu) and on_disk["cpu_seconds"] == pytest.approx(sum(cpu))
    assert training.cpu_total([{"cpu_seconds": 1.0}, {"cpu_seconds": None}]) == {}  # not measured: no total


# ------------------------------------------------------------------------------------------------------
# output folders


def test_staged_output_leaves_nothing_behind_on_failure(tmp_path: Path) -> None:
    out = tmp_path / "new" / "run"
    with pytest.raises(RuntimeError), training.staged_output(out) as staging:
        (staging / "model.zip").write_text("half")
        raise RuntimeError("boom")
    assert not (tmp_path / "new").exists()
    with training.staged_output(out) as staging:
        (staging / "heartpole.json").write_text("{}")
    assert (out / "heartpole.json").is_file() and os.listdir(out.parent) == ["run"]


def test_force_replaces_only_an_earlier_training_run(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "notes.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="--force"):
        training.check_output_folder(run)
    with pytest.raises(PermissionError, match="refusing"):
        training.check_output_folder(run, force=True)
    (run / "heartpole.json").write_text("{}")
    with training.staged_output(run, force=True) as staging:
        (staging / "heartpole.json").write_text('{"new": true}')
    assert sorted(os.listdir(run)) == ["heartpole.json"] and "new" in (run / "heartpole.json").read_text()
    assert os.listdir(tmp_path) == ["run"]


# ------------------------------------------------------------------------------------------------------
# the command line


def test_cli_train_then_evaluate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ppo"
    args = ["train", "--timesteps", "2048", "--n-envs", "4", "--seed", "1", "--eval-episodes", "10", "--out", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "seed 1: heart attacks" in printed and f"wrote {out}/" in printed
    assert all((out / name).is_file() for name in RUN_FILES)
    assert main(["evaluate", "--policy", str(out / "model.zip"), "--episodes", "10", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["episodes"] == 10 and np.isfinite(result["score"])
    # the same run again: refused without --force, replaced with it
    assert main(args) == 2
    assert "--force" in capsys.readouterr().err
    before = (out / "model.zip").stat().st_mtime_ns
    assert main([*args, "--force", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["out"] == str(out) and data["seed"] == 1 and (out / "model.zip").stat().st_mtime_ns != before


def test_cli_train_seeds_prints_the_aggregate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "seeds"
    args = ["train", "--seeds", "0-1", "--timesteps", "1024", "--n-envs", "2", "--eval-episodes", "10"]
    assert main([*args, "--algo", "a2c", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "interquartile mean" in printed and "of 2 seeds" in printed
    assert (out / "summary.json").is_file() and (out / "seed_0" / "model.zip").is_file()
    assert json.loads((out / "seed_1" / "heartpole.json").read_text())["algo"] == "a2c"


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--algo", "sac"], "unknown algorithm 'sac'"),
        (["--timesteps", "0"], "--timesteps must be a whole number >= 1, got 0"),
        (["--timesteps", "-5"], "--timesteps must be a whole number >= 1"),
        (["--timesteps", "lots"], "--timesteps must be a whole number >= 1, got 'lots'"),
        (["--n-envs", "0"], "--n-envs must be"),
        (["--seed", "-1"], "--seed must be a whole number >= 0"),
        (["--seeds", "4-2"], "--seeds takes ranges"),
        (["--seeds", "1,1"], "twice"),
        (["--seeds", "a-b"], "--seeds takes a list"),
        (["--seeds", "0-100"], "--seeds: at most 100 seeds with --backend sb3, got '0-100'"),
        pytest.param(
            ["--backend", "jax", "--seeds", "0-4,10-65541"],
            "at most 65,536 seeds with --backend jax",
            marks=pytest.mark.skipif(importlib.util.find_spec("jax") is None, reason="needs the 'jax' extra"),
        ),
        (["--preset", "fast"], "unknown preset 'fast'"),
        (["--env", "CartPole-v1"], "not a HeartPole env"),
        (["--env", "NoSuchEnv-v0"], "'NoSuchEnv-v0' is not a HeartPole env; accepted: HeartPole-v0"),
        (["--env", "evilmod:HeartPole-v0"], "'evilmod:HeartPole-v0' is not a HeartPole env"),
        (["--eval-episodes", "1"], "--eval-episodes must be a whole number >= 2"),
        (["--seed", "1", "--seeds", "0-4"], "not allowed with argument"),
    ],
)
def test_cli_bad_arguments_give_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], fragment: str
) -> None:
    out = tmp_path / "out"
    try:
        code = main(["train", *args, "--out", str(out)])
    except SystemExit as exit:  # argparse's own checks (mutually exclusive options) exit from parse_args
        code = exit.code
    assert code == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("heartpole train: error:") and fragment in lines[0], err
    assert not out.exists() and os.listdir(tmp_path) == []


def test_cli_refuses_a_non_empty_out_without_force(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "keep.txt").write_text("precious")
    assert main(["train", "--timesteps", "100", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not empty; pass --force" in err[0]
    assert main(["train", "--timesteps", "100", "--out", str(tmp_path), "--force"]) == 2
    assert "refusing" in capsys.readouterr().err
    assert os.listdir(tmp_path) == ["keep.txt"]


def test_cli_says_what_to_install_without_the_train_extra(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import heartpole.cli.train as command

    real = command.importlib.util.find_spec
    monkeypatch.setattr(
        command.importlib.util, "find_spec", lambda name, *a: None if name == "stable_baselines3" else real(name, *a)
    )
    assert main(["train", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "heartpole train: error: training needs stable_baselines3, which this Python cannot import: "
        "pip install 'heartpole[train]'"
    ]


def test_import_heartpole_and_the_cli_parser_stay_light() -> None:
    code = (
        "import sys, heartpole, heartpole.cli; heartpole.cli.build_parser(); "
        "print(sorted(m for m in ('stable_baselines3', 'torch', 'heartpole.training') if m in sys.modules))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


# ------------------------------------------------------------------------------------------------------
# the tutorial's Python flow, in Gymnasium terms


@pytest.mark.filterwarnings("ignore:Evaluation environment is not wrapped with a ``Monitor``:UserWarning")
def test_tutorial_flow_runs_unchanged() -> None:
    from stable_baselines3 import DQN
    from stable_baselines3.common.evaluation import evaluate_policy

    env = gym.make("HeartPole-v0")
    model = DQN("MlpPolicy", env, verbose=0, policy_kwargs={"net_arch": [16, 16]}, seed=0, device="cpu")
    model.learn(total_timesteps=500, log_interval=10)
    mean_reward, std_reward = evaluate_policy(model, gym.make("HeartPole-v0"), n_eval_episodes=2)
    assert np.isfinite(mean_reward) and np.isfinite(std_reward)
    assert isinstance(model.env.envs[0].unwrapped, heartpole.HeartPole)
