"""heartpole.optimum.people: each person's optimum, solved once and cached, the oracle's table, oracle regret."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import heartpole.optimum.people as optimum_people
from heartpole.actions import V0_ACTIONS
from heartpole.optimum import NotCoveredError, optimum, oracle_regret, solve, solve_people
from heartpole.parameters import V0_VARIABLES, Params
from heartpole.people import People, Person, Uniform
from heartpole.stats import confidence_interval

# Ada is v0, Bo sleeps 6 hours, Cy is Ada again; on a short day with costly heart attacks, where drinks are ruled
# out by the cheap per-step check (a solve of about a second; v0's full day takes 15 s with the lifetime check)
BASE = {"max_steps": 100, "heart_attack_penalty": 800.0}
SMALL = People(
    cohort=[
        Person("Ada", sleep_half_hours=16, wake_alertness=(0.7, 1.3)),
        Person("Bo", sleep_half_hours=12, wake_alertness=(0.6, 1.2)),
        Person("Cy", sleep_half_hours=16, wake_alertness=(0.7, 1.3)),
    ]
)


@pytest.fixture(scope="module")
def small() -> optimum_people.PeopleOptimum:
    return solve_people(SMALL, env_kwargs=BASE)


def test_each_person_gets_their_own_optimum(small: optimum_people.PeopleOptimum) -> None:
    assert [s.params for s in small.solutions] == [p.params(Params(**BASE)) for p in SMALL.cohort]
    assert small.solutions[0].expected_return == optimum("HeartPole-v0", BASE).expected_return
    bo = optimum("HeartPole-v0", {**BASE, **SMALL.cohort[1].values()})
    assert small.solutions[1].expected_return == bo.expected_return
    np.testing.assert_array_equal(small.expected_returns, [s.expected_return for s in small.solutions])
    assert small.expected_returns[0] == small.expected_returns[2] != small.expected_returns[1]


def test_the_env_kwargs_are_each_persons_base() -> None:
    cohort = People(cohort=[Person("Bo", sleep_half_hours=12, wake_alertness=(0.6, 1.2))])
    base = {**BASE, "sleep_half_hours": 20}
    solved = solve_people(cohort, env_kwargs=base)
    assert solved.solutions[0].params.max_steps == 100 and solved.env_kwargs == base
    assert solved.solutions[0].params.heart_attack_penalty == 800.0
    assert solved.solutions[0].params.sleep_half_hours == 12  # the person's own field wins


def test_equal_people_are_solved_once_and_progress_is_reported() -> None:
    calls: list[tuple[int, int]] = []
    solve_people(SMALL, env_kwargs=BASE, progress=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 2), (2, 2)]  # Ada and Cy are one person to the solver


def test_the_oracle_table_acts_as_each_persons_optimal_policy(small: optimum_people.PeopleOptimum) -> None:
    rng = np.random.default_rng(0)
    n = 20_000
    person = rng.integers(0, 3, n)
    alertness = rng.uniform(-1.0, 2.0, n)
    awake = rng.integers(0, 90, n)  # beyond both people's max_awake too
    left = rng.integers(1, BASE["max_steps"] + 1, n)
    oracle = small.sleeps(person, alertness, awake, left)
    for index, solution in enumerate(small.solutions):
        mine = person == index
        np.testing.assert_array_equal(oracle[mine], solution.sleeps(alertness[mine], awake[mine], left[mine]))
    assert 0.05 < oracle.mean() < 0.95  # both decisions are exercised
    assert small.thresholds.shape == (3, max(len(s.thresholds) for s in small.solutions), int(small.max_awake.max()))


def test_oracle_regret_of_the_optimal_values_is_exactly_zero(small: optimum_people.PeopleOptimum) -> None:
    person = np.random.default_rng(1).integers(0, 3, 500)
    result = small.regret(person, small.expected_returns[person])
    assert result.regret == 0.0 and result.episodes == 500
    widen = float(small.margins[person].mean())
    assert result.ci95 == (-widen, widen)


def test_oracle_regret_is_the_mean_gap_with_a_students_t_interval() -> None:
    optimal = np.array([-120.0, -80.0])
    person = np.array([0, 1, 1, 0, 1])
    returns = np.array([-121.0, -80.5, -82.0, -120.0, -80.0])
    gaps = np.array([1.0, 0.5, 2.0, 0.0, 0.0])
    result = oracle_regret(optimal, person, returns, np.array([0.01, 0.03]))
    assert result.regret == pytest.approx(gaps.mean(), abs=1e-12)
    low, high = confidence_interval(gaps)
    widen = (0.01 * 2 + 0.03 * 3) / 5
    assert result.ci95 == pytest.approx((low - widen, high + widen), abs=1e-12)
    np.testing.assert_allclose(result.regrets, gaps, atol=1e-12)
    one = oracle_regret(optimal, np.array([1]), np.array([-81.0]))
    assert one.regret == 1.0 and all(math.isnan(x) for x in one.ci95)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (([1.0], [], []), r"person and expected_returns must be \(episodes,\) arrays of one length >= 1"),
        (([1.0], [0, 0], [1.0]), r"got \(2,\) and \(1,\)"),
        (([1.0], [1], [1.0]), r"integer indices in 0..0, got int64 in 1..1"),
        (([1.0], [-1], [1.0]), "integer indices in 0..0"),
        (([1.0], [0.0], [1.0]), "integer indices"),
        (([[1.0]], [0], [1.0]), r"must be \(people,\) arrays"),
    ],
)
def test_bad_regret_inputs_are_refused(args: tuple[list[float], list[float], list[float]], message: str) -> None:
    optimal, person, returns = (np.array(x) for x in args)
    with pytest.raises(ValueError, match=message):
        oracle_regret(optimal, person, returns)


def test_only_finite_covered_cohorts_are_solved() -> None:
    with pytest.raises(ValueError, match="needs a finite cohort"):
        solve_people(People(heart_attack_proclivity=Uniform(0.4, 0.6)))
    with pytest.raises(ValueError, match="processes must be an integer >= 1, got 0"):
        solve_people(SMALL, processes=0)
    sober = People(cohort=[Person("Vic", heart_attack_proclivity=0.0)])
    with pytest.raises(NotCoveredError, match="person 'Vic': drinking may pay"):
        solve_people(sober)


@pytest.mark.slow  # three solves, one in a spawned worker that imports everything: about 45 s in CI
@pytest.mark.audit  # CI's default cohort is solved in spawned workers (the tables and oracle tests check it)
def test_workers_solve_what_the_parent_would(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With an empty cache the first person is solved here and the second in a spawned worker: the same
    solution as solving it here, saved in the parent's cache."""
    monkeypatch.setenv("HEARTPOLE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(optimum_people, "SOLVED_HERE_SECONDS", 0.0)  # whatever the first took, use workers
    cohort = People(
        cohort=[
            Person("Bo", sleep_half_hours=12, wake_alertness=(0.6, 1.2)),
            Person("Di", sleep_half_hours=12, wake_alertness=(0.5, 1.1)),
        ]
    )
    parallel = solve_people(cohort, processes=2)
    saved = [p for p in (tmp_path / "optimum").iterdir() if not p.name.startswith(".")]  # not the hidden locks
    assert len(saved) == 2  # both saved, the worker's in the parent's cache
    here = solve("HeartPole-v0", **cohort.cohort[1].values())  # solved here, no cache
    assert parallel.solutions[1].expected_return == here.expected_return
    np.testing.assert_array_equal(parallel.solutions[1].thresholds, here.thresholds)


@pytest.mark.slow  # 24 solves: about a minute on two cores
def test_the_solver_covers_every_default_person() -> None:
    solved = solve_people("default")
    assert len(solved.solutions) == 24
    assert np.all(np.isfinite(solved.expected_returns)) and np.all(solved.error_bounds < 1e-5)
    for person, solution in zip(People.default().cohort, solved.solutions):
        assert solution.params == person.params()


def test_from_the_first_lookup_that_solves_the_rest_go_to_workers(monkeypatch: pytest.MonkeyPatch) -> None:
    """A cohort whose first people are cached (the default cohort's Ada is v0) is looked up here until a lookup
    takes a solve; the people after it go to the worker pool (they were all solved here, one at a time)."""
    import time
    from concurrent.futures import Future

    solving = {"Cy"}  # Ada and Bo are cache hits, Cy is the first solve
    submitted: list[str] = []

    def lookup(dynamics: object, env_id: str, kwargs: dict[str, object]) -> str:
        if kwargs["name"] in solving:
            time.sleep(0.05)
        return f"solution of {kwargs['name']}"

    class Pool:
        def __init__(self, workers: int, mp_context: object) -> None:
            assert workers == 2

        def __enter__(self) -> Pool:
            return self

        def __exit__(self, *exc: object) -> None:
            return None

        def submit(self, worker: object, job: optimum_people.Job) -> Future[str]:
            submitted.append(job.name)
            future: Future[str] = Future()
            future.set_result(job.solve())  # type: ignore[arg-type]
            return future

    monkeypatch.setattr(optimum_people, "optimum_for", lookup)
    monkeypatch.setattr(optimum_people, "ProcessPoolExecutor", Pool)
    monkeypatch.setattr(optimum_people, "SOLVED_HERE_SECONDS", 0.02)
    jobs = [
        optimum_people.Job(name, "HeartPole-v0", {"name": name}, V0_ACTIONS, Params(), V0_VARIABLES)
        for name in ("Ada", "Bo", "Cy", "Di", "Ed")
    ]
    done: list[tuple[int, int]] = []
    solved = optimum_people._solve_distinct(jobs, 2, lambda k, n: done.append((k, n)))
    assert solved == [f"solution of {name}" for name in ("Ada", "Bo", "Cy", "Di", "Ed")]  # type: ignore[comparison-overlap]
    assert submitted == ["Di", "Ed"] and done == [(k, 5) for k in range(1, 6)]
