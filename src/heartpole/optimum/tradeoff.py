"""The productivity-risk frontier: the optimum's expected score against its expected heart attacks, penalty by penalty.

HeartPole's return is ``final score - heart_attack_penalty x heart attacks``: the penalty is the price of a heart
attack in units of score. Each penalty has its optimal policy, and that policy has an expected score and expected
heart attacks per episode. As the penalty falls, the optimum buys score with risk (coffee and beer raise the blood
pressure); from some penalty on drinks stop paying and the optimum is the no-drink one, whose heart attacks are the
floor no policy beats. The points ``(expected heart attacks, expected score)`` over the penalties from 0 up to there
are the frontier: every policy lies on or below it (each penalty's optimum maximises ``score - penalty x attacks``,
the line of slope ``penalty`` through it), and each point is the best score reachable at its risk, where the
frontier is concave.

Two solvers give the points, each penalty in turn:

* **The no-drink optimum** ([`optimum`][heartpole.optimum.solution.optimum]) wherever its own check
  ([`check_drinks`][heartpole.optimum.lifetime.check_drinks]) proves that drinks never pay. Its first, per-step
  argument charges each drink its own step's heart-attack cost, which grows with the penalty, so it passes from a
  threshold penalty on: [`no_drink_threshold`][heartpole.optimum.tradeoff.no_drink_threshold] finds it by bisection
  on that check itself (``check_beer``, then ``check_coffee``), about 70.1 on v0, and the default penalties run from
  0 up to it. Below it the lifetime check (a drink's whole lifetime of blood pressure, minutes a penalty) may still
  prove it: [`Frontier.proven_from`][heartpole.optimum.tradeoff.Frontier.proven_from] is the least solved penalty
  from which on every point is proven. Every penalty above has the same optimal policy: one point.
* **A drinking solver** where the check refuses (``drinking``; default
  [`frontier_point`][heartpole.optimum.point.frontier_point]'s coffee program, whose policy is a lower bound, not a
  proven optimum). With ``drinking=None`` those penalties are listed in
  [`Frontier.missing`][heartpole.optimum.tradeoff.Frontier] with the check's reason.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from heartpole.parameters import Params

from .common import NotCoveredError
from .drinks import check_beer, check_coffee
from .sleep import solve_params

NO_DRINK = "no-drink optimum"
"""[`FrontierRow.solver`][heartpole.optimum.tradeoff.FrontierRow] of the points the no-drink optimum solved."""
DRINKING = "drinking optimum"
"""[`FrontierRow.solver`][heartpole.optimum.tradeoff.FrontierRow] of the points the drinking solver proved optimal."""
LOWER_BOUND = "best solved policy"
"""[`FrontierRow.solver`][heartpole.optimum.tradeoff.FrontierRow] where the drinking solver has a policy, not a proven
optimum: its value is a lower bound on the optimum's (``upper`` unknown, ``nan``)."""
THRESHOLD_TOLERANCE = 1e-3
"""Relative width at which [`no_drink_threshold`][heartpole.optimum.tradeoff.no_drink_threshold]'s bisection stops."""
RATE_GRID = 100
"""Waking-alertness grid of the no-drink rate the coffee check is given (as ``check_no_drinks`` uses)."""
LARGEST_PENALTY = 1e9
"""Where [`no_drink_threshold`][heartpole.optimum.tradeoff.no_drink_threshold] stops doubling the penalty."""
DEFAULT_POINTS = 9
"""Penalties of the default frontier: 0, then geometric from 1 up to the threshold."""
NO_DRINKS = 1e-3
"""Drinks per episode below which a point counts as drinking nothing (its policy is the no-drink one)."""


class DrinkingFigures(Protocol):
    """What a drinking solver returns for one penalty ([`FrontierPoint`][heartpole.optimum.point.FrontierPoint]).

    The expected drinks, coffees and beers per episode of the solved policy; ``lower`` and ``upper`` bound the
    optimal expected return (the solved policy's value below, a bound on every policy above: ``nan`` where the
    solver has none); ``optimal`` is whether the policy is the proven optimum."""

    @property
    def expected_return(self) -> float:
        """The solved policy's expected return."""

    @property
    def expected_score(self) -> float:
        """Its expected final score."""

    @property
    def expected_attacks(self) -> float:
        """Its expected heart attacks per episode."""

    @property
    def coffees_per_episode(self) -> float:
        """Its expected coffees per episode."""

    @property
    def beers_per_episode(self) -> float:
        """Its expected beers per episode."""

    @property
    def drinks_per_episode(self) -> float:
        """Coffees and beers per episode."""

    @property
    def lower(self) -> float:
        """The optimum's expected return is at least this."""

    @property
    def upper(self) -> float:
        """... and at most this (``nan``: unknown)."""

    @property
    def optimal(self) -> bool:
        """Whether the policy is the proven optimum."""


DrinkingSolver = Callable[[str, Mapping[str, Any]], DrinkingFigures]
"""``solver(env_id, env_kwargs)``: the optimum where drinks may pay (``env_kwargs`` holds the penalty)."""


def package_drinking(env_id: str, env_kwargs: Mapping[str, Any]) -> DrinkingFigures:
    """The package's drinking solver: [`frontier_point`][heartpole.optimum.point.frontier_point] (the coffee
    program's policy where drinks may pay)."""
    from .point import frontier_point

    return frontier_point(env_id, **env_kwargs)


@dataclass(frozen=True)
class FrontierRow:
    """The optimum at one heart-attack penalty.

    Attributes:
        penalty: ``heart_attack_penalty``.
        expected_score: the optimal policy's expected final score (``work_done / time_elapsed``).
        expected_heart_attacks: its expected heart attacks per episode.
        coffees, beers: its expected coffees and beers per episode.
        drinks: its expected drinks per episode.
        expected_return: ``expected_score - penalty x expected_heart_attacks``.
        lower, upper: the optimal expected return lies in ``[lower, upper]``: the solved policy's value (less the
            grid's error) below, a bound on every policy above.
        solver: which solver gave it ([`NO_DRINK`][heartpole.optimum.tradeoff.NO_DRINK],
            [`DRINKING`][heartpole.optimum.tradeoff.DRINKING] or
            [`LOWER_BOUND`][heartpole.optimum.tradeoff.LOWER_BOUND]).
    """

    penalty: float
    expected_score: float
    expected_heart_attacks: float
    coffees: float
    beers: float
    drinks: float
    expected_return: float
    lower: float
    upper: float
    solver: str

    def summary(self) -> dict[str, Any]:
        """JSON-safe figures (``nan`` as ``None``)."""
        return {key: _json(value) for key, value in self.__dict__.items()}


@dataclass(frozen=True)
class Frontier:
    """The productivity-risk frontier of an env (see the module docstring).

    Attributes:
        env_id, env_kwargs: the env (``env_kwargs`` without the penalty).
        points: the solved penalties, in increasing order.
        threshold: from this penalty on the no-drink optimum's per-step check proves that drinks never pay
            ([`no_drink_threshold`][heartpole.optimum.tradeoff.no_drink_threshold]).
        missing: ``(penalty, reason)`` of the penalties asked for that no solver covers.
    """

    env_id: str
    env_kwargs: dict[str, Any]
    points: tuple[FrontierRow, ...]
    threshold: float
    missing: tuple[tuple[float, str], ...]

    @property
    def proven_from(self) -> float:
        """The least solved penalty from which on every solved point is the no-drink optimum, proven by the solver's
        check (``nan`` if the highest is not): where drinks stop paying, as far as the points show."""
        proven = math.nan
        for point in reversed(self.points):
            if point.solver != NO_DRINK:
                break
            proven = point.penalty
        return proven

    @property
    def drinks_stop(self) -> float:
        """The least solved penalty from which on every solved point drinks nothing (``nan`` if the highest drinks):
        at most `proven_from` (a policy that is not proven optimal may drink nothing too)."""
        stop = math.nan
        for point in reversed(self.points):
            if point.drinks >= NO_DRINKS:
                break
            stop = point.penalty
        return stop

    def pareto_front(self) -> list[tuple[float, float]]:
        """The distinct ``(expected score, -expected heart attacks)`` of the points, none dominated by another
        (both objectives maximised): what a multi-objective agent can reach, at best."""
        pairs = sorted({(p.expected_score, -p.expected_heart_attacks) for p in self.points}, reverse=True)
        front: list[tuple[float, float]] = []
        for score, health in pairs:  # by score, highest first: kept if healthier than every one kept before
            if not front or health > front[-1][1]:
                front.append((score, health))
        return front

    def summary(self) -> dict[str, Any]:
        """JSON-safe figures."""
        return {
            "env_id": self.env_id,
            "env_kwargs": self.env_kwargs,
            "threshold": self.threshold,
            "proven_from": _json(self.proven_from),
            "drinks_stop": _json(self.drinks_stop),
            "points": [p.summary() for p in self.points],
            "missing": [{"penalty": p, "reason": reason} for p, reason in self.missing],
        }


@functools.lru_cache(maxsize=32)
def no_drink_threshold(params: Params, tolerance: float = THRESHOLD_TOLERANCE) -> float:
    """The least ``heart_attack_penalty`` (to ``tolerance``, relative) from which the no-drink optimum's own check
    proves that drinks never pay with ``params``' other numbers.

    Each check charges every drink ``max_steps x drink_floor``, which is proportional to the penalty, against what
    a drink can buy, which does not depend on it: each passes from a penalty on. Bisection on
    [`check_beer`][heartpole.optimum.drinks.check_beer] (a bound: instant) finds its threshold; the coffee check
    ([`check_coffee`][heartpole.optimum.drinks.check_coffee], a pass over the states: seconds) runs there, and only
    if it refuses is the bisection carried on with it. The returned penalty passes both. Kept in memory per
    ``params``.

    Raises:
        NotCoveredError: no penalty up to `LARGEST_PENALTY` passes (``heart_attack_proclivity=0``: drinks cost
            nothing, say), with the check's reason.
    """
    rate = solve_params(params, RATE_GRID).rate  # the no-drink rate: the same at every penalty

    def beer(penalty: float) -> object:
        return check_beer(replace(params, heart_attack_penalty=penalty))

    def coffee(penalty: float) -> object:
        return check_coffee(replace(params, heart_attack_penalty=penalty), rate)

    low = _bisect(beer, 0.0, tolerance)
    return low if _passes(coffee, low) else _bisect(coffee, low, tolerance)


def _bisect(check: Callable[[float], object], low: float, tolerance: float) -> float:
    """The least penalty above ``low`` (which fails, or is 0) that ``check`` passes, to ``tolerance`` (relative):
    doubling up to `LARGEST_PENALTY` (where a refusal is raised, with the check's reason), then halving."""
    high = max(2.0 * low, 1.0)
    while not _passes(check, high):
        low, high = high, 2.0 * high
        if high > LARGEST_PENALTY:
            check(high)  # raises the check's reason, or says it passes only above LARGEST_PENALTY
            raise NotCoveredError(f"drinks may pay at every heart_attack_penalty up to {LARGEST_PENALTY:g}")
    while high - low > tolerance * high:
        middle = (low + high) / 2
        low, high = (low, middle) if _passes(check, middle) else (middle, high)
    return high


def _passes(check: Callable[[float], object], penalty: float) -> bool:
    """Whether ``check(penalty)`` passes (refuses with ``NotCoveredError`` otherwise)."""
    try:
        check(penalty)
    except NotCoveredError:
        return False
    return True


def default_penalties(threshold: float, points: int = DEFAULT_POINTS) -> list[float]:
    """``points`` penalties from 0 to ``threshold``: 0, then geometric from 1 (3 significant digits), then
    ``threshold`` itself."""
    if points < 2:
        raise ValueError(f"points must be at least 2 (0 and the threshold), got {points}")
    if threshold <= 1.0:
        return sorted({0.0, float(threshold)})
    inner = [float(f"{p:.3g}") for p in np.geomspace(1.0, threshold, points - 1)[:-1]]
    return sorted({0.0, *inner, float(threshold)})


def frontier(
    env_id: str = "HeartPole-v0",
    penalties: Sequence[float] | None = None,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    drinking: DrinkingSolver | None = package_drinking,
    points: int = DEFAULT_POINTS,
    progress: Callable[[int], object] | None = None,
) -> Frontier:
    """The productivity-risk frontier of ``env_id``: the optimum at each penalty (see the module docstring).

    Args:
        env_id: a HeartPole id the optimum covers (v0's actions and variables).
        penalties: the heart-attack penalties (>= 0) to solve; default: `points` from 0 to the no-drink threshold
            ([`default_penalties`][heartpole.optimum.tradeoff.default_penalties]).
        env_kwargs: the env's other keyword arguments (not ``heart_attack_penalty``, which the frontier varies).
        drinking: the solver for the penalties the no-drink optimum refuses (default:
            [`package_drinking`][heartpole.optimum.tradeoff.package_drinking]); ``None`` lists them in ``missing``.
        points: how many default penalties.
        progress: called with 1 after each penalty is solved (a progress bar's ``update``).

    Raises:
        NotCoveredError: an env the no-drink optimum does not cover at any penalty (the reason says why).
        ValueError, TypeError: bad arguments.
    """
    from heartpole.registry import env_dynamics

    from .drinks import check_covered

    kwargs = dict(env_kwargs or {})
    if "heart_attack_penalty" in kwargs:
        raise ValueError("env_kwargs must not set heart_attack_penalty: the frontier varies it (give penalties)")
    if kwargs.get("people") is not None:
        raise NotCoveredError(f"people={kwargs['people']!r}: the frontier is one person's; solve each person alone")
    given = None if penalties is None else _checked(penalties)  # before the threshold's solve (seconds)
    dynamics = env_dynamics(env_id, kwargs)
    check_covered(env_id, dynamics)
    threshold = no_drink_threshold(dynamics.params)
    asked = default_penalties(threshold, points) if given is None else given
    solved: list[FrontierRow] = []
    missing: list[tuple[float, str]] = []
    for penalty in asked:
        point = _point(env_id, {**kwargs, "heart_attack_penalty": penalty}, threshold, drinking)
        if isinstance(point, FrontierRow):
            solved.append(point)
        else:
            missing.append((penalty, point))
        if progress is not None:
            progress(1)
    return Frontier(env_id, kwargs, tuple(solved), threshold, tuple(missing))


def _checked(penalties: Sequence[float]) -> list[float]:
    """The penalties, sorted without repeats; each a finite number >= 0."""
    checked = []
    for penalty in penalties:
        if isinstance(penalty, bool) or not isinstance(penalty, (int, float)) or not 0 <= penalty < math.inf:
            raise ValueError(f"penalties must be finite numbers >= 0, got {penalty!r}")
        checked.append(float(penalty))
    if not checked:
        raise ValueError("penalties is empty; give at least one (or None for the default ones)")
    return sorted(set(checked))


def _point(
    env_id: str, env_kwargs: dict[str, Any], threshold: float, drinking: DrinkingSolver | None
) -> FrontierRow | str:
    """The optimum at one penalty: the no-drink one from the threshold on (its check passes there), the drinking
    solver's below it (which answers where the no-drink optimum's check passes too), else the no-drink optimum or
    its refusal's reason."""
    from .solution import optimum

    penalty = float(env_kwargs["heart_attack_penalty"])
    try:
        if drinking is not None and penalty < threshold:
            return drinking_point(penalty, drinking(env_id, env_kwargs))
        solution = optimum(env_id, env_kwargs)
    except NotCoveredError as error:
        solver = "no drinking solver given" if drinking is None else "the drinking solver"
        return f"{error} ({solver})"
    return FrontierRow(
        penalty=penalty,
        expected_score=solution.expected_score,
        expected_heart_attacks=solution.expected_heart_attacks,
        coffees=0.0,
        beers=0.0,
        drinks=0.0,
        expected_return=solution.expected_return,
        lower=solution.expected_return - solution.error_bound,
        upper=solution.expected_return + solution.margin,
        solver=NO_DRINK,
    )


def drinking_point(penalty: float, solution: DrinkingFigures) -> FrontierRow:
    """A drinking solver's ``solution`` at ``penalty`` as a row: the no-drink optimum's where it is proven optimal and
    drinks nothing, else the drinking optimum's or (not proven) the best solved policy's."""
    drinks = float(solution.drinks_per_episode)
    if solution.optimal:
        solver = NO_DRINK if drinks == 0 else DRINKING
    else:
        solver = LOWER_BOUND
    return FrontierRow(
        penalty=penalty,
        expected_score=float(solution.expected_score),
        expected_heart_attacks=float(solution.expected_attacks),
        coffees=float(solution.coffees_per_episode),
        beers=float(solution.beers_per_episode),
        drinks=drinks,
        expected_return=float(solution.expected_return),
        lower=float(solution.lower),
        upper=float(solution.upper),
        solver=solver,
    )


def _json(value: Any) -> Any:
    return None if isinstance(value, float) and not math.isfinite(value) else value
