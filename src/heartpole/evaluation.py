"""Honest evaluation of HeartPole policies: many episodes, 95% intervals, a low-variance estimate, pairs.

[`evaluate`][heartpole.evaluation.evaluate] runs a policy for ``episodes`` full episodes on the native vector env and
returns an [`EvaluationResult`][heartpole.evaluation.EvaluationResult] with two estimates of the expected return, each
with a 95% interval:

* the *realized* return, the mean of the episodes' returns. An episode's return telescopes to its final
  score (``work_done / time_elapsed``) minus 100 per heart attack, so its standard deviation is about
  110 from heart attacks alone: 20 episodes (the published protocol) give a standard error near 25.
* the *expected-risk* return, the final score minus 100 times the sum of the steps' heart-attack
  probabilities (``info["heart_attack_risk"]``). Each attack is a coin flipped with that known
  probability, so the sum of probabilities has the same expectation as the count of attacks (the
  difference is a martingale) but none of the coin's noise: same expected value, no bias, an interval
  hundreds of times narrower. Policies are ranked by it.

[`compare`][heartpole.evaluation.compare] evaluates two policies with common random numbers. The vector env draws one
block of uniforms per step with a fixed column per random event (each effect, waking, the heart-attack coin), and
evaluation splits the episodes into chunks that depend only on ``(episodes, seed, num_envs)``; so episode ``i`` of
policy A meets the same coins as episode ``i`` of policy B, and the interval of the paired difference is far tighter
than the two separate intervals.

Everything random is seeded from ``seed`` through NumPy ``SeedSequence`` s: chunk ``c`` of the episodes
resets its env with a seed drawn from ``SeedSequence(seed, spawn_key=(0, c))``, and the ``random``
built-in draws its actions from ``SeedSequence(seed, spawn_key=(1,))``, apart from the env's draws.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from heartpole.model import check_integer
from heartpole.policies import Policy, available_builtins, load_policy, policy_name
from heartpole.rewards import expected_risk
from heartpole.rollout import base_env, episode_steps, policy_actions, vector_env
from heartpole.solved import SOLVED_REGRET as SOLVED_REGRET
from heartpole.solved import regret_solved
from heartpole.stats import confidence_interval, json_interval, json_number
from heartpole.truth import NO_SINGLE_OPTIMUM, oracle_fields, people_truth

if TYPE_CHECKING:
    from gymnasium.vector import VectorEnv

    from heartpole.optimum import OptimumSolution, PeopleOptimum

DEFAULT_EPISODES = 2000
DEFAULT_NUM_ENVS = 10_000
"""Episodes run side by side in one vector env; more episodes run in chunks of this many. Wider chunks
amortise the per-step Python overhead (measured: 10,000 episodes ran ~2x faster in chunks of 10,000 than
of 2,000, and ~3x faster than of 1,000)."""

ENV_STREAM, POLICY_STREAM = 0, 1
"""The seed's spawn keys of the envs' episodes and of random policies, kept apart."""

PolicyLike = Policy | str
Progress = Callable[[int], None]


# ------------------------------------------------------------------------------------------------------
# results

SUMMARIES = (
    ("mean_return", "ci95", "returns"),
    ("expected_return", "expected_ci95", "expected_returns"),
    ("heart_attacks_per_episode", "heart_attacks_ci95", "heart_attacks"),
    ("expected_heart_attacks_per_episode", None, "expected_heart_attacks"),
    ("score", "score_ci95", "scores"),
    ("drinks_per_episode", None, "drinks"),
    ("sleeps_per_episode", None, "sleeps"),
)
"""How [`EvaluationResult`][heartpole.evaluation.EvaluationResult] summarises per-episode values: (its mean's
field, its 95% interval's field or ``None``, the per-episode field)."""


@dataclass(frozen=True)
class EvaluationResult:
    """A policy's performance over ``episodes`` episodes, with 95% intervals and the per-episode values.

    ``mean_return`` is the realized mean return; ``expected_return`` the expected-risk estimate of the same
    quantity (final score - 100 x the summed heart-attack probabilities). ``score`` is the mean final
    ``work_done / time_elapsed``. Per-episode arrays (float64 or int64) are in episode order. With fewer
    than two episodes the intervals are ``nan``; without an optimum the regret is, and ``no_regret_reason``
    says why. Under ``people``, ``person`` is each episode's person (cohort index, -1 without one) and
    ``oracle_regret`` the mean of (that person's optimum - expected-risk return), [`heartpole.truth`][heartpole.truth]'s
    (``nan`` without people or a cohort's optima: ``no_oracle_regret_reason`` says why).
    """

    policy: str
    env_id: str
    episodes: int
    seed: int
    num_envs: int
    max_steps: int
    mean_return: float
    ci95: tuple[float, float]
    expected_return: float
    expected_ci95: tuple[float, float]
    heart_attacks_per_episode: float
    heart_attacks_ci95: tuple[float, float]
    expected_heart_attacks_per_episode: float
    score: float
    score_ci95: tuple[float, float]
    drinks_per_episode: float
    sleeps_per_episode: float
    seconds: float
    returns: np.ndarray = field(repr=False, compare=False)
    expected_returns: np.ndarray = field(repr=False, compare=False)
    scores: np.ndarray = field(repr=False, compare=False)
    heart_attacks: np.ndarray = field(repr=False, compare=False)
    expected_heart_attacks: np.ndarray = field(repr=False, compare=False)
    drinks: np.ndarray = field(repr=False, compare=False)
    sleeps: np.ndarray = field(repr=False, compare=False)
    person: np.ndarray = field(repr=False, compare=False)
    optimal_return: float = math.nan
    regret: float = math.nan
    regret_ci95: tuple[float, float] = (math.nan, math.nan)
    no_regret_reason: str | None = None
    oracle_regret: float = math.nan
    oracle_regret_ci95: tuple[float, float] = (math.nan, math.nan)
    no_oracle_regret_reason: str | None = None

    def with_regret(self, optimal_return: float, error_bound: float = 0.0) -> EvaluationResult:
        """This result with its regret: ``optimal_return`` minus the expected-risk return.

        The 95% interval is the expected-risk interval reflected, widened by ``error_bound``: the optimum's
        [`margin`][heartpole.optimum.solution.OptimumSolution.margin] (its grid's error and what the history it does
        not see is worth) where evaluation computes the regret.
        """
        low, high = self.expected_ci95
        interval = (optimal_return - high - error_bound, optimal_return - low + error_bound)
        regret = optimal_return - self.expected_return
        return replace(self, optimal_return=optimal_return, regret=regret, regret_ci95=interval)

    @property
    def solved(self) -> bool | None:
        """Whether the regret's 95% upper bound is at most [`SOLVED_REGRET`][heartpole.solved.SOLVED_REGRET];
        ``None`` without an optimum."""
        return regret_solved(self.regret_ci95[1])

    @classmethod
    def from_episodes(cls, episodes: Episodes, **about: Any) -> EvaluationResult:
        """Summarise per-episode values; ``about`` holds policy, env_id, seed, num_envs, max_steps, seconds."""
        summary: dict[str, Any] = {}
        for mean, interval, values in SUMMARIES:
            array = getattr(episodes, values)
            summary[mean] = float(array.mean())
            if interval is not None:
                summary[interval] = confidence_interval(array)
        arrays = {name: getattr(episodes, name) for name in Episodes.__dataclass_fields__}
        return cls(episodes=len(episodes.returns), **summary, **arrays, **about)

    @property
    def width_ratio(self) -> float:
        """How many times narrower the expected-risk interval is than the realized one (``inf`` where the
        expected-risk return is the same in every episode, ``nan`` with fewer than two episodes)."""
        expected = self.expected_ci95[1] - self.expected_ci95[0]
        realized = self.ci95[1] - self.ci95[0]
        return realized / expected if expected > 0 else math.inf

    def to_dict(self, per_episode: bool = False) -> dict[str, Any]:
        """JSON-safe summary (NaN and infinities become ``None``); ``per_episode`` adds the arrays as lists."""
        out: dict[str, Any] = {
            "policy": self.policy,
            "env_id": self.env_id,
            "episodes": self.episodes,
            "seed": self.seed,
            "num_envs": self.num_envs,
            "max_steps": self.max_steps,
            "mean_return": json_number(self.mean_return),
            "ci95": json_interval(self.ci95),
            "expected_return": json_number(self.expected_return),
            "expected_ci95": json_interval(self.expected_ci95),
            "heart_attacks_per_episode": json_number(self.heart_attacks_per_episode),
            "heart_attacks_ci95": json_interval(self.heart_attacks_ci95),
            "expected_heart_attacks_per_episode": json_number(self.expected_heart_attacks_per_episode),
            "score": json_number(self.score),
            "score_ci95": json_interval(self.score_ci95),
            "drinks_per_episode": json_number(self.drinks_per_episode),
            "sleeps_per_episode": json_number(self.sleeps_per_episode),
            "optimal_return": json_number(self.optimal_return),
            "regret": json_number(self.regret),
            "regret_ci95": json_interval(self.regret_ci95),
            "solved": self.solved,
            "no_regret_reason": self.no_regret_reason,
            "oracle_regret": json_number(self.oracle_regret),
            "oracle_regret_ci95": json_interval(self.oracle_regret_ci95),
            "no_oracle_regret_reason": self.no_oracle_regret_reason,
            "seconds": round(self.seconds, 3),
        }
        if per_episode:
            for key in ("returns", "expected_returns", "scores", "heart_attacks", "drinks", "sleeps", "person"):
                out[key] = getattr(self, key).tolist()
        return out


@dataclass(frozen=True)
class Comparison:
    """Policy ``a`` minus policy ``b``, episode by episode, from evaluations with common random numbers.

    ``difference`` is the mean realized return of ``a`` minus that of ``b``, ``expected_difference`` the
    same for the expected-risk estimate, ``score_difference`` for the final score; each with the 95%
    interval of the paired differences.
    """

    a: EvaluationResult
    b: EvaluationResult
    difference: float
    ci95: tuple[float, float]
    expected_difference: float
    expected_ci95: tuple[float, float]
    score_difference: float
    score_ci95: tuple[float, float]

    @classmethod
    def of(cls, a: EvaluationResult, b: EvaluationResult) -> Comparison:
        """Pair two results episode by episode; they must come from the same env, seed and chunking.

        Raises:
            ValueError: if the results cannot be paired.
        """
        for key in ("env_id", "episodes", "seed", "num_envs", "max_steps"):
            mine, theirs = getattr(a, key), getattr(b, key)
            if mine != theirs:
                raise ValueError(f"cannot pair evaluations with different {key}: {mine} vs {theirs}")
        returns = a.returns - b.returns
        expected = a.expected_returns - b.expected_returns
        scores = a.scores - b.scores
        return cls(
            a=a,
            b=b,
            difference=float(returns.mean()),
            ci95=confidence_interval(returns),
            expected_difference=float(expected.mean()),
            expected_ci95=confidence_interval(expected),
            score_difference=float(scores.mean()),
            score_ci95=confidence_interval(scores),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: both results' summaries and the paired differences."""
        return {
            "a": self.a.to_dict(),
            "b": self.b.to_dict(),
            "difference": {
                "mean_return": json_number(self.difference),
                "ci95": json_interval(self.ci95),
                "expected_return": json_number(self.expected_difference),
                "expected_ci95": json_interval(self.expected_ci95),
                "score": json_number(self.score_difference),
                "score_ci95": json_interval(self.score_ci95),
            },
            "env_id": self.a.env_id,
            "episodes": self.a.episodes,
            "seed": self.a.seed,
        }


# ------------------------------------------------------------------------------------------------------
# running episodes


@dataclass
class Episodes:
    """Per-episode values of an evaluation, or of one chunk of its episodes: the returns, expected-risk returns
    and final scores (float64), heart attacks (int64), summed heart-attack probabilities (float64), drinks and
    sleeps (int64) and each episode's person (int64, -1 without one)."""

    returns: np.ndarray
    expected_returns: np.ndarray
    scores: np.ndarray
    heart_attacks: np.ndarray
    expected_heart_attacks: np.ndarray
    drinks: np.ndarray
    sleeps: np.ndarray
    person: np.ndarray

    @classmethod
    def concatenate(cls, parts: Sequence[Episodes]) -> Episodes:
        """The episodes of ``parts``, in order."""
        return cls(*(np.concatenate([getattr(part, f) for part in parts]) for f in cls.__dataclass_fields__))


def evaluate(
    policy: PolicyLike,
    env_id: str = "HeartPole-v0",
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    *,
    num_envs: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool | Progress = False,
    regret: bool = True,
) -> EvaluationResult:
    """Run ``policy`` for ``episodes`` full episodes of ``env_id`` and summarise them.

    Args:
        policy: a [`Policy`][heartpole.policies.Policy] callable, a built-in name or a model ``.zip`` path.
        env_id: a HeartPole env id; episodes run on its native vector env.
        episodes: how many episodes (>= 1; intervals need >= 2).
        seed: the seed of everything random (>= 0). The same seed gives the same result, and two policies
            evaluated with the same seed and ``num_envs`` share their random numbers (see
            [`compare`][heartpole.evaluation.compare]).
        num_envs: episodes run side by side (default: ``min(episodes, DEFAULT_NUM_ENVS)``).
        env_kwargs: the env's keyword arguments (``max_steps``, ``heart_attack_proclivity``, ...).
        progress: ``True`` for a progress bar on stderr (shown when stderr is a terminal), or a callable
            given the number of env steps done since its last call.
        regret: add the regret against [`heartpole.optimum`][heartpole.optimum]'s optimum where the solver covers the
            env (solved before the episodes run, once per parameter set, and cached; elsewhere ``nan``, with
            ``no_regret_reason`` saying why); under a finite cohort of ``people`` the oracle regret instead (each person
            solved once and cached, see [`people_truth`][heartpole.truth.people_truth]).

    Raises:
        ValueError: bad arguments, an unknown policy or env, or a policy returning invalid actions.
        FileNotFoundError: a model path that does not exist.

    >>> result = evaluate("expert", "HeartPole-v0", episodes=20, seed=0, env_kwargs={"max_steps": 100})
    >>> result.policy, result.episodes, result.max_steps
    ('expert', 20, 100)
    >>> result.expected_ci95[0] <= result.expected_return <= result.expected_ci95[1]
    True
    """
    episodes, seed = check_integer("episodes", episodes, 1), check_integer("seed", seed, 0)
    chunk = min(episodes, DEFAULT_NUM_ENVS if num_envs is None else check_integer("num_envs", num_envs, 1))
    env_kwargs = dict(env_kwargs or {})
    truth = people_truth(env_id, env_kwargs, show_progress=progress is True) if regret else None
    act, name = _resolve(policy, env_id, env_kwargs, seed)
    solution = optimum_or_reason(env_id, env_kwargs) if regret else None  # before the episodes: no failure loses them
    started = time.perf_counter()
    parts = []
    with _progress_callback(progress, f"evaluating {name}", episodes, env_id, env_kwargs) as tick:
        for index, first in enumerate(range(0, episodes, chunk)):
            with vector_env(env_id, env_kwargs, min(chunk, episodes - first)) as env:
                parts.append(_run_episodes(env, act, name, chunk_seed(seed, index), tick))
                max_steps = int(base_env(env).max_steps)
    return summarise(
        Episodes.concatenate(parts),
        truth,
        solution,
        policy=name,
        env_id=env_id,
        seed=seed,
        num_envs=chunk,
        max_steps=max_steps,
        seconds=time.perf_counter() - started,
    )


def summarise(
    episodes: Episodes, truth: PeopleOptimum | str | None, solution: OptimumSolution | str | None, **about: Any
) -> EvaluationResult:
    """The [`EvaluationResult`][heartpole.evaluation.EvaluationResult] of ``episodes`` (every engine's:
    [`evaluate`][heartpole.evaluation.evaluate]'s and [`heartpole.jax.evaluate`][heartpole.jax.evaluation.evaluate]'s),
    with the oracle regret against ``truth`` ([`people_truth`][heartpole.truth.people_truth]) and the regret against
    ``solution`` ([`optimum_or_reason`][heartpole.evaluation.optimum_or_reason]; ``None``: not asked for);
    ``about`` holds policy, env_id, seed, num_envs, max_steps and seconds."""
    result = EvaluationResult.from_episodes(episodes, **about)
    result = replace(result, **oracle_fields(truth, result.person, result.expected_returns))
    if solution is None or isinstance(solution, str):
        return replace(result, no_regret_reason=solution)
    return result.with_regret(solution.expected_return, solution.margin)


def optimum_or_reason(env_id: str, env_kwargs: Mapping[str, Any]) -> OptimumSolution | str:
    """The optimum of the env ([`heartpole.optimum.optimum`][heartpole.optimum.solution.optimum]), or why the solver
    does not cover it."""
    from heartpole.optimum import NotCoveredError, optimum

    if env_kwargs.get("people") is not None:
        return NO_SINGLE_OPTIMUM
    try:
        return optimum(env_id, env_kwargs)
    except NotCoveredError as error:
        return f"the optimum is not known here ({' '.join(str(error).split())})"


class _SharedOptions(TypedDict):
    """The keyword arguments of [`evaluate`][heartpole.evaluation.evaluate] that
    [`compare`][heartpole.evaluation.compare] and [`baselines`][heartpole.evaluation.baselines] pass on alike."""

    num_envs: int | None
    env_kwargs: Mapping[str, Any] | None
    progress: bool | Progress


def compare(
    policy_a: PolicyLike,
    policy_b: PolicyLike,
    env_id: str = "HeartPole-v0",
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    *,
    num_envs: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool | Progress = False,
) -> Comparison:
    """Evaluate two policies with common random numbers and pair their episodes: ``a - b``.

    Arguments are [`evaluate`][heartpole.evaluation.evaluate]'s; both policies see the same seed and chunking.

    >>> pair = compare("expert", "nothing", episodes=20, env_kwargs={"max_steps": 100})
    >>> pair.a.policy, pair.b.policy, pair.expected_difference == pair.a.expected_return - pair.b.expected_return
    ('expert', 'nothing', True)
    """
    for policy in (policy_a, policy_b):  # both checked before either runs: a bad ``b`` cannot waste ``a``
        _resolve(policy, env_id, dict(env_kwargs or {}), seed)
    options: _SharedOptions = {"num_envs": num_envs, "env_kwargs": env_kwargs, "progress": progress}
    a = evaluate(policy_a, env_id, episodes, seed, **options)
    b = evaluate(policy_b, env_id, episodes, seed, **options)
    return Comparison.of(a, b)


def baselines(
    extra: Iterable[PolicyLike] = (),
    env_id: str = "HeartPole-v0",
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    *,
    num_envs: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool | Progress = False,
) -> list[EvaluationResult]:
    """Every built-in policy and each of ``extra``, evaluated alike, best expected-risk return first.

    ``optimal`` is left out where [`heartpole.optimum`][heartpole.optimum] does not cover the variant."""
    policies: list[PolicyLike] = [*available_builtins(env_id, env_kwargs), *extra]
    options: _SharedOptions = {"num_envs": num_envs, "env_kwargs": env_kwargs, "progress": progress}
    return rank([evaluate(policy, env_id, episodes, seed, **options) for policy in policies])


def rank(results: Iterable[EvaluationResult]) -> list[EvaluationResult]:
    """``results`` sorted by expected-risk return, best first (the low-variance estimate ranks)."""
    return sorted(results, key=lambda result: -result.expected_return)


def _run_episodes(env: VectorEnv, act: Policy, name: str, reset_seed: int, tick: Progress) -> Episodes:
    """Run every env of the vector env ``env`` for one full episode (``max_steps`` steps after reset)."""
    size, dynamics = env.num_envs, base_env(env).dynamics
    drinks_table = np.array([action.is_drink for action in dynamics.actions])
    sleeps_table = np.array([action.sleeps for action in dynamics.actions])
    returns, risks = np.zeros(size), np.zeros(size)
    attacks, drinks, sleeps = (np.zeros(size, dtype=np.int64) for _ in range(3))
    for step in episode_steps(env, reset_seed, policy_actions(act, name, env)):
        drinks += drinks_table[step.actions]
        sleeps += sleeps_table[step.actions]
        returns += step.rewards
        risks += step.info["heart_attack_risk"]  # float32 probabilities summed in float64
        attacks += step.info["heart_attack"]
        tick(size)
    scores = np.asarray(step.info["score"], dtype=np.float64)
    return Episodes(
        returns=returns,
        expected_returns=expected_risk(scores, risks, dynamics.params.heart_attack_penalty),
        scores=scores,
        heart_attacks=attacks,
        expected_heart_attacks=risks,
        drinks=drinks,
        sleeps=sleeps,
        person=np.full(size, -1, dtype=np.int64) if step.person is None else step.person,
    )


def _resolve(policy: PolicyLike, env_id: str, env_kwargs: dict[str, Any], seed: int) -> tuple[Policy, str]:
    """The callable and the display name of ``policy``; a ``random`` built-in gets a generator from ``seed``."""
    if isinstance(policy, str):
        rng = policy_rng(seed)
        return load_policy(policy, env_id, env_kwargs=env_kwargs, rng=rng), policy
    if not callable(policy):
        raise ValueError(f"policy must be a callable on observation batches or a policy name, got {policy!r}")
    return policy, policy_name(policy)


def chunk_seed(seed: int, index: int) -> int:
    """The reset seed of chunk ``index``: independent streams per chunk, fixed by ``(seed, index)``; every
    evaluation and recording of the same seed and chunks meets the same episodes."""
    return int(np.random.SeedSequence(seed, spawn_key=(ENV_STREAM, index)).generate_state(1, np.uint64)[0])


def policy_rng(seed: int, *key: int) -> np.random.Generator:
    """A random policy's own generator for ``seed``, apart from the envs' streams."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(POLICY_STREAM, *key)))


@contextmanager
def _progress_callback(
    progress: bool | Progress, description: str, episodes: int, env_id: str, env_kwargs: dict[str, Any]
) -> Iterator[Progress]:
    """A ``tick(steps)`` callable for the run: a stderr bar for ``True``, the user's callable, or nothing."""
    if callable(progress):
        yield progress
        return
    if not progress:
        yield _ignore
        return
    from heartpole.progress import Progress as Bar
    from heartpole.registry import env_dynamics

    bar = Bar(episodes * env_dynamics(env_id, env_kwargs).params.max_steps, description)
    try:
        yield bar.update
    finally:
        bar.close()


def _ignore(steps: int) -> None:
    """A progress callback that shows nothing."""
