"""heartpole.truth and evaluation under people: each episode's person, the oracle regret, its JSON and CLI.

Statistical tolerances. The oracle: over 10 seeds of 2,000 episodes, at least 8 of its 95% intervals of the
oracle regret contain 0 (each does with chance 0.95 if it is unbiased: 7 or fewer has chance 1.2%), and each is
narrower than +-0.001, so an oracle that ignored who it treats (about 0.007 here, see tests/people_cohorts.py)
would miss every one. The expert: its 95% interval lies above 0 (its oracle regret is about 0.001, 5 standard
errors). The people drawn: each of the three within 5 standard deviations of a third of the episodes.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import heartpole.people
from heartpole.evaluation import compare, evaluate
from heartpole.optimum import PeopleOptimum, oracle_regret, solve_people
from heartpole.people import People, Uniform
from heartpole.truth import NO_SINGLE_OPTIMUM, oracle_fields, people_truth
from tests.people_cohorts import TRIO

pytestmark = pytest.mark.slow  # a cohort of people solved and their loop compiled: minutes in all

EPISODES = 2000


@pytest.fixture(scope="module")
def trio() -> PeopleOptimum:
    return solve_people(TRIO)


def test_oracle_fields_are_the_mean_gap_to_each_persons_optimum(trio: PeopleOptimum) -> None:
    person = np.array([0, 2, 1, 1, 0, 2, 2])
    returns = trio.expected_returns[person] - np.array([0.5, 0.0, 1.0, 2.0, 0.25, 0.125, 3.0])
    fields = oracle_fields(trio, person, returns)
    assert fields["oracle_regret"] == pytest.approx(6.875 / 7, abs=1e-12)
    assert fields["oracle_regret"] == np.mean(trio.expected_returns[person] - returns)  # exactly
    expected = oracle_regret(trio.expected_returns, person, returns, trio.margins)
    assert fields["oracle_regret_ci95"] == expected.ci95
    assert oracle_fields(None, person, returns) == {}
    assert oracle_fields("why not", person, returns) == {"no_oracle_regret_reason": "why not"}


def test_people_truth_solves_a_cohort_and_says_why_not_otherwise(trio: PeopleOptimum) -> None:
    assert people_truth("HeartPole-v0", {}) is None
    found = people_truth("HeartPole-v0", {"people": TRIO, "observe_traits": True})
    assert isinstance(found, PeopleOptimum)
    np.testing.assert_array_equal(found.expected_returns, trio.expected_returns)
    spread = people_truth("HeartPole-v0", {"people": People(decay_rate=Uniform(0.93, 0.97))})
    assert isinstance(spread, str) and "distribution" in spread
    with pytest.raises(ValueError, match="unknown population 'nobody'"):
        people_truth("HeartPole-v0", {"people": "nobody"})


@pytest.fixture(scope="module")
def expert() -> object:
    return evaluate("expert", episodes=EPISODES, seed=5, env_kwargs={"people": TRIO})


def test_evaluation_records_each_episodes_person(expert) -> None:  # type: ignore[no-untyped-def]
    counts = np.bincount(expert.person, minlength=3)
    assert expert.person.shape == (EPISODES,) and len(counts) == 3
    # each person drawn with chance 1/3: 2,000 draws give 667 +- 21 (sd); 5 sd either side
    assert np.all(np.abs(counts - EPISODES / 3) < 5 * math.sqrt(EPISODES * 2 / 9))
    again = evaluate("nothing", episodes=EPISODES, seed=5, env_kwargs={"people": TRIO})
    np.testing.assert_array_equal(again.person, expert.person)  # the seed draws the people, not the policy
    assert np.all(evaluate("expert", episodes=5).person == -1)


def test_oracle_regret_is_each_persons_optimum_minus_the_expected_return(  # type: ignore[no-untyped-def]
    expert, trio: PeopleOptimum
) -> None:
    gaps = trio.expected_returns[expert.person] - expert.expected_returns
    assert expert.oracle_regret == gaps.mean()  # exactly: the same numbers, the same sum
    widen = trio.margins[expert.person].mean()
    half = (expert.oracle_regret_ci95[1] - expert.oracle_regret_ci95[0]) / 2
    assert half == pytest.approx(1.96 * gaps.std(ddof=1) / math.sqrt(EPISODES) + widen, rel=0.01)


def test_the_experts_oracle_regret_is_above_zero_beyond_doubt(expert) -> None:  # type: ignore[no-untyped-def]
    assert expert.oracle_regret_ci95[0] > 0


def test_the_oracles_oracle_regret_is_zero_within_its_intervals() -> None:
    results = [evaluate("oracle", episodes=EPISODES, seed=seed, env_kwargs={"people": TRIO}) for seed in range(10)]
    intervals = [result.oracle_regret_ci95 for result in results]
    assert all(high - low < 0.002 for low, high in intervals), intervals
    assert sum(low <= 0 <= high for low, high in intervals) >= 8, intervals
    assert all(result.drinks_per_episode == 0 for result in results)


def test_under_people_one_optimum_is_no_ones_and_json_has_the_oracle_keys(expert) -> None:  # type: ignore[no-untyped-def]
    assert math.isnan(expert.regret) and expert.no_regret_reason == NO_SINGLE_OPTIMUM
    data = json.loads(json.dumps(expert.to_dict(), allow_nan=False))
    assert data["regret"] is None and data["no_regret_reason"] == NO_SINGLE_OPTIMUM
    assert data["oracle_regret"] == expert.oracle_regret and data["no_oracle_regret_reason"] is None
    assert data["oracle_regret_ci95"] == list(expert.oracle_regret_ci95)
    assert len(expert.to_dict(per_episode=True)["person"]) == EPISODES
    plain = evaluate("expert", episodes=5).to_dict()
    assert plain["oracle_regret"] is None and plain["oracle_regret_ci95"] == [None, None]
    assert plain["regret"] is not None and plain["no_oracle_regret_reason"] is None


@pytest.mark.slow  # compiles the distribution's own loop
def test_a_distribution_of_people_says_why_there_is_no_oracle_regret() -> None:
    result = evaluate("expert", episodes=20, env_kwargs={"people": People(decay_rate=Uniform(0.93, 0.97))})
    assert math.isnan(result.oracle_regret) and "distribution" in (result.no_oracle_regret_reason or "")
    assert np.all(result.person == -1)


def test_compare_pairs_the_same_people() -> None:
    pair = compare("oracle", "expert", episodes=200, seed=2, env_kwargs={"people": TRIO})
    np.testing.assert_array_equal(pair.a.person, pair.b.person)
    assert pair.b.oracle_regret - pair.a.oracle_regret == pytest.approx(pair.expected_difference, abs=1e-9)


# ------------------------------------------------------------------------------------------------------
# the command line (in process, with the trio as a named population: the default cohort's first solve
# takes a minute or two, which the slow test below pays)


def _run(capsys, monkeypatch, *argv: str) -> tuple[int, str, str]:  # type: ignore[no-untyped-def]
    from heartpole.cli import main

    monkeypatch.setitem(heartpole.people.POPULATIONS, "trio", lambda: TRIO)  # type: ignore[index]
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_cli_evaluate_reports_the_oracle_regret(capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    code, out, _ = _run(capsys, monkeypatch, "evaluate", "--policy", "expert", "--people", "trio", "--episodes", "50")
    assert code == 0 and "oracle regret (person's optimum - expected-risk return)" in out
    assert "no regret: under people each person has their own optimum" in out
    code, out, _ = _run(
        capsys, monkeypatch, "evaluate", "--policy", "oracle", "--people", "trio", "--episodes", "50", "--json"
    )
    data = json.loads(out)
    assert code == 0 and data["policy"] == "oracle" and data["regret"] is None
    assert data["oracle_regret_ci95"][0] <= 0 <= data["oracle_regret_ci95"][1]


def test_cli_observe_traits_widens_the_observation(capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    argv = ("evaluate", "--policy", "expert", "--people", "trio", "--observe-traits", "--episodes", "20", "--json")
    code, out, _ = _run(capsys, monkeypatch, *argv)
    assert code == 0 and json.loads(out)["oracle_regret"] > 0
    code, _, err = _run(capsys, monkeypatch, "evaluate", "--policy", "expert", "--observe-traits")
    assert code == 2 and "--observe-traits needs --people" in err


def test_cli_compare_and_baselines_show_the_oracle_regret(capsys, monkeypatch, tmp_path) -> None:  # type: ignore[no-untyped-def]
    argv = ("compare", "--policy", "oracle", "--policy", "expert", "--people", "trio", "--episodes", "40")
    code, out, _ = _run(capsys, monkeypatch, *argv)
    assert code == 0 and any(line.startswith("oracle regret") for line in out.splitlines())
    argv = ("baselines", "--people", "trio", "--episodes", "40", "--out", str(tmp_path), "--json")
    code, out, _ = _run(capsys, monkeypatch, *argv)
    results = {r["policy"]: r for r in json.loads(out)["results"]}
    assert code == 0 and "oracle" in results and results["expert"]["oracle_regret"] > 0
    assert "oracle regret (95% CI)" in (tmp_path / "baselines.md").read_text()
    assert "oracle_regret_ci95_low" in (tmp_path / "baselines.csv").read_text().splitlines()[0]
    code, out, _ = _run(capsys, monkeypatch, *argv[:-1], "--out", str(tmp_path / "table"))
    (note,) = [line for line in out.splitlines() if line.startswith("optimal - expert")]
    assert "oracle regret = each person's optimum" in note and "nan" not in note


def test_cli_refuses_an_unknown_population(capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    code, out, err = _run(capsys, monkeypatch, "evaluate", "--policy", "expert", "--people", "nobody")
    assert code == 2 and out == "" and "unknown population 'nobody'" in err and "'default'" in err


@pytest.mark.slow  # the default cohort: 24 solves the first time (a minute or two), then cached
def test_the_default_population_oracle_and_expert() -> None:
    oracle = evaluate("oracle", episodes=EPISODES, seed=0, env_kwargs={"people": "default"})
    assert oracle.oracle_regret_ci95[0] <= 0 <= oracle.oracle_regret_ci95[1]
    expert = evaluate("expert", episodes=EPISODES, seed=0, env_kwargs={"people": "default"})
    assert expert.oracle_regret_ci95[0] > 0
    assert set(np.unique(expert.person)) == set(range(24))


def test_cli_optimum_solves_each_person(capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    code, out, _ = _run(capsys, monkeypatch, "optimum", "--people", "trio", "--check", "0")
    assert code == 0 and "people trio: each person's optimum" in out
    assert all(name in out for name in ("Ada", "Bo", "Max")) and "-123.30428" in out  # Ada is v0
    code, out, _ = _run(capsys, monkeypatch, "optimum", "--people", "trio", "--check", "0", "--json")
    assert code == 0 and [p["name"] for p in json.loads(out)["people"]] == ["Ada", "Bo", "Max"]
    code, _, err = _run(capsys, monkeypatch, "optimum", "--people", "trio", "--grid", "800")
    assert code == 2 and "--grid and --out solve one person" in err
