"""The productivity-risk frontier (heartpole.optimum.frontier, ``heartpole optimum --frontier``): its threshold from
the solver's own checks, its points, its Pareto front, the command's table, JSON and PNG, and its refusals."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from heartpole.cli import main
from heartpole.optimum import NotCoveredError, check_beer, check_coffee, frontier, no_drink_threshold, optimum, tradeoff
from heartpole.optimum.tradeoff import (
    DRINKING,
    NO_DRINK,
    THRESHOLD_TOLERANCE,
    Frontier,
    FrontierRow,
    default_penalties,
)
from heartpole.parameters import Params

SHORT = Params(max_steps=100)
"""A short horizon: every solve here takes a second or two. The drink floor's charge is ``max_steps x floor``, so
its no-drink threshold is ten times v0's (about 701)."""


def _refuses(check: object) -> bool:
    try:
        check()  # type: ignore[operator]
    except NotCoveredError:
        return True
    return False


def test_the_threshold_is_where_the_solvers_own_checks_start_to_pass() -> None:
    threshold = no_drink_threshold(SHORT)
    rate = tradeoff.solve_params(SHORT, tradeoff.RATE_GRID).rate
    at = replace(SHORT, heart_attack_penalty=threshold)
    below = replace(SHORT, heart_attack_penalty=threshold * (1 - 2 * THRESHOLD_TOLERANCE))
    check_beer(at)  # both pass at the threshold ...
    check_coffee(at, rate)
    assert _refuses(lambda: check_beer(below))  # ... and the beer's bound refuses just below it
    # The beer's bound is linear in the penalty (the charge max_steps x floor against a fixed gain): its root
    figures = check_beer(at)
    exact = threshold * figures["beer_gain_bound"] / figures["charge"]
    assert exact <= threshold <= exact * (1 + THRESHOLD_TOLERANCE)


def test_a_coffee_check_that_refuses_longer_carries_the_bisection_on(monkeypatch: pytest.MonkeyPatch) -> None:
    beer = no_drink_threshold(SHORT)
    calls: list[float] = []

    def coffee(params: Params, rate: float) -> dict[str, float]:
        calls.append(params.heart_attack_penalty)
        if params.heart_attack_penalty < 3 * beer:
            raise NotCoveredError("coffee may pay")
        return {"coffee_best_gain": -1.0}

    monkeypatch.setattr(tradeoff, "check_coffee", coffee)
    no_drink_threshold.cache_clear()  # solved above with the real check
    try:
        threshold = no_drink_threshold(SHORT)
    finally:
        no_drink_threshold.cache_clear()
    assert 3 * beer <= threshold <= 3 * beer * (1 + THRESHOLD_TOLERANCE)
    assert calls[0] == beer  # the coffee check ran first where the beer's passes


def test_proclivity_zero_has_no_threshold_and_says_why() -> None:
    with pytest.raises(NotCoveredError, match="drinking may pay"):
        no_drink_threshold(replace(SHORT, heart_attack_proclivity=0.0))


def test_default_penalties_run_from_zero_to_the_threshold() -> None:
    penalties = default_penalties(70.125)
    assert penalties[0] == 0.0 and penalties[-1] == 70.125 and penalties == sorted(set(penalties))
    assert len(penalties) == tradeoff.DEFAULT_POINTS
    with pytest.raises(ValueError, match="at least 2"):
        default_penalties(70.0, 1)


@dataclass
class _Drinking:
    """What a drinking solver returns (the protocol's fields), made up."""

    expected_return: float
    expected_score: float
    expected_attacks: float
    coffees_per_episode: float
    beers_per_episode: float
    lower: float
    upper: float
    optimal: bool = True

    @property
    def drinks_per_episode(self) -> float:
        return self.coffees_per_episode + self.beers_per_episode


def test_points_come_from_the_no_drink_optimum_above_the_threshold_and_the_drinking_solver_below() -> None:
    kwargs = {"max_steps": 100}
    asked: list[dict[str, object]] = []

    def drinking(env_id: str, env_kwargs: dict[str, object]) -> _Drinking:
        asked.append(dict(env_kwargs))
        if env_kwargs["heart_attack_penalty"] == 0.2:
            raise NotCoveredError("not at 0.2")
        return _Drinking(1.0, 1.5, 5.0, 200.0, 80.0, 0.99, 1.01)

    ticks: list[int] = []
    solved = frontier(penalties=[800, 0.1, 0.2], env_kwargs=kwargs, drinking=drinking, progress=ticks.append)
    assert [p.penalty for p in solved.points] == [0.1, 800.0] and ticks == [1, 1, 1]
    assert solved.missing == ((0.2, "not at 0.2 (the drinking solver)"),)
    assert asked == [{"max_steps": 100, "heart_attack_penalty": p} for p in (0.1, 0.2)]
    low = solved.points[0]
    assert (low.solver, low.coffees, low.beers, low.drinks) == (DRINKING, 200.0, 80.0, 280.0)
    assert (low.expected_score, low.expected_heart_attacks, low.lower, low.upper) == (1.5, 5.0, 0.99, 1.01)
    exact = optimum("HeartPole-v0", {**kwargs, "heart_attack_penalty": 800})
    high = solved.points[1]
    assert high.solver == NO_DRINK and high.drinks == 0.0
    assert (high.expected_score, high.expected_heart_attacks) == (exact.expected_score, exact.expected_heart_attacks)
    assert high.lower <= exact.expected_return <= high.upper and high.upper - high.lower == pytest.approx(
        exact.error_bound + exact.margin
    )
    assert solved.drinks_stop == 800.0 and solved.proven_from == 800.0
    # without a drinking solver the penalty below is listed with the no-drink solver's reason
    alone = frontier(penalties=[0.1, 800], env_kwargs=kwargs, drinking=None)
    assert [p.penalty for p in alone.points] == [800.0]
    assert (
        alone.missing[0][0] == 0.1 and "drinking" in alone.missing[0][1] and "no drinking solver" in alone.missing[0][1]
    )


def _point(penalty: float, score: float, attacks: float, drinks: float = 0.0) -> FrontierRow:
    value = score - penalty * attacks
    return FrontierRow(penalty, score, attacks, drinks, 0.0, drinks, value, value, value, DRINKING)


def test_the_pareto_front_keeps_the_points_no_other_dominates() -> None:
    points = (
        _point(0, 1.1, 300.0, 700),
        _point(1, 1.0, 40.0, 300),
        _point(2, 0.9, 50.0, 200),  # dominated by the point above: less score, more attacks
        _point(3, 0.8, 40.0, 150),  # dominated too: less score, as many attacks
        _point(30, 0.5, 2.0, 5),
        _point(60, 0.327, 1.236),
        _point(70, 0.327, 1.236),  # the same policy at another penalty: one point
    )
    front = Frontier("HeartPole-v0", {}, points, 70.0, ()).pareto_front()
    assert front == [(1.1, -300.0), (1.0, -40.0), (0.5, -2.0), (0.327, -1.236)]
    assert Frontier("HeartPole-v0", {}, points, 70.0, ()).drinks_stop == 60
    assert math.isnan(Frontier("HeartPole-v0", {}, points, 70.0, ()).proven_from)  # every point a drinking one


def test_bad_arguments_are_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match="penalties must be finite numbers >= 0, got -1"):
        frontier(penalties=[-1])
    with pytest.raises(ValueError, match="penalties is empty"):
        frontier(penalties=[])
    with pytest.raises(ValueError, match="must not set heart_attack_penalty"):
        frontier(env_kwargs={"heart_attack_penalty": 10})
    with pytest.raises(NotCoveredError, match="HeartPole-v1 has state variables"):
        frontier("HeartPole-v1")


def test_the_command_prints_the_table_and_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["optimum", "--frontier", "--param", "max_steps=100", "--penalties", "800,900", "--check", "0"]) == 0
    out = capsys.readouterr().out
    assert "penalty" in out and "no-drink optimum" in out and "drinks never pay from penalty 701 on" in out
    assert "not solved" not in out and out.count("no-drink optimum") == 2
    assert main(["optimum", "--frontier", "--param", "max_steps=100", "--penalties", "800", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["threshold"] == pytest.approx(701, rel=THRESHOLD_TOLERANCE) and data["missing"] == []
    assert data["points"][0]["penalty"] == 800 and data["points"][0]["solver"] == NO_DRINK


def test_the_plot_draws_the_frontier_and_the_policies(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    target = tmp_path / "figures" / "frontier.png"
    argv = ["optimum", "--frontier", "--param", "max_steps=100", "--penalties", "800", "--plot", str(target)]
    assert main([*argv, "--policy", "expert", "--policy", "coffee", "--check", "20"]) == 0
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {target}" in capsys.readouterr().out
    assert main(argv) == 2  # an existing file stays unless --force
    assert "exists; pass --force" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--plot", "x.png"], "--plot go with --frontier"),
        (["--frontier", "--policy", "expert"], "give --plot FILE.png too"),
        (["--frontier", "--out", "d"], "it takes no --out"),
        (["--frontier", "--penalties", "1,x"], "--penalties takes numbers >= 0 separated by commas"),
        (["--frontier", "--penalties", "-1"], "--penalties takes finite numbers >= 0"),
        (["--frontier", "--plot", "x.txt"], "unsupported file type '.txt'"),
    ],
)
def test_the_command_refuses_bad_options_in_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["optimum", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_a_model_that_cannot_be_loaded_fails_before_the_solve_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "frontier.png"
    argv = ["optimum", "--frontier", "--plot", str(target), "--model", str(tmp_path / "nothing")]
    assert main(argv) == 2
    assert not target.exists() and list(tmp_path.iterdir()) == []
    assert "solving the frontier" not in capsys.readouterr().err


@pytest.mark.slow
def test_v0s_threshold_and_its_point() -> None:
    """v0: drinks provably never pay from 70.1 (the beer's bound: 12.58 units of work against 17.94 at 100)."""
    solved = frontier(penalties=[100])
    assert solved.threshold == pytest.approx(100 * 12.5771515980937 / 17.94385509464435, rel=THRESHOLD_TOLERANCE)
    (point,) = solved.points
    assert point.expected_return == pytest.approx(-123.30428, abs=1e-5) and math.isclose(point.drinks, 0.0)


def test_a_drinking_policy_not_proven_optimal_says_so() -> None:
    point = tradeoff.drinking_point(0.0, _Drinking(1.0, 1.0, 0.0, 500.0, 0.0, 0.9, math.nan, optimal=False))
    assert point.solver == tradeoff.LOWER_BOUND and math.isnan(point.upper)
    assert point.summary()["upper"] is None and (point.coffees, point.beers, point.drinks) == (500.0, 0.0, 500.0)


@pytest.mark.slow
def test_a_signal_ends_a_long_frontier_solve_at_once_and_writes_nothing(tmp_path: Path) -> None:
    """As `heartpole optimum`'s own solve (tests/test_optimum_signals.py): a horizon of a hundred billion decisions
    keeps the threshold's solve in numba's loop for minutes; SIGTERM ends it within a second, no PNG written."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from tests.signal_dispositions import as_in_a_terminal

    source = Path(__file__).resolve().parents[1] / "src"
    env = {**os.environ, "HEARTPOLE_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(source), os.environ.get("PYTHONPATH", "")])}  # fmt: skip
    target = tmp_path / "frontier.png"
    command = [sys.executable, "-m", "heartpole", "optimum", "--frontier", "--param", "max_steps=100000000000",
               "--plot", str(target)]  # fmt: skip
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                               preexec_fn=as_in_a_terminal)  # fmt: skip
    time.sleep(4)  # into the threshold's solve (minutes long)
    assert process.poll() is None
    sent = time.monotonic()
    process.send_signal(signal.SIGTERM)
    try:
        _, err = process.communicate(timeout=30)
    finally:
        process.kill()
    assert process.returncode == 128 + signal.SIGTERM, err
    assert (
        time.monotonic() - sent < 1.5 and not target.exists() and list(tmp_path.iterdir()) in ([], [tmp_path / "cache"])
    )


@pytest.mark.slow
def test_a_trained_models_folder_is_drawn(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    pytest.importorskip("matplotlib")
    import heartpole as hp

    folder = tmp_path / "run"
    folder.mkdir()
    sb3.DQN("MlpPolicy", hp.HeartPole(), policy_kwargs={"net_arch": [8]}, seed=0).save(folder / "model.zip")
    (folder / "heartpole.json").write_text(json.dumps({"algo": "dqn"}))
    target = tmp_path / "frontier.png"
    argv = ["optimum", "--frontier", "--param", "max_steps=100", "--penalties", "800", "--plot", str(target)]
    assert main([*argv, "--model", str(folder), "--check", "10", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["policies"][0]["policy"].endswith("model.zip") and data["policies"][0]["episodes"] == 10
    assert target.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_the_package_drinking_solver_gives_the_free_penalty_its_coffee_policy() -> None:
    """At penalty 0 drinks are free: frontier_point's coffee program (minutes) buys score with heart attacks."""
    solved = frontier(penalties=[0, 800], env_kwargs={"max_steps": 100})
    free, dear = solved.points
    assert (free.solver, dear.solver) == (tradeoff.LOWER_BOUND, NO_DRINK) and solved.missing == ()
    assert free.coffees > 10 and free.beers == 0 and math.isnan(free.upper)
    assert free.expected_score > dear.expected_score + 0.1 and free.expected_heart_attacks > dear.expected_heart_attacks
    assert solved.pareto_front() == [
        (free.expected_score, -free.expected_heart_attacks),
        (dear.expected_score, -dear.expected_heart_attacks),
    ]


@pytest.mark.parametrize("coffee_return", [-1e9, 1e9], ids=["coffee-scores-less", "coffee-scores-more"])
def test_the_point_where_drinks_may_pay_is_the_better_of_the_coffee_policy_and_no_drink(
    coffee_return: float, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """Just below where drinks are proven not to pay the coffee program's grid policy may score less than the
    no-drink optimum (v0, 1,000 decisions, penalties 1.84-6.18: by 2.8e-4 of return): the point is then the no-drink
    optimum, not proven best. A stand-in coffee solution either side of it shows the choice."""
    from types import SimpleNamespace

    from heartpole.optimum import point as point_module
    from heartpole.optimum.solution import _solve

    monkeypatch.setenv("HEARTPOLE_CACHE_DIR", str(tmp_path))
    params = Params(max_steps=100, heart_attack_penalty=1.0)  # drinks may pay: refused by the no-drink solver
    figures = dict(expected_score=0.5, expected_attacks=0.2, coffees_per_episode=3.0, beers_per_episode=0.0)
    stand_in = SimpleNamespace(expected_return=coffee_return, sleeps_per_episode=4.0, lower=coffee_return - 1.0,
                               episodes=10, **figures)  # fmt: skip
    monkeypatch.setattr(point_module, "solve_coffee", lambda params, error: stand_in)
    got = point_module.frontier_point(params)
    assert not got.optimal and math.isnan(got.upper)
    if coffee_return < 0:
        no_drink = _solve(params, 400, "HeartPole-v0", {"max_steps": 100, "heart_attack_penalty": 1.0}, drinks=False)
        assert (got.expected_return, got.drinks_per_episode) == (no_drink.expected_return, 0.0)
        assert got.lower == no_drink.expected_return - no_drink.error_bound and "no-drink" in got.how
    else:
        assert (got.expected_return, got.coffees_per_episode, got.lower) == (1e9, 3.0, 1e9 - 1.0)
