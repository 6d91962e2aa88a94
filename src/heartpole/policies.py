"""Built-in HeartPole policies: plain callables from a batch of observations to a batch of actions.

A policy is anything with the signature of :data:`Policy`: it takes observations of shape
``(n, obs_dim)`` (float32, in the env's variable order: alertness, hypertension, intoxication,
time_since_slept, time_elapsed, work_done, then any variant's extras) and returns ``n`` integer action
indices. Write your own the same way and pass it to :func:`heartpole.evaluate`::

    import numpy as np
    import heartpole

    def nap_when_tired(obs: np.ndarray) -> np.ndarray:
        return np.where(obs[:, 0] < 0.5, 3, 0)  # 3 is v0's "sleep"

    print(heartpole.evaluate(nap_when_tired, episodes=2000, seed=0).expected_return)

Policies carry no hidden state between calls: whatever they need (the phase of a daily cycle, say) they
read from the observation, so one policy object serves any number of envs and any episode boundary.
Each built-in looks its action indices up by name in the env's :class:`~heartpole.dynamics.Dynamics`, so
it keeps working in variants whose action set is larger than v0's.

Decisions left. A policy may also ask for the number of decisions left in each env's episode, which the
observation does not show (``time_elapsed`` mixes work and sleep): a policy with a true attribute
``needs_decisions_left`` is called as ``policy(obs, decisions_left)`` with an integer array ``(n,)``,
``max_steps`` on the first decision and 1 on the last. Every loop in this package that runs policies
(:func:`heartpole.evaluate` and friends, ``heartpole record``, ``heartpole plot episode``) calls them
through :func:`act_batch`, which passes it; other loops must pass it too (the env counts decisions:
``env.unwrapped.max_steps`` minus the steps taken since reset).

Built-ins (:data:`BUILTIN_POLICIES`): ``random``, ``nothing``, ``coffee``, ``reference``, ``expert`` and
``optimal`` (the solved optimum of :mod:`heartpole.optimum`, which needs the decisions left).
:func:`load_policy` turns a built-in name or the path of a Stable-Baselines3 model saved by ``heartpole
train`` into a :data:`Policy`.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import numpy.typing as npt

from heartpole.actions import TAKE_NAP
from heartpole.dynamics import Dynamics
from heartpole.model import (
    ALERTNESS,
    INTOXICATION,
    TIME_ELAPSED,
    TIME_SINCE_SLEPT,
    Params,
    alertness_decay,
    productivity,
)

if TYPE_CHECKING:
    from heartpole.optimum import OptimumSolution

Observations = np.ndarray
"""A batch of observations, ``(n, obs_dim)`` float32 (one row per env, in observation order)."""
Actions = np.ndarray
"""A batch of actions, ``(n,)`` integers in ``0 .. num_actions - 1``."""
DecisionsLeft = int | np.ndarray | None
"""The decisions left in each env's episode (a number for all, ``(n,)`` integers, or ``None``: unknown)."""
Policy = Callable[[Observations], Actions]
"""A policy: observations ``(n, obs_dim)`` float32 -> integer actions ``(n,)``."""


class Predictor(Protocol):
    """What :class:`heartpole.training.models.ModelPolicy` needs of a model: Stable-Baselines3's ``predict``."""

    def predict(self, observation: np.ndarray, /, *, deterministic: bool = ...) -> tuple[np.ndarray, object]:
        """The actions for ``observation`` and the next recurrent state (``None`` without one)."""
        ...


SB3_ALGORITHMS = ("ppo", "a2c", "dqn")
"""The Stable-Baselines3 algorithms HeartPole trains and loads."""
# The files a training run writes in its folder (heartpole.training writes them; loading and plots read them).
MODEL_NAME = "model.zip"
SIDECAR_NAME = "heartpole.json"
VECNORMALIZE_NAME = "vecnormalize.pkl"
CURVE_NAME = "learning_curve.csv"
CURVE_COLUMNS = ("timesteps", "mean_return", "heart_attacks", "score")
"""The columns of a learning curve: after each evaluation, its timestep and the mean return, heart
attacks and score of the episodes finished since the last one."""


def _observations(obs: npt.ArrayLike) -> np.ndarray:
    array = np.asarray(obs)
    if array.ndim != 2:
        raise ValueError(f"a policy takes a batch of observations of shape (n, obs_dim), got shape {array.shape}")
    return array


class RandomPolicy:
    """Uniformly random actions among all of the env's actions, drawn from the policy's own generator.

    Args:
        dynamics: the env's dynamics (default: v0's); only the number of actions is used.
        rng: a ``numpy.random.Generator``, or a seed for one (default 0). NumPy's global state is never used.
    """

    name = "random"

    def __init__(self, dynamics: Dynamics | None = None, rng: np.random.Generator | int | None = None) -> None:
        self.num_actions = len((dynamics or _v0_dynamics()).actions)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.integers(0, self.num_actions, len(_observations(obs)))


class ConstantPolicy:
    """The same action in every state, looked up by name: ``do_nothing`` for ``nothing``, and so on.

    Args:
        action: the action's name in the env's dynamics.
        dynamics: the env's dynamics (default: v0's).
        name: the policy's name in results tables (default: the action's).
    """

    def __init__(self, action: str, dynamics: Dynamics | None = None, name: str | None = None) -> None:
        self.action = (dynamics or _v0_dynamics()).action_index(action)
        self.name = name or action

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.full(len(_observations(obs)), self.action, dtype=np.int64)


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
        dynamics = dynamics or _v0_dynamics()
        self.coffee = dynamics.action_index("drink_coffee")
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")
        self.cycle = cycle

    def phase(self, obs: np.ndarray) -> np.ndarray:
        """The position of each observation in the cycle, 0 (coffee) to ``cycle - 1`` (sleep)."""
        obs = _observations(obs)
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

    When to sleep. What remains is the score, work_done / time_elapsed. A day's alertness only falls
    (fact 6), so the coming half-hour's productivity falls too, and the classic renewal argument applies:
    keep working while the coming half-hour earns at least the long-run rate (work per half-hour, sleep
    included); sleep once it would earn less. Sleep pays for its 16 half-hours because a fresh day then
    earns above the rate. The rate is the score the policy itself reaches, a fixed point that
    :func:`expert_rate` solves from the dynamics: 0.327 for v0, reached when alertness falls to about 0.38
    (about 16 decisions after waking, ~63 sleeps an episode).

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
        rate: the productivity below which it sleeps (default: :func:`expert_rate` of ``dynamics``).
    """

    name = "expert"

    NAP_BELOW_ALERTNESS = 2.35
    NAP_WITHIN_HALF_HOURS_AWAKE = 23
    RATE_WITH_NAPS = 0.69

    def __init__(self, dynamics: Dynamics | None = None, rate: float | None = None) -> None:
        dynamics = dynamics or _v0_dynamics()
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")
        names = [action.name for action in dynamics.actions]
        self.nap = names.index("take_nap") if TAKE_NAP in dynamics.actions else None
        default_rate = self.RATE_WITH_NAPS if self.nap is not None else expert_rate(dynamics.params)
        self.rate = default_rate if rate is None else float(rate)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = _observations(obs)
        coming = productivity(obs[:, ALERTNESS], obs[:, INTOXICATION])
        actions = np.where(coming < self.rate, self.sleep, self.nothing)
        if self.nap is not None:
            nap = (obs[:, ALERTNESS] < self.NAP_BELOW_ALERTNESS) & (
                obs[:, TIME_SINCE_SLEPT] < self.NAP_WITHIN_HALF_HOURS_AWAKE
            )
            actions = np.where(nap, self.nap, actions)
        return actions.astype(np.int64)


@functools.lru_cache(maxsize=32)
def expert_rate(params: Params, grid: int = 400) -> float:
    """The long-run score of "sleep when the coming half-hour earns less than the score", as a fixed point.

    A day starts with waking alertness ``w`` uniform on ``params.wake_alertness``; its ``s``-th half-hour of
    work earns ``productivity(w - sum(alertness_decay(j) for j < s), 0)``. For a threshold ``rate`` a day
    lasts ``L(w)`` decisions and earns ``W(w)``. An episode of ``D = max_steps`` decisions holds ``D / E[L]``
    days and ``D / E[L] - 1`` sleeps, so its score is ``(D / E[L]) E[W] / (D + sleep (D / E[L] - 1))``.
    Iterating ``rate <- score(rate)`` from 0 converges to the best threshold (Dinkelbach's method), since a
    threshold equal to the score it achieves cannot be improved on. ``w`` is integrated on a midpoint grid.

    Memory does not grow with ``max_steps``: the rate is never negative, and a day's work turns negative
    (and so stops) once alertness is below 0, so only the half-hours up to then are computed.
    """
    low, high = params.wake_alertness
    wake = low + (high - low) * (np.arange(grid) + 0.5) / grid
    horizon = params.max_steps
    earned = productivity(_waking_alertness(wake, horizon), 0.0)
    columns = earned.shape[1]  # < horizon: every day has ended by the last column
    rate = 0.0
    for _ in range(200):
        working = earned >= rate
        working[:, 0] = True  # the decision to sleep comes with the first half-hour of the new day
        whole = working.all(axis=1)
        length = np.where(whole, horizon, np.argmin(working, axis=1))
        work = np.where(np.arange(columns)[None, :] < length[:, None], earned, 0.0).sum(axis=1)
        days = horizon / length.mean()
        new_rate = days * work.mean() / (horizon + params.sleep_half_hours * max(days - 1.0, 0.0))
        if abs(new_rate - rate) < 1e-12:
            break
        rate = new_rate
    return float(rate)


def _waking_alertness(wake: np.ndarray, horizon: int, block: int = 64) -> np.ndarray:
    """Alertness over a day for each waking alertness in ``wake``: ``(len(wake), columns)``.

    ``columns`` is ``horizon``, or fewer: up to the first half-hour after waking at which every day's
    alertness is below 0 (productivity is negative from there on, and alertness only falls).
    """
    decay: list[np.ndarray] = [np.zeros(1)]
    total, start = 0.0, 0
    while start < horizon - 1 and (start == 0 or total <= wake.max()):
        steps = np.arange(start, min(start + block, horizon - 1), dtype=np.float64)
        part = total + np.cumsum(alertness_decay(steps))
        decay.append(part)
        total, start = float(part[-1]), start + len(steps)
        block *= 2
    cumulative = np.concatenate(decay)
    if total > wake.max():  # cut just after the first half-hour at which every day is below 0
        cumulative = cumulative[: max(int(np.argmax(cumulative > wake.max())) + 1, 2)]
    return wake[:, None] - cumulative[None, :]


class OptimalPolicy:
    """``optimal``: the policy of :mod:`heartpole.optimum`'s dynamic program. Never drink; sleep when alertness
    falls below a threshold that depends on the half-hours awake and the decisions left.

    Far from the end it sleeps near the alertness where ``expert`` does; in the last days it re-times the
    days so that the last one ends with the episode, and over the last few decisions it stays awake. It
    needs the number of decisions left (``needs_decisions_left``): call it as ``policy(obs, decisions_left)``.
    The solution is solved once per parameter set and cached (:func:`heartpole.optimum.optimum`).

    Args:
        dynamics: the env's dynamics (default: v0's); must be v0's actions and variables.
        solution: a solved :class:`~heartpole.optimum.OptimumSolution` to act on (default: solve or load
            the cached one for ``dynamics``).

    Raises:
        heartpole.optimum.NotCoveredError: a variant the solver does not cover.
    """

    name = "optimal"
    needs_decisions_left = True

    def __init__(self, dynamics: Dynamics | None = None, solution: OptimumSolution | None = None) -> None:
        from heartpole.optimum import optimum_for

        dynamics = dynamics or _v0_dynamics()
        self.solution = solution if solution is not None else optimum_for(dynamics)
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")

    def __call__(self, obs: Observations, decisions_left: DecisionsLeft = None) -> Actions:
        obs = _observations(obs)
        if decisions_left is None:
            raise ValueError(
                "the optimal policy needs the number of decisions left: call policy(obs, decisions_left) "
                "(heartpole.policies.act_batch does it for loops that count steps)"
            )
        left = np.broadcast_to(np.asarray(decisions_left, dtype=np.int64), (len(obs),))
        sleeps = self.solution.sleeps(obs[:, ALERTNESS], obs[:, TIME_SINCE_SLEPT], left)
        return np.where(sleeps, self.sleep, self.nothing).astype(np.int64)


def policy_name(policy: object) -> str:
    """A display name: the policy's ``name`` attribute, its ``__name__``, or its class name."""
    for attribute in ("name", "__name__"):
        value = getattr(policy, attribute, None)
        if isinstance(value, str) and value:
            return value
    return type(policy).__name__


def act_batch(policy: Policy, obs: Observations, decisions_left: DecisionsLeft) -> Actions:
    """``policy``'s actions for ``obs``, passing ``decisions_left`` to a policy that ``needs_decisions_left``."""
    if getattr(policy, "needs_decisions_left", False):
        return policy(obs, decisions_left)  # type: ignore[call-arg]
    return policy(obs)


BUILTIN_POLICIES: Mapping[str, Callable[..., Policy]] = {
    "random": RandomPolicy,
    "nothing": nothing_policy,
    "coffee": coffee_policy,
    "reference": ReferencePolicy,
    "expert": ExpertPolicy,
    "optimal": OptimalPolicy,
}
"""The built-in policies by name; each entry builds the policy for a :class:`~heartpole.dynamics.Dynamics`."""


def available_builtins(env_id: str = "HeartPole-v0", env_kwargs: Mapping[str, Any] | None = None) -> list[str]:
    """The built-in policy names that can act in ``env_id``: all of them, but ``optimal`` only where
    :mod:`heartpole.optimum` covers the variant (solving it once, cached)."""
    from heartpole.optimum import available

    names = list(BUILTIN_POLICIES)
    if available(env_id, env_kwargs) is None:
        names.remove("optimal")
    return names


def make_policy(name: str, dynamics: Dynamics | None = None, rng: np.random.Generator | int | None = None) -> Policy:
    """The built-in policy ``name`` for ``dynamics`` (default: v0's); ``rng`` seeds ``random`` only.

    Raises:
        ValueError: for an unknown name, listing the valid ones.
    """
    if name not in BUILTIN_POLICIES:
        raise ValueError(f"unknown policy {name!r}; built-in policies are {', '.join(BUILTIN_POLICIES)}")
    if name == "random":
        return RandomPolicy(dynamics, rng)
    return BUILTIN_POLICIES[name](dynamics)


def load_policy(
    spec: str,
    env_id: str = "HeartPole-v0",
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    rng: np.random.Generator | int | None = None,
) -> Policy:
    """A built-in policy by name, or a Stable-Baselines3 model (a ``.zip`` saved by ``heartpole train``).

    For a model, the algorithm is read from a ``heartpole.json`` beside the zip (``{"algo": "ppo"}``) or
    else from the policy class recorded in the zip. Observations are normalised only with the
    ``VecNormalize`` statistics that ``heartpole.json`` records as saved with this model (see
    :func:`heartpole.training.models.recorded_normalizer`); the returned policy's ``normalizer_path`` names
    them. The model then acts deterministically. Model files are pickles: load only files you trust.

    Args:
        spec: a name in :data:`BUILTIN_POLICIES` or a path to a model ``.zip``.
        env_id: the env the policy will act in (its action names and spaces).
        env_kwargs: keyword arguments of that env (a variant's parameters).
        rng: generator or seed of the ``random`` policy.

    Raises:
        ValueError: unknown name, or a file that is not a usable model for this env.
        FileNotFoundError: a path that does not exist.

    A policy maps a batch of observations to a batch of action indices:

    >>> import numpy as np
    >>> policy = load_policy("coffee")
    >>> policy(np.zeros((3, 6), dtype=np.float32))
    array([1, 1, 1])
    """
    dynamics = env_dynamics(env_id, env_kwargs)
    if spec in BUILTIN_POLICIES:
        return make_policy(spec, dynamics, rng)
    if not _looks_like_path(spec):
        raise ValueError(
            f"unknown policy {spec!r}; built-in policies are {', '.join(BUILTIN_POLICIES)}, "
            "or give the path of a model .zip saved by 'heartpole train'"
        )
    from heartpole.training.models import load_model_policy  # Stable-Baselines3 models live with training

    return load_model_policy(spec, dynamics)


def env_dynamics(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> Dynamics:
    """The :class:`Dynamics` of the HeartPole env ``env_id`` built with ``env_kwargs``.

    Raises:
        ValueError: for an unknown id, a bad value or an env that is not a HeartPole.
        TypeError: for a keyword argument the env does not take.
    """
    import gymnasium as gym

    try:
        with quiet_version_warnings():
            env = gym.make(env_id, **dict(env_kwargs or {}))
    except gym.error.Error as error:
        raise ValueError(f"unknown env {env_id!r} ({_one_line(error)}); HeartPole envs: {_heartpole_ids()}") from None
    except TypeError as error:  # an unexpected keyword stays Python's TypeError, which callers branch on
        raise TypeError(f"env {env_id!r}: {_one_line(error)}") from None
    dynamics = getattr(env.unwrapped, "dynamics", None)
    env.close()
    if not isinstance(dynamics, Dynamics):
        raise ValueError(f"env {env_id!r} is not a HeartPole env; HeartPole envs: {_heartpole_ids()}")
    return dynamics


@contextmanager
def quiet_version_warnings() -> Iterator[None]:
    """Silence Gymnasium's "environment HeartPole-v0 is out of date" warning: evaluating v0 is deliberate."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*is out of date.*", category=DeprecationWarning)
        yield


def _heartpole_ids() -> str:
    import gymnasium as gym

    return ", ".join(sorted(i for i in gym.registry if i.startswith("HeartPole")))


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())


def _looks_like_path(spec: str) -> bool:
    return bool(spec) and (spec.endswith(".zip") or "/" in spec or "\\" in spec or Path(spec).exists())


@functools.lru_cache(maxsize=1)
def _v0_dynamics() -> Dynamics:
    return Dynamics()
