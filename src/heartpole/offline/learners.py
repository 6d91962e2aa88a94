"""Offline RL from a HeartPole dataset: behaviour cloning and discrete conservative Q-learning (PyTorch).

Both learn from [`Trajectories`][heartpole.offline.trajectories.Trajectories] alone (no env steps) and return a
[`NetworkPolicy`][heartpole.offline.learners.NetworkPolicy], a plain policy callable that
[`heartpole.evaluate`][heartpole.evaluation.evaluate] scores with the standard protocol. Needs PyTorch (``pip install
heartpole[train]``).

* [`behaviour_cloning`][heartpole.offline.learners.behaviour_cloning]: a small MLP classifier of the logged actions; it
  imitates the behaviour's most likely action, so it removes epsilon-noise but cannot beat the behaviour's base policy.
* [`conservative_q_learning`][heartpole.offline.learners.conservative_q_learning]: discrete CQL (Kumar et al. 2020):
  Q-learning whose loss adds ``alpha * (logsumexp_a Q(s, a) - Q(s, a_data))``, pushing down the values of actions the
  data never tried, so the greedy policy stays where the data can vouch for it.

Rewards: by default the expected-risk rewards (each heart-attack coin replaced by its logged
probability, [`Trajectories.expected_rewards`][heartpole.offline.trajectories.Trajectories.expected_rewards]): the
same expectation, without the -100 spikes that drown the productivity signal. Observations are standardised with the
dataset's mean and deviation."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import torch

from heartpole.offline.trajectories import Trajectories


class NetworkPolicy:
    """Greedy actions of a small PyTorch network on standardised observations (a plain policy callable).

    Args:
        network: maps standardised observations ``(n, obs_dim)`` to action scores ``(n, num_actions)``.
        mean: the observation mean used for standardising.
        scale: the observation deviation used for standardising.
        name: the policy's name in results tables.
    """

    def __init__(self, network: torch.nn.Module, mean: np.ndarray, scale: np.ndarray, name: str) -> None:
        self.network, self.mean, self.scale, self.name = network, mean, scale, name

    def scores(self, obs: np.ndarray) -> np.ndarray:
        """``(n, num_actions)``: the network's scores (logits for BC, Q-values for CQL)."""
        import torch

        with _one_thread(), torch.no_grad():
            x = torch.as_tensor((np.asarray(obs, dtype=np.float32) - self.mean) / self.scale)
            return self.network(x).numpy()

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.scores(obs).argmax(axis=1).astype(np.int64)


@dataclass(frozen=True)
class TrainingLog:
    """The loss every ``every`` updates, to check that training went somewhere."""

    losses: list[float]
    every: int


def behaviour_cloning(
    data: Trajectories,
    steps: int = 3000,
    batch_size: int = 512,
    hidden: int = 64,
    learning_rate: float = 1e-3,
    seed: int = 0,
) -> tuple[NetworkPolicy, TrainingLog]:
    """Fit an MLP to the logged (observation, action) pairs by cross-entropy; act greedily."""
    import torch

    obs, actions, *_ = _transitions(data)
    mean, scale = _standardiser(data)
    with _one_thread():
        network = _mlp(obs.shape[1], data.num_actions, hidden, seed)
        optimiser = torch.optim.Adam(network.parameters(), lr=learning_rate)
        x, y = torch.as_tensor((obs - mean) / scale), torch.as_tensor(actions)
        rng = np.random.default_rng(seed)
        losses = []
        for step in range(steps):
            batch = torch.as_tensor(rng.integers(0, len(x), batch_size))
            loss = torch.nn.functional.cross_entropy(network(x[batch]), y[batch])
            optimiser.zero_grad()
            loss.backward()  # type: ignore[no-untyped-call]  # torch leaves Tensor.backward unannotated
            optimiser.step()
            if step % 100 == 0:
                losses.append(loss.item())
    return NetworkPolicy(network.eval(), mean, scale, "bc"), TrainingLog(losses, 100)


def conservative_q_learning(
    data: Trajectories,
    gamma: float = 0.99,
    alpha: float = 1.0,
    steps: int = 5000,
    batch_size: int = 512,
    hidden: int = 64,
    learning_rate: float = 3e-4,
    target_every: int = 250,
    expected_rewards: bool = True,
    seed: int = 0,
) -> tuple[NetworkPolicy, TrainingLog]:
    """Discrete CQL: double-Q-free DQN targets from a periodically copied network, plus the CQL penalty.

    Args:
        data: the dataset's episodes.
        gamma: the discount.
        alpha: the weight of the conservative penalty (0 gives plain offline DQN).
        steps: gradient updates.
        batch_size: transitions per update.
        hidden: units in each of the two hidden layers.
        learning_rate: Adam's step size.
        target_every: updates between copies of the network into the target network.
        expected_rewards: learn from the expected-risk rewards (see the module docstring).
        seed: the seed of the initial weights and of the minibatches.
    """
    import copy

    import torch

    obs, actions, rewards, next_obs, last = _transitions(data, expected_rewards)
    mean, scale = _standardiser(data)
    with _one_thread():
        network = _mlp(obs.shape[1], data.num_actions, hidden, seed)
        target = copy.deepcopy(network)
        optimiser = torch.optim.Adam(network.parameters(), lr=learning_rate)
        x, x_next = torch.as_tensor((obs - mean) / scale), torch.as_tensor((next_obs - mean) / scale)
        a, r = torch.as_tensor(actions), torch.as_tensor(rewards, dtype=torch.float32)
        carry = torch.as_tensor(~last, dtype=torch.float32)
        rng = np.random.default_rng(seed)
        losses = []
        for step in range(steps):
            batch = torch.as_tensor(rng.integers(0, len(x), batch_size))
            q = network(x[batch])
            q_taken = q.gather(1, a[batch, None])[:, 0]
            with torch.no_grad():
                bootstrap = target(x_next[batch]).max(dim=1).values
                goal = r[batch] + gamma * carry[batch] * bootstrap
            td = torch.nn.functional.smooth_l1_loss(q_taken, goal)
            conservative = (torch.logsumexp(q, dim=1) - q_taken).mean()
            loss = td + alpha * conservative
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            if (step + 1) % target_every == 0:
                target.load_state_dict(network.state_dict())
            if step % 100 == 0:
                losses.append(loss.item())
    return NetworkPolicy(network.eval(), mean, scale, f"cql(alpha={alpha:g})"), TrainingLog(losses, 100)


def _transitions(data: Trajectories, expected_rewards: bool = True) -> tuple[np.ndarray, ...]:
    """Flat ``(obs, action, reward, next_obs, last)`` arrays of every step."""
    dim = data.observations.shape[2]
    obs = data.observations[:, :-1].reshape(-1, dim)
    next_obs = data.observations[:, 1:].reshape(-1, dim)
    rewards = (data.expected_rewards() if expected_rewards else data.rewards).reshape(-1)
    last = np.zeros(data.actions.shape, dtype=bool)
    last[:, -1] = True
    return obs, data.actions.reshape(-1), rewards.astype(np.float32), next_obs, last.reshape(-1)


def _standardiser(data: Trajectories) -> tuple[np.ndarray, np.ndarray]:
    flat = data.observations.reshape(-1, data.observations.shape[2]).astype(np.float64)
    scale = flat.std(axis=0)
    scale[scale == 0] = 1.0
    return flat.mean(axis=0).astype(np.float32), scale.astype(np.float32)


def _mlp(inputs: int, outputs: int, hidden: int, seed: int) -> torch.nn.Sequential:
    """Two hidden ReLU layers, initialised from ``seed`` without touching PyTorch's global generator."""
    import torch

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        return torch.nn.Sequential(
            torch.nn.Linear(inputs, hidden),
            torch.nn.ReLU(),
            torch.nn.Linear(hidden, hidden),
            torch.nn.ReLU(),
            torch.nn.Linear(hidden, outputs),
        )


@contextlib.contextmanager
def _one_thread() -> Iterator[None]:
    """PyTorch on one thread (small networks; a shared 2-core machine), its setting restored after."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)
