"""Off-policy evaluation: estimate a target policy's value from episodes a behaviour policy recorded.

All estimators estimate the discounted value from the start state, ``V = E[sum_t gamma^t r_t]``, the
quantity [`heartpole.offline.truth.true_value`][heartpole.offline.truth.true_value] measures. With ``w_t`` the product
of the importance ratios ``pi(a_k | s_k) / mu(a_k | s_k)`` for ``k <= t`` (``pi`` the target, ``mu`` the behaviour,
whose probabilities the dataset stores):

* **PDIS**, per-decision importance sampling (Precup et al. 2000): ``mean_i sum_t gamma^t w_it r_it``.
  Unbiased; its variance grows with the horizon.
* **WPDIS**, weighted per-decision importance sampling: each step's weights normalised over episodes,
  ``sum_t gamma^t sum_i w_it r_it / sum_i w_it``. Biased but consistent, far lower variance.
* **FQE**, fitted Q evaluation (Le et al. 2019) with a linear model: ``Q(s, a) = theta_a . z(s)`` over
  features of HeartPole's observations, solved in closed form at the fixed point of the
  evaluation Bellman equation (LSTD-Q, Lagoudakis & Parr 2003): what iterated FQE with linear regression
  converges to. ``V = mean_i sum_a pi(a | s_i0) Q(s_i0, a)``.
* **DR**, the per-decision doubly robust estimator (Jiang & Li 2016; Thomas & Brunskill 2016) with FQE's
  ``Q``: ``mean_i sum_t gamma^t (w_it (r_it - Q(s_it, a_it)) + w_i(t-1) V(s_it))``. Unbiased whatever
  ``Q`` is; a good ``Q`` removes most of the variance.

PDIS and DR come with a 95% Student-t interval over episodes (their per-episode terms are independent);
WPDIS and FQE with none.

A dataset recorded with ``people`` is evaluated against the truth over the same population: the target's true
value in the env with the dataset's ``people`` (and ``observe_traits``), and for a finite cohort its oracle
regret (see [`heartpole.offline.population`][heartpole.offline.population]).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from heartpole.model import (
    ALERTNESS,
    HYPERTENSION,
    INTOXICATION,
    TIME_ELAPSED,
    TIME_SINCE_SLEPT,
    WORK_DONE,
    alertness_decay,
    heart_attack_risk,
    productivity,
)
from heartpole.offline.behaviour import action_probabilities
from heartpole.offline.population import dataset_env_kwargs, people_truth_fields
from heartpole.offline.trajectories import Trajectories
from heartpole.offline.truth import DEFAULT_GAMMA, TrueValue, true_value
from heartpole.offline.weights import WeightDiagnostics, weight_diagnostics
from heartpole.policies import Policy, load_policy, policy_name
from heartpole.stats import confidence_interval, json_interval, json_number

ESTIMATORS = ("PDIS", "WPDIS", "FQE", "DR")
DEFAULT_RIDGE = 1e-6
NAN_PAIR = (math.nan, math.nan)
LOW_SUPPORT = 0.01
"""Below this share of a dataset's steps taking the target's action ([`support`][heartpole.offline.ope.support]),
[`estimate_all`][heartpole.offline.ope.estimate_all] warns that its estimates rest on almost nothing."""


@dataclass(frozen=True)
class Estimate:
    """One estimator's estimate of the target's discounted value, with its 95% interval if it has one."""

    estimator: str
    value: float
    ci95: tuple[float, float] = NAN_PAIR
    weights: WeightDiagnostics | None = None
    """What its importance weights leave to estimate with (PDIS, WPDIS, DR; ``None`` for FQE)."""


def target_probabilities(policy: Policy, trajectories: Trajectories, batch: int = 200_000) -> np.ndarray:
    """``(N, T + 1, num_actions)``: the target policy's probabilities at every observation of the dataset."""
    n, steps, dim = trajectories.observations.shape
    flat = trajectories.observations.reshape(-1, dim)
    probs = np.concatenate(
        [
            action_probabilities(policy, flat[i : i + batch], trajectories.num_actions)
            for i in range(0, len(flat), batch)
        ]
    )
    return probs.reshape(n, steps, trajectories.num_actions)


def importance_weights(target: np.ndarray, trajectories: Trajectories) -> np.ndarray:
    """``(N, T)``: cumulative importance weights ``w_t = prod_{k <= t} pi(a_k | s_k) / mu(a_k | s_k)``."""
    chosen = np.take_along_axis(target[:, :-1], trajectories.actions[..., None], axis=2)[..., 0]
    behaviour = trajectories.propensities
    if np.any((behaviour <= 0) & (chosen > 0)):
        raise ValueError("the dataset holds actions its behaviour policy gave probability 0")
    ratios = np.divide(chosen, behaviour, out=np.zeros_like(chosen), where=behaviour > 0)
    return np.cumprod(ratios, axis=1)


def pdis(weights: np.ndarray, rewards: np.ndarray, gamma: float) -> Estimate:
    """Per-decision importance sampling, with the t interval over episodes."""
    per_episode = (weights * rewards) @ _discounts(gamma, rewards.shape[1])
    return Estimate("PDIS", float(per_episode.mean()), confidence_interval(per_episode))


def wpdis(weights: np.ndarray, rewards: np.ndarray, gamma: float) -> Estimate:
    """Weighted per-decision importance sampling (steps whose weights are all 0 contribute 0)."""
    totals = weights.sum(axis=0)
    safe = np.where(totals > 0, totals, 1.0)
    per_step = np.where(totals > 0, (weights * rewards).sum(axis=0) / safe, 0.0)
    return Estimate("WPDIS", float(per_step @ _discounts(gamma, rewards.shape[1])))


def doubly_robust(
    weights: np.ndarray, rewards: np.ndarray, q_taken: np.ndarray, v: np.ndarray, gamma: float
) -> Estimate:
    """Per-decision doubly robust with ``q_taken`` ``(N, T)`` = Q(s_t, a_t) and ``v`` ``(N, T + 1)`` = V(s_t)."""
    previous = np.concatenate([np.ones((len(weights), 1)), weights[:, :-1]], axis=1)
    terms = weights * (rewards - q_taken) + previous * v[:, :-1]
    per_episode = terms @ _discounts(gamma, rewards.shape[1])
    return Estimate("DR", float(per_episode.mean()), confidence_interval(per_episode))


class LinearFQE:
    """Fitted Q evaluation with ``Q(s, a) = theta_a . z(s)``, solved at its fixed point (LSTD-Q).

    ``z(s)`` are standardised features of a HeartPole observation ([`features`][heartpole.offline.ope.features]). The
    last step of an episode has no successor (the time limit ends it): its target is its reward.

    Args:
        gamma: the discount.
        ridge: a small L2 penalty that keeps the linear system well posed.
        featurize: observations ``(n, obs_dim)`` -> features ``(n, d)`` whose first column is the constant 1
            (default: [`features`][heartpole.offline.ope.features]).
    """

    def __init__(
        self,
        gamma: float,
        ridge: float = DEFAULT_RIDGE,
        featurize: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self.gamma, self.ridge = float(gamma), float(ridge)
        self.featurize = featurize or features
        self.theta: np.ndarray | None = None
        self.mean: np.ndarray | None = None
        self.scale: np.ndarray | None = None

    def fit(self, trajectories: Trajectories, target: np.ndarray, rewards: np.ndarray) -> LinearFQE:
        """Solve for ``theta`` from the episodes, the target's probabilities and the rewards to evaluate."""
        n, steps = trajectories.actions.shape
        k = trajectories.num_actions
        raw = self.featurize(trajectories.observations.reshape(-1, trajectories.observations.shape[2]))
        self.mean, self.scale = raw.mean(axis=0), raw.std(axis=0)
        self.mean[0], self.scale[0] = 0.0, 1.0  # the constant feature stays 1
        self.scale[self.scale == 0] = 1.0
        z = ((raw - self.mean) / self.scale).reshape(n, steps + 1, -1)
        d = z.shape[2]
        a_matrix, b_vector = np.zeros((k * d, k * d)), np.zeros(k * d)
        for first in range(0, n, max(1, 200_000 // (steps + 1))):
            part = slice(first, first + max(1, 200_000 // (steps + 1)))
            now = _state_action(z[part, :-1], trajectories.actions[part], k)  # (m, k*d)
            after = (target[part, 1:, :, None] * z[part, 1:, None, :]).reshape(-1, steps, k * d)
            after[:, -1] = 0.0  # the episode ends after its last step
            after = after.reshape(-1, k * d)
            a_matrix += now.T @ (now - self.gamma * after)
            b_vector += now.T @ rewards[part].reshape(-1)
        a_matrix += self.ridge * len(trajectories.actions.reshape(-1)) * np.eye(k * d)
        self.theta = np.linalg.solve(a_matrix, b_vector).reshape(k, d)
        return self

    def q_values(self, observations: np.ndarray) -> np.ndarray:
        """``(..., num_actions)``: Q of every action at each observation."""
        if self.theta is None or self.mean is None or self.scale is None:
            raise RuntimeError("call fit() first")
        shape = observations.shape[:-1]
        z = (self.featurize(observations.reshape(-1, observations.shape[-1])) - self.mean) / self.scale
        return (z @ self.theta.T).reshape(*shape, -1)


def features(obs: np.ndarray) -> np.ndarray:
    """``(n, 15 + extras)`` float64 features of observations: what a step's reward and risk depend on.

    The reward is the change of score ``work_done / time_elapsed``, about ``(p - score) / time_elapsed``
    with ``p`` the coming half-hour's productivity, minus 100 for a heart attack whose probability
    follows hypertension. So the features are the score, ``p``, the risk, the state variables and their
    squares, and the score terms divided by ``time_elapsed + 1``; a variant's extra variables are appended.
    """
    obs = np.asarray(obs, dtype=np.float64)
    alert, tension, intox = obs[:, ALERTNESS], obs[:, HYPERTENSION], obs[:, INTOXICATION]
    awake, elapsed, work = obs[:, TIME_SINCE_SLEPT], obs[:, TIME_ELAPSED], obs[:, WORK_DONE]
    inverse = 1.0 / (elapsed + 1.0)
    score = work * inverse
    coming = productivity(alert, intox)
    columns = [
        np.ones(len(obs)),
        alert,
        alert**2,
        tension,
        tension**2,
        heart_attack_risk(tension),
        intox,
        awake / 48.0,
        (awake / 48.0) ** 2,
        alertness_decay(awake),
        score,
        coming,
        inverse,
        coming * inverse,
        score * inverse,
    ]
    extras = [obs[:, i] for i in range(max(WORK_DONE, TIME_ELAPSED) + 1, obs.shape[1])]
    return np.stack(columns + extras, axis=1)


def estimate_all(
    trajectories: Trajectories,
    policy: Policy,
    gamma: float,
    *,
    expected_rewards: bool = False,
    ridge: float = DEFAULT_RIDGE,
    featurize: Callable[[np.ndarray], np.ndarray] | None = None,
) -> list[Estimate]:
    """PDIS, WPDIS, FQE and DR estimates of ``policy``'s discounted value from ``trajectories``.

    Args:
        trajectories: the behaviour's episodes, with its propensities.
        policy: the target policy (deterministic, or with ``action_probabilities``).
        gamma: the discount, in (0, 1].
        expected_rewards: use the rewards with each heart-attack coin replaced by its probability
            (``Trajectories.expected_rewards``): same expectation, less noise.
        ridge: FQE's L2 penalty.
        featurize: FQE's features (default: [`features`][heartpole.offline.ope.features]).

    Warns:
        RuntimeWarning: when the dataset's actions are the target's at fewer than
            [`LOW_SUPPORT`][heartpole.offline.ope.LOW_SUPPORT] of its steps (never, for a target the behaviour never
            followed: an epsilon-0 dataset of another policy): the estimates then rest on almost nothing; and when
            the importance weights' effective sample size is too small or no episode keeps weight past a step
            ([`heartpole.offline.weights`][heartpole.offline.weights]; the estimates that weigh carry it).
    """
    if not 0.0 < float(gamma) <= 1.0:
        raise ValueError(f"gamma must be in (0, 1], got {gamma!r}")
    target = target_probabilities(policy, trajectories)
    weights = importance_weights(target, trajectories)
    _warn_on_support(target, trajectories)
    diagnostics = weight_diagnostics(weights, gamma)
    if diagnostics.warning is not None and support(target, trajectories) >= LOW_SUPPORT:  # else said already
        warnings.warn(diagnostics.warning, RuntimeWarning, stacklevel=2)
    rewards = trajectories.expected_rewards() if expected_rewards else trajectories.rewards
    fqe = LinearFQE(gamma, ridge, featurize).fit(trajectories, target, rewards)
    q = fqe.q_values(trajectories.observations)
    v = (q * target).sum(axis=2)
    q_taken = np.take_along_axis(q[:, :-1], trajectories.actions[..., None], axis=2)[..., 0]
    weighed = [pdis(weights, rewards, gamma), wpdis(weights, rewards, gamma)]
    weighed.append(doubly_robust(weights, rewards, q_taken, v, gamma))
    pdis_, wpdis_, dr = (replace(e, weights=diagnostics) for e in weighed)
    return [pdis_, wpdis_, Estimate("FQE", float(v[:, 0].mean())), dr]


def support(target: np.ndarray, trajectories: Trajectories) -> float:
    """The share of the dataset's steps whose recorded action the target policy takes with a positive probability
    (``target`` from [`target_probabilities`][heartpole.offline.ope.target_probabilities]): what the
    importance-sampling estimators have to weigh."""
    chosen = np.take_along_axis(target[:, :-1], trajectories.actions[..., None], axis=2)[..., 0]
    return float(np.mean(chosen > 0)) if chosen.size else 0.0


def _warn_on_support(target: np.ndarray, trajectories: Trajectories) -> None:
    share = support(target, trajectories)
    if share >= LOW_SUPPORT:
        return
    steps = trajectories.actions.size
    seen = "never took an action the target would take" if share == 0 else f"took the target's action at {share:.2%}"
    warnings.warn(
        f"the dataset {seen} ({steps:,} steps): importance sampling (PDIS, WPDIS, DR's correction) has "
        f"{'nothing' if share == 0 else 'almost nothing'} to weigh and FQE extrapolates, so these estimates say "
        "little; record a behaviour that explores (epsilon > 0) or one closer to the target",
        RuntimeWarning,
        stacklevel=3,
    )


@dataclass(frozen=True)
class OPEReport:
    """The estimates of one target policy's value from one dataset, beside the true value.

    For a dataset recorded with ``people``, ``truth`` is measured over the same population, ``people`` is the
    population (``People.to_dict()``) and ``oracle`` holds the target's ``oracle_regret`` and
    ``oracle_regret_ci95`` (a finite cohort) or its ``no_oracle_regret_reason``; both are empty without people.
    """

    dataset_id: str
    policy: str
    gamma: float
    expected_rewards: bool
    estimates: list[Estimate]
    truth: TrueValue
    people: dict[str, Any] = field(default_factory=dict)
    oracle: dict[str, Any] = field(default_factory=dict)

    def error(self, estimate: Estimate) -> float:
        """``estimate - truth`` (the truth's expected-risk discounted value)."""
        return estimate.value - self.truth.value

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: the estimates with their errors, and the truth."""
        return {
            "dataset_id": self.dataset_id,
            "policy": self.policy,
            "gamma": self.gamma,
            "expected_rewards": self.expected_rewards,
            "estimates": [
                {
                    "estimator": e.estimator,
                    "value": json_number(e.value),
                    "ci95": json_interval(e.ci95),  # null without an interval (a dataset of one episode)
                    "error": json_number(self.error(e)),
                    **_weights_dict(e.weights),
                }
                for e in self.estimates
            ],
            "truth": self.truth.to_dict(),
            "people": self.people or None,
            "oracle_regret": json_number(self.oracle.get("oracle_regret", math.nan)),
            "oracle_regret_ci95": json_interval(self.oracle.get("oracle_regret_ci95", NAN_PAIR)),
            "no_oracle_regret_reason": self.oracle.get(
                "no_oracle_regret_reason", None if self.people else "the dataset was recorded without people"
            ),
        }


def _weights_dict(weights: WeightDiagnostics | None) -> dict[str, Any]:
    """An estimate's weight diagnostics in its JSON (null for FQE, which weighs nothing)."""
    if weights is None:
        return {"effective_sample_size": None, "weight_horizon": None, "warning": None}
    ess = json_number(weights.effective_sample_size)
    return {"effective_sample_size": ess, "weight_horizon": weights.weight_horizon, "warning": weights.warning}


def evaluate_off_policy(
    dataset_id: str,
    policy: Policy | str,
    gamma: float = DEFAULT_GAMMA,
    *,
    truth_episodes: int = 2000,
    seed: int = 0,
    expected_rewards: bool = False,
) -> OPEReport:
    """Estimate ``policy``'s value from the local Minari dataset ``dataset_id`` and measure the truth.

    Args:
        dataset_id: a dataset recorded by ``heartpole dataset`` (in ``MINARI_DATASETS_PATH``).
        policy: the target: a policy callable, a built-in name or a model path.
        gamma: the discount, in (0, 1].
        truth_episodes: episodes for [`true_value`][heartpole.offline.truth.true_value] (and, under a finite
            cohort of people, for the oracle regret).
        seed: the seed of the truth's episodes and of a ``random`` target.
        expected_rewards: estimate from the expected-risk rewards (see
            [`estimate_all`][heartpole.offline.ope.estimate_all]).

    Raises:
        ValueError: an unknown dataset, a dataset without propensities, an unknown policy, bad gamma, a target
            that needs each step's person (``oracle``).
    """
    from heartpole.offline.datasets import load_local

    dataset = load_local(dataset_id)
    metadata = dataset.storage.metadata
    env_id, env_kwargs = str(metadata.get("env_id", "HeartPole-v0")), dataset_env_kwargs(metadata)
    trajectories = Trajectories.from_dataset(dataset)
    if isinstance(policy, str):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(1,)))
        target, name = load_policy(policy, env_id, env_kwargs=env_kwargs, rng=rng), policy
    else:
        target, name = policy, policy_name(policy)
    if getattr(target, "needs_person", False):
        raise ValueError(f"policy {name!r} needs each episode's person: off-policy evaluation estimates policies of "
                         "the observations only")  # fmt: skip
    estimates = estimate_all(trajectories, target, gamma, expected_rewards=expected_rewards)
    truth = true_value(policy, gamma, truth_episodes, env_id, seed, env_kwargs=env_kwargs)
    oracle = people_truth_fields(policy, truth_episodes, env_id, seed, env_kwargs)
    people = dict(metadata.get("people") or {})
    return OPEReport(dataset_id, name, float(gamma), expected_rewards, estimates, truth, people, oracle)


def _state_action(z: np.ndarray, actions: np.ndarray, k: int) -> np.ndarray:
    """Rows ``onehot(a) (x) z(s)`` for each (s, a): ``(m, k * d)``."""
    m, d = actions.size, z.shape[-1]
    out = np.zeros((m, k, d))
    out[np.arange(m), actions.reshape(-1)] = z.reshape(m, d)
    return out.reshape(m, k * d)


def _discounts(gamma: float, steps: int) -> np.ndarray:
    return float(gamma) ** np.arange(steps)


__all__ = [
    "ESTIMATORS",
    "Estimate",
    "LinearFQE",
    "OPEReport",
    "doubly_robust",
    "estimate_all",
    "evaluate_off_policy",
    "features",
    "importance_weights",
    "pdis",
    "target_probabilities",
    "wpdis",
]
