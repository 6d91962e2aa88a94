"""``heartpole evaluate``, ``compare`` and ``baselines`` through a subprocess, bad input included."""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

KEYS = ("mean_return", "ci95", "expected_return", "expected_ci95", "heart_attacks_per_episode", "score", "episodes")


def heartpole(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "HEARTPOLE_PROGRESS"}
    return subprocess.run(
        [sys.executable, "-m", "heartpole", *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=300
    )


def assert_one_line_error(result: subprocess.CompletedProcess[str], *fragments: str) -> None:
    """Exit code 2, no traceback, and the last stderr line is one ``heartpole ...: error: ...`` line."""
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("heartpole") and "error:" in last
    for fragment in fragments:
        assert fragment in last


def test_evaluate_json_has_the_documented_keys() -> None:
    result = heartpole("evaluate", "--policy", "expert", "--episodes", "40", "--seed", "3", "--json")
    assert result.returncode == 0 and result.stderr == ""
    data = json.loads(result.stdout)
    assert all(key in data for key in KEYS)
    assert data["episodes"] == 40 and data["seed"] == 3 and data["policy"] == "expert"
    low, high = data["expected_ci95"]
    assert low <= data["expected_return"] <= high and data["drinks_per_episode"] == 0
    assert data["ci95"][1] - data["ci95"][0] > 10 * (high - low)


def test_evaluate_prints_a_table() -> None:
    result = heartpole("evaluate", "--policy", "reference", "--episodes", "20")
    assert result.returncode == 0
    for text in ("reference on HeartPole-v0: 20 episodes", "expected-risk return", "95% CI", "narrower"):
        assert text in result.stdout


def test_compare_reports_a_paired_difference() -> None:
    args = ("compare", "--policy", "expert", "--policy", "reference", "--episodes", "200", "--json")
    result = heartpole(*args)
    assert result.returncode == 0 and result.stderr == ""
    data = json.loads(result.stdout)
    difference = data["difference"]
    assert difference["expected_ci95"][0] > 10  # the expert is better, beyond doubt
    paired = difference["ci95"][1] - difference["ci95"][0]
    assert paired < min(side["ci95"][1] - side["ci95"][0] for side in (data["a"], data["b"]))
    text = heartpole(*args[:-1])
    assert text.returncode == 0 and "difference (paired)" in text.stdout and "separate" in text.stdout


def test_baselines_writes_markdown_and_csv(tmp_path: Path) -> None:
    out = tmp_path / "results" / "nested"
    result = heartpole("baselines", "--episodes", "20", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert "published Table 1" in result.stdout and "expert" in result.stdout
    markdown = (out / "baselines.md").read_text()
    # 20 episodes cannot separate optimal from expert (0.00075 apart), but both lead the others
    assert {"| 1 | optimal |" in markdown, "| 1 | expert |" in markdown} == {True, False}
    assert "## Published Table 1" in markdown and "-84.96" in markdown
    rows = list(csv.DictReader((out / "baselines.csv").open()))
    ours = [row["policy"] for row in rows if row["source"] == "heartpole evaluate"]
    assert sorted(ours[:2]) == ["expert", "optimal"]
    assert sorted(ours) == ["coffee", "expert", "nothing", "optimal", "random", "reference"]
    assert len([row for row in rows if row["source"] == "published Table 1"]) == 7
    umask = os.umask(0)
    os.umask(umask)
    assert (out / "baselines.csv").stat().st_mode & 0o777 == 0o666 & ~umask  # not mkstemp's 0600
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary files left


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["evaluate", "--policy", "expret"], ["unknown policy 'expret'", "random, nothing, coffee, reference, expert"]),
        (["evaluate", "--policy", "missing/model.zip"], ["model file not found"]),
        (["evaluate", "--policy", str(Path(__file__).parent)], ["is a folder"]),
        (["evaluate", "--policy", "expert", "--episodes", "0"], ["--episodes"]),
        (["evaluate", "--policy", "expert", "--seed", "-3"], ["--seed"]),
        (["evaluate", "--policy", "expert", "--env", "NoSuchPole-v0"], ["'NoSuchPole-v0' is not a HeartPole env"]),
        (["compare", "--policy", "expert"], ["exactly two --policy"]),
    ],
)
def test_bad_input_gives_one_clear_line(args: list[str], fragments: list[str]) -> None:
    assert_one_line_error(heartpole(*args), *fragments)


def test_a_module_env_id_on_the_command_line_imports_nothing(tmp_path: Path) -> None:
    # Gymnasium imports the module of a "module:Name-v0" id, and `python -m` puts the current folder on the path
    (tmp_path / "evilmod.py").write_text("open('imported', 'w').close()\n")
    result = heartpole("evaluate", "--policy", "expert", "--env", "evilmod:HeartPole-v0", cwd=tmp_path)
    assert_one_line_error(result, "'evilmod:HeartPole-v0' is not a HeartPole env", "nothing was imported")
    assert not (tmp_path / "imported").exists()


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_full_or_closed_standard_output_is_one_line_or_quiet() -> None:
    command = [sys.executable, "-m", "heartpole", "evaluate", "--policy", "expert", "--episodes", "4"]
    with open("/dev/full", "w") as full:
        result = subprocess.run(command, stdout=full, stderr=subprocess.PIPE, text=True, timeout=300)
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert result.stderr.strip().splitlines()[-1] == (
        "heartpole evaluate: error: cannot write the standard output: No space left on device"
    )
    # `heartpole evaluate | head -0`: the reader left before the table was written
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert process.stdout is not None
    process.stdout.close()
    _, errors = process.communicate(timeout=300)
    assert process.returncode == 0 and "Traceback" not in errors, errors


def test_corrupt_model_and_bad_output_folder(tmp_path: Path) -> None:
    corrupt = tmp_path / "model.zip"
    corrupt.write_bytes(b"\x00garbage")
    assert_one_line_error(heartpole("evaluate", "--policy", str(corrupt)), "not a Stable-Baselines3 model zip")
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    result = heartpole("baselines", "--episodes", "2", "--out", str(not_a_folder))
    assert_one_line_error(result, "is a file, expected a folder")
    result = heartpole("baselines", "--episodes", "2", "--policy", "expret", "--out", str(tmp_path / "out"))
    assert_one_line_error(result, "unknown policy 'expret'")
    assert not (tmp_path / "out" / "baselines.md").exists()


def test_evaluate_a_saved_model(tmp_path: Path) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    import heartpole as hp

    sb3.DQN("MlpPolicy", hp.HeartPole(), policy_kwargs={"net_arch": [8]}, seed=0).save(tmp_path / "dqn.zip")
    (tmp_path / "heartpole.json").write_text(json.dumps({"algo": "dqn"}))
    result = heartpole("evaluate", "--policy", str(tmp_path / "dqn.zip"), "--episodes", "4", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["policy"].endswith("dqn.zip")


def test_evaluate_tells_which_recorded_statistics_a_model_applies(tmp_path: Path, capsys) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    import heartpole as hp
    from heartpole.cli import main

    sb3.DQN("MlpPolicy", hp.HeartPole(), policy_kwargs={"net_arch": [8]}, seed=0).save(tmp_path / "dqn.zip")
    VecNormalize(DummyVecEnv([hp.HeartPole])).save(str(tmp_path / "vecnormalize.pkl"))
    argv = ["evaluate", "--policy", str(tmp_path / "dqn.zip"), "--episodes", "4"]
    with pytest.warns(UserWarning, match="ignoring .*vecnormalize.pkl"):  # lying there, not recorded
        assert main(argv) == 0
    assert "normalises observations" not in capsys.readouterr().err
    record = {"algo": "dqn", "model": "dqn.zip", "vecnormalize": "vecnormalize.pkl"}
    (tmp_path / "heartpole.json").write_text(json.dumps(record))
    assert main(argv) == 0
    assert f"normalises observations with {tmp_path / 'vecnormalize.pkl'}" in capsys.readouterr().err


# ---------------------------------------------------------------------------------------------------------
# one episode, no optimum, failures after the episodes (in-process: quicker than a subprocess each)

NOT_A_NUMBER = re.compile(r"(?<![a-z])(nan|inf|infinity|infx)(?![a-z])", re.IGNORECASE)


def _refuse(constant: str) -> None:
    raise ValueError(f"{constant} is not JSON")


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    from heartpole.cli import main

    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize(
    "argv",
    [
        ["evaluate", "--policy", "expert"],
        ["evaluate", "--policy", "nothing"],
        ["evaluate", "--policy", "expert", "--env", "HeartPole-v1"],
        ["compare", "--policy", "expert", "--policy", "reference"],
        ["compare", "--policy", "optimal", "--policy", "expert"],
        ["baselines"],
        ["optimum", "--check", "1"],
    ],
    ids=lambda argv: " ".join(argv),
)
@pytest.mark.parametrize("json_output", [False, True], ids=["text", "json"])
def test_one_episode_says_there_is_no_interval_and_never_prints_nan(
    argv: list[str], json_output: bool, capsys, tmp_path: Path
) -> None:
    """Issue 24: with one episode there is no interval. Text says so in words; JSON has null and parses with a
    strict parser; neither shows nan or inf."""
    episodes = [] if argv[0] == "optimum" else ["--episodes", "1"]
    out = ["--out", str(tmp_path)] if argv[0] == "baselines" else []
    code, stdout, stderr = _run(capsys, *argv, *episodes, *out, *(["--json"] if json_output else []))
    assert code == 0, stderr
    assert not NOT_A_NUMBER.search(stdout), stdout
    if json_output:
        json.loads(stdout, parse_constant=_refuse)
    else:
        assert "no 95% intervals: fewer than 2 episodes" in stdout
    if argv[0] == "baselines":
        for name in ("baselines.md", "baselines.csv"):
            assert not NOT_A_NUMBER.search((tmp_path / name).read_text())


def test_a_variant_without_optimum_says_why_in_one_line(capsys) -> None:
    code, stdout, _ = _run(capsys, "evaluate", "--policy", "expert", "--env", "HeartPole-v1", "--episodes", "3")
    assert code == 0 and "regret" not in stdout.replace("no regret", "")
    lines = [line for line in stdout.splitlines() if line.startswith("no regret:")]
    assert len(lines) == 1 and "HeartPole-v0's six" in lines[0]
    code, stdout, _ = _run(
        capsys, "evaluate", "--policy", "expert", "--env", "HeartPole-v1", "--episodes", "3", "--json"
    )
    data = json.loads(stdout, parse_constant=_refuse)
    assert data["regret"] is None and "HeartPole-v0's six" in data["no_regret_reason"]


def test_baselines_prints_its_results_before_writing_the_files(capsys, tmp_path: Path, monkeypatch) -> None:
    """A failure writing the files comes after the results are on the screen: nothing computed is lost."""
    import heartpole.cli.evaluate as command

    def full_disk(*args: object) -> None:
        raise OSError("No space left on device")

    monkeypatch.setattr(command, "_write_both", full_disk)
    code, stdout, stderr = _run(capsys, "baselines", "--episodes", "2", "--out", str(tmp_path))
    assert code == 2 and "No space left on device" in stderr
    assert "published Table 1" in stdout and "expert" in stdout


def test_compare_checks_both_policies_before_running_either(capsys, monkeypatch, tmp_path: Path) -> None:
    import heartpole.evaluation

    ran: list[object] = []
    monkeypatch.setattr(heartpole.evaluation, "evaluate", lambda *args, **kwargs: ran.append(args))
    missing = str(tmp_path / "missing.zip")
    code, _, stderr = _run(capsys, "compare", "--policy", "expert", "--policy", missing, "--episodes", "5")
    assert code == 2 and "model file not found" in stderr and ran == []
