"""One point of the productivity-risk frontier: the optimum's (or the best solved policy's) expected score, heart
attacks and drinks at one ``heart_attack_penalty`` ([`frontier_point`][heartpole.optimum.point.frontier_point])."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass
from typing import Any

from heartpole import files
from heartpole.parameters import Params

from .coffee import CoffeeSolution, solve_coffee
from .common import DEFAULT_GRID, SOLVER_VERSION, NotCoveredError, params_dict
from .solution import OptimumSolution, _changed_params, _solve, cache_dir, optimum


@dataclass(frozen=True)
class FrontierPoint:
    """The optimum of one setting, or where it is not known the best solved policy and what bounds it.

    Attributes:
        params: the setting.
        expected_return: the policy's expected return (final score less the penalty times the expected attacks).
        expected_score: its expected final score ``E[work / time]``.
        expected_attacks: its expected heart attacks per episode.
        coffees_per_episode, beers_per_episode, sleeps_per_episode: what it does.
        lower: what a playable policy is known to get at least (the interval's lower end).
        upper: what no policy beats (``nan`` where that is not known).
        optimal: whether the policy is the optimum (``lower`` and ``upper`` then hold its value between them).
        how: how the figures were obtained, in a few words.
    """

    params: Params
    expected_return: float
    expected_score: float
    expected_attacks: float
    coffees_per_episode: float
    beers_per_episode: float
    sleeps_per_episode: float
    lower: float
    upper: float
    optimal: bool
    how: str

    @property
    def drinks_per_episode(self) -> float:
        """Coffees and beers per episode."""
        return self.coffees_per_episode + self.beers_per_episode

    def summary(self) -> dict[str, Any]:
        """JSON-safe figures (an unknown ``upper`` as ``None``)."""
        out = asdict(self)
        out["upper"] = None if math.isnan(self.upper) else self.upper
        out["params"] = params_dict(self.params)
        out["drinks_per_episode"] = self.drinks_per_episode
        return out


def frontier_point(env: str | Params = "HeartPole-v0", **env_kwargs: Any) -> FrontierPoint:
    """The frontier's point for an env id and its keyword arguments (or a v0 ``Params``), solved once and cached.

    Where drinks never pay ([`check_drinks`][heartpole.optimum.lifetime.check_drinks]) it is the no-drink optimum
    ([`optimum`][heartpole.optimum.solution.optimum]): no drinks, its interval from the grid's error and the history's
    worth. Where they may pay it is the coffee program's policy
    ([`solve_coffee`][heartpole.optimum.coffee.solve_coffee]), its value by Monte Carlo (``lower``: the 95% interval's
    lower end) and no proven ``upper`` (``nan``): it drinks no beer, which may pay there (see docs/optimum.md); or the
    no-drink optimum where its value is above the coffee policy's estimate (the coffee program's grid policy falls
    short of it just below where drinks are proven not to pay), with no proven ``upper`` either.

    Raises:
        NotCoveredError: a variant with other actions or variables (as `optimum`).
        TypeError, ValueError: bad arguments.
    """
    if isinstance(env, Params):
        if env_kwargs:
            raise TypeError(f"frontier_point(Params) takes no keyword arguments, got {sorted(env_kwargs)}")
        env_id, kwargs = "HeartPole-v0", _changed_params(env)
    elif isinstance(env, str):
        env_id, kwargs = env, dict(env_kwargs)
    else:
        raise TypeError(f"frontier_point takes an env id or a heartpole.parameters.Params, got {type(env).__name__}")
    try:
        solution = optimum(env_id, kwargs)
    except NotCoveredError as refused:
        if "drink" not in str(refused):
            raise
        from heartpole.registry import env_dynamics

        return _coffee_point(env_dynamics(env_id, kwargs).params)
    return _no_drink_point(solution, proven=True)


def _coffee_point(params: Params) -> FrontierPoint:
    key = hashlib.sha256(json.dumps([SOLVER_VERSION, "best known", params_dict(params)], sort_keys=True).encode())
    path = cache_dir() / "frontier" / f"{key.hexdigest()[:16]}.json"
    try:
        meta = json.loads(path.read_text())
        meta.pop("drinks_per_episode", None)
        meta["upper"] = math.nan if meta["upper"] is None else meta["upper"]
        meta["params"] = Params(**{**meta["params"], "wake_alertness": tuple(meta["params"]["wake_alertness"])})
        return FrontierPoint(**meta)
    except (OSError, ValueError, TypeError, KeyError):
        pass  # not cached (or unreadable): solve it
    solved = solve_coffee(params, error=False)
    no_drink = _solve(params, DEFAULT_GRID, "HeartPole-v0", _changed_params(params), drinks=False)
    better = no_drink.expected_return > solved.expected_return
    point = _no_drink_point(no_drink, proven=False) if better else _coffee_policy_point(params, solved)
    try:
        with files.atomic_files(path) as (target,):
            target.write_text(files.json_text(point.summary()))
    except OSError:
        pass
    return point


def _no_drink_point(solution: OptimumSolution, proven: bool) -> FrontierPoint:
    """The no-drink optimum's point: ``proven`` where no drink pays (its interval from the grid's error and the
    history's worth), else the best policy known where drinks may pay (no proven ``upper``)."""
    return FrontierPoint(
        params=solution.params,
        expected_return=solution.expected_return,
        expected_score=solution.expected_score,
        expected_attacks=solution.expected_heart_attacks,
        coffees_per_episode=0.0,
        beers_per_episode=0.0,
        sleeps_per_episode=solution.expected_sleeps,
        lower=solution.expected_return - solution.error_bound,
        upper=solution.expected_return + solution.margin if proven else math.nan,
        optimal=proven,
        how="no drink pays: the no-drink optimum (grid error and history's worth around it)"
        if proven
        else "drinks may pay, but the coffee program's policy scores less: the no-drink optimum, not proven best",
    )


def _coffee_policy_point(params: Params, solved: CoffeeSolution) -> FrontierPoint:
    """The coffee program's policy where drinks may pay: its Monte Carlo value, no proven ``upper``."""
    return FrontierPoint(
        params=params,
        expected_return=solved.expected_return,
        expected_score=solved.expected_score,
        expected_attacks=solved.expected_attacks,
        coffees_per_episode=solved.coffees_per_episode,
        beers_per_episode=solved.beers_per_episode,
        sleeps_per_episode=solved.sleeps_per_episode,
        lower=solved.lower,
        upper=math.nan,
        optimal=False,
        how=f"drinks may pay: the coffee program's policy (no beer), {solved.episodes} Monte Carlo episodes",
    )
