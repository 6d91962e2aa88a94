"""The built-in policies as JAX functions, for [`heartpole.jax.evaluate`][heartpole.jax.evaluation.evaluate].

Each is the NumPy built-in of the same name ([`heartpole.policies`][heartpole.policies]) read for its numbers (the
expert's rate and nap thresholds, the optimum's sleep thresholds, the actions' indices), so no number of a rule is
written twice; only the few lines that apply them are, on ``jax.numpy``. Every one is an `Act`: a function of the
observations, the decisions left, each env's person and a key.

Deterministic built-ins choose the NumPy built-ins' very actions for the same observations (the sleep-timing optimum's
float64 thresholds are rounded up to float32, which decides every float32 alertness alike; the history-aware optimum,
which ``optimal`` and ``oracle`` play up to 3,000 decisions, is the NumPy policy called from JAX). ``random`` draws
from ``key``, so its actions are not the NumPy ``random``'s.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from heartpole.jax.traced import MODEL
from heartpole.model import ALERTNESS, TIME_ELAPSED, TIME_SINCE_SLEPT
from heartpole.policies import BUILTIN_POLICIES, load_policy
from heartpole.policies.builtins import ConstantPolicy, ExpertPolicy, OptimalPolicy, RandomPolicy, ReferencePolicy
from heartpole.policies.oracle import OraclePolicy

Act = Callable[[jax.Array, jax.Array, jax.Array, jax.Array], jax.Array]
"""``act(obs, decisions_left, person, key) -> actions``: ``obs`` ``(n, obs_dim)`` float32, ``decisions_left``
an int32 number (every env is at the same step), ``person`` ``(n,)`` int32 (cohort indices, -1 without),
``key`` a JAX key for this step; the actions ``(n,)`` int32."""


def builtin_act(name: str, env_id: str, env_kwargs: Mapping[str, Any]) -> Act:
    """The built-in policy ``name`` of ``env_id`` made with ``env_kwargs``, as an `Act`.

    Raises:
        ValueError: an unknown name (listing the built-ins), or a policy that cannot act in the env (``optimal``
            where the optimum is not covered, ``oracle`` without a cohort of people).
    """
    if name not in BUILTIN_POLICIES:
        raise ValueError(f"unknown policy {name!r}; built-in policies are {', '.join(BUILTIN_POLICIES)}")
    policy = load_policy(name, env_id, env_kwargs=dict(env_kwargs))
    if isinstance(policy, RandomPolicy):
        return _random(policy.num_actions)
    if isinstance(policy, ConstantPolicy):
        return _constant(policy.action)
    if isinstance(policy, ReferencePolicy):
        return _reference(policy)
    if isinstance(policy, ExpertPolicy):
        return _expert(policy)
    if isinstance(policy, OptimalPolicy):
        solution = policy.solution
        if solution.history is not None:
            return _on_host(lambda obs, left, person: policy(obs, left))
        thresholds = _rounded_up(solution.thresholds[None])
        return _thresholds(thresholds, np.array([solution.max_awake]), policy.sleep, policy.nothing, personal=False)
    if isinstance(policy, OraclePolicy):
        optimum = policy.optimum
        if any(s.history is not None for s in optimum.solutions):
            return _on_host(lambda obs, left, person: policy(obs, left, person=person))
        return _thresholds(_rounded_up(optimum.thresholds), optimum.max_awake, policy.sleep, policy.nothing, True)
    raise ValueError(f"the built-in policy {name!r} has no JAX version")  # pragma: no cover - every built-in has


def _on_host(decide: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]) -> Act:
    """A NumPy policy called from JAX (``jax.pure_callback``): the history-aware optimum's decisions compare values
    of lines in float64, which float32 arithmetic would decide otherwise near ties, so the JAX ``optimal`` and
    ``oracle`` call the NumPy policy itself on the same float32 observations and choose its very actions (a host
    round trip each step: slower than a traced rule, on an accelerator most of all)."""

    def on_host(obs: np.ndarray, left: np.ndarray, person: np.ndarray) -> np.ndarray:
        actions = decide(np.asarray(obs), np.full(len(obs), int(left)), np.asarray(person))
        return np.asarray(actions, dtype=np.int32)

    def act(obs: jax.Array, left: jax.Array, person: jax.Array, key: jax.Array) -> jax.Array:
        shape = jax.ShapeDtypeStruct((obs.shape[0],), jnp.int32)
        return jax.pure_callback(on_host, shape, obs, left, person)

    return act


def _rounded_up(thresholds: np.ndarray) -> jax.Array:
    """float64 thresholds as the smallest float32 at or above each: ``a < t`` and ``a < up(t)`` agree for every
    float32 ``a``, so the float32 comparison decides as NumPy's float64 one."""
    low = thresholds.astype(np.float32)
    return jnp.asarray(np.where(low < thresholds, np.nextafter(low, np.float32(np.inf)), low))


def _random(num_actions: int) -> Act:
    def act(obs: jax.Array, left: jax.Array, person: jax.Array, key: jax.Array) -> jax.Array:
        return jax.random.randint(key, (obs.shape[0],), 0, num_actions, dtype=jnp.int32)

    return act


def _constant(action: int) -> Act:
    def act(obs: jax.Array, left: jax.Array, person: jax.Array, key: jax.Array) -> jax.Array:
        return jnp.full(obs.shape[0], action, dtype=jnp.int32)

    return act


def _reference(policy: ReferencePolicy) -> Act:
    """[`ReferencePolicy`][heartpole.policies.builtins.ReferencePolicy]'s cycle: coffee, work, sleep."""

    def act(obs: jax.Array, left: jax.Array, person: jax.Array, key: jax.Array) -> jax.Array:
        since = obs[:, TIME_SINCE_SLEPT].astype(jnp.int32)
        phase = since - (obs[:, TIME_ELAPSED] > obs[:, TIME_SINCE_SLEPT]).astype(jnp.int32)
        actions = jnp.where(phase == 0, policy.coffee, policy.nothing)
        return jnp.where(phase >= policy.cycle - 1, policy.sleep, actions).astype(jnp.int32)

    return act


def _expert(policy: ExpertPolicy) -> Act:
    """[`ExpertPolicy`][heartpole.policies.builtins.ExpertPolicy]'s rule itself (`ExpertPolicy.rule`), on ``jax.numpy``:
    sleep when the coming half-hour earns less than its rate; nap (where the variant has v1's nap) while sleepy."""

    def act(obs: jax.Array, left: jax.Array, person: jax.Array, key: jax.Array) -> jax.Array:
        return policy.rule(obs, MODEL.productivity, jnp.where).astype(jnp.int32)

    return act


def _thresholds(table: jax.Array, max_awake: np.ndarray, sleep: int, nothing: int, personal: bool) -> Act:
    """The optimum's rule ([`OptimumSolution.sleeps`][heartpole.optimum.solution.OptimumSolution.sleeps]): sleep
    once awake ``max_awake`` half-hours or when alertness is below the threshold of (decisions left, half-hours
    awake); ``table`` is ``(people, decisions left, half-hours awake)`` (one person unless ``personal``)."""
    longest = jnp.asarray(max_awake, dtype=jnp.int32)

    def act(obs: jax.Array, left: jax.Array, person: jax.Array, key: jax.Array) -> jax.Array:
        who = person if personal else jnp.zeros_like(person)
        awake = obs[:, TIME_SINCE_SLEPT].astype(jnp.int32)
        row = jnp.clip(left, 0, table.shape[1] - 1)
        threshold = table[who, row, jnp.minimum(awake, table.shape[2] - 1)]
        sleeps = (awake >= longest[who]) | (obs[:, ALERTNESS] < threshold)
        return jnp.where(sleeps, sleep, nothing).astype(jnp.int32)

    return act
