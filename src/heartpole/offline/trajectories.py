"""Whole episodes as arrays: what a behaviour policy did, with its propensities and the env's infos.

[`collect`][heartpole.offline.trajectories.collect] runs a behaviour policy on the native vector env and returns
[`Trajectories`][heartpole.offline.trajectories.Trajectories];
[`heartpole.offline.datasets`][heartpole.offline.datasets] writes them as a Minari dataset and
[`Trajectories.from_dataset`][heartpole.offline.trajectories.Trajectories.from_dataset] reads one back. The
off-policy estimators ([`heartpole.offline.ope`][heartpole.offline.ope]) and learners work on these arrays."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from heartpole.offline.behaviour import EpsilonGreedy, check_deterministic, sample
from heartpole.registry import heartpole_ids, quiet_version_warnings
from heartpole.rewards import expected_risk
from heartpole.rollout import base_env, check_actions, episode_steps, vector_env

_ARRAYS = (
    "observations",
    "actions",
    "rewards",
    "action_probabilities",
    "heart_attack_risk",
    "productivity",
    "heart_attack",
    "score",
)

if TYPE_CHECKING:
    from minari import MinariDataset

    from heartpole.env import HeartPole

INFO_KEYS = ("heart_attack_risk", "productivity", "heart_attack", "score")
PEOPLE_KEYS = ("person", "traits")
"""The infos of a dataset recorded with ``people``: each episode's person, repeated at every observation."""
_INFO_DTYPES = {"heart_attack_risk": np.float32, "productivity": np.float32, "heart_attack": bool, "score": np.float32}


@dataclass
class Trajectories:
    """``N`` episodes of ``T`` steps. Per-observation arrays have ``T + 1`` entries, per-action arrays ``T``.

    ``action_probabilities[n, t]`` is the behaviour's distribution at observation ``t``; the infos at
    ``t + 1`` are those the env returned for the step from ``t`` (index 0 is the reset, all zeros).
    ``penalty`` is the env's heart-attack penalty (100 in HeartPole). In an env with ``people``, ``person``
    ``(N,)`` int64 is each episode's person (cohort index, -1 for a distribution's) and ``traits``
    ``(N, len(people.traits))`` float32 their traits (the reset's ``info["person"]`` and ``info["traits"]``);
    both are ``None`` without people.
    """

    observations: np.ndarray  # (N, T + 1, obs_dim) float32
    actions: np.ndarray  # (N, T) int64
    rewards: np.ndarray  # (N, T) float64
    action_probabilities: np.ndarray  # (N, T + 1, num_actions) float64
    heart_attack_risk: np.ndarray  # (N, T + 1) float32
    productivity: np.ndarray  # (N, T + 1) float32
    heart_attack: np.ndarray  # (N, T + 1) bool
    score: np.ndarray  # (N, T + 1) float32
    penalty: float = 100.0
    person: np.ndarray | None = None  # (N,) int64, or None without people
    traits: np.ndarray | None = None  # (N, k) float32, or None without people

    @property
    def episodes(self) -> int:
        """The number of episodes ``N``."""
        return int(self.actions.shape[0])

    @property
    def steps(self) -> int:
        """The number of steps per episode ``T``."""
        return int(self.actions.shape[1])

    @property
    def num_actions(self) -> int:
        """The env's number of actions."""
        return int(self.action_probabilities.shape[2])

    @property
    def propensities(self) -> np.ndarray:
        """``(N, T)``: the behaviour's probability of each action it took."""
        return np.take_along_axis(self.action_probabilities[:, :-1], self.actions[..., None], axis=2)[..., 0]

    def expected_rewards(self) -> np.ndarray:
        """``(N, T)``: rewards with each heart-attack coin replaced by its probability (same expectation).

        ``reward + penalty * heart_attack - penalty * heart_attack_risk``: the coin's noise removed, as in
        the expected-risk estimate of [`heartpole.evaluate`][heartpole.evaluation.evaluate].
        """
        attacks = self.heart_attack[:, 1:].astype(np.float64)
        return cast(
            "np.ndarray",
            expected_risk(self.rewards, self.heart_attack_risk[:, 1:].astype(np.float64), self.penalty, attacks),
        )

    def returns(self, gamma: float = 1.0, expected: bool = False) -> np.ndarray:
        """``(N,)``: each episode's discounted return from its first observation."""
        rewards = self.expected_rewards() if expected else self.rewards
        return rewards @ (gamma ** np.arange(self.steps))

    def subset(self, index: slice | np.ndarray) -> Trajectories:
        """The episodes selected by ``index`` (a slice, mask or index array)."""
        arrays: dict[str, Any] = {n: getattr(self, n)[index] for n in _ARRAYS}
        return Trajectories(
            **arrays,
            penalty=self.penalty,
            person=None if self.person is None else self.person[index],
            traits=None if self.traits is None else self.traits[index],
        )

    @classmethod
    def concatenate(cls, parts: Sequence[Trajectories]) -> Trajectories:
        """The episodes of ``parts``, in order."""
        with_people = [p.person is not None and p.traits is not None for p in parts]
        if any(w != with_people[0] for w in with_people):
            raise ValueError("cannot concatenate episodes with people and episodes without")
        arrays: dict[str, Any] = {n: np.concatenate([getattr(p, n) for p in parts]) for n in _ARRAYS}
        if with_people[0]:
            arrays["person"] = np.concatenate([p.person for p in parts])
            arrays["traits"] = np.concatenate([p.traits for p in parts])
        return cls(**arrays, penalty=parts[0].penalty)

    @classmethod
    def from_dataset(cls, dataset: MinariDataset, penalty: float | None = None) -> Trajectories:
        """Read a Minari dataset recorded by
        [`heartpole.offline.datasets.record_dataset`][heartpole.offline.datasets.record_dataset].

        Raises:
            ValueError: if the dataset lacks HeartPole's infos or its episodes differ in length.
        """
        name = str(dataset.spec.dataset_id)
        try:
            return cls._from_dataset(dataset, penalty)
        except UNREADABLE as error:
            if isinstance(error, ValueError) and str(error).startswith(f"dataset {name!r}"):
                raise  # already says what is wrong with it
            raise unreadable(name, error) from None

    @classmethod
    def _from_dataset(cls, dataset: MinariDataset, penalty: float | None) -> Trajectories:
        episodes = list(dataset.iterate_episodes())
        if not episodes:
            raise ValueError(f"dataset {dataset.spec.dataset_id!r} has no episodes")
        missing = {"action_probabilities", *INFO_KEYS} - set(episodes[0].infos or {})
        if missing:
            raise ValueError(
                f"dataset {dataset.spec.dataset_id!r} lacks the infos {sorted(missing)}: record it with "
                "'heartpole dataset', which stores the behaviour's propensities"
            )
        if len({len(e.actions) for e in episodes}) != 1:
            raise ValueError(f"dataset {dataset.spec.dataset_id!r} has episodes of different lengths")
        if penalty is None:
            penalty = _penalty(dataset)
        numbers: dict[str, np.ndarray] = {
            "observations": np.stack([e.observations for e in episodes]).astype(np.float32),
            "rewards": np.stack([e.rewards for e in episodes]).astype(np.float64),
            "action_probabilities": np.stack([e.infos["action_probabilities"] for e in episodes]).astype(np.float64),
            **{key: np.stack([e.infos[key] for e in episodes]).astype(_INFO_DTYPES[key]) for key in INFO_KEYS},
        }
        for key, values in numbers.items():
            _check_finite(str(dataset.spec.dataset_id), key, values)
        return cls(
            actions=_recorded_actions(str(dataset.spec.dataset_id), episodes),
            **numbers,
            penalty=float(penalty),
            **_episode_people(episodes),
        )


UNREADABLE = (KeyError, AssertionError, MemoryError, OSError, TypeError, ValueError)
"""What Minari and h5py raise reading a damaged dataset: a missing group, a metadata type Minari asserts, a
count that asks for more memory than there is, a truncated file."""


def unreadable(dataset_id: str, error: BaseException) -> ValueError:
    """A one-line ``ValueError`` for the dataset ``dataset_id`` that ``error`` stopped from being read."""
    reason = " ".join(str(error).split()) or type(error).__name__
    return ValueError(f"dataset {dataset_id!r} cannot be read (damaged, or not a dataset 'heartpole dataset' "
                      f"wrote): {reason}")  # fmt: skip


def _check_finite(dataset_id: str, name: str, values: np.ndarray) -> None:
    """``ValueError`` naming the dataset, the field, the episode and the step of a NaN or infinite number."""
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        where = np.argwhere(~np.isfinite(values))[0]
        raise ValueError(f"dataset {dataset_id!r}: episode {where[0]}, step {where[1]}: {name} holds "
                         f"{values[tuple(where)].item()!r}; every recorded number must be finite")  # fmt: skip


def _recorded_actions(dataset_id: str, episodes: Sequence[Any]) -> np.ndarray:
    """The episodes' actions as ``(N, T)`` int64, once each is one of the env's actions (0 to the number of
    action probabilities recorded, less one): a tampered dataset's -1 (which indexing would read as the last
    action), 7 or 1.5 is a ``ValueError`` naming the dataset, the episode, the step and the accepted range."""
    raw = np.stack([np.asarray(e.actions) for e in episodes])
    num_actions = int(np.shape(episodes[0].infos["action_probabilities"])[-1])
    if raw.dtype.kind not in "iufb" or raw.ndim != 2:
        raise ValueError(f"dataset {dataset_id!r}: actions must be whole numbers, one per step; got {raw.dtype} "
                         f"of shape {raw.shape}")  # fmt: skip
    with np.errstate(invalid="ignore"):
        valid = (raw >= 0) & (raw < num_actions) & (raw == np.floor(raw))
    if not valid.all():
        episode, step = (int(i) for i in np.argwhere(~valid)[0])
        name = getattr(episodes[episode], "id", episode)
        raise ValueError(
            f"dataset {dataset_id!r}: episode {name}, step {step}: action {raw[episode, step].item()!r} is not one "
            f"of the env's actions, whole numbers 0 to {num_actions - 1}"
        )
    return raw.astype(np.int64)


def collect(
    behaviour: EpsilonGreedy,
    episodes: int,
    env_id: str = "HeartPole-v0",
    seeds: Sequence[int] = (0,),
    progress: Callable[[int], None] | None = None,
    env_kwargs: dict[str, Any] | None = None,
) -> Trajectories:
    """Run ``behaviour`` for ``episodes`` whole episodes, ``len(seeds)`` chunks side by side, one seed each.

    Raises:
        ValueError: if the behaviour's policy returns invalid actions or acts at random without saying how.
    """
    return Trajectories.concatenate(list(iter_collect(behaviour, episodes, env_id, seeds, progress, env_kwargs)))


def iter_collect(
    behaviour: EpsilonGreedy,
    episodes: int,
    env_id: str = "HeartPole-v0",
    seeds: Sequence[int] = (0,),
    progress: Callable[[int], None] | None = None,
    env_kwargs: dict[str, Any] | None = None,
) -> Iterator[Trajectories]:
    """[`collect`][heartpole.offline.trajectories.collect] one chunk at a time (``ceil(episodes / len(seeds))``
    episodes each), to bound memory."""
    chunk = -(-episodes // len(seeds))
    for first, seed in zip(range(0, episodes, chunk), seeds):
        yield _collect_chunk(behaviour, min(chunk, episodes - first), env_id, seed, progress, env_kwargs or {})


def _collect_chunk(
    behaviour: EpsilonGreedy,
    size: int,
    env_id: str,
    reset_seed: int,
    progress: Callable[[int], None] | None,
    env_kwargs: dict[str, Any],
) -> Trajectories:
    with vector_env(env_id, env_kwargs, size) as env:
        steps, num_actions = int(base_env(env).max_steps), behaviour.num_actions
        penalty = float(base_env(env).dynamics.params.heart_attack_penalty)
        obs_dim = int(np.prod(cast("tuple[int, ...]", env.single_observation_space.shape)))
        observations = np.empty((steps + 1, size, obs_dim), dtype=np.float32)
        probabilities = np.empty((steps + 1, size, num_actions), dtype=np.float64)
        actions = np.empty((steps, size), dtype=np.int64)
        rewards = np.empty((steps, size), dtype=np.float64)
        infos = {key: np.zeros((steps + 1, size), dtype=dtype) for key, dtype in _INFO_DTYPES.items()}
        people: dict[str, np.ndarray] = {}

        def choose(obs: np.ndarray, t: int) -> np.ndarray:
            if t == 0:
                check_deterministic(behaviour.policy, obs)
            observations[t] = obs
            probabilities[t] = behaviour.action_probabilities(obs)
            return check_actions(sample(probabilities[t], behaviour.rng), size, num_actions, behaviour.name)

        for step in episode_steps(env, reset_seed, choose):
            actions[step.t], rewards[step.t] = step.actions, step.rewards
            if step.t == 0 and step.person is not None:  # NEXT_STEP autoreset: step 0's info is this episode's
                people = {"person": step.person.copy(), "traits": np.asarray(step.info["traits"], np.float32).copy()}
            for key in INFO_KEYS:
                infos[key][step.t + 1] = step.info[key]
            if progress:
                progress(size)
        observations[steps] = step.observations
        probabilities[steps] = behaviour.action_probabilities(step.observations)
    return Trajectories(
        observations=observations.transpose(1, 0, 2).copy(),
        actions=actions.T.copy(),
        rewards=rewards.T.copy(),
        action_probabilities=probabilities.transpose(1, 0, 2).copy(),
        **{key: value.T.copy() for key, value in infos.items()},
        penalty=penalty,
        **people,
    )


def _episode_people(episodes: Sequence[Any]) -> dict[str, np.ndarray]:
    """``person`` and ``traits`` of a dataset's episodes (the first observation's infos), if recorded."""
    if "person" not in (episodes[0].infos or {}):
        return {}
    return {
        "person": np.array([e.infos["person"][0] for e in episodes], dtype=np.int64),
        "traits": np.stack([np.asarray(e.infos["traits"][0], dtype=np.float32) for e in episodes]),
    }


def _penalty(dataset: MinariDataset) -> float:
    import gymnasium as gym

    env_id = dataset.storage.metadata.get("env_id", "HeartPole-v0")
    if env_id not in heartpole_ids():  # never made (nor its module imported): the default penalty
        return 100.0
    with quiet_version_warnings():
        try:
            env = gym.make(env_id)
        except gym.error.Error:
            return 100.0
    try:
        return float(cast("HeartPole", env.unwrapped).dynamics.params.heart_attack_penalty)
    finally:
        env.close()
