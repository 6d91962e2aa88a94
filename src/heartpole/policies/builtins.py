"""The built-in policies: ``random``, ``nothing``, ``coffee``, ``reference``, ``expert``, ``optimal`` and
``oracle``, each built for an env's [`Dynamics`][heartpole.dynamics.Dynamics] by name (see
[`BUILTIN_POLICIES`][heartpole.policies.BUILTIN_POLICIES]; ``oracle`` needs the env's people too, see
[`oracle_policy`][heartpole.policies.oracle.oracle_policy])."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole.actions import TAKE_NAP
from heartpole.dynamics import Dynamics
from heartpole.model import ALERTNESS, INTOXICATION, TIME_ELAPSED, TIME_SINCE_SLEPT, productivity
from heartpole.policies.common import Actions, DecisionsLeft, Observations, Policy, default_dynamics, observation_batch
from heartpole.policies.oracle import OraclePolicy
from heartpole.rates import RATE_WITH_NAPS, best_known_rate

if TYPE_CHECKING:
    from heartpole.optimum import HistoryOptimum, OptimumSolution


class RandomPolicy:
    """Uniformly random actions among all of the env's actions, drawn from the policy's own generator.

    Args:
        dynamics: the env's dynamics (default: v0's); only the number of actions is used.
        rng: a ``numpy.random.Generator``, or a seed for one (default 0). NumPy's global state is never used.
    """

    name = "random"

    def __init__(self, dynamics: Dynamics | None = None, rng: np.random.Generator | int | None = None) -> None:
        self.num_actions = len((dynamics or default_dynamics()).actions)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.integers(0, self.num_actions, len(observation_batch(obs)))


class ConstantPolicy:
    """The same action in every state, looked up by name: ``do_nothing`` for ``nothing``, and so on.

    Args:
        action: the action's name in the env's dynamics.
        dynamics: the env's dynamics (default: v0's).
        name: the policy's name in results tables (default: the action's).
    """

    def __init__(self, action: str, dynamics: Dynamics | None = None, name: str | None = None) -> None:
        self.action = (dynamics or default_dynamics()).action_index(action)
        self.name = name or action

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.full(len(observation_batch(obs)), self.action, dtype=np.int64)


def nothing_policy(dynamics: Dynamics | None = None) -> ConstantPolicy:
    """``nothing``: never drink, never sleep. Alertness runs down and productivity turns negative."""
    return ConstantPolicy("do_nothing", dynamics, name="nothing")


def coffee_policy(dynamics: Dynamics | None = None) -> ConstantPolicy:
    """``coffee``: a coffee every half-hour, never sleep (the tutorial's heart-attack demonstration)."""
    return ConstantPolicy("drink_coffee", dynamics, name="coffee")


class ReferencePolicy:
    """``reference``: the strategy published with the package. One coffee, 31 steps of work, sleep; repeat.

    The cycle is 33 decisions long and starts with the episode: decision ``k`` (0-based) is a coffee when
    ``k % 33 == 0``, a sleep when ``k % 33 == 32`` and nothing otherwise. So the first day is 32 work
    steps (the coffee's included) and the sleep step's own half-hour of work opens the next day. This
    phase reproduces the published expected-risk estimate, -138.74 (measured: -138.76 +- 0.014 over 60,000
    episodes); phases counted from ``time_since_slept`` alone (coffee at 1, sleep at 31 to 33) give -139.0
    to -139.9.

    The phase is read from the observation, not counted: on the first day ``time_since_slept`` is the
    decision index itself (it starts at 0), while after a sleep the next observation already shows
    ``time_since_slept == 1`` (waking sets it to 0, then the half-hour of work passes). Hence
    ``phase = time_since_slept - 1`` once ``time_elapsed > time_since_slept`` (the agent has slept) and
    ``phase = time_since_slept`` before.

    Args:
        dynamics: the env's dynamics (default: v0's); needs ``drink_coffee``, ``do_nothing`` and ``sleep``.
        cycle: decisions per cycle (33: coffee, 31 of work, sleep).
    """

    name = "reference"

    def __init__(self, dynamics: Dynamics | None = None, cycle: int = 33) -> None:
        dynamics = dynamics or default_dynamics()
        self.coffee = dynamics.action_index("drink_coffee")
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")
        self.cycle = cycle

    def phase(self, obs: np.ndarray) -> np.ndarray:
        """The position of each observation in the cycle, 0 (coffee) to ``cycle - 1`` (sleep)."""
        obs = observation_batch(obs)
        since_slept = obs[:, TIME_SINCE_SLEPT].astype(np.int64)
        has_slept = obs[:, TIME_ELAPSED] > obs[:, TIME_SINCE_SLEPT]
        return since_slept - has_slept

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        phase = self.phase(obs)
        actions = np.full(len(phase), self.nothing, dtype=np.int64)
        actions[phase == 0] = self.coffee
        actions[phase >= self.cycle - 1] = self.sleep
        return actions


class ExpertPolicy:
    """``expert``: never drink; sleep when the coming half-hour would earn less than the long-run rate.

    Why never drink. Return = final score - 100 x heart attacks, and a step's heart-attack probability is
    ``0.5 * sigmoid(hypertension - 6)``, about 0.001236 at rest, rising by ``0.5 * s * (1 - s)`` = 0.00123
    per unit of hypertension. A coffee adds 0.15 hypertension on average, which fades by 0.97 a half-hour,
    so it adds at most 0.15 / 0.03 = 5 hypertension-steps: up to 0.006 expected heart attacks, -0.6 of
    return. What it buys is +0.5 alertness for the rest of the day, a few units of work in an episode of
    ~2,000 half-hours: a few thousandths of score. Measured (paired, 2,000 episodes): a coffee after each
    waking costs 0.0043 expected heart attacks (-0.43) and buys +0.0036 of score, a hundred times less. A
    beer costs as much and lowers alertness (its Ballmer peak needs 0.135 blood alcohol, about seven beers
    of hypertension). So the expert never drinks, its blood pressure stays at 0 and its heart-attack risk
    at the floor: 1,000 x 0.001236 = 1.236 attacks per episode, which no policy can beat.

    When to sleep. What remains is the score, work_done / time_elapsed. A day's alertness only falls (fact 6), so the
    coming half-hour's productivity falls too, and the classic renewal argument applies: keep working while the coming
    half-hour earns at least the long-run rate (work per half-hour, sleep included); sleep once it would earn less.
    Sleep pays for its 16 half-hours because a fresh day then earns above the rate. The rate is the score the policy
    itself reaches, a fixed point that `expert_rate` solves from the dynamics: 0.327 for
    v0, reached when alertness falls to about 0.38 (about 16 decisions after waking, ~63 sleeps an episode).

    Naps (HeartPole-v1). A nap costs only time: one half-hour without work for +U(0.3, 0.6) alertness, no
    blood pressure. In v1 the expert naps while alertness is below 2.35 and it has been awake for fewer than
    23 half-hours, and otherwise sleeps when the coming half-hour would earn less than 0.69 (v1's long-run
    rate). These thresholds come from a dynamic program over (alertness, time since slept) whose optimal
    rate is 0.691; the rule reaches an expected-risk return of -122.938 against -123.305 without naps, and a
    score of 0.69 against 0.33. Tea, cannabis and exercise do not help: each raises blood pressure or, for
    exercise, lowers one that never rises. The nap rule is used only when the variant's ``take_nap`` is
    v1's own, the one the thresholds were tuned for; other variants get the sleep-only expert.

    What it leaves on the table. Over the last few steps of an episode a sleep cannot pay back its 16
    half-hours, so a policy that knew the step count would stay awake (+0.0005 of score, measured). The
    observations do not reveal the step count (``time_elapsed`` mixes work and sleep), so the expert ignores
    it. It is tuned for v0's heart-attack risk: with ``heart_attack_proclivity=0`` coffee would pay.

    Args:
        dynamics: the env's dynamics (default: v0's); needs ``do_nothing`` and ``sleep``.
        rate: the productivity below which it sleeps (default:
            `best_known_rate` of ``dynamics``).
    """

    name = "expert"

    NAP_BELOW_ALERTNESS = 2.35
    NAP_WITHIN_HALF_HOURS_AWAKE = 23
    RATE_WITH_NAPS = RATE_WITH_NAPS

    def __init__(self, dynamics: Dynamics | None = None, rate: float | None = None) -> None:
        dynamics = dynamics or default_dynamics()
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")
        names = [action.name for action in dynamics.actions]
        self.nap = names.index("take_nap") if TAKE_NAP in dynamics.actions else None
        known = best_known_rate(dynamics)
        assert known is not None  # the env has do_nothing and sleep: looked up above
        self.rate = known if rate is None else float(rate)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.rule(observation_batch(obs), productivity, np.where).astype(np.int64)

    def rule(self, obs: Any, work: Callable[[Any, Any], Any], where: Callable[[Any, Any, Any], Any]) -> Any:
        """The rule on a batch of observations with a backend's ``productivity`` and ``where`` (NumPy's for
        ``__call__``; ``jax.numpy``'s in [`heartpole.jax.policies`][heartpole.jax.policies])."""
        coming = work(obs[:, ALERTNESS], obs[:, INTOXICATION])
        actions = where(coming < self.rate, self.sleep, self.nothing)
        if self.nap is not None:
            nap = (obs[:, ALERTNESS] < self.NAP_BELOW_ALERTNESS) & (
                obs[:, TIME_SINCE_SLEPT] < self.NAP_WITHIN_HALF_HOURS_AWAKE
            )
            actions = where(nap, self.nap, actions)
        return actions


class OptimalPolicy:
    """``optimal``: the policy of [`heartpole.optimum`][heartpole.optimum]'s dynamic program. Never drink; sleep when
    sleeping now is worth at least as much as any later sleep of the day, by the history-aware optimum's values,
    which read the alertness, the half-hours awake, the work done, the time elapsed and the decisions left
    ([`OptimumSolution.decide`][heartpole.optimum.solution.OptimumSolution.decide]; beyond 3,000 decisions the
    sleep-timing policy: sleep when alertness falls below a threshold of the half-hours awake and decisions left).

    Far from the end it sleeps near the alertness where ``expert`` does; in the last days it re-times the
    days so that the last one ends with the episode, and over the last few decisions it stays awake. It
    needs the number of decisions left (``needs_decisions_left``): call it as ``policy(obs, decisions_left)``.
    The solution is solved once per parameter set and cached
    ([`heartpole.optimum.optimum`][heartpole.optimum.solution.optimum]).

    Args:
        dynamics: the env's dynamics (default: v0's); must be v0's actions and variables.
        solution: a solved [`OptimumSolution`][heartpole.optimum.solution.OptimumSolution] to act on (default: solve or
            load the cached one for ``dynamics``).

    Raises:
        heartpole.optimum.NotCoveredError: a variant the solver does not cover.
    """

    name = "optimal"
    needs_decisions_left = True

    def __init__(self, dynamics: Dynamics | None = None, solution: OptimumSolution | None = None) -> None:
        from heartpole.optimum import optimum_for

        dynamics = dynamics or default_dynamics()
        self.solution = solution if solution is not None else optimum_for(dynamics)
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")

    def __call__(self, obs: Observations, decisions_left: DecisionsLeft = None) -> Actions:
        obs = observation_batch(obs)
        if decisions_left is None:
            raise ValueError(
                "the optimal policy needs the number of decisions left: call policy(obs, decisions_left) "
                "(heartpole.policies.act_batch does it for loops that count steps)"
            )
        return np.where(self.solution.decide(obs, decisions_left), self.sleep, self.nothing).astype(np.int64)


class HistoryOptimalPolicy:
    """The optimum over every policy: like ``optimal``, but it also reads the work done and the time elapsed
    ([`heartpole.optimum.whole`][heartpole.optimum.whole]'s program over day starts). Its expected score is the
    program's lower value; ``heartpole optimum --history --check N`` runs it through the evaluator. ``optimal`` plays
    the same program solved on fixed grids; this one plays ``solved`` (any grids).

    Args:
        dynamics: the env's dynamics (default: v0's); must be v0's actions and variables.
        solved: a [`HistoryOptimum`][heartpole.optimum.whole.HistoryOptimum] solved with its policy (default: solve
            one for ``dynamics``' parameters, seconds at 1,000 decisions).
    """

    name = "optimal-history"
    needs_decisions_left = True

    def __init__(self, dynamics: Dynamics | None = None, solved: HistoryOptimum | None = None) -> None:
        from heartpole.optimum import solve_history
        from heartpole.optimum.drinks import check_covered

        dynamics = dynamics or default_dynamics()
        check_covered("this env", dynamics)
        self.solved = solved if solved is not None else solve_history(dynamics.params)
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")

    def __call__(self, obs: Observations, decisions_left: DecisionsLeft = None) -> Actions:
        obs = observation_batch(obs)
        if decisions_left is None:
            raise ValueError("the optimal-history policy needs the number of decisions left: call policy(obs, left)")
        left = np.broadcast_to(np.asarray(decisions_left, dtype=np.int64), (len(obs),))
        return np.where(self.solved.sleeps(obs, left), self.sleep, self.nothing).astype(np.int64)


BUILTIN_POLICIES: Mapping[str, Callable[..., Policy]] = {
    "random": RandomPolicy,
    "nothing": nothing_policy,
    "coffee": coffee_policy,
    "reference": ReferencePolicy,
    "expert": ExpertPolicy,
    "optimal": OptimalPolicy,
    "oracle": OraclePolicy,
}
"""The built-in policies by name; each entry builds the policy for a [`Dynamics`][heartpole.dynamics.Dynamics]."""


def available_builtins(
    env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None, dynamics: Dynamics | None = None
) -> list[str]:
    """The built-in policy names that can act in ``env_id``: all of them, but ``optimal`` only where
    [`heartpole.optimum`][heartpole.optimum] covers the variant (solving it once, cached), and ``oracle`` only
    where ``env_kwargs`` give a finite cohort of ``people``. ``dynamics``: the env's, where the caller resolved
    ``env_id`` already (``people`` do not change an env's dynamics)."""
    from heartpole.optimum import NotCoveredError, available, optimum_for, split_people

    people, base = split_people(env_kwargs)
    names = list(BUILTIN_POLICIES)
    try:
        covered = available(env_id, base) if dynamics is None else optimum_for(dynamics, env_id, base)
    except NotCoveredError:
        covered = None
    if covered is None:
        names.remove("optimal")
    if people is None or not people.finite:
        names.remove("oracle")
    return names


def make_policy(name: str, dynamics: Dynamics | None = None, rng: np.random.Generator | int | None = None) -> Policy:
    """The built-in policy ``name`` for ``dynamics`` (default: v0's); ``rng`` seeds ``random`` only.

    Raises:
        ValueError: for an unknown name, listing the valid ones, and for ``oracle``, which needs the env's
            people ([`load_policy`][heartpole.policies.load_policy] builds it from the env's keyword arguments).
    """
    if name not in BUILTIN_POLICIES:
        raise ValueError(f"unknown policy {name!r}; built-in policies are {', '.join(BUILTIN_POLICIES)}")
    if name == "random":
        return RandomPolicy(dynamics, rng)
    return BUILTIN_POLICIES[name](dynamics)
