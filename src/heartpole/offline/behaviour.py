"""Action probabilities of policies: what importance sampling needs from a behaviour and a target policy.

HeartPole's policies ([`heartpole.policies.Policy`][heartpole.policies.Policy]) return actions, not probabilities. This
module gives every policy that [`heartpole.evaluate`][heartpole.evaluation.evaluate] accepts a probability table ``(n,
num_actions)``:

* a policy object with an ``action_probabilities(obs)`` method says its own probabilities;
* the built-in ``random`` policy is uniform;
* any other policy is taken to be deterministic: probability 1 on the action it returns. A policy that
  returns different actions for the same observations without an ``action_probabilities`` method is
  rejected (its propensities would be wrong).

[`EpsilonGreedy`][heartpole.offline.behaviour.EpsilonGreedy] (a policy mixed with epsilon-uniform random actions) and
[`Mixture`][heartpole.offline.behaviour.Mixture] (at each step, one of several policies drawn with fixed weights) are
themselves policies with known probabilities, so they can be recorded, used as targets, and evaluated with
[`heartpole.evaluate`][heartpole.evaluation.evaluate]."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from heartpole.parameters import check_number
from heartpole.policies import Policy, RandomPolicy, policy_name
from heartpole.rollout import check_actions as check_actions


def action_probabilities(policy: Policy, obs: np.ndarray, num_actions: int) -> np.ndarray:
    """The probabilities ``(n, num_actions)`` float64 with which ``policy`` picks each action in ``obs``.

    Raises:
        ValueError: if the policy returns invalid actions, returns probabilities that are not a
            distribution, or acts at random without saying its probabilities.
    """
    obs = np.asarray(obs)
    size, name = len(obs), policy_name(policy)
    method = getattr(policy, "action_probabilities", None)
    if callable(method):
        probs = np.asarray(method(obs), dtype=np.float64)
        if probs.shape != (size, num_actions):
            raise ValueError(
                f"policy {name!r} gave probabilities of shape {probs.shape}, expected {(size, num_actions)}"
            )
        if (probs < 0).any() or not np.allclose(probs.sum(axis=1), 1.0, atol=1e-6):
            raise ValueError(f"policy {name!r} gave probabilities that are negative or do not sum to 1")
        return probs
    if isinstance(policy, RandomPolicy):
        if policy.num_actions != num_actions:
            raise ValueError(f"policy {name!r} draws among {policy.num_actions} actions, the env has {num_actions}")
        return np.full((size, num_actions), 1.0 / num_actions)
    actions = check_actions(policy(obs), size, num_actions, name)
    return one_hot(actions, num_actions)


def check_deterministic(policy: Policy, obs: np.ndarray) -> None:
    """Raise ``ValueError`` if ``policy`` (without ``action_probabilities``) acts at random on ``obs``."""
    if callable(getattr(policy, "action_probabilities", None)) or isinstance(policy, RandomPolicy):
        return
    if not np.array_equal(np.asarray(policy(obs)), np.asarray(policy(obs))):
        raise ValueError(
            f"policy {policy_name(policy)!r} acts at random but has no action_probabilities(obs) method; "
            "give it one so that its propensities are known"
        )


def one_hot(actions: np.ndarray, num_actions: int) -> np.ndarray:
    """``(n, num_actions)`` float64 with 1 at each row's action."""
    probs = np.zeros((len(actions), num_actions))
    probs[np.arange(len(actions)), actions] = 1.0
    return probs


def sample(probs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One action per row of ``probs`` drawn with ``rng`` (inverse CDF on one uniform per row)."""
    cumulative = np.cumsum(probs, axis=1)
    u = rng.random(len(probs))[:, None] * cumulative[:, -1:]
    return np.minimum((cumulative <= u).sum(axis=1), probs.shape[1] - 1)


class EpsilonGreedy:
    """``policy``'s action with probability ``1 - epsilon``, else a uniformly random action (any of them).

    Its probabilities are ``(1 - epsilon) * p(a | s) + epsilon / num_actions`` with ``p`` the base policy's
    (see [`action_probabilities`][heartpole.offline.behaviour.EpsilonGreedy.action_probabilities]). Calling it samples
    actions with its own generator.

    Args:
        policy: the base policy.
        epsilon: the share of uniformly random actions, in [0, 1].
        num_actions: the env's number of actions.
        rng: generator or seed for the sampling (default 0).
    """

    def __init__(self, policy: Policy, epsilon: float, num_actions: int, rng: np.random.Generator | int | None = None):
        self.policy, self.epsilon, self.num_actions = policy, check_epsilon(epsilon), int(num_actions)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)
        self.name = f"{policy_name(policy)}-eps{round(100 * self.epsilon)}"

    def action_probabilities(self, obs: np.ndarray) -> np.ndarray:
        """``(1 - epsilon)`` times the base policy's probabilities plus ``epsilon`` spread evenly."""
        base = action_probabilities(self.policy, obs, self.num_actions)
        return (1.0 - self.epsilon) * base + self.epsilon / self.num_actions

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return sample(self.action_probabilities(obs), self.rng)


class Mixture:
    """At every step, one of ``policies`` chosen at random with ``weights``: a ward of several clinicians.

    Args:
        policies: the component policies.
        weights: their probabilities (default: equal); normalised to sum to 1.
        num_actions: the env's number of actions.
        rng: generator or seed for the sampling (default 0).
        name: the display name (default: the components' names joined with ``+``).
    """

    def __init__(
        self,
        policies: Sequence[Policy],
        num_actions: int,
        weights: Sequence[float] | None = None,
        rng: np.random.Generator | int | None = None,
        name: str | None = None,
    ) -> None:
        if not policies:
            raise ValueError("a mixture needs at least one policy")
        shares = np.ones(len(policies)) if weights is None else np.asarray(weights, dtype=np.float64)
        if shares.shape != (len(policies),) or (shares < 0).any() or shares.sum() <= 0:
            raise ValueError(f"weights must be {len(policies)} non-negative numbers with a positive sum")
        self.policies, self.weights, self.num_actions = list(policies), shares / shares.sum(), int(num_actions)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(0 if rng is None else rng)
        self.name = name or "+".join(policy_name(p) for p in self.policies)

    def action_probabilities(self, obs: np.ndarray) -> np.ndarray:
        """The weighted sum of the components' probabilities."""
        return sum(w * action_probabilities(p, obs, self.num_actions) for p, w in zip(self.policies, self.weights))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return sample(self.action_probabilities(obs), self.rng)


def check_epsilon(epsilon: Any) -> float:
    """``epsilon`` as a float in [0, 1], or ``ValueError`` (a bool or a string is no number)."""
    return check_number("epsilon", epsilon, 0.0, 1.0)
