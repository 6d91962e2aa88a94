"""Ray Tune for seeds and searches (heartpole.scale, heartpole train --ray, heartpole tune).

The tests that start Ray share one local Ray session on one CPU (started once for the module, ~5-15 s)
and are marked slow; every training is a smoke run of a few thousand steps with a handful of evaluation
episodes: they check the plumbing (files, summaries, identical results, failures, resuming), not learning.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("ray")
pytest.importorskip("optuna")
torch = pytest.importorskip("torch")

from heartpole import training  # noqa: E402
from heartpole.cli import main  # noqa: E402
from tests.signal_dispositions import as_in_a_terminal  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore:.*is out of date.*:DeprecationWarning")
RUN_FILES = ("model.zip", "vecnormalize.pkl", "heartpole.json", "learning_curve.csv", "evaluation.json")
TINY = ["--timesteps", "1024", "--n-envs", "2", "--eval-episodes", "10"]


@pytest.fixture(scope="module")
def local_ray() -> Iterator[None]:
    """One local Ray session on one CPU for the module's Ray tests (the library reuses a running session)."""
    from heartpole import scale

    with scale.ray_session(num_cpus=1):
        yield


def one_line_error(capsys: pytest.CaptureFixture[str], command: str, fragment: str) -> None:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"heartpole {command}: error:") and fragment in err[0], err


# ------------------------------------------------------------------------------------------------------
# without starting Ray


def test_import_heartpole_and_the_cli_parser_never_import_ray() -> None:
    code = (
        "import sys, heartpole, heartpole.cli; heartpole.cli.build_parser(); "
        "print(sorted(m for m in ('ray', 'optuna', 'heartpole.scale') if m in sys.modules))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["train", "--seeds", "5-2", "--ray"], "--seeds takes ranges low-high with 0 <= low <= high, got '5-2'"),
        (["train", "--ray"], "--ray runs the seeds of --seeds"),
        (["train", "--seeds", "0-1", "--address", "auto"], "--address needs --ray"),
        (["train", "--seeds", "0-1", "--ray", "--cpus-per-trial", "0"], "--cpus-per-trial must be a whole number"),
        (["tune", "--algo", "sac"], "unknown algorithm 'sac' for a search; choose one of ppo, a2c"),
        (["tune", "--algo", "dqn"], "unknown algorithm 'dqn' for a search"),
        (["tune", "--trials", "0"], "--trials must be a whole number >= 1, got 0"),
        (["tune", "--trials", "many"], "--trials must be a whole number >= 1, got 'many'"),
        (["tune", "--seeds-per-trial", "0"], "--seeds-per-trial must be a whole number >= 1"),
        # 10**8 seeds a trial: minutes building the list, and SIGTERM then ended it with status 15, not 143
        (["tune", "--seeds-per-trial", "100000000"], "--seeds-per-trial must be at most 100"),
        (["tune", "--timesteps", "1", "--n-envs", "4"], "--timesteps (1) must be at least --n-envs (4)"),
        (["tune", "--env", "CartPole-v1"], "not a HeartPole env"),
        (["tune", "--resume"], "--resume: no search to continue in"),
        (["tune", "--cpus-per-trial", "0"], "--cpus-per-trial must be a whole number >= 1"),
    ],
)
def test_bad_arguments_give_one_line_and_leave_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], fragment: str
) -> None:
    out = tmp_path / "out"
    assert main([*args, "--out", str(out)]) == 2
    one_line_error(capsys, args[0], fragment)
    assert os.listdir(tmp_path) == []


def test_tune_refuses_a_folder_it_did_not_write(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["tune", "--out", str(tmp_path)]) == 2
    one_line_error(capsys, "tune", "--resume to continue its search or --force")
    assert main(["tune", "--force", "--out", str(tmp_path)]) == 2
    one_line_error(capsys, "tune", "holds no search")
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_default_space_and_apply_params() -> None:
    from heartpole import scale

    space = scale.default_space("ppo")
    assert set(space) == {"learning_rate", "ent_coef", "gamma", "n_steps", "net_width", "net_depth"}
    assert set(space["n_steps"].categories) == {32, 64, 128, 256, 512}
    assert set(scale.default_space("a2c")["n_steps"].categories) == {5, 8, 16, 32}
    base = training.preset_config()
    config = scale.apply_params(base, {"learning_rate": 1e-4, "n_steps": 64.0, "net_width": 32, "net_depth": 3})
    assert config.net_arch == (32, 32, 32)
    assert config.hyperparameters["n_steps"] == 64 and isinstance(config.hyperparameters["n_steps"], int)
    assert config.hyperparameters["learning_rate"] == 1e-4
    assert config.hyperparameters["batch_size"] == base.hyperparameters["batch_size"]  # the preset's
    with pytest.raises(ValueError, match="no default search space for 'dqn'"):
        scale.default_space("dqn")


def test_progress_bar_counts_trials_and_the_best_figure(capsys: pytest.CaptureFixture[str]) -> None:
    from types import SimpleNamespace

    from heartpole import scale

    seen: list[dict] = []
    bar = scale.TrialsBar(3, "seeds", "expected_return", seen.append)
    old = SimpleNamespace(status="TERMINATED", last_result={"expected_return": -130.0})  # restored, finished
    new = SimpleNamespace(status="RUNNING", last_result={"expected_return": -124.0})
    broken = SimpleNamespace(status="RUNNING", last_result={})
    bar.on_trial_complete(0, [old, new, broken], new)
    assert bar._describe() == "seeds 2/3, best expected-risk return -124.000" and seen == [{"expected_return": -124.0}]
    new.status = "TERMINATED"
    bar.on_trial_error(0, [old, new, broken], broken)
    assert bar._describe() == "seeds 3/3, 1 failed, best expected-risk return -124.000"
    assert bar.bar.done == 3
    bar.close()


def test_search_settings_round_trip() -> None:
    from heartpole import scale

    settings = scale.SearchSettings(training.preset_config(timesteps=2048), trials=3, seeds=(0, 1), eval_episodes=5)
    assert scale.SearchSettings.from_dict(json.loads(json.dumps(settings.to_dict()))) == settings


# ------------------------------------------------------------------------------------------------------
# seeds on Ray


def comparable(folder: Path) -> dict[str, object]:
    """A seed folder's evaluation and learning curve, without the timings."""
    evaluation = json.loads((folder / "evaluation.json").read_text())
    evaluation.pop("seconds", None)
    return {"evaluation": evaluation, "curve": (folder / "learning_curve.csv").read_text()}


@pytest.mark.slow
def test_train_ray_writes_what_the_sequential_path_writes_with_identical_results(
    local_ray: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ray_out, plain_out = tmp_path / "ray", tmp_path / "plain"
    assert main(["train", "--seeds", "0-1", "--ray", *TINY, "--out", str(ray_out)]) == 0
    printed, noise = capsys.readouterr()
    assert noise == "", "Ray or Tune printed something"  # the progress bar shows only on a terminal
    assert "seed 0: heart attacks" in printed and "seed 1: heart attacks" in printed
    assert "interquartile mean" in printed and "of 2 seeds" in printed and "failed" not in printed
    assert main(["train", "--seeds", "0-1", *TINY, "--out", str(plain_out)]) == 0
    capsys.readouterr()
    for seed in (0, 1):
        assert all((ray_out / f"seed_{seed}" / name).is_file() for name in RUN_FILES)
        ray_run, plain_run = comparable(ray_out / f"seed_{seed}"), comparable(plain_out / f"seed_{seed}")
        ray_run["evaluation"]["policy"] = plain_run["evaluation"]["policy"]  # type: ignore[index]
        assert ray_run == plain_run
    timing = ("train_seconds", "wall_seconds", "cpu_seconds")
    ray_summary = json.loads((ray_out / "summary.json").read_text())
    plain_summary = json.loads((plain_out / "summary.json").read_text())
    for summary in (ray_summary, plain_summary):
        assert summary.pop("cpu_seconds") == pytest.approx(sum(run["cpu_seconds"] for run in summary["runs"]))
        summary["runs"] = [{k: v for k, v in run.items() if k not in timing} for run in summary["runs"]]
        summary["aggregate"].pop("wall_seconds")
    assert ray_summary == plain_summary
    assert not list(tmp_path.glob(".*partial"))


@pytest.mark.slow
def test_train_ray_failed_seeds_are_one_line_each(local_ray: None, tmp_path: Path) -> None:
    from heartpole import scale

    impossible = training.preset_config(timesteps=64, n_envs=1, hyperparameters={"n_steps": 1})  # PPO needs > 1
    with pytest.raises(scale.AllTrialsFailedError) as caught:
        scale.train_seeds_ray(impossible, [0, 1], tmp_path / "out", eval_episodes=4)
    lines = [failure.line() for failure in caught.value.failures]
    assert sorted(lines) == lines and len(lines) == 2 and all("\n" not in line for line in lines)
    assert lines[0].startswith("seed 0 failed: AssertionError:") and "n_steps" in lines[0]


# ------------------------------------------------------------------------------------------------------
# searches on Ray


@pytest.mark.slow
def test_tune_reports_a_failed_trial_and_writes_a_preset_that_train_accepts(
    local_ray: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from ray import tune

    from heartpole import scale

    settings = scale.SearchSettings(training.preset_config(timesteps=1024, n_envs=2), trials=2, seeds=(0,),
                                    eval_episodes=10)  # fmt: skip
    space = {"learning_rate": tune.choice([-1.0, 3e-4]), "net_width": tune.choice([8, 16])}
    points = [{"learning_rate": -1.0, "net_width": 8}, {"learning_rate": 3e-4, "net_width": 16}]
    out = tmp_path / "search"
    summary = scale.tune_search(settings, out, space=space, points_to_evaluate=points)
    assert [row["trial"] for row in summary["trials"]] == [1, 2]
    assert summary["failed"] == [{"trial": "trial 1", "error": "ValueError: Invalid learning rate: -1.0"}]
    assert summary["best"]["trial"] == 2 and summary["best"]["learning_rate"] == 3e-4
    rows = list(csv.DictReader((out / "trials.csv").open()))
    assert len(rows) == 2 and rows[0]["error"] and float(rows[1]["objective"]) == summary["best"]["objective"]
    assert (out / "search.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from heartpole.cli.tune import format_trials

    table = format_trials(summary).splitlines()
    assert table[-1] == "trial 1 failed: ValueError: Invalid learning rate: -1.0"
    preset = training.load_preset(out / "best_preset.json")
    assert preset.net_arch == (16, 16) and preset.hyperparameters["learning_rate"] == 3e-4
    trained = tmp_path / "trained"
    args = ["train", "--preset", str(out / "best_preset.json"), "--eval-episodes", "4", "--out", str(trained)]
    assert main(args) == 0
    capsys.readouterr()
    sidecar = json.loads((trained / "heartpole.json").read_text())
    assert sidecar["config"]["net_arch"] == [16, 16] and sidecar["config"]["hyperparameters"]["learning_rate"] == 3e-4


@pytest.mark.slow
def test_an_interrupted_search_resumes_without_rerunning_finished_trials(tmp_path: Path) -> None:
    out = tmp_path / "search"
    command = [sys.executable, "-m", "heartpole", "tune", "--trials", "2", "--seeds-per-trial", "1", *TINY,
               "--out", str(out)]  # fmt: skip
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=as_in_a_terminal
    )  # SIGINT not ignored even where the run was started as a background job
    deadline = time.monotonic() + 240
    while not list(out.glob("trials/*/summary.json")) and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.2)
    early = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("trials/*/summary.json")}
    time.sleep(3)  # long enough for these trials to report to Tune, which then counts them as finished
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    if process.returncode == 0:
        pytest.skip("the search finished before it could be interrupted")
    assert process.returncode == 130, err
    assert f"heartpole tune --resume --trust-pickles --out {out}" in err.strip().splitlines()[-1]
    refused = subprocess.run([*command[:4], "--resume", "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert refused.returncode == 2 and "--trust-pickles" in refused.stderr, refused.stderr
    resumed = subprocess.run([*command[:4], "--resume", "--trust-pickles", "--out", str(out), "--json"],
                             capture_output=True,
                             text=True, timeout=600)  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    assert resumed.stderr == "", "Ray, Tune or Optuna printed something"  # the bar shows only on a terminal
    summary = json.loads(resumed.stdout)
    assert [row["trial"] for row in summary["trials"]] == [1, 2]
    assert set(early) <= {row["trial_id"] for row in summary["trials"]}
    for trial_id, written in early.items():  # trials finished before the interruption were not run again
        assert (out / "trials" / trial_id / "summary.json").stat().st_mtime_ns == written


# ------------------------------------------------------------------------------------------------------
# the RLlib example: registration and a few steps only (RLlib itself is not installed by any extra)

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rllib_heartpole.py"


@pytest.fixture(scope="module")
def rllib_example() -> object:
    """examples/rllib_heartpole.py as a module, pickled by value as when it runs as a script."""
    import importlib.util

    from ray import cloudpickle  # Ray's own copy pickles the registry's creators

    spec = importlib.util.spec_from_file_location("rllib_heartpole", EXAMPLE)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules["rllib_heartpole"] = module
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    cloudpickle.register_pickle_by_value(module)
    yield module
    cloudpickle.unregister_pickle_by_value(module)
    del sys.modules["rllib_heartpole"]


def steps_of(env: object, n: int) -> list[tuple[bool, bool]]:
    env.reset(seed=0)  # type: ignore[attr-defined]
    return [tuple(bool(x) for x in env.step(0)[2:4]) for _ in range(n)]  # type: ignore[attr-defined]


def test_rllib_example_registers_a_creator_of_heartpole(rllib_example: object) -> None:
    from ray.tune.registry import ENV_CREATOR, _global_registry

    name = rllib_example.register("HeartPole-test-v0")  # type: ignore[attr-defined]
    assert _global_registry.contains(ENV_CREATOR, name)
    env = _global_registry.get(ENV_CREATOR, name)({"max_steps": 4})
    assert env.unwrapped.max_steps == 4
    assert steps_of(env, 4) == [(False, False)] * 3 + [(False, True)]  # truncated at max_steps, never terminated


@pytest.mark.slow
def test_rllib_example_env_is_made_inside_a_ray_worker(local_ray: None, rllib_example: object) -> None:
    import ray

    name = rllib_example.register("HeartPole-worker-v0")  # type: ignore[attr-defined]

    @ray.remote
    def in_worker(name: str) -> dict[str, object]:
        import gymnasium as gym
        from ray.tune.registry import ENV_CREATOR, _global_registry

        fresh = "heartpole" not in sys.modules
        try:
            gym.make("HeartPole-v0")
            plain = True
        except gym.error.NameNotFound:
            plain = False
        env = _global_registry.get(ENV_CREATOR, name)({"max_steps": 3})
        env.reset(seed=0)
        steps = [tuple(bool(x) for x in env.step(0)[2:4]) for _ in range(3)]
        return {"fresh": fresh, "plain_id_works": plain, "steps": steps}

    result = ray.get(in_worker.remote(name), timeout=120)
    assert result["steps"] == [(False, False), (False, False), (False, True)]
    if result["fresh"]:  # a worker that never imported heartpole does not know the plain id
        assert result["plain_id_works"] is False


def test_a_search_folder_is_checked_before_any_trial(tmp_path: Path) -> None:
    from heartpole import scale

    assert scale.prepare_search_folder(tmp_path / "new") == (tmp_path / "new").resolve()
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        scale.prepare_search_folder(tmp_path / "file")
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("x")
    with pytest.raises(ValueError, match="not empty"):
        scale.prepare_search_folder(other)
    with pytest.raises(ValueError, match="holds no search"):
        scale.prepare_search_folder(other, force=True)
    with pytest.raises(ValueError, match="no search to continue"):
        scale.prepare_search_folder(other, resume=True)
    with pytest.raises(ValueError, match="give one"):
        scale.prepare_search_folder(other, resume=True, force=True)
    assert (other / "keep.txt").is_file()  # nothing but a search is ever removed
    (other / scale.SEARCH_SETTINGS_FILE).write_text("{}")
    assert scale.prepare_search_folder(other, force=True) == other.resolve()
    assert sorted(os.listdir(other)) == ["keep.txt", scale.SEARCH_SETTINGS_FILE]  # replaced only when a search is done
