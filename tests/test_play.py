"""``heartpole play`` driven through a pseudo-terminal, the way a person (or tmux) drives it."""

from __future__ import annotations

import subprocess
import sys

import pytest

from heartpole.game import action_keys, new_game, prompt, status_lines
from tests.signal_dispositions import as_in_a_terminal

pexpect = pytest.importorskip("pexpect")

PLAY = [sys.executable, "-m", "heartpole", "play", "--seed", "3", "--baseline-episodes", "20"]
TIMEOUT = 60


def spawn(*extra: str) -> pexpect.spawn:
    """The game in a new pseudo-terminal, its signals at a terminal's defaults: the suite may run where SIGINT
    is ignored (``cmd &`` in a script), which the game, as every command, would keep ignoring."""
    child = pexpect.spawn(
        PLAY[0],
        PLAY[1:] + list(extra),
        encoding="utf-8",
        timeout=TIMEOUT,
        dimensions=(24, 80),
        env={"PATH": "/usr/bin:/bin", "NO_COLOR": "1"},
        preexec_fn=as_in_a_terminal,
    )
    child.expect_exact("Day 1 09:00  (step 0/")
    return child


def move(child: pexpect.spawn, key: str, shows: str) -> None:
    child.expect_exact("q=quit > ")
    child.send(key)
    child.expect_exact(shows)


def test_a_scripted_game_through_a_pty_ends_with_the_summary() -> None:
    child = spawn("--steps", "5")
    move(child, "c", "You chose drink coffee")
    child.expect_exact("(step 1/5)")
    move(child, "z", "Not a key of this game")  # a wrong key costs nothing
    move(child, "b", "You chose drink beer")
    child.expect_exact("(step 2/5)")
    move(child, "s", "You chose sleep")
    child.expect(r"--- Day 1 (1[89]|2[0-3]):[03]0  \(step 3/5\)")  # eight hours of sleep passed
    move(child, "n", "You chose do nothing")
    move(child, "1", "You chose drink coffee")  # digits are action indices
    child.expect_exact("=== Summary ===")
    child.expect(r"You: 5 decisions, return -?\d+\.\d{3}, score \d+\.\d{3}, heart attacks \d")
    child.expect_exact("Your choices: drink coffee 2, drink beer 1, sleep 1, do nothing 1")
    child.expect(r"Your expected return -?\d+\.\d{3} = score - 100 x the heart-attack risk you ran")
    child.expect_exact("The built-in policies over 20 episodes of 5 decisions (seed 3)")
    child.expect_exact(pexpect.EOF)
    table = child.before
    for name in ("random", "nothing", "coffee", "reference", "expert", "you"):
        assert f"\n{name} " in table.replace("\r", "")
    assert "You placed " in table
    child.close()
    assert child.exitstatus == 0


def test_q_quits_early_with_a_summary_over_the_steps_played() -> None:
    child = spawn("--steps", "50")
    move(child, "c", "(step 1/50)")
    move(child, "q", "You stopped after 1 of 50 half-hour decisions.")
    child.expect_exact("The built-in policies over 20 episodes of 1 decisions")
    child.expect_exact("You placed ")
    child.expect_exact(pexpect.EOF)
    child.close()
    assert child.exitstatus == 0


def test_ctrl_c_quits_at_once_with_exit_code_130() -> None:
    child = spawn("--steps", "50")
    move(child, "s", "(step 1/50)")
    child.expect_exact("q=quit > ")
    child.sendintr()
    child.expect_exact("Interrupted.")
    child.expect(r"You: 1 decisions, return")
    child.expect_exact(pexpect.EOF)
    assert "Summary" not in child.before
    child.close()
    assert child.exitstatus == 130


def test_keys_can_be_piped_too() -> None:
    result = subprocess.run(PLAY + ["--steps", "3"], input="c\nb\ns\n", capture_output=True, text=True, timeout=TIMEOUT)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count("You chose") == 3 and "=== Summary ===" in result.stdout
    ended = subprocess.run(PLAY + ["--steps", "3"], input="c", capture_output=True, text=True, timeout=TIMEOUT)
    assert ended.returncode == 0 and "You stopped after 1 of 3" in ended.stdout  # end of input quits


def test_action_keys() -> None:
    assert action_keys(["do_nothing", "drink_coffee", "drink_beer", "sleep"]) == {
        "n": 0,
        "c": 1,
        "b": 2,
        "s": 3,
        "0": 0,
        "1": 1,
        "2": 2,
        "3": 3,
    }
    names = ["do_nothing", "drink_coffee", "drink_beer", "sleep", "drink_tea", "take_nap", "exercise", "smoke_cannabis"]
    keys = action_keys(names)
    letters = {index: key for key, index in keys.items() if key.isalpha()}
    assert sorted(letters) == list(range(len(names))) and "q" not in keys


def test_status_fits_an_80_column_terminal() -> None:
    state = {
        "alertness": -12.25,
        "hypertension": 17.5,
        "intoxication": 0.25,
        "time_since_slept": 300.0,
        "time_elapsed": 4000.0,
        "work_done": -1234.5,
        "thc": 2.0,
    }
    lines = status_lines(state, 999, 1000, 12)
    assert all(len(line) <= 80 for line in lines)
    assert lines[0].startswith("--- Day 84 ") and any("thc" in line for line in lines)


def test_the_prompt_wraps_many_actions_to_80_columns() -> None:
    import gymnasium as gym

    if "HeartPole-v1" not in gym.registry:
        pytest.skip("no HeartPole-v1 registered")
    game = new_game("HeartPole-v1", 5, 0)
    text = prompt(game)
    assert all(len(line) <= 80 for line in text.splitlines()) and text.endswith("q=quit > ")
    for index, action in enumerate(game.env.unwrapped.actions):
        key = next(k for k, i in game.keys.items() if i == index and k.isalpha())
        assert f"{key}={action.name.replace('_', ' ')}" in text


def test_an_env_that_is_not_heartpole_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from heartpole.cli import main

    for env_id, words in (("Nope-v0", "'Nope-v0' is not a HeartPole env"), ("CartPole-v1", "is not a HeartPole env")):
        assert main(["play", "--env", env_id]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("heartpole play: error:") and words in err[0]
