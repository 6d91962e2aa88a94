"""The one progress bar: when it draws, what it shows, and the training callbacks that use it."""

from __future__ import annotations

import io
from types import SimpleNamespace

import pytest

from heartpole.progress import FORCE_VARIABLE, Progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_bar_draws_on_a_terminal_only_unless_told(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(FORCE_VARIABLE, raising=False)
    for stream, enabled, drawn in [
        (io.StringIO(), None, False),
        (Terminal(), None, True),
        (io.StringIO(), True, True),
        (Terminal(), False, False),
    ]:
        with Progress(10, "work", stream, enabled=enabled) as bar:
            bar.update(10)
        assert bool(stream.getvalue()) is drawn, (type(stream).__name__, enabled)
    monkeypatch.setenv(FORCE_VARIABLE, "1")
    forced, hidden = io.StringIO(), io.StringIO()
    with Progress(10, "work", forced) as bar, Progress(10, "work", hidden, enabled=False) as off:
        bar.update(10)
        off.update(10)
    assert forced.getvalue() and not hidden.getvalue()


def test_a_bar_stops_at_its_total_and_shows_the_rate_in_its_unit() -> None:
    stream = io.StringIO()
    with Progress(100, "training", stream, enabled=True, unit="step") as bar:
        bar.update(60)
        bar.update(60)  # past the end
        assert bar.done == 100
    line = stream.getvalue().rstrip("\n").split("\r")[-1]
    assert line.startswith("training [") and "100.0%" in line and line.endswith(" step/s")
    assert stream.getvalue().endswith("\n")  # leaving the block ends the line
    plain = io.StringIO()
    with Progress(5, "evaluating", plain, enabled=True) as bar:
        bar.update(5)
    assert "/s" not in plain.getvalue()


def test_the_sb3_callback_draws_with_the_same_bar(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("stable_baselines3")
    from heartpole.training import ProgressBar

    callback = ProgressBar(100, "training ppo seed 0", force=True)
    env = SimpleNamespace(num_envs=16)
    callback.model = SimpleNamespace(get_env=lambda: env)  # type: ignore[assignment]
    callback._on_training_start()
    for _ in range(7):  # 112 steps of 16 envs: the bar stops at 100
        callback._on_step()
    callback._on_training_end()
    err = capsys.readouterr().err
    assert "training ppo seed 0 [" in err and "100.0%" in err and "step/s" in err and err.endswith("\n")


def test_clear_wipes_the_line_only_when_the_bar_shows() -> None:
    shown, hidden = io.StringIO(), io.StringIO()
    Progress(10, "work", stream=shown, enabled=True).clear()
    Progress(10, "work", stream=hidden, enabled=False).clear()
    assert shown.getvalue() == "\r\x1b[K" and hidden.getvalue() == ""
