"""The optimum of HeartPole-v0 by dynamic programming: the ceiling every policy's regret is measured from.

What is solved. An episode's return telescopes to ``final score - penalty x heart attacks``, with the score
``work_done / time_elapsed`` (fact 0's bookkeeping). The solver finds the policy that maximises the
expected return of HeartPole-v0, with any of its [`Params`][heartpole.parameters.Params] changed, in two steps:

1. **Drinks never pay** (while ``heart_attack_proclivity * heart_attack_penalty > 0`` and the check below
   passes). A step's heart-attack risk ``r(H) = proclivity * sigmoid(H - 6)`` is convex for ``H <= 6`` and
   hypertension never exceeds ``0.3 * decay / (1 - decay)`` (9.7 for v0), so ``r(H) >= r(0) + r'(0) H``
   on every reachable state. A drink adds ``h ~ U(0, 0.3)`` of hypertension, of which ``decay * h`` is still
   there when its own step's coin is flipped: each drink costs at least
   ``penalty * r'(0) * decay * 0.15`` = 0.0179 expected return on v0
   ([`drink_floor`][heartpole.optimum.drinks.drink_floor]), whatever the policy does.
   [`check_no_drinks`][heartpole.optimum.drinks.check_no_drinks] then bounds what a drink can buy (in the
   ratio-of-expectations sense of step 2, where a unit of return is worth at least ``max_steps`` units of work) and
   refuses parameters where the bound does not rule drinks out.
2. **Only the sleep timing is left.** Without drinks hypertension stays 0, the heart-attack part is
   fixed (``max_steps * r(0)`` expected attacks) and a day is deterministic once its waking alertness
   ``w ~ U(wake_alertness)`` is drawn: at ``t`` half-hours after waking the alertness is
   ``w - sum(alertness_decay(j) for j < t)``. The state is ``(decisions left n, w, t)``. The ratio
   ``E[work] / E[time]`` is maximised by Dinkelbach's method: for a rate ``lam`` the dynamic program
   maximises ``E[work - lam * time]``; ``lam <- E[work] / E[time]`` of its policy, until the maximum is 0.

Discretisation. ``t`` and ``n`` are exact integers. ``w`` is a midpoint grid of ``grid`` points on
``wake_alertness``; every decision on the grid is exact for its ``w`` (the day is deterministic), and the
only approximation is the expectation over the next waking alertness (the midpoint rule, error
``O(1/grid**2)``). Days are cut at ``max_awake`` half-hours, where productivity is so negative that a sleep
pays even on the last decision (checked). The reported expected score is the exact ``E[work / time]`` of
the grid policy, computed by a forward pass over days and sleeps (``time = max_steps + sleep_half_hours
x sleeps``); ``error_bound`` is the change of the expected return between ``grid // 2`` and ``grid``.

Long horizons. Far from the end the policy settles into a stationary one (on v0 to rounding within about
1,200 decisions of the end): the backward pass stops there, the expected work and time of the decisions
beyond grow by the settled gain, and the thresholds of the settled row serve every ``n`` above it. The
forward pass carries only a window of sleeps so far around its mean, and goes day by day where the days
have settled. Memory stays small (tens of MB at a million decisions) and time grows with the horizon only
through the forward pass (see docs/optimum.md for measurements).

What it does not cover, refused with a clear error: action sets other than v0's four (HeartPole-v1's
naps, tea, exercise and cannabis), extra state variables, ``heart_attack_proclivity = 0`` or
``heart_attack_penalty = 0`` (drinking then pays: see docs/optimum.md) and parameters where neither
[`check_no_drinks`][heartpole.optimum.drinks.check_no_drinks] nor the check over a drink's whole lifetime of blood
pressure ([`check_drinks`][heartpole.optimum.lifetime.check_drinks], which covers v0 at penalties 10 to 100 and
proclivity 0.2) rules drinks out.

The optimum over every policy (issue 42). The program above sees ``(n, alertness, t)``; the score is a ratio, so the
work and sleeps so far are worth a little more (9.3e-6 on v0, 4e-5 at 300 decisions).
[`solve_history`][heartpole.optimum.whole.solve_history] solves the whole problem over day starts, its policy's value
below and a bound above; up to [`HISTORY_HORIZON`][heartpole.optimum.whole.HISTORY_HORIZON] decisions the solution
plays that policy ([`OptimumSolution.decide`][heartpole.optimum.solution.OptimumSolution.decide]), its expected
return is the sleep-timing optimum's plus the history program's gain, and its
[`margin`][heartpole.optimum.solution.OptimumSolution.margin] is the solver's own error: the grids' errors and the
program's gap (1.7e-6 on v0). Beyond that horizon it plays the sleep-timing policy and the margin states what the
history is worth ([`history_worth`][heartpole.optimum.whole.history_worth]).

Also here: [`sleep_rule_value`][heartpole.optimum.sleep.sleep_rule_value], the exact expected return of any no-drink
sleep rule (``expert``'s regret without sampling), and [`solve_drinking`][heartpole.optimum.drinking.solve_drinking], a
grid DP for ``heart_attack_proclivity=0``, where
drinking pays: its stationary policy is a lower bound and its whole-episode value an upper bound on the grid,
not a certified optimum.

Layout: `.solution` (the solution, the entry points, the cache), `.sleep` (the sleep-timing
program), `.days` (the days of a policy and the exact expected score), `.drinks` (why drinks
never pay), `.drinking` (proclivity 0), `.history` (a history-aware rule measured against the optimum),
`.whole` (the optimum over every policy, history included, with its bounds), `.played` (the history program a
solution plays, and its storage), `.pressure` (the program over alertness, blood pressure and time awake, with
coffee), `.lifetime` (why drinks never pay, over their whole lifetime), `.coffee` (the coffee program's policy where
drinks may pay), `.point` (a point of the productivity-risk frontier), `.tradeoff` (the frontier itself: the
optimum's score against its heart attacks over the penalties), `.common` (what they share).
"""

from __future__ import annotations

from .coffee import CoffeeSolution, solve_coffee
from .common import DEFAULT_GRID, SOLVER_VERSION, NotCoveredError
from .drinking import (
    DRINKING_ACTIONS,
    NEVER,
    DrinkingGrid,
    DrinkingSolution,
    drinking_rule_value,
    solve_drinking,
)
from .drinks import COFFEE_CHECK_ALERTNESS, check_beer, check_coffee, check_no_drinks, coffee_check, drink_floor
from .lifetime import check_drinks, check_drinks_lifetime
from .people import POPULATION_KWARGS, OracleRegret, PeopleOptimum, oracle_regret, solve_people, split_people
from .point import FrontierPoint, frontier_point
from .sleep import MAX_DINKELBACH_ITERATIONS, GridSolution, sleep_rule_value, solve_params
from .solution import OptimumSolution, available, cache_dir, optimum, optimum_for, solve
from .tradeoff import Frontier, FrontierRow, frontier, no_drink_threshold
from .whole import HistoryOptimum, solve_history

__all__ = [
    "COFFEE_CHECK_ALERTNESS",
    "DEFAULT_GRID",
    "DRINKING_ACTIONS",
    "MAX_DINKELBACH_ITERATIONS",
    "NEVER",
    "SOLVER_VERSION",
    "CoffeeSolution",
    "DrinkingGrid",
    "FrontierPoint",
    "DrinkingSolution",
    "Frontier",
    "FrontierRow",
    "GridSolution",
    "HistoryOptimum",
    "NotCoveredError",
    "OptimumSolution",
    "OracleRegret",
    "PeopleOptimum",
    "available",
    "cache_dir",
    "check_beer",
    "check_coffee",
    "check_drinks",
    "check_drinks_lifetime",
    "check_no_drinks",
    "coffee_check",
    "drink_floor",
    "drinking_rule_value",
    "frontier",
    "frontier_point",
    "no_drink_threshold",
    "optimum",
    "optimum_for",
    "oracle_regret",
    "sleep_rule_value",
    "solve",
    "solve_coffee",
    "solve_drinking",
    "solve_history",
    "solve_params",
    "solve_people",
    "split_people",
    "POPULATION_KWARGS",
]
