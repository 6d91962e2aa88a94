"""Messages of the commands for odd input, and results that would mislead in silence (issue 35, rows B1, B8-B13,
B16, B19): each names the option, the value and what is accepted, or warns."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from heartpole.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_error(result: tuple[int, str, str], command: str, *words: str) -> str:
    code, out, err = result
    lines = err.strip().splitlines()
    assert code == 2, out + err
    assert len(lines) == 1 and lines[0].startswith(f"heartpole {command}: error:"), err
    for word in words:
        assert word in lines[0], err
    return lines[0]


def test_optimal_on_v1_names_v1(capsys: pytest.CaptureFixture[str]) -> None:  # B1
    line = one_error(run(capsys, "evaluate", "--policy", "optimal", "--env", "HeartPole-v1", "--episodes", "2"),
                     "evaluate", "HeartPole-v1 has state variables")  # fmt: skip
    assert "HeartPole-v0 has" not in line


@pytest.mark.parametrize(
    ("argv", "command", "option"),
    [
        (["train", "--out", ""], "train", "--out"),
        (["baselines", "--out", "", "--episodes", "2"], "baselines", "--out"),
        (["dataset", "--policy", "expert", "--id", ""], "dataset", "--id"),
    ],
)
def test_an_empty_name_is_not_the_default(  # B8
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, argv: list[str], command: str,
    option: str,
) -> None:  # fmt: skip
    if command == "train":
        pytest.importorskip("stable_baselines3")
    if command == "dataset":
        pytest.importorskip("minari")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    one_error(run(capsys, *argv), command, f"{option} must name something, got ''")
    assert list(tmp_path.iterdir()) == []


def test_a_dataset_id_too_long_for_the_file_system_is_refused_first(  # B9
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("minari")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    long_id = f"heartpole/{'a' * 300}-v0"
    line = one_error(run(capsys, "dataset", "--policy", "expert", "--episodes", "2", "--id", long_id), "dataset",
                     "a name too long", "(313 characters)")  # fmt: skip
    assert "Errno" not in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["dataset", "ope"])
def test_offline_commands_list_the_policies_their_help_lists(  # B10
    capsys: pytest.CaptureFixture[str], command: str
) -> None:
    pytest.importorskip("minari")
    head = ["dataset", "--episodes", "2"] if command == "dataset" else ["ope", "--dataset", "x"]
    accepted = "use one of random, nothing, coffee, reference, expert, or the path of a model .zip"
    line = one_error(run(capsys, *head, "--policy", "optimal"), command, "--policy optimal", accepted)
    assert "decisions_left" not in line and "policy(obs" not in line
    one_error(run(capsys, *head, "--policy", "nosuch"), command, "unknown policy 'nosuch' for --policy", accepted)
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert "random, nothing, coffee, reference, expert)" in " ".join(capsys.readouterr().out.split())


@pytest.mark.slow  # two evaluations and an ope run: about 15 s
def test_a_policy_against_itself_shows_no_negative_zero(capsys: pytest.CaptureFixture[str]) -> None:  # B11
    code, out, err = run(capsys, "compare", "--policy", "expert", "--policy", "expert", "--episodes", "4")
    assert code == 0, err
    assert "-0.0000" not in out and "0.00000 [0.00000, 0.00000]" in out


def test_one_seed_has_no_interval_across_seeds() -> None:  # B12
    from heartpole import records

    figures = dict(records.aggregate_figures(records.aggregate([{"mean_return": -120.0, "score": 0.3}])))
    assert figures["return"] == "-120.00 (one seed: no interval)"
    assert "[" not in "".join(figures.values())


def test_the_regret_verdict_reads_as_a_true_inequality(capsys: pytest.CaptureFixture[str]) -> None:  # B13
    code, out, err = run(capsys, "evaluate", "--policy", "nothing", "--episodes", "2")
    assert code == 0, err
    verdict = next(line for line in out.splitlines() if "regret bar" in line)
    assert "not solved: the regret's 95% upper bound" in verdict and "> 0.01" in verdict
    assert "<= 0.01)" not in verdict.split("(the regret bar")[0]


def test_plot_training_warns_of_points_it_cannot_draw(  # B16
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    pytest.importorskip("matplotlib")
    with (tmp_path / "learning_curve.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["timesteps", "mean_return", "heart_attacks", "score"])
        writer.writerows([[1000, -150, 1.3, 0.2], [2000, "nan", 1.3, "inf"], [3000, "1e400", 1.2, 0.3]])
    code, out, err = run(capsys, "plot", "training", str(tmp_path))
    assert code == 0, err
    assert "mean_return: 2 of 3 values NaN or infinite" in err and "score: 1 of 3" in err
    assert (tmp_path / "learning_curve.png").is_file()


@pytest.mark.slow  # records a dataset and estimates: about 15 s
def test_ope_warns_when_the_data_never_took_the_targets_actions(  # B19
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("minari")
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    assert main(["dataset", "--policy", "expert", "--episodes", "4", "--id", "heartpole/v0/expert0-v0"]) == 0
    capsys.readouterr()
    argv = ["ope", "--dataset", "heartpole/v0/expert0-v0", "--truth-episodes", "2"]
    code, _, err = run(capsys, *argv, "--policy", "coffee")
    assert code == 0 and "warning: the dataset never took an action the target would take" in err, err
    code, _, err = run(capsys, *argv, "--policy", "expert")
    assert code == 0 and "warning" not in err, err
