"""Honest evaluation of HeartPole policies: many episodes, 95% intervals, a low-variance estimate, pairs.

[`evaluate`][heartpole.evaluation.evaluate] runs a policy for ``episodes`` full episodes on the native vector env and
returns an [`EvaluationResult`][heartpole.results.EvaluationResult] with two estimates of the expected return, each
with a 95% interval:

* the *realized* return, the mean of the episodes' returns. An episode's return telescopes to its final
  score (``work_done / time_elapsed``) minus 100 per heart attack, so its standard deviation is about
  110 from heart attacks alone: 20 episodes (the published protocol) give a standard error near 25.
* the *expected-risk* return, the final score minus 100 times the sum of the steps' heart-attack
  probabilities (``info["heart_attack_risk"]``, recomputed in float64 from the state the step left:
  [`step_risks`][heartpole.rollout.step_risks]). Each attack is a coin flipped with that known
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

import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import replace
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from heartpole import paths
from heartpole.dynamics import Dynamics
from heartpole.parameters import check_integer
from heartpole.policies import Policy, available_builtins, load_policy, policy_name
from heartpole.registry import env_dynamics
from heartpole.results import Comparison as Comparison
from heartpole.results import Episodes as Episodes
from heartpole.results import EvaluationResult as EvaluationResult
from heartpole.rewards import expected_risk
from heartpole.rollout import ENV_BYTES, base_env, episode_steps, policy_actions, step_risks, vector_env
from heartpole.solved import SOLVED_REGRET as SOLVED_REGRET
from heartpole.truth import NO_SINGLE_OPTIMUM, oracle_fields, people_truth

if TYPE_CHECKING:
    from gymnasium.vector import VectorEnv

    from heartpole.optimum import OptimumSolution, PeopleOptimum

DEFAULT_EPISODES = 2000
DEFAULT_NUM_ENVS = 10_000
"""Episodes run side by side in one vector env; more episodes run in chunks of this many. Wider chunks
amortise the per-step Python overhead (measured: 10,000 episodes ran ~2x faster in chunks of 10,000 than
of 2,000, and ~3x faster than of 1,000)."""
EPISODE_BYTES = 128
"""Bytes an evaluation keeps per episode (its results' arrays and their summaries), counted generously."""

ENV_STREAM, POLICY_STREAM = 0, 1
"""The seed's spawn keys of the envs' episodes and of random policies, kept apart."""

PolicyLike = Policy | str
Progress = Callable[[int], None]


# ------------------------------------------------------------------------------------------------------
# running episodes


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
    episodes, seed, chunk, env_kwargs = _checked(episodes, seed, num_envs, env_kwargs)
    dynamics = env_dynamics(env_id, env_kwargs)  # the one resolution of env_id: everything below takes it
    truth = people_truth(env_id, env_kwargs, show_progress=progress is True, dynamics=dynamics) if regret else None
    act, name = _resolve(policy, env_id, env_kwargs, seed, dynamics)
    return _evaluate(act, name, _Run(env_id, env_kwargs, dynamics, episodes, seed, chunk), truth, progress, regret)


class _Run(NamedTuple):
    """What one evaluation runs on, checked and resolved once: the env (its id, keyword arguments and
    [`Dynamics`][heartpole.dynamics.Dynamics]), the episodes, the seed and the chunk of episodes run side by side."""

    env_id: str
    env_kwargs: dict[str, Any]
    dynamics: Dynamics
    episodes: int
    seed: int
    chunk: int


def _checked(
    episodes: int, seed: int, num_envs: int | None, env_kwargs: Mapping[str, Any] | None
) -> tuple[int, int, int, dict[str, Any]]:
    """``episodes``, ``seed``, the chunk and ``env_kwargs`` of an evaluation, checked."""
    episodes, seed = check_integer("episodes", episodes, 1), check_integer("seed", seed, 0)
    chunk = min(episodes, DEFAULT_NUM_ENVS if num_envs is None else check_integer("num_envs", num_envs, 1))
    paths.check_memory(episodes * EPISODE_BYTES + chunk * ENV_BYTES, f"evaluating {episodes:,} episodes")
    return episodes, seed, chunk, dict(env_kwargs or {})


def _evaluate(
    act: Policy, name: str, run: _Run, truth: PeopleOptimum | str | None, progress: bool | Progress, regret: bool
) -> EvaluationResult:
    """[`evaluate`][heartpole.evaluation.evaluate] of the resolved policy ``act`` on the resolved ``run``."""
    # solved before the episodes: no failure loses them
    solution = optimum_or_reason(run.env_id, run.env_kwargs, run.dynamics) if regret else None
    started = time.perf_counter()
    parts = []
    total = run.episodes * run.dynamics.params.max_steps
    with _progress_callback(progress, f"evaluating {name}", total) as tick:
        for index, first in enumerate(range(0, run.episodes, run.chunk)):
            with vector_env(run.env_id, run.env_kwargs, min(run.chunk, run.episodes - first)) as env:
                parts.append(_run_episodes(env, act, name, chunk_seed(run.seed, index), tick))
                max_steps = int(base_env(env).max_steps)
    return summarise(
        Episodes.concatenate(parts),
        truth,
        solution,
        policy=name,
        env_id=run.env_id,
        seed=run.seed,
        num_envs=run.chunk,
        max_steps=max_steps,
        seconds=time.perf_counter() - started,
    )


def summarise(
    episodes: Episodes, truth: PeopleOptimum | str | None, solution: OptimumSolution | str | None, **about: Any
) -> EvaluationResult:
    """The [`EvaluationResult`][heartpole.results.EvaluationResult] of ``episodes`` (every engine's:
    [`evaluate`][heartpole.evaluation.evaluate]'s and [`heartpole.jax.evaluate`][heartpole.jax.evaluation.evaluate]'s),
    with the oracle regret against ``truth`` ([`people_truth`][heartpole.truth.people_truth]) and the regret against
    ``solution`` ([`optimum_or_reason`][heartpole.evaluation.optimum_or_reason]; ``None``: not asked for);
    ``about`` holds policy, env_id, seed, num_envs, max_steps and seconds."""
    result = EvaluationResult.from_episodes(episodes, **about)
    result = replace(result, **oracle_fields(truth, result.person, result.expected_returns))
    if solution is None or isinstance(solution, str):
        return replace(result, no_regret_reason=solution)
    return result.with_regret(solution.expected_return, solution.margin)


def optimum_or_reason(
    env_id: str, env_kwargs: Mapping[str, Any], dynamics: Dynamics | None = None
) -> OptimumSolution | str:
    """The optimum of the env ([`heartpole.optimum.optimum`][heartpole.optimum.solution.optimum]), or why the solver
    does not cover it; ``dynamics``: the env's, where the caller resolved ``env_id`` already."""
    from heartpole.optimum import NotCoveredError, optimum, optimum_for

    if env_kwargs.get("people") is not None:
        return NO_SINGLE_OPTIMUM
    try:
        return optimum(env_id, env_kwargs) if dynamics is None else optimum_for(dynamics, env_id, env_kwargs)
    except NotCoveredError as error:
        return f"the optimum is not known here ({' '.join(str(error).split())})"


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
    episodes, seed, chunk, kwargs = _checked(episodes, seed, num_envs, env_kwargs)
    run = _Run(env_id, kwargs, env_dynamics(env_id, kwargs), episodes, seed, chunk)
    # both policies resolved before either runs: a bad ``b`` cannot waste ``a``
    resolved = [_resolve(policy, env_id, kwargs, seed, run.dynamics) for policy in (policy_a, policy_b)]
    truth = people_truth(env_id, kwargs, show_progress=progress is True, dynamics=run.dynamics)
    return Comparison.of(*(_evaluate(act, name, run, truth, progress, True) for act, name in resolved))


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
    episodes, seed, chunk, kwargs = _checked(episodes, seed, num_envs, env_kwargs)
    run = _Run(env_id, kwargs, env_dynamics(env_id, kwargs), episodes, seed, chunk)
    policies: list[PolicyLike] = [*available_builtins(env_id, kwargs, run.dynamics), *extra]
    truth = people_truth(env_id, kwargs, show_progress=progress is True, dynamics=run.dynamics)
    resolved = [_resolve(policy, env_id, kwargs, seed, run.dynamics) for policy in policies]
    return rank([_evaluate(act, name, run, truth, progress, True) for act, name in resolved])


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
    proclivity = None  # each env's, read at the first step: an episode keeps its person
    for step in episode_steps(env, reset_seed, policy_actions(act, name, env)):
        drinks += drinks_table[step.actions]
        sleeps += sleeps_table[step.actions]
        returns += step.rewards
        proclivity = base_env(env).heart_attack_proclivity if proclivity is None else proclivity
        risks += step_risks(env, step.info, proclivity)  # each step's probability in float64, from its state
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


def _resolve(
    policy: PolicyLike, env_id: str, env_kwargs: dict[str, Any], seed: int, dynamics: Dynamics
) -> tuple[Policy, str]:
    """The callable and the display name of ``policy`` in the env of ``dynamics``; a ``random`` built-in gets a
    generator from ``seed``."""
    if isinstance(policy, str):
        rng = policy_rng(seed)
        return load_policy(policy, env_id, env_kwargs=env_kwargs, rng=rng, dynamics=dynamics), policy
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
def _progress_callback(progress: bool | Progress, description: str, total: int) -> Iterator[Progress]:
    """A ``tick(steps)`` callable for a run of ``total`` env steps: a stderr bar for ``True``, the user's callable,
    or nothing."""
    if callable(progress):
        yield progress
        return
    if not progress:
        yield _ignore
        return
    from heartpole.progress import Progress as Bar

    bar = Bar(total, description)
    try:
        yield bar.update
    finally:
        bar.close()


def _ignore(steps: int) -> None:
    """A progress callback that shows nothing."""
