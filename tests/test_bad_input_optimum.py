"""Hostile input to ``heartpole optimum`` and its cache (issue 35, rows A5, A6, A10, B5, B6)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from heartpole.cli import main
from heartpole.optimum import NotCoveredError, optimum, solve
from heartpole.optimum import solution as solution_module
from heartpole.parameters import Params
from heartpole.registry import env_dynamics


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def error_line(result: tuple[int, str, str], *words: str) -> str:
    code, out, err = result
    assert code == 2, out + err
    line = err.strip().splitlines()[-1]
    assert line.startswith("heartpole optimum: error:") or "error: argument" in line, err
    for word in words:
        assert word in line, err
    assert "Traceback" not in err and "nan" not in out
    return line


# A5: a population has no single optimum


def test_a_population_given_as_a_param_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    for check in ("0", "50"):
        line = error_line(run(capsys, "optimum", "--check", check, "--param", 'people="default"'), "population")
        assert "--people" in line
    with pytest.raises(NotCoveredError, match="one optimum per person"):
        optimum("HeartPole-v0", {"people": "default"})
    with pytest.raises(NotCoveredError, match="one optimum per person"):
        solve("HeartPole-v0", people="default")


# A6: max_episode_steps is a time limit on the env's max_steps (the registered one unless given), as make_vec's


def test_max_episode_steps_is_a_time_limit_on_the_episode_length() -> None:
    assert env_dynamics("HeartPole-v0", {"max_episode_steps": 500}).params.max_steps == 500
    with pytest.raises(ValueError, match="max_episode_steps=3000 is above max_steps=1000.*with max_steps=3000"):
        env_dynamics("HeartPole-v0", {"max_episode_steps": 3000})  # what make_vec refuses and make cuts at 1,000
    assert env_dynamics("HeartPole-v0", {"max_steps": 2000, "max_episode_steps": 2000}).params.max_steps == 2000
    assert env_dynamics("HeartPole-v0", {"max_steps": 3000, "max_episode_steps": 2000}).params.max_steps == 2000
    with pytest.raises(ValueError, match="max_episode_steps=3000 is above max_steps=2000"):
        env_dynamics("HeartPole-v0", {"max_steps": 2000, "max_episode_steps": 3000})


def test_the_cli_refuses_a_time_limit_above_the_length(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["optimum", "--check", "0", "--param", "max_steps=2000", "--param", "max_episode_steps=3000"]
    error_line(run(capsys, *argv), "max_steps=2000", "max_episode_steps=3000", "is above")


# B5, B6: messages that name the option, the value and what is accepted


def test_an_unknown_or_mistyped_param_names_the_option(capsys: pytest.CaptureFixture[str]) -> None:
    line = error_line(run(capsys, "optimum", "--check", "0", "--param", "nosuch=1"), "--param nosuch=1", "'nosuch'")
    assert "environment creator" not in line and "it accepts" in line
    line = error_line(run(capsys, "optimum", "--check", "0", "--param", "actions=1"), "--param actions=1")
    assert "actions must be a sequence of heartpole.Action" in line and "not iterable" not in line


@pytest.mark.parametrize(
    ("argv", "option", "accepted"),
    [
        (["optimum", "--grid", "1"], "--grid", ">= 4, got 1"),
        (["optimum", "--check", "-1"], "--check", ">= 0, got -1"),
        (["ope", "--dataset", "x", "--policy", "expert", "--truth-episodes", "1"], "--truth-episodes", ">= 2, got 1"),
    ],
)
def test_numbers_below_the_minimum_are_refused_by_the_parser(
    capsys: pytest.CaptureFixture[str], argv: list[str], option: str, accepted: str
) -> None:
    with pytest.raises(SystemExit) as exited:
        main(argv)
    assert exited.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: expected a whole number {accepted}" in err, err


# A10: a cache entry that cannot be read is solved again, said once, never fatal


class SolvedError(Exception):
    """Stands for a fresh solve (seconds of work the test need not spend)."""


@pytest.mark.parametrize("damage", ["truncated", "empty", "not json"])
def test_a_damaged_cache_entry_is_solved_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: str) -> None:
    params = Params(heart_attack_proclivity=0.51)
    monkeypatch.setattr(solution_module, "_solve", lambda *args: (_ for _ in ()).throw(SolvedError()))
    solution_module._cached.cache_clear()
    with pytest.raises(SolvedError):  # no entry: a solve, silently
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            solution_module._cached(params, str(tmp_path))
    entry = _entry(tmp_path, params)
    entry.mkdir(parents=True)
    buffer = tmp_path / "whole.npz"
    np.savez_compressed(buffer, thresholds=np.zeros(3))
    (entry / "optimum.json").write_text('{"solver_version": 3}')
    if damage == "truncated":
        (entry / "optimum.npz").write_bytes(buffer.read_bytes()[:100])
    elif damage == "empty":
        (entry / "optimum.npz").write_bytes(b"")
    else:
        (entry / "optimum.npz").write_bytes(buffer.read_bytes())
        (entry / "optimum.json").write_text("[1, 2")
    solution_module._cached.cache_clear()
    said = "cached optimum cannot be used.*solving it again"
    with pytest.warns(RuntimeWarning, match=said), pytest.raises(SolvedError):
        solution_module._cached(params, str(tmp_path))
    solution_module._cached.cache_clear()


def _entry(root: Path, params: Params) -> Path:
    import hashlib
    import json

    from heartpole.optimum.common import DEFAULT_GRID, SOLVER_VERSION, params_dict

    key = json.dumps([SOLVER_VERSION, DEFAULT_GRID, params_dict(params)], sort_keys=True).encode()
    return root / "optimum" / hashlib.sha256(key).hexdigest()[:16]
