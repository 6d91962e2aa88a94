"""Why drinks never pay, counting a drink's whole lifetime of blood pressure: the program over (alertness,
hypertension, half-hours awake) finds no state where a coffee or a beer beats the no-drink optimum.

[`check_no_drinks`][heartpole.optimum.drinks.check_no_drinks] charges a drink only the risk of its own step, so it
proves v0 at penalty 100 and not at lower penalties. A drink's hypertension stays for about
``1 / (1 - decay_rate)`` half-hours (33 on v0) and raises the risk at every one of them; this check counts all of it,
with heart attacks resetting hypertension to 0, by the dynamic program of
[`heartpole.optimum.pressure`][heartpole.optimum.pressure]:

* **The argument.** For the no-drink rate ``lam`` (Dinkelbach's, ratio of expectations), a policy ``pi`` scores
  ``E[work] / E[time] - penalty * E[attacks] > lam - penalty * max_steps * r(0)`` only if ``E[work - lam * time] >
  E[time] * penalty * E[extra] >= max_steps * penalty * E[extra]`` (``extra``: the summed risk above the floor
  ``r(0)`` each step, which no policy avoids). The program maximises ``E[work - lam * time - max_steps * penalty *
  extra]`` over every policy with coffee; if in no state and no number of decisions left a coffee beats the best
  other action, its value is the no-drink one, which is 0 at ``lam``: no policy beats the no-drink optimum.
* **Beer** adds intoxication, which the program leaves out. Intoxication ``x`` changes a half-hour's work by at most
  ``G x`` (``G``: the largest ``productivity(a, 0) * (ballmer(x) / ballmer(0) - 1) / x`` over the grid's alertness and
  every ``x``), so ``V_n(b, h, t) + G x (1 - decay_rate ** n) / (1 - decay_rate)`` (``n`` decisions left) satisfies
  the Bellman inequality for every action that is not a beer; a beer keeps it if its alertness and hypertension lose
  at least ``G * 0.02 * (1 - decay_rate ** n) / (1 - decay_rate)`` (its mean intoxication is worth at most that) in
  every state. By the verification theorem of finite-horizon dynamic programming the no-drink value then bounds
  every policy, beer included.

It holds on the program's grid (alertness on a lattice ``alertness_step`` apart within ``alertness_range``, drinks
that would leave it not taken), as the coffee check of ``drinks.py`` holds on its grid.
"""

from __future__ import annotations

import numpy as np

from heartpole.model import ballmer, productivity
from heartpole.parameters import Params

from .common import NotCoveredError
from .drinks import check_beer, check_coffee
from .pressure import PressureGrid, backward

BEER_INTOXICATION = (0.01, 0.03)
"""A beer's intoxication rise (checked against v0's action data by `beer_bonus`)."""


def beer_bonus(grid: PressureGrid) -> float:
    """What a beer's intoxication is worth at most, in units of work: ``G * E[rise] / (1 - decay_rate)`` (see the
    module docstring), ``G`` over the grid's alertness (one lattice step beyond its ends) and intoxication in (0, 1]."""
    from heartpole.actions import DRINK_BEER

    if DRINK_BEER.effects["intoxication"] != BEER_INTOXICATION:
        raise NotCoveredError(f"the beer check models v0's beer, got {dict(DRINK_BEER.effects)}")
    low, high = grid.alertness_range
    alertness = np.linspace(low - grid.alertness_step, high + grid.alertness_step, 2001)[:, None]
    x = np.linspace(1e-4, 1.0, 10001)[None, :]
    b0 = float(ballmer(0.0))
    per_unit = float((productivity(alertness, 0.0) * (ballmer(x) / b0 - 1.0) / x).max())
    return per_unit * float(np.mean(BEER_INTOXICATION)) / (1.0 - grid.params.decay_rate)


def check_drinks_lifetime(params: Params, rate: float, alertness_step: float = 0.1) -> dict[str, float]:
    """Check that neither coffee nor beer pays under ``params`` over a drink's whole lifetime (module docstring).

    Args:
        params: v0's numbers.
        rate: the no-drink optimal rate (ratio of expectations) of ``params``.
        alertness_step: the program's alertness lattice.

    Returns:
        The most a coffee and a beer gain over the best other action in any state (units of work; negative: never).

    Raises:
        NotCoveredError: if a drink gains somewhere (drinking may pay).
    """
    grid = PressureGrid(params, alertness_step)
    bonus = beer_bonus(grid)
    sweep = backward(grid, rate, float(params.max_steps), 1, bonus=bonus, stop_at_gain=True)
    coffee, beer = sweep.gains
    if coffee > 0 or beer > 0:
        raise NotCoveredError(
            f"drinking may pay at heart_attack_penalty={params.heart_attack_penalty:g}, heart_attack_proclivity="
            f"{params.heart_attack_proclivity:g}, max_steps={params.max_steps}: counting a drink's whole lifetime of "
            "blood pressure, a coffee "
            f"gains {coffee:.4g} and a beer {beer:.4g} units of work over the no-drink optimum in some state (the "
            "check stops at the first gain); the optimum covers variants where drinking never pays"
        )
    return {"coffee_lifetime_gain": coffee, "beer_lifetime_gain": beer, "beer_bonus": bonus}


def check_drinks(params: Params, rate: float) -> float:
    """Check that no drink pays under ``params``; return the most a coffee gains in any state (units of work).

    First the cheap argument of [`check_no_drinks`][heartpole.optimum.drinks.check_no_drinks] (a drink charged its own
    step's risk); where it cannot rule drinks out, the lifetime check
    ([`check_drinks_lifetime`][heartpole.optimum.lifetime.check_drinks_lifetime], about two minutes at 1,000
    decisions).

    Raises:
        NotCoveredError: if neither rules drinks out (the lifetime check's reason).
    """
    if params.heart_attack_penalty * params.heart_attack_proclivity == 0:
        raise NotCoveredError(
            "drinking may pay with these parameters: heart attacks cost nothing (heart_attack_penalty * "
            "heart_attack_proclivity == 0), so coffee and beer are free; the optimum covers variants where drinking "
            "never pays (heartpole.optimum.solve_drinking has a grid policy for proclivity 0)"
        )
    try:
        check_beer(params)
        return check_coffee(params, rate)["coffee_best_gain"]
    except NotCoveredError:
        return check_drinks_lifetime(params, rate)["coffee_lifetime_gain"]
