"""Evaluation on the JAX device: [`heartpole.evaluate`][heartpole.evaluation.evaluate]'s estimator, its episodes
played in one compiled call.

[`evaluate`][heartpole.jax.evaluation.evaluate] takes ``heartpole.evaluate``'s arguments and returns its
[`EvaluationResult`][heartpole.results.EvaluationResult] (the same JSON): the expected-risk return, the regret
against the optimum, the oracle regret under ``people``, the 95% intervals and the per-episode values. Its episodes
are the NumPy evaluation's: each chunk of episodes starts where ``heartpole.evaluate``'s vector env starts (the same
reset seed, the same people) and every step draws from the same generator states
([`heartpole.rng`][heartpole.rng]), so a deterministic policy plays the same episodes on both engines, up to
float32 rounding (``exp`` is each backend's own). [`evaluate_batch`][heartpole.jax.evaluation.evaluate_batch]
evaluates a batch of networks (one per seed, say) in one call, each on the same episodes.

A policy is a built-in name (`heartpole.jax.policies`) or a function of a batch of observations ``(n, obs_dim)``
returning ``(n,)`` integer actions, traceable by JAX; one with a true ``needs_decisions_left`` attribute is called
as ``policy(obs, decisions_left)``.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from heartpole.evaluation import (
    DEFAULT_EPISODES,
    DEFAULT_NUM_ENVS,
    Episodes,
    EvaluationResult,
    chunk_seed,
    optimum_or_reason,
    summarise,
)
from heartpole.jax.env import EnvParams, EnvState, HeartPoleJax
from heartpole.jax.policies import Act, builtin_act
from heartpole.jax.traced import MODEL, RNG
from heartpole.model import HYPERTENSION, TIME_ELAPSED, WORK_DONE
from heartpole.parameters import check_integer
from heartpole.policies import policy_name
from heartpole.rewards import expected_risk
from heartpole.rng import COUNTER, KEY_HIGH, KEY_LOW
from heartpole.rollout import base_env, episode_people, invalid_actions, vector_env
from heartpole.truth import people_truth

JaxPolicy = Callable[..., jax.Array]
"""A JAX policy: ``policy(obs) -> actions`` (``(n, obs_dim)`` float32 to ``(n,)`` integers), or
``policy(obs, decisions_left)`` where it has a true ``needs_decisions_left`` attribute."""


@dataclass(frozen=True)
class Start:
    """Where the episodes of an evaluation start: the NumPy evaluation's vector envs after their resets, every
    chunk's envs one after the other. ``variables`` ``(num_variables, episodes)`` float32, ``generators``
    ``(3, episodes)`` uint32 (`heartpole.rng`'s rows), ``person`` ``(episodes,)`` int64 (-1 without people),
    ``proclivity`` ``(episodes,)`` float32 (each episode's heart-attack proclivity, as its steps use it)."""

    variables: np.ndarray
    generators: np.ndarray
    person: np.ndarray
    max_steps: int
    chunk: int
    proclivity: np.ndarray

    @classmethod
    def of(cls, env_id: str, env_kwargs: Mapping[str, Any], episodes: int, seed: int, chunk: int) -> Start:
        """The starts of ``episodes`` episodes of ``seed`` in chunks of ``chunk``, as ``heartpole.evaluate``'s."""
        parts = []
        for index, first in enumerate(range(0, episodes, chunk)):
            with vector_env(env_id, env_kwargs, min(chunk, episodes - first)) as env:
                _, info = env.reset(seed=chunk_seed(seed, index))
                base = base_env(env)
                person = episode_people(info)
                person = np.full(env.num_envs, -1, dtype=np.int64) if person is None else person
                parts.append((base.state, base.generators, person, int(base.max_steps), base.heart_attack_proclivity))
        variables, generators, person, steps, proclivity = zip(*parts)
        return cls(
            np.concatenate(variables, 1),
            np.concatenate(generators, 1),
            np.concatenate(person),
            steps[0],
            chunk,
            np.concatenate(proclivity),
        )


class Totals(NamedTuple):
    """Per-episode sums carried through a rollout (float32 sums with Kahan's compensation, so 1,000 steps add up
    as NumPy's float64 sums do to about 1e-6), and the heart-attack risks summed as NumPy's evaluation sums them
    ([`heartpole.rewards.exact_risk`][heartpole.rewards.exact_risk]), without float64: ``sigmoid(hypertension - 6)``
    of the steps without an attack as a float32 pair (`exact_sigmoid`, summed by `_add_pair`: ``sigmoids +
    sigmoids_low``, about 1e-13 per step), to be multiplied by the episode's proclivity in float64, and the
    float32 risks of the steps with one (an attack resets the blood pressure the risk was computed at)."""

    returns: jax.Array
    returns_error: jax.Array
    sigmoids: jax.Array
    sigmoids_low: jax.Array
    attack_risks: jax.Array
    attack_risks_error: jax.Array
    attacks: jax.Array
    drinks: jax.Array
    sleeps: jax.Array


class ActionCheck(NamedTuple):
    """The first step at which a policy chose an action outside ``0..num_actions - 1``: whether there was one
    (``found``) and that step's smallest and largest actions, as NumPy's evaluation reports them."""

    found: jax.Array
    low: jax.Array
    high: jax.Array


def _kahan(total: jax.Array, error: jax.Array, value: jax.Array) -> tuple[jax.Array, jax.Array]:
    corrected = value - error
    new = total + corrected
    return new, (new - total) - corrected


SIGMOID_GRID = 256
"""Points of `sigmoid_table` per unit of blood pressure: steps of 1/256 keep its cubic's error near 1e-13."""
SIGMOID_RANGE = 40
"""`sigmoid_table` covers blood pressures in ``[-40, 40]``; beyond, float32's ``sigmoid(hypertension - 6)`` is 1
(or below 1e-19) to far better than 1e-13."""
SPLIT = 2**20
"""`exact_sigmoid` splits the distance to the grid (below 2**-9) at multiples of 2**-20: 12 bits at most, whose
product with a 12-bit coefficient float32 holds exactly."""


def _twelve_bits(values: np.ndarray) -> np.ndarray:
    """``values`` rounded to 12 significant bits (float64)."""
    mantissa, exponent = np.frexp(values)
    return np.ldexp(np.round(mantissa * 2.0**12), exponent - 12)


@functools.lru_cache(maxsize=1)
def sigmoid_table() -> np.ndarray:
    """``(6, 2 * SIGMOID_RANGE * SIGMOID_GRID + 1)`` float32: at each grid point ``x`` of blood pressure,
    ``sigmoid(x - 6)`` computed in float64 as a float32 pair (rows 0 and 1: high and low parts), its first Taylor
    coefficient as a pair whose high part has 12 significant bits (rows 2 and 3), then the second and third
    coefficients (rows 4 and 5)."""
    x = np.arange(-SIGMOID_RANGE * SIGMOID_GRID, SIGMOID_RANGE * SIGMOID_GRID + 1) / SIGMOID_GRID
    sigmoid = 1.0 / (1.0 + np.exp(6.0 - x))
    first = sigmoid * (1.0 - sigmoid)
    high, first_high = sigmoid.astype(np.float32), _twelve_bits(first)
    rows = (high, sigmoid - high, first_high, first - first_high, first * (1.0 - 2.0 * sigmoid) / 2.0,
            first * (1.0 - 6.0 * first) / 6.0)  # fmt: skip
    return np.stack(rows).astype(np.float32)


def exact_sigmoid(pressure: jax.Array, table: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``sigmoid(pressure - 6)`` of float32 blood pressures, to about 1e-13 without float64: a float32 pair ``(high,
    low)``, `sigmoid_table`'s nearest point and a cubic in the exact distance ``d`` to it, whose largest part
    (the first coefficient's high part times ``d``'s high bits) float32 holds exactly. Beyond the table, float32's
    sigmoid and a low part of 0."""
    scaled = jnp.round(pressure * SIGMOID_GRID)  # exact: a power of two, then a whole number
    inside = jnp.abs(pressure) <= SIGMOID_RANGE
    index = jnp.clip(scaled.astype(jnp.int32) + SIGMOID_RANGE * SIGMOID_GRID, 0, table.shape[1] - 1)
    high, low, first_high, first_low, second, third = (table[row, index] for row in range(6))
    distance = pressure - scaled / SIGMOID_GRID  # exact: the low bits of the pressure
    near = jnp.round(distance * SPLIT) / SPLIT  # exact, and 12 bits at most
    large = first_high * near  # exact: 12 bits times 12 bits
    rest = first_low * near + (first_high + first_low) * (distance - near)
    rest = rest + distance * distance * (second + distance * third)
    total = high + large  # Knuth's two-sum: high + large is total + error exactly
    part = total - high
    error = (high - (total - part)) + (large - part)
    outside = 1.0 / (1.0 + jnp.exp(6.0 - pressure))
    return jnp.where(inside, total, outside), jnp.where(inside, error + (low + rest), jnp.float32(0.0))


def _add_pair(high: jax.Array, low: jax.Array, value: jax.Array, value_low: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The float32 pair ``high + low`` plus the pair ``value + value_low`` (Knuth's two-sum, then renormalised)."""
    total = high + value
    part = total - high
    error = (high - (total - part)) + (value - part)
    low = low + (error + value_low)
    new = total + low
    return new, low - (new - total)


def rollout(
    env: HeartPoleJax, params: EnvParams, act: Act, start: Start, key: jax.Array
) -> tuple[Totals, jax.Array, ActionCheck]:
    """Every episode of ``start`` played to its end by ``act``, drawing from its generator state: ``(totals,
    scores, check)``, the per-episode `Totals`, final scores and the `ActionCheck` of ``act``'s actions (the
    results mean nothing where ``check.found``: the caller refuses them). Traceable: ``jit`` it (and ``vmap``
    over ``act``'s parameters to evaluate several policies at once)."""
    n, num_variables = start.person.shape[0], env.num_variables
    zeros = (jnp.float32(0.0),) * num_variables
    drinks = jnp.asarray([a.is_drink for a in env.dynamics.actions], dtype=jnp.int32)
    sleeps = jnp.asarray([a.sleeps for a in env.dynamics.actions], dtype=jnp.int32)
    _check_cohort(env)
    person = jnp.asarray(start.person, dtype=jnp.int32)
    state = EnvState(
        variables=tuple(jnp.asarray(start.variables[v]) for v in range(num_variables)),
        time=jnp.zeros(n, jnp.int32),
        person=person if env.population is not None else jnp.zeros((n, 0), jnp.int32),
        person_values=jnp.zeros((n, 0), jnp.float32),  # a cohort's person is their index
        seen=jnp.zeros((n, 0), jnp.float32),
        age=jnp.zeros((n, 0), jnp.float32),
    )
    key_low, key_high = (jnp.asarray(start.generators[row]) for row in (KEY_LOW, KEY_HIGH))

    def one_draw(low: jax.Array, high: jax.Array, counter: jax.Array) -> tuple[jax.Array, ...]:
        return tuple(RNG.draws(low, high, counter, zeros))

    draw = jax.vmap(one_draw)
    advance = jax.vmap(env.advance, in_axes=(None, 0, 0, None, 0))
    observe = jax.vmap(env.get_obs)

    num_actions = len(env.dynamics.actions)

    def step(
        carry: tuple[EnvState, jax.Array, Totals, ActionCheck], t: jax.Array
    ) -> tuple[tuple[EnvState, jax.Array, Totals, ActionCheck], None]:
        state, counter, totals, check = carry
        actions = act(observe(state), start.max_steps - t, person, jax.random.fold_in(key, t))
        low, high = jnp.min(actions), jnp.max(actions)
        first = ((low < 0) | (high >= num_actions)) & ~check.found
        check = ActionCheck(check.found | first, jnp.where(first, low, check.low), jnp.where(first, high, check.high))
        uniforms = draw(key_low, key_high, counter)
        _, state, reward, _, info = advance(key, state, actions, params, uniforms)
        returns, returns_error = _kahan(totals.returns, totals.returns_error, reward)
        attack, zero = info["heart_attack"], jnp.float32(0.0)
        high, low = exact_sigmoid(state.variables[HYPERTENSION], table)
        high, low = jnp.where(attack, zero, high), jnp.where(attack, zero, low)
        sigmoids, sigmoids_low = _add_pair(totals.sigmoids, totals.sigmoids_low, high, low)
        risk = jnp.where(attack, info["heart_attack_risk"], zero)
        attack_risks = _kahan(totals.attack_risks, totals.attack_risks_error, risk)
        totals = Totals(returns, returns_error, sigmoids, sigmoids_low, *attack_risks, totals.attacks + attack,
                        totals.drinks + drinks[actions], totals.sleeps + sleeps[actions])  # fmt: skip
        return (state, counter + jnp.uint32(1), totals, check), None

    floats, ints = jnp.zeros(n, jnp.float32), jnp.zeros(n, jnp.int32)
    counter = jnp.asarray(start.generators[COUNTER])
    check = ActionCheck(jnp.bool_(False), jnp.int32(0), jnp.int32(0))
    table = jnp.asarray(sigmoid_table())
    carry = (state, counter, Totals(floats, floats, floats, floats, floats, floats, ints, ints, ints), check)
    (state, _, totals, check), _ = jax.lax.scan(step, carry, jnp.arange(start.max_steps, dtype=jnp.int32))
    return totals, MODEL.score(state.variables[WORK_DONE], state.variables[TIME_ELAPSED]), check


def policy_key(seed: int) -> int:
    """The seed of the JAX key a random policy draws from: ``seed`` itself below 2**63 (what ``jax.random.key``
    takes), and for larger seeds (which ``heartpole.evaluate`` accepts too) 63 bits derived from it."""
    if seed < 2**63:
        return seed
    high, low = (int(x) for x in np.random.SeedSequence(seed).generate_state(2, np.uint32))
    return ((high << 32) | low) & (2**63 - 1)


def _check_cohort(env: HeartPoleJax) -> None:
    """Refuse a distribution of people: their values are drawn by the NumPy env's generator."""
    if env.population is not None and env.population.cohort_values is None:
        raise ValueError(
            "heartpole.jax.evaluate plays the people of a cohort (people='default' or People(cohort=[...])); a "
            "distribution's people are drawn by the NumPy env: evaluate them with heartpole.evaluate"
        )


def _act(
    policy: str | JaxPolicy, env_id: str, env_kwargs: Mapping[str, Any], num_actions: int, name: str | None = None
) -> tuple[Act, str]:
    """``policy`` as an `Act` and its display name (``name`` if given). The actions' shape and dtype are checked
    as the policy is traced (``ValueError`` with NumPy's evaluation's message); their values by
    [`rollout`][heartpole.jax.evaluation.rollout]'s `ActionCheck`."""
    if isinstance(policy, str):
        return builtin_act(policy, env_id, env_kwargs), policy
    if not callable(policy):
        raise ValueError(f"policy must be a JAX function of observation batches or a built-in name, got {policy!r}")
    wants_left = bool(getattr(policy, "needs_decisions_left", False))
    label = policy_name(policy) if name is None else name

    def act(obs: jax.Array, left: jax.Array, person: jax.Array, key: jax.Array) -> jax.Array:
        raw = policy(obs, left) if wants_left else policy(obs)
        actions, size = jnp.asarray(raw), obs.shape[0]
        shape, dtype = tuple(getattr(raw, "shape", actions.shape)), _dtype(raw, actions)  # as NumPy sees them
        if shape != (size,):
            raise ValueError(invalid_actions(label, size, num_actions, shape=shape))
        if dtype.kind not in "iu":
            raise ValueError(invalid_actions(label, size, num_actions, dtype=dtype))
        return actions.astype(jnp.int32)

    return act, label


def _dtype(raw: object, actions: jax.Array) -> np.dtype[Any]:
    """The dtype of a policy's return as ``numpy.asarray`` gives it (float64 for a list of floats, where JAX
    would say float32), so that the refusal names what NumPy's evaluation names."""
    dtype = getattr(raw, "dtype", None)
    if dtype is None:
        try:
            dtype = np.asarray(raw).dtype
        except Exception:  # noqa: BLE001 - a list holding traced values: JAX's own dtype
            dtype = actions.dtype
    return np.dtype(dtype)


def evaluate(
    policy: str | JaxPolicy,
    env_id: str = "HeartPole-v0",
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    *,
    num_envs: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    regret: bool = True,
) -> EvaluationResult:
    """[`heartpole.evaluate`][heartpole.evaluation.evaluate] of a JAX policy, its episodes played on the JAX device
    in one compiled call; the arguments and the result are ``heartpole.evaluate``'s, and so, for a deterministic
    policy, are the episodes (``num_envs`` fixes the chunks whose seeds start them, as there).

    Raises:
        ValueError: bad arguments, an unknown built-in, a policy returning invalid actions (refused as
            ``heartpole.evaluate`` refuses them, with its message, before any result is made), an env with
            ``measurement`` (its noise is the NumPy env's) or with a distribution of people.

    >>> from heartpole.jax import evaluate
    >>> result = evaluate("expert", episodes=20, env_kwargs={"max_steps": 100})
    >>> result.policy, result.episodes, result.max_steps
    ('expert', 20, 100)
    """
    return evaluate_batch(policy, None, env_id, episodes, seed, num_envs=num_envs, env_kwargs=env_kwargs,
                          regret=regret)[0]  # fmt: skip


def evaluate_batch(
    policy: str | JaxPolicy,
    batch: Any,
    env_id: str = "HeartPole-v0",
    episodes: int = DEFAULT_EPISODES,
    seed: int = 0,
    *,
    num_envs: int | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    regret: bool = True,
    names: list[str] | None = None,
) -> list[EvaluationResult]:
    """`evaluate` of ``policy(batch[i], obs)`` for every ``i`` along the first axis of the pytree ``batch`` (a
    batch of seeds' networks, say), all in one compiled call and each on the same episodes; ``batch=None``
    evaluates ``policy`` itself once. ``names`` name the results (default: the policy's name, with ``[i]``)."""
    episodes, seed = check_integer("episodes", episodes, 1), check_integer("seed", seed, 0)
    chunk = min(episodes, DEFAULT_NUM_ENVS if num_envs is None else check_integer("num_envs", num_envs, 1))
    env_kwargs = dict(env_kwargs or {})
    if env_kwargs.get("measurement") is not None:
        raise ValueError(
            "heartpole.jax.evaluate plays envs without measurement (a measured env's noise is the NumPy env's own): "
            "evaluate it with heartpole.evaluate"
        )
    env = HeartPoleJax.from_id(env_id, **env_kwargs)
    truth = people_truth(env_id, env_kwargs) if regret else None
    solution = optimum_or_reason(env_id, env_kwargs) if regret else None
    start = Start.of(env_id, env_kwargs, episodes, seed, chunk)
    started = time.perf_counter()
    key = jax.random.key(policy_key(seed))
    num_actions = len(env.dynamics.actions)
    if batch is None:
        act, name = _act(policy, env_id, env_kwargs, num_actions)
        outputs = jax.jit(lambda: rollout(env, env.default_params, act, start, key))()
        totals, scores, check = jax.tree_util.tree_map(lambda x: x[None], outputs)
        labels = [name]
    else:
        name = policy if isinstance(policy, str) else policy_name(policy)

        def one(weights: Any) -> tuple[Totals, jax.Array, ActionCheck]:
            act, _ = _act(lambda obs: policy(weights, obs), env_id, env_kwargs, num_actions, name)  # type: ignore[operator]
            return rollout(env, env.default_params, act, start, key)

        totals, scores, check = jax.jit(jax.vmap(one))(batch)
        labels = names or [f"{name}[{i}]" for i in range(int(scores.shape[0]))]
    totals, scores, check = jax.device_get((totals, scores, check))
    for found, low, high in zip(*check):
        if found:
            raise ValueError(invalid_actions(name, start.person.shape[0], num_actions, low=low, high=high))
    seconds = (time.perf_counter() - started) / len(labels)
    penalty = env.dynamics.params.heart_attack_penalty
    results = []
    for i, label in enumerate(labels):
        score = np.asarray(scores[i], dtype=np.float64)
        risks = episode_risks(totals, i, start.proclivity)
        found = Episodes(
            returns=np.asarray(totals.returns[i], dtype=np.float64),
            expected_returns=expected_risk(score, risks, penalty),
            scores=score,
            heart_attacks=np.asarray(totals.attacks[i], dtype=np.int64),
            expected_heart_attacks=risks,
            drinks=np.asarray(totals.drinks[i], dtype=np.int64),
            sleeps=np.asarray(totals.sleeps[i], dtype=np.int64),
            person=start.person,
        )
        about = {"policy": label, "env_id": env_id, "seed": seed, "num_envs": chunk, "max_steps": start.max_steps}
        results.append(summarise(found, truth, solution, seconds=seconds, **about))
    return results


def episode_risks(totals: Totals, i: int, proclivity: np.ndarray) -> np.ndarray:
    """The summed heart-attack risks of the episodes of policy ``i`` of ``totals``, in float64: the proclivity
    times the summed sigmoids, and the risks of the steps with an attack."""
    sigmoids = np.asarray(totals.sigmoids[i], dtype=np.float64) + np.asarray(totals.sigmoids_low[i], dtype=np.float64)
    attacks = np.asarray(totals.attack_risks[i], dtype=np.float64)
    return np.asarray(proclivity, dtype=np.float64) * sigmoids + attacks
