"""``heartpole dataset`` and ``heartpole ope``: results, and bad input as one line, exit 2, nothing written."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("minari")

from heartpole.cli import main  # noqa: E402


@pytest.fixture(autouse=True)
def minari_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    return tmp_path


def files(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())


def run(argv):
    """The exit code of ``heartpole ARGV``, argparse's own errors included."""
    try:
        return main(argv)
    except SystemExit as exit:
        return exit.code


def one_error_line(capsys, command):
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"heartpole {command}: error:")
    return err[-1]


def test_dataset_then_ope(capsys):
    assert main(["dataset", "--policy", "reference", "--epsilon", "0.2", "--episodes", "20", "--seed", "1"]) == 0
    assert "recorded heartpole/v0/reference-eps20-v0: 20 episodes" in capsys.readouterr().out
    argv = ["ope", "--dataset", "heartpole/v0/reference-eps20-v0", "--policy", "expert", "--truth-episodes", "50"]
    assert main([*argv, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [e["estimator"] for e in report["estimates"]] == ["PDIS", "WPDIS", "FQE", "DR"]
    assert report["truth"]["episodes"] == 50 and report["gamma"] == 0.95
    assert main([*argv, "--expected-risk", "--gamma", "0.9"]) == 0
    out = capsys.readouterr().out
    assert "true value" in out and "DR" in out and "expected-risk rewards" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["dataset", "--policy", "expert", "--epsilon", "1.5"], "[0, 1]"),
        (["dataset", "--policy", "expert", "--epsilon", "x"], "[0, 1]"),
        (["dataset", "--policy", "nobody"], "unknown policy"),
        (["dataset", "--policy", "expert", "--env", "Nope-v0"], "Nope-v0"),
        (["dataset"], "--policy P or --standard"),
        (["dataset", "--policy", "expert", "--standard"], "--policy P or --standard"),
        (["ope", "--dataset", "heartpole/v0/none-v0", "--policy", "expert"], "unknown dataset id"),
        (["ope", "--dataset", "x-v0", "--policy", "expert", "--gamma", "0"], "(0, 1]"),
    ],
)
def test_bad_input(capsys, minari_folder, argv, message):
    assert run(argv) == 2
    assert message in one_error_line(capsys, argv[0])
    assert files(minari_folder) == []


def test_existing_dataset_without_force(capsys, minari_folder):
    assert main(["dataset", "--policy", "expert", "--epsilon", "0.1", "--episodes", "2"]) == 0
    before = files(minari_folder)
    capsys.readouterr()
    assert main(["dataset", "--policy", "expert", "--epsilon", "0.1", "--episodes", "3"]) == 2
    assert "already exists" in one_error_line(capsys, "dataset")
    assert files(minari_folder) == before
    assert main(["dataset", "--policy", "expert", "--epsilon", "0.1", "--episodes", "3", "--force"]) == 0


@pytest.mark.slow
def test_sigterm_while_recording_leaves_nothing(minari_folder):
    """A recording killed with SIGTERM (while it writes) removes its temporary folder."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from tests.signal_dispositions import as_in_a_terminal

    env = {**os.environ, "MINARI_DATASETS_PATH": str(minari_folder)}
    argv = [sys.executable, "-m", "heartpole", "dataset", "--policy", "expert", "--episodes", "2000"]
    process = subprocess.Popen(argv, env=env, stderr=subprocess.PIPE, text=True, preexec_fn=as_in_a_terminal)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not list(minari_folder.iterdir()):
        time.sleep(0.01)  # the temporary folder appears when the dataset is being written
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 143, err
    assert [p for p in minari_folder.rglob("*") if p.is_file()] == []
