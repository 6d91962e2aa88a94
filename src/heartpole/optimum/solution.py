"""The solved optimum of a variant ([`OptimumSolution`][heartpole.optimum.solution.OptimumSolution]), the public
entry points, and the cache."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import math
import os
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole import files
from heartpole.model import ALERTNESS, TIME_SINCE_SLEPT
from heartpole.parameters import Params, check_integer
from heartpole.rewards import expected_risk, least_heart_attacks

from .common import DEFAULT_GRID, SOLVER_VERSION, NotCoveredError, params_dict
from .drinks import check_covered, drink_floor
from .lifetime import check_drinks
from .played import history_arrays, history_from, history_meta, solve_played
from .sleep import solve_params
from .whole import HistoryOptimum, history_worth

if TYPE_CHECKING:
    from heartpole.dynamics import Dynamics


@dataclass(frozen=True)
class OptimumSolution:
    """The optimal policy of a HeartPole variant and its expected return.

    The policy played ([`decide`][heartpole.optimum.solution.OptimumSolution.decide]) is the history-aware optimum
    (`history`: it reads the alertness, the half-hours awake, the time elapsed and the work done) up to
    [`HISTORY_HORIZON`][heartpole.optimum.whole.HISTORY_HORIZON] decisions, and the sleep-timing policy
    (`thresholds`: alertness, half-hours awake, decisions left) beyond, or where the history gains nothing.

    Attributes:
        env_id, env_kwargs: the env solved.
        params: its [`Params`][heartpole.parameters.Params].
        grid: midpoint-grid points of the waking alertness.
        rate: Dinkelbach's optimal ``E[work] / E[time]`` on the grid.
        expected_score: the played policy's ``E[work / time]``: the sleep-timing policy's, exact on the grid,
            plus what the history-aware policy adds to it (`history`'s ``lower - markov``, on its own grid).
        expected_heart_attacks: ``max_steps * heart_attack_risk(0)``, the floor no policy beats.
        expected_return: ``expected_score - heart_attack_penalty * expected_heart_attacks``.
        error_bound: ``|expected_return(grid) - expected_return(grid // 2)|``, the grid's error bound (the
            midpoint rule converges as ``1/grid**2``, so the fine grid's error is about a third of it), plus
            the same for the history's gain (its grid against half of it).
        expected_sleeps: mean sleeps per episode of the optimal policy.
        drink_floor: expected return each drink costs at least
            (`drink_floor`).
        coffee_best_gain: the most a coffee gains over the no-drink optimum in any state checked, in units of
            work (`coffee_check`; negative: coffee never pays).
        history_worth: what any policy can add to `expected_return`, at most: the history program's gap
            ``upper - lower`` where `history` is played; beyond its horizon, what seeing the work done and the
            sleeps so far adds to the sleep-timing policy ([`history_worth`][heartpole.optimum.whole.history_worth]).
        thresholds: ``(rows, max_awake)`` alertness thresholds: with ``n`` decisions left and
            ``t = time_since_slept``, sleep when ``alertness < thresholds[n, t]`` (``t >= max_awake``: sleep).
            Far from the end the policy settles into a stationary one; the rows stop there and
            ``n >= rows`` uses the last row ([`thresholds_at`][heartpole.optimum.solution.OptimumSolution.thresholds_at]
            and [`sleeps`][heartpole.optimum.solution.OptimumSolution.sleeps] do). About 1,000 rows on v0 whatever the
            horizon (``max_steps + 1`` where the policy never settles).
        history: the history-aware policy played, ``None`` where the sleep-timing policy is.
    """

    env_id: str
    env_kwargs: dict[str, Any]
    params: Params
    grid: int
    rate: float
    expected_score: float
    expected_heart_attacks: float
    expected_return: float
    error_bound: float
    expected_sleeps: float
    drink_floor: float
    coffee_best_gain: float
    history_worth: float
    thresholds: np.ndarray = field(repr=False, compare=False)
    history: HistoryOptimum | None = field(default=None, repr=False, compare=False)

    @property
    def margin(self) -> float:
        """How far `expected_return` may be from the optimum over all policies (and from the played policy's value):
        the grids' `error_bound` plus `history_worth`, the history program's gap (beyond its horizon, what seeing the
        work done and the sleeps so far can add). Regret intervals are widened by it."""
        return self.error_bound + self.history_worth

    def decide(self, obs: np.ndarray, decisions_left: int | np.ndarray) -> np.ndarray:
        """Whether the played policy sleeps, for no-drink observations ``(envs, obs_dim)`` and the decisions left
        (1..max_steps): `history`'s decision where the observation lies in its solved region
        ([`HistoryOptimum.inside`][heartpole.optimum.whole.HistoryOptimum.inside]), else
        [`sleeps`][heartpole.optimum.solution.OptimumSolution.sleeps]' (another person's episodes leave the region)."""
        obs = np.asarray(obs)
        left = np.broadcast_to(np.asarray(decisions_left, dtype=np.int64), (len(obs),))
        timing = self.sleeps(obs[:, ALERTNESS], obs[:, TIME_SINCE_SLEPT], left)
        if self.history is None:
            return timing
        return np.where(self.history.inside(obs, left), self.history.sleeps(obs, left), timing)

    @property
    def max_awake(self) -> int:
        """Half-hours awake after which the policy always sleeps."""
        return int(self.thresholds.shape[1])

    def thresholds_at(self, decisions_left: int | np.ndarray) -> np.ndarray:
        """The rows of `thresholds` for ``decisions_left``
        (any of 0..max_steps; shape ``(..., max_awake)``)."""
        return self.thresholds[self._row(decisions_left)]

    def sleeps(
        self, alertness: np.ndarray, time_since_slept: np.ndarray, decisions_left: int | np.ndarray
    ) -> np.ndarray:
        """Whether the optimal policy sleeps, elementwise (no-drink states; ``decisions_left`` in 1..max_steps)."""
        t = np.asarray(time_since_slept, dtype=np.int64)
        inside = t < self.max_awake
        threshold = self.thresholds[
            np.broadcast_to(self._row(decisions_left), t.shape), np.minimum(t, self.max_awake - 1)
        ]
        return ~inside | (np.asarray(alertness, dtype=np.float64) < threshold)

    def _row(self, decisions_left: int | np.ndarray) -> np.ndarray:
        return np.clip(np.asarray(decisions_left, dtype=np.int64), 0, len(self.thresholds) - 1)

    def within(self, interval: tuple[float, float]) -> bool:
        """Whether `expected_return` lies in
        ``interval`` (an evaluator's 95% interval, say) widened by the grid's
        `error_bound` on both sides."""
        low, high = interval
        return bool(low - self.error_bound <= self.expected_return <= high + self.error_bound)

    def summary(self) -> dict[str, Any]:
        """JSON-safe figures of the solution (no arrays)."""
        return {
            "env_id": self.env_id,
            "env_kwargs": self.env_kwargs,
            "params": params_dict(self.params),
            "grid": self.grid,
            "rate": self.rate,
            "expected_score": self.expected_score,
            "expected_heart_attacks": self.expected_heart_attacks,
            "expected_return": self.expected_return,
            "error_bound": self.error_bound,
            "expected_sleeps": self.expected_sleeps,
            "drink_floor": self.drink_floor,
            "coffee_best_gain": self.coffee_best_gain,
            "history_worth": self.history_worth,
            "history": None if self.history is None else history_meta(self.history),
            "max_awake": self.max_awake,
            "solver_version": SOLVER_VERSION,
        }

    def save(self, directory: str | Path) -> Path:
        """Write ``optimum.json`` and ``optimum.npz`` into ``directory`` (created), both or neither, atomically."""
        directory = Path(directory)
        with files.atomic_files(directory / "optimum.npz", directory / "optimum.json") as (npz, summary):
            with npz.open("wb") as handle:
                arrays = {"thresholds": self.thresholds}
                arrays.update({} if self.history is None else history_arrays(self.history))
                np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]
            summary.write_text(files.json_text(self.summary()))
        return directory

    @classmethod
    def load(cls, directory: str | Path) -> OptimumSolution:
        """Read a solution saved by [`save`][heartpole.optimum.solution.OptimumSolution.save].

        Raises:
            FileNotFoundError: a missing file.
            ValueError: files that are not a solution of this solver version, or that cannot be read (cut
                short, damaged, not what they should hold).
        """
        directory = Path(directory)
        for name in ("optimum.json", "optimum.npz"):
            if not (directory / name).is_file():
                raise FileNotFoundError(f"{directory / name} not found; save a solution with OptimumSolution.save")
        try:
            meta = json.loads((directory / "optimum.json").read_text())
            if meta.get("solver_version") != SOLVER_VERSION:
                raise ValueError(f"solver version {meta.get('solver_version')}, expected {SOLVER_VERSION}")
            params = Params(**{**meta["params"], "wake_alertness": tuple(meta["params"]["wake_alertness"])})
            with np.load(directory / "optimum.npz") as arrays:
                thresholds = np.asarray(arrays["thresholds"], dtype=np.float64)
                history = None if meta["history"] is None else history_from(params, meta["history"], arrays)
            fields = ("rate", "expected_score", "expected_heart_attacks", "expected_return", "error_bound")
            return cls(
                env_id=meta["env_id"],
                env_kwargs=meta["env_kwargs"],
                params=params,
                grid=int(meta["grid"]),
                expected_sleeps=float(meta["expected_sleeps"]),
                drink_floor=float(meta["drink_floor"]),
                coffee_best_gain=float(meta["coffee_best_gain"]),
                history_worth=float(meta["history_worth"]),
                thresholds=thresholds,
                history=history,
                **{key: float(meta[key]) for key in fields},
            )
        except Exception as error:  # noqa: BLE001 - whatever a damaged file raises (BadZipFile, EOFError, ...)
            reason = " ".join(str(error).split()) or type(error).__name__
            raise ValueError(f"{directory}: not a HeartPole optimum ({reason})") from None


# ------------------------------------------------------------------------------------------------------
# the public entry points


def solve(env_id: str = "HeartPole-v0", *, grid: int = DEFAULT_GRID, **env_kwargs: Any) -> OptimumSolution:
    """Solve the optimal policy of ``env_id`` built with ``env_kwargs`` (see the module docstring).

    Args:
        env_id: a registered HeartPole id whose dynamics are v0's (actions and variables).
        grid: midpoint-grid points of the waking alertness (>= 4); the error bound compares ``grid // 2``.
        env_kwargs: the env's keyword arguments (``heart_attack_proclivity``, ``max_steps``, ...).

    Raises:
        NotCoveredError: a variant the solver does not cover (the message says why).
        ValueError: an unknown env or bad arguments.
    """
    from heartpole.registry import env_dynamics

    check_integer("grid", grid, 4)
    _one_person(env_kwargs)
    dynamics = env_dynamics(env_id, env_kwargs)
    check_covered(env_id, dynamics)
    return _solve(dynamics.params, int(grid), env_id, dict(env_kwargs))


def _solve(
    params: Params, grid: int, env_id: str, env_kwargs: dict[str, Any], *, drinks: bool = True
) -> OptimumSolution:
    """The no-drink optimum of ``params``; ``drinks=False`` skips the check that no drink pays (its
    ``coffee_best_gain`` is then NaN: the best no-drink policy, not shown to be the optimum)."""
    fine = solve_params(params, grid)
    coffee = check_drinks(params, fine.rate) if drinks else math.nan
    coarse = solve_params(params, grid // 2)
    attacks = least_heart_attacks(params)
    score, error, worth, history = _with_history(
        params, fine.expected_score, abs(fine.expected_score - coarse.expected_score)
    )
    return OptimumSolution(
        env_id=env_id,
        env_kwargs=env_kwargs,
        params=params,
        grid=grid,
        rate=fine.rate,
        expected_score=score,
        expected_heart_attacks=attacks,
        expected_return=expected_risk(score, attacks, params.heart_attack_penalty),
        error_bound=error,
        expected_sleeps=fine.expected_sleeps,
        drink_floor=drink_floor(params),
        coffee_best_gain=coffee,
        history_worth=worth,
        thresholds=fine.thresholds,
        history=history,
    )


def _with_history(params: Params, score: float, error: float) -> tuple[float, float, float, HistoryOptimum | None]:
    """The played policy's score, error bound and `history_worth`, and its history program: the sleep-timing
    policy's ``score`` and grid ``error`` plus the history program's gain, its grid error and its gap; beyond the
    history's horizon (or where the history gains nothing), the sleep-timing policy with its history's worth."""
    played = solve_played(params)
    if played is None:
        return score, error, history_worth(params), None
    solved, gain_error = played
    if solved.gain <= 0:
        return score, error + gain_error, max(solved.upper - solved.markov, 0.0), None
    return score + solved.gain, error + gain_error, solved.gap, solved


def optimum(env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None) -> OptimumSolution:
    """The solution for ``env_id`` and ``env_kwargs``, solved once: kept in memory and in the user cache.

    The disk cache lives in ``$HEARTPOLE_CACHE_DIR``, else ``$XDG_CACHE_HOME/heartpole``, else
    ``~/.cache/heartpole``, under ``optimum/<hash of the parameters and solver version>/``. An entry there that
    cannot be read (cut short, damaged) is solved again and replaced, with a ``RuntimeWarning`` saying so.

    Raises:
        NotCoveredError, ValueError: as [`solve`][heartpole.optimum.solution.solve].
    """
    from heartpole.registry import env_dynamics

    kwargs = dict(env_kwargs or {})
    _one_person(kwargs)
    return optimum_for(env_dynamics(env_id, kwargs), env_id, kwargs)


def _one_person(env_kwargs: Mapping[str, Any]) -> None:
    """Refuse a population: it has one optimum per person, never one for all."""
    if env_kwargs.get("people") is not None:
        raise NotCoveredError(
            f"people={env_kwargs['people']!r} is a population, with one optimum per person and none for all of "
            "them; solve each person with heartpole.optimum.solve_people (heartpole optimum --people NAME)"
        )


def optimum_for(
    dynamics: Dynamics, env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None
) -> OptimumSolution:
    """[`optimum`][heartpole.optimum.solution.optimum] for a [`Dynamics`][heartpole.dynamics.Dynamics] (``env_id``
    and ``env_kwargs`` label it)."""
    check_covered(env_id, dynamics)
    solution = _cached(dynamics.params, str(cache_dir()))
    if isinstance(solution, NotCoveredError):
        raise NotCoveredError(str(solution))
    return replace(solution, env_id=env_id, env_kwargs=dict(env_kwargs or {}))


def available(env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None) -> OptimumSolution | None:
    """[`optimum`][heartpole.optimum.solution.optimum], or ``None`` for a variant the solver does not cover."""
    try:
        return optimum(env_id, env_kwargs)
    except NotCoveredError:
        return None


@functools.lru_cache(maxsize=32)
def _cached(params: Params, cache_root: str) -> OptimumSolution | NotCoveredError:
    """The solution of ``params`` (or the solver's refusal) from memory, the disk cache or a fresh solve.

    A solve holds a lock on its cache entry, so processes that want the same solution at once (test workers, Ray
    trials) solve it once: the others wait, then read it from the disk.
    """
    key = hashlib.sha256(
        json.dumps([SOLVER_VERSION, DEFAULT_GRID, params_dict(params)], sort_keys=True).encode()
    ).hexdigest()[:16]
    directory = Path(cache_root) / "optimum" / key
    found = _stored(directory, params, warn=False)
    if found is not None:
        return found
    with _solving(directory):
        found = _stored(directory, params, warn=True)  # another process may have solved it meanwhile
        if found is not None:
            return found
        try:
            solution = _solve(params, DEFAULT_GRID, "HeartPole-v0", _changed_params(params))
        except NotCoveredError as error:
            _store_refusal(directory, params, error)
            return error
        try:
            solution.save(directory)
        except OSError:  # a read-only home still gets the solution, just not cached on disk
            pass
    return solution


REFUSAL_NAME = "refused.json"
"""The file a refusal is cached in (some take the lifetime check a minute to find)."""


def _stored(directory: Path, params: Params, warn: bool) -> OptimumSolution | NotCoveredError | None:
    """The solution or refusal cached in ``directory`` for ``params``; ``None`` when there is none (a damaged or
    mismatched entry is said, with ``warn``, and solved again)."""
    try:
        refusal = json.loads((directory / REFUSAL_NAME).read_text())
        if refusal.get("solver_version") == SOLVER_VERSION and refusal.get("params") == params_dict(params):
            return NotCoveredError(str(refusal["message"]))
    except (OSError, ValueError, AttributeError, KeyError):
        pass
    try:
        solution = OptimumSolution.load(directory)
        if solution.params == params and solution.grid == DEFAULT_GRID:
            return solution
        damaged = f"{directory} holds another solution"
    except FileNotFoundError:
        return None
    except ValueError as error:
        damaged = str(error)
    if warn:  # said once per process: _cached is cached
        warnings.warn(f"the cached optimum cannot be used ({damaged}); solving it again", RuntimeWarning, stacklevel=3)
    return None


def _store_refusal(directory: Path, params: Params, error: NotCoveredError) -> None:
    record = {"solver_version": SOLVER_VERSION, "params": params_dict(params), "message": str(error)}
    try:
        files.write_json(directory / REFUSAL_NAME, record)
    except OSError:
        pass  # not cached on disk: refused again next time


@contextlib.contextmanager
def _solving(directory: Path) -> Iterator[None]:
    """Hold an exclusive lock on the cache entry ``directory`` (blocking) while the block runs. No lock where the
    cache's folder does not exist yet (nothing is made before the solve, so a solve cut short by a signal leaves
    nothing behind), cannot be written, or the platform has no ``fcntl``."""
    lock = directory.parent / f".{directory.name}.lock"
    try:
        import fcntl

        handle = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666) if directory.parent.is_dir() else None
    except (ImportError, OSError):
        handle = None
    if handle is None:
        yield
        return
    try:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield
    finally:
        os.close(handle)


def cache_dir() -> Path:
    """Where solutions are cached on disk (see [`optimum`][heartpole.optimum.solution.optimum])."""
    if os.environ.get("HEARTPOLE_CACHE_DIR"):
        return Path(os.environ["HEARTPOLE_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "heartpole"


def _changed_params(params: Params) -> dict[str, Any]:
    """The env keyword arguments that give ``params``: the fields that differ from the defaults."""
    defaults = params_dict(Params())
    return {key: value for key, value in params_dict(params).items() if defaults[key] != value}
