"""The optimum of every person of a cohort, and oracle regret: how far a policy is from each person's best.

[`solve_people`][heartpole.optimum.people.solve_people] solves each distinct person of a finite
[`People`][heartpole.people.People] once, through [`optimum`][heartpole.optimum.optimum] and its cache
(memory and disk), several at a time in worker processes. The person's optimal expected return is the
quantity [`EvaluationResult.with_regret`][heartpole.results.EvaluationResult.with_regret] compares a
policy's expected-risk return with: ``OptimumSolution.expected_return``, within its ``margin`` (the grids' errors
and what any policy may add to the played one).

[`oracle_regret`][heartpole.optimum.people.oracle_regret] is then the mean over episodes of (the episode's
person's optimal expected return - the policy's expected-risk return in that episode), with a 95% Student-t
interval over episodes widened by the optimum's margin.
[`PeopleOptimum.decide`][heartpole.optimum.people.PeopleOptimum.decide] acts as the ``oracle`` policy: each env
sleeps as its own person's optimal policy would.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple, TypeVar

import numpy as np

from heartpole.actions import Action
from heartpole.dynamics import Dynamics
from heartpole.parameters import Params, Variable, check_integer
from heartpole.people import People
from heartpole.stats import confidence_interval

from .solution import OptimumSolution, optimum_for

SOLVED_HERE_SECONDS = 0.5
"""A lookup slower than this was a solve, not a cache hit: the remaining people go to worker processes."""

T = TypeVar("T")
ProgressCallback = Callable[[int, int], None]
"""Called as ``progress(done, total)`` after each distinct person is solved or loaded."""
POPULATION_KWARGS = ("people", "observe_traits", "measurement")
"""An env's keyword arguments about who the person is and what is observed: none is a person's parameter, so
[`split_people`][heartpole.optimum.people.split_people] sets them apart (each person's optimum is the
full-information optimum of their MDP, whatever the observation shows)."""


@dataclass(frozen=True)
class OracleRegret:
    """Oracle regret over episodes: mean of (person's optimal expected return - expected-risk return).

    Attributes:
        regret: the mean over episodes.
        ci95: its 95% Student-t interval, widened on both sides by the mean grid error of the episodes'
            optima (``(nan, nan)`` below two episodes).
        episodes: how many episodes.
        regrets: ``(episodes,)`` float64, each episode's regret.
    """

    regret: float
    ci95: tuple[float, float]
    episodes: int
    regrets: np.ndarray = field(repr=False, compare=False)


def oracle_regret(
    optimal_returns: np.ndarray,
    person: np.ndarray,
    expected_returns: np.ndarray,
    error_bounds: np.ndarray | None = None,
) -> OracleRegret:
    """Oracle regret of episodes whose persons are ``person`` and expected-risk returns ``expected_returns``.

    Args:
        optimal_returns: ``(people,)`` each person's optimal expected return.
        person: ``(episodes,)`` each episode's person (an index into ``optimal_returns``).
        expected_returns: ``(episodes,)`` each episode's expected-risk return (final score - penalty x the
            summed heart-attack risks, as evaluation computes it).
        error_bounds: ``(people,)`` how far each optimum may be off, the intervals' widening (default 0;
            [`PeopleOptimum.regret`][heartpole.optimum.people.PeopleOptimum.regret] gives their margins).

    Raises:
        ValueError: no episode, shapes that differ, or a person index out of range.
    """
    optimal = np.asarray(optimal_returns, dtype=np.float64)
    who = np.asarray(person)
    returns = np.asarray(expected_returns, dtype=np.float64)
    bounds = np.zeros_like(optimal) if error_bounds is None else np.asarray(error_bounds, dtype=np.float64)
    if optimal.ndim != 1 or bounds.shape != optimal.shape:
        raise ValueError(
            f"optimal_returns and error_bounds must be (people,) arrays, got {optimal.shape} and {bounds.shape}"
        )
    if who.ndim != 1 or who.shape != returns.shape or len(who) == 0:
        raise ValueError(
            "person and expected_returns must be (episodes,) arrays of one length >= 1, "
            f"got {who.shape} and {returns.shape}"
        )
    if not np.issubdtype(who.dtype, np.integer) or who.min() < 0 or who.max() >= len(optimal):
        raise ValueError(
            f"person must hold integer indices in 0..{len(optimal) - 1}, got {who.dtype} in {who.min()}..{who.max()}"
        )
    regrets = optimal[who] - returns
    low, high = confidence_interval(regrets)
    widen = float(bounds[who].mean())
    return OracleRegret(float(regrets.mean()), (low - widen, high + widen), len(regrets), regrets)


@dataclass(frozen=True, eq=False)
class PeopleOptimum:
    """Each person's optimum: their optimal expected returns, and the oracle policy's table.

    Attributes:
        people: the cohort.
        env_id, env_kwargs: the env each person's parameters change.
        solutions: one [`OptimumSolution`][heartpole.optimum.OptimumSolution] per person, in cohort order.
    """

    people: People
    env_id: str
    env_kwargs: dict[str, Any]
    solutions: tuple[OptimumSolution, ...]

    @cached_property
    def expected_returns(self) -> np.ndarray:
        """``(people,)`` float64: each person's optimal expected return."""
        return np.array([s.expected_return for s in self.solutions], dtype=np.float64)

    @cached_property
    def error_bounds(self) -> np.ndarray:
        """``(people,)`` float64: each optimum's grid error bound."""
        return np.array([s.error_bound for s in self.solutions], dtype=np.float64)

    @cached_property
    def margins(self) -> np.ndarray:
        """``(people,)`` float64: each optimum's [`margin`][heartpole.optimum.solution.OptimumSolution.margin], by
        which oracle regret intervals are widened."""
        return np.array([s.margin for s in self.solutions], dtype=np.float64)

    @cached_property
    def max_awake(self) -> np.ndarray:
        """``(people,)`` int64: half-hours awake after which each person's optimal policy always sleeps."""
        return np.array([s.max_awake for s in self.solutions], dtype=np.int64)

    @cached_property
    def thresholds(self) -> np.ndarray:
        """``(people, rows, width)`` float64: each person's thresholds (rows as
        [`OptimumSolution.thresholds`][heartpole.optimum.OptimumSolution]), the shorter tables padded with
        their own last row and with ``inf`` beyond their ``max_awake``."""
        rows = max(len(s.thresholds) for s in self.solutions)
        width = int(self.max_awake.max())
        table = np.full((len(self.solutions), rows, width), np.inf)
        for index, solution in enumerate(self.solutions):
            own = solution.thresholds
            table[index, : len(own), : own.shape[1]] = own
            table[index, len(own) :, : own.shape[1]] = own[-1]
        return table

    def sleeps(
        self, person: np.ndarray, alertness: np.ndarray, time_since_slept: np.ndarray, decisions_left: np.ndarray
    ) -> np.ndarray:
        """Whether each env's person's optimal policy sleeps: ``OptimumSolution.sleeps`` of env ``i``'s person,
        for all envs at once (``(n,)`` arrays; ``decisions_left`` in 1..max_steps)."""
        who = np.asarray(person, dtype=np.int64)
        t = np.asarray(time_since_slept, dtype=np.int64)
        table = self.thresholds
        row = np.clip(np.asarray(decisions_left, dtype=np.int64), 0, table.shape[1] - 1)
        threshold = table[who, np.broadcast_to(row, t.shape), np.minimum(t, table.shape[2] - 1)]
        return (t >= self.max_awake[who]) | (np.asarray(alertness, dtype=np.float64) < threshold)

    def decide(self, person: np.ndarray, obs: np.ndarray, decisions_left: np.ndarray) -> np.ndarray:
        """Whether each env's person's optimal policy sleeps: [`OptimumSolution.decide`][heartpole.optimum.solution.
        OptimumSolution.decide] of env ``i``'s person, which reads the whole observation (``obs`` ``(n, obs_dim)``,
        ``person`` and ``decisions_left`` ``(n,)``)."""
        who = np.asarray(person, dtype=np.int64)
        left = np.broadcast_to(np.asarray(decisions_left, dtype=np.int64), who.shape)
        sleeps = np.zeros(who.shape, dtype=bool)
        for index in np.unique(who):
            mine = who == index
            sleeps[mine] = self.solutions[index].decide(obs[mine], left[mine])
        return sleeps

    def regret(self, person: np.ndarray, expected_returns: np.ndarray) -> OracleRegret:
        """[`oracle_regret`][heartpole.optimum.people.oracle_regret] of episodes of these people."""
        return oracle_regret(self.expected_returns, person, expected_returns, self.margins)


def split_people(env_kwargs: Mapping[str, Any] | None) -> tuple[People | None, dict[str, Any]]:
    """The population of an env's keyword arguments (``people=``, resolved; ``None`` without) and the rest of
    them without [`POPULATION_KWARGS`][heartpole.optimum.people.POPULATION_KWARGS]: the env whose parameters
    each person changes.

    Raises:
        ValueError, TypeError: a ``people`` that [`People.resolve`][heartpole.people.People.resolve] refuses.
    """
    kwargs = dict(env_kwargs or {})
    people = People.resolve(kwargs.get("people"))
    return people, {key: value for key, value in kwargs.items() if key not in POPULATION_KWARGS}


def solve_people(
    people: People | str,
    env_id: str = "HeartPole-v0",
    env_kwargs: Mapping[str, Any] | None = None,
    *,
    processes: int | None = None,
    progress: ProgressCallback | None = None,
    dynamics: Dynamics | None = None,
) -> PeopleOptimum:
    """Each person's optimum, each distinct person solved once and cached as [`optimum`][heartpole.optimum.optimum]
    caches (memory and disk: later calls only load).

    Distinct people are looked up here while each lookup is a cache hit; from the first that took a solve (longer
    than ``SOLVED_HERE_SECONDS``), the others are solved ``processes`` at a time in worker processes (spawned: safe
    beside numba's threads).

    Args:
        people: a finite cohort, or a population's name (``"default"``).
        env_id: the env whose parameters each person changes.
        env_kwargs: its keyword arguments (a person's fields win;
            [`POPULATION_KWARGS`][heartpole.optimum.people.POPULATION_KWARGS] are left out).
        processes: worker processes (default: 2, or 1 on a one-core machine).
        progress: called as ``progress(done, total)`` after each distinct person.
        dynamics: the env's [`Dynamics`][heartpole.dynamics.Dynamics] where the caller has resolved ``env_id``
            already (its parameters are each person's base); ``None``: resolved here, once for the cohort.

    Raises:
        ValueError: a population that is not a finite cohort, or ``processes`` below 1.
        NotCoveredError: a person the solver does not cover (the message names the person).
    """
    cohort = People.resolve(people)
    if cohort is None or not cohort.finite:
        raise ValueError(
            f"each person's optimum needs a finite cohort (People(cohort=...) or 'default'), got {people!r}"
        )
    workers = min(2, os.cpu_count() or 1) if processes is None else processes
    workers = check_integer("processes", workers, 1)
    base = split_people(env_kwargs)[1]  # the env's own population, if any, is not a parameter
    if dynamics is None:
        from heartpole.registry import env_dynamics

        dynamics = env_dynamics(env_id, base)
    kwargs = [{**base, **person.values()} for person in cohort.cohort]
    jobs: dict[tuple[tuple[str, Any], ...], Job] = {}
    for person, changed in zip(cohort.cohort, kwargs):
        key = _key(changed)
        if key not in jobs:  # the first person of equal ones names it
            params = _named(person.name, lambda: person.params(dynamics.params))  # noqa: B023 (called at once)
            jobs[key] = Job(person.name, env_id, changed, dynamics.actions, params, dynamics.variables)
    solved = _solve_distinct(list(jobs.values()), workers, progress or _quiet)
    by_key = dict(zip(jobs, solved))
    return PeopleOptimum(cohort, env_id, base, tuple(by_key[_key(changed)] for changed in kwargs))


class Job(NamedTuple):
    """One distinct person to solve: the env's actions and variables with the person's parameters (plain data, for
    a worker process), labelled by the env id and keyword arguments that make that person's env."""

    name: str
    env_id: str
    env_kwargs: dict[str, Any]
    actions: tuple[Action, ...]
    params: Params
    variables: tuple[Variable, ...]

    def solve(self) -> OptimumSolution:
        """The person's optimum, solved or loaded ([`optimum_for`][heartpole.optimum.solution.optimum_for])."""
        return optimum_for(Dynamics(self.actions, self.params, self.variables), self.env_id, self.env_kwargs)


def _solve_distinct(jobs: list[Job], workers: int, progress: ProgressCallback) -> list[OptimumSolution]:
    """Solve or load each job: here while lookups are cache hits, then, from the first lookup that was a solve, the
    rest in workers (so a cohort whose first person is cached, v0's Ada, is solved in parallel)."""
    total = len(jobs)
    solutions: list[OptimumSolution] = []
    for index, job in enumerate(jobs):
        start = time.perf_counter()
        solutions.append(_named(job.name, job.solve))
        progress(len(solutions), total)
        rest = jobs[index + 1 :]
        if workers > 1 and rest and time.perf_counter() - start > SOLVED_HERE_SECONDS:
            context = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(min(workers, len(rest)), mp_context=context) as pool:
                futures = [(other.name, pool.submit(_worker, other)) for other in rest]
                for name, future in futures:
                    solutions.append(_named(name, future.result))
                    progress(len(solutions), total)
            break
    return solutions


def _worker(job: Job) -> OptimumSolution:
    """Solve (or load) one person in a worker process (its environment, so its cache folder, is the parent's)."""
    return job.solve()


def _named(name: str, get: Callable[[], T]) -> T:
    """``get()``, the person's name put before an error's message (the same type: NotCoveredError stays one)."""
    try:
        return get()
    except ValueError as error:
        raise type(error)(f"person {name!r}: {error}") from None


def _key(kwargs: Mapping[str, Any]) -> tuple[tuple[str, Any], ...]:
    return tuple(sorted(kwargs.items()))


def _quiet(done: int, total: int) -> None:
    """No progress report."""
