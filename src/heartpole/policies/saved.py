"""Stable-Baselines3 models saved by ``heartpole train`` (or the JAX trainer) as policies: loading, the
observation statistics recorded with them, and which algorithm saved them. Stable-Baselines3 is imported only
when a model is loaded, and no training code is needed.

Loading runs no code from the files: the network is rebuilt from its recorded architecture and its weights
read with PyTorch's weights-only reader ([`heartpole.policies.rebuild`][heartpole.policies.rebuild]), the
statistics come from plain JSON or a restricted unpickler
([`heartpole.policies.untrusted`][heartpole.policies.untrusted]). A file that could be read only by
unpickling it is refused unless ``trust_pickles=True``, which falls back to Stable-Baselines3's ``load`` and
``pickle`` for what the safe readers cannot read."""

from __future__ import annotations

import hashlib
import json
import pickle
import sys
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from heartpole.dynamics import Dynamics

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

from heartpole.policies.common import (
    OFF_POLICY_ALGORITHMS,
    SB3_ALGORITHMS,
    SIDECAR_NAME,
    VECNORMALIZE_JSON_NAME,
    VECNORMALIZE_NAME,
    Predictor,
    check_model_format,
    default_dynamics,
    observation_batch,
)
from heartpole.policies.rebuild import SavedModel, check_data_pickles, model_data, rebuild_model
from heartpole.policies.untrusted import UnsafeFileError, load_statistics, unpickle_statistics
from heartpole.registry import one_line


class RunningStats(Protocol):
    """Running mean and variance of observations, as SB3's ``RunningMeanStd`` keeps them."""

    @property
    def mean(self) -> np.ndarray: ...
    @property
    def var(self) -> np.ndarray: ...


class Normalizer(Protocol):
    """What `ModelPolicy` reads of SB3's ``VecNormalize``: the
    statistics and how they are applied (``norm_obs``, when present and false, turns normalisation off)."""

    @property
    def obs_rms(self) -> RunningStats: ...
    @property
    def epsilon(self) -> float: ...
    @property
    def clip_obs(self) -> float: ...


class ModelPolicy:
    """A Stable-Baselines3 model as a [`Policy`][heartpole.policies.Policy]: optional observation normalisation, then
    ``model.predict(obs, deterministic=True)``.

    Args:
        model: anything with SB3's ``predict(observation, deterministic=...)``.
        normalizer: a ``VecNormalize`` (or any object with ``obs_rms``, ``clip_obs``, ``epsilon`` and
            ``norm_obs``) whose statistics normalise observations, as during training; ``None`` for none.
        name: the policy's name in results tables.
    """

    def __init__(self, model: Predictor, normalizer: Normalizer | None = None, name: str = "model") -> None:
        self.model = model
        self.name = name
        self.normalization = _normalization(normalizer)
        self.normalizer_path: Path | None = None  # the file the statistics came from, when loaded from one
        self._greedy = _greedy_actor(model)

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """Observations as the model saw them in training (VecNormalize's formula), float32."""
        if self.normalization is None:
            return obs
        mean, scale, clip = self.normalization
        return np.clip((obs - mean) / scale, -clip, clip).astype(np.float32)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        with _one_torch_thread():
            if self._greedy is not None:
                return self._greedy(self.normalize(observation_batch(obs)))
            actions, _ = self.model.predict(self.normalize(observation_batch(obs)), deterministic=True)
        return np.asarray(actions, dtype=np.int64).reshape(-1)


def _greedy_actor(model: Any) -> Callable[[np.ndarray], np.ndarray] | None:
    """For a PPO or A2C model with discrete actions, ``predict(obs, deterministic=True)`` without its
    detours: the actor's logits and their argmax, in inference mode; ``None`` for any other model.

    ``predict`` takes the argmax of the softmax of the same logits (the same action, but where two logits
    round to one probability), and spends a third of an evaluation's time building the distribution and
    toggling training mode on every call.
    """
    policy = getattr(model, "policy", None)
    if "torch" not in sys.modules or policy is None:
        return None
    from stable_baselines3.common.distributions import CategoricalDistribution
    from stable_baselines3.common.policies import ActorCriticPolicy, BasePolicy

    if type(policy) is not ActorCriticPolicy or not isinstance(policy.action_dist, CategoricalDistribution):
        return None
    torch = sys.modules["torch"]
    policy.set_training_mode(False)

    def act(obs: np.ndarray) -> np.ndarray:
        with torch.inference_mode():
            # the actor's features as SB3's get_distribution takes them: BasePolicy's extract_features with the
            # actor's extractor, one tensor whether or not the critic shares it (ActorCriticPolicy's own
            # extract_features returns the pair (actor's, critic's) when share_features_extractor=False)
            obs_tensor = torch.as_tensor(obs, device=policy.device)
            features = BasePolicy.extract_features(policy, obs_tensor, policy.pi_features_extractor)
            logits = policy.action_net(policy.mlp_extractor.forward_actor(features))
            return np.asarray(logits.argmax(dim=1).cpu().numpy(), dtype=np.int64)

    return act


@contextmanager
def _one_torch_thread() -> Iterator[None]:
    """Run PyTorch on one thread, then restore its setting.

    A policy's batches are small; on a busy machine PyTorch's thread pool turned each tiny softmax into
    milliseconds of waiting (measured: 7.6 ms with 2 threads against 4 microseconds with one).
    """
    torch = sys.modules.get("torch")  # a model that runs on PyTorch has imported it already
    if torch is None:
        yield
        return
    threads = torch.get_num_threads()
    if threads != 1:
        torch.set_num_threads(1)
    try:
        yield
    finally:
        if threads != 1:
            torch.set_num_threads(threads)


def _normalization(normalizer: Normalizer | None) -> tuple[np.ndarray, np.ndarray, float] | None:
    if normalizer is None or not getattr(normalizer, "norm_obs", True):
        return None
    rms = normalizer.obs_rms
    scale = np.sqrt(np.asarray(rms.var, dtype=np.float64) + float(normalizer.epsilon))
    return np.asarray(rms.mean, dtype=np.float64), scale, float(normalizer.clip_obs)


def load_model_policy(
    path: str | Path,
    dynamics: Dynamics | None = None,
    obs_shape: tuple[int, ...] | None = None,
    *,
    trust_pickles: bool = False,
) -> ModelPolicy:
    """The SB3 model saved at ``path`` (with the statistics its ``heartpole.json`` records, if any) as a policy,
    read without running code from the files (`load_model`, `load_normalizer`).

    ``obs_shape`` is the env's observation shape where it is wider than ``dynamics``' variables (an env
    with ``observe_traits`` or ``measurement``); ``None``: one entry per variable. ``trust_pickles``: read
    by unpickling (which can run code) what the safe readers refuse. A model whose zip shows it was trained
    on ``VecNormalize``-wrapped envs, loaded without recorded statistics, gets a warning: it acts on raw
    observations.

    Raises:
        FileNotFoundError: no such file, or a folder.
        UnsafeFileError: a file that only unpickling could read, without ``trust_pickles``.
        ValueError: not a regular file, not an SB3 model zip, an unknown algorithm, or spaces that do not match the
            env's.
    """
    path = _model_path(path)
    algo = detect_algorithm(path)
    model = load_model(path, algo, trust_pickles=trust_pickles)
    _check_spaces(path, model, dynamics or default_dynamics(), obs_shape)
    normalizer_path = recorded_normalizer(path)
    normalizer = load_normalizer(normalizer_path, trust_pickles=trust_pickles) if normalizer_path is not None else None
    if normalizer is None:
        _warn_if_trained_normalized(path, algo)
    policy = ModelPolicy(model, normalizer, name=str(path))
    policy.normalizer_path = normalizer_path
    return policy


def _model_path(path: str | Path) -> Path:
    """``path`` if it is a regular file; else ``FileNotFoundError`` (nothing there, a folder) or ``ValueError``
    (a named pipe, a device, a socket: opening one would block or read forever), told from its status alone."""
    path = Path(path)
    if path.is_dir():
        raise FileNotFoundError(f"{path} is a folder; give the path of the model .zip inside it")
    if path.exists() and not path.is_file():
        raise ValueError(f"{path} is not a regular file (a named pipe, a device or a socket); give a model .zip")
    if not path.is_file():
        raise FileNotFoundError(f"model file not found: {path}")
    return path


def load_model(path: str | Path, algo: str, *, trust_pickles: bool = False) -> SavedModel | BaseAlgorithm:
    """The model saved at ``path``, rebuilt without unpickling
    ([`rebuild_model`][heartpole.policies.rebuild.rebuild_model]: ``heartpole.json``'s ``net_arch`` or the
    zip's plain record, and the weights-only ``policy.pth``).

    A zip whose pickled data entries import what SB3 never saves is refused (they are parsed, never run).
    With ``trust_pickles`` that check is skipped, and a model the safe reader cannot rebuild (another policy
    class, an architecture recorded only in pickles) is loaded by SB3's ``load``, which unpickles.

    Raises:
        UnsafeFileError: only unpickling could read it, and not ``trust_pickles``.
        ValueError: not a usable SB3 model zip.
    """
    path = Path(path)
    data = model_data(path)
    if not trust_pickles:
        check_data_pickles(path, data)
    try:
        return rebuild_model(path, algo, data, _recorded_net_arch(path))
    except UnsafeFileError:
        if not trust_pickles:
            raise
    return _unpickle_model(path, algo)


def load_normalizer(path: str | Path, *, trust_pickles: bool = False) -> Normalizer:
    """The observation statistics in ``path``: ``vecnormalize.json`` as plain JSON, a ``vecnormalize.pkl``
    through the restricted unpickler (arrays and numbers only), or, with ``trust_pickles``, by ``pickle`` where
    that refuses it.

    Raises:
        UnsafeFileError: a pickle that refers to more than a ``VecNormalize`` holds, and not ``trust_pickles``.
        ValueError: not a statistics file.
    """
    path = Path(path)
    if path.suffix == ".json":
        return load_statistics(path)
    try:
        return unpickle_statistics(path)
    except UnsafeFileError:
        if not trust_pickles:
            raise
    return _unpickle_normalizer(path)


def _recorded_net_arch(path: Path) -> list[int] | None:
    """The hidden layer sizes ``heartpole.json`` records for this model (``config.net_arch``), if any."""
    record = _sidecar_record(path)
    config = record.get("config") if record is not None else None
    net_arch = config.get("net_arch") if isinstance(config, dict) else None
    if net_arch is None:
        return None
    if not isinstance(net_arch, list) or not all(isinstance(n, int) and not isinstance(n, bool) for n in net_arch):
        raise ValueError(f"{path.parent / SIDECAR_NAME}: config.net_arch must list layer sizes, got {net_arch!r}")
    return net_arch


def _warn_if_trained_normalized(path: Path, algo: str) -> None:
    """Warn when the zip of an on-policy ``algo`` records the unnormalised observations SB3 keeps for those only
    under ``VecNormalize`` (``_last_original_obs``), since no statistics are applied (unless statistics lie beside
    it unrecorded: `recorded_normalizer` has warned about those). An off-policy model keeps them with or without
    ``VecNormalize`` ([`OFF_POLICY_ALGORITHMS`][heartpole.policies.common.OFF_POLICY_ALGORITHMS]): its zip does not
    tell, and nothing is said."""
    if algo in OFF_POLICY_ALGORITHMS:
        return
    if any((path.parent / name).is_file() for name in (VECNORMALIZE_JSON_NAME, VECNORMALIZE_NAME)):
        return
    try:
        trained_normalized = model_data(path).get("_last_original_obs") is not None
    except ValueError:
        return
    if trained_normalized:
        warnings.warn(
            f"{path} was trained on VecNormalize-wrapped envs (its data records unnormalised observations), but no "
            f"statistics are recorded with it in a {SIDECAR_NAME} beside it: it acts on raw observations and may "
            f"behave nothing like it did in training. Copy the {SIDECAR_NAME} and {VECNORMALIZE_JSON_NAME} (or "
            f"{VECNORMALIZE_NAME}) saved with it into its folder.",
            UserWarning,
            stacklevel=3,
        )


def recorded_normalizer(path: str | Path) -> Path | None:
    """The observation statistics saved with the model at ``path``, as its ``heartpole.json`` records them.

    ``heartpole train`` writes ``heartpole.json`` beside the model with ``"model"`` (the zip's name),
    ``"vecnormalize"`` (``VecNormalize.save``'s pickle, or ``null``) and ``"vecnormalize_json"`` (the same
    statistics as plain JSON, which is preferred: runs before it have only the pickle), each with its
    SHA-256. Only a file recorded there for this model is applied; statistics that merely lie beside the
    model are ignored, with a warning. For a model of your own, write ``{"algo": "ppo", "model": "my.zip",
    "vecnormalize": "my_vecnormalize.pkl"}`` beside it.

    Raises:
        ValueError: the record names statistics that are missing or were changed since they were saved.
    """
    path = Path(path)
    record = _sidecar_record(path)
    key = "vecnormalize"
    if record is not None and record.get("vecnormalize_json") is not None:
        key = "vecnormalize_json"
    if record is None or record.get(key) is None:
        for beside in (path.parent / VECNORMALIZE_JSON_NAME, path.parent / VECNORMALIZE_NAME):
            if beside.is_file():
                why = "records no statistics for it" if record is not None else f"has no {SIDECAR_NAME} recording them"
                warnings.warn(
                    f"ignoring {beside}: the model {path.name} {why}, so they may belong to another model. If they "
                    f'are this model\'s, record them beside it in {SIDECAR_NAME}: {{"model": "{path.name}", '
                    f'"vecnormalize": "{beside.name}"}}',
                    UserWarning,
                    stacklevel=3,
                )
                break
        return None
    name = record[key]
    if not isinstance(name, str) or Path(name).name != name:
        raise ValueError(f"{path.parent / SIDECAR_NAME}: {key!r} must be a file name beside the model, got {name!r}")
    statistics = path.parent / name
    if not statistics.is_file():
        raise ValueError(f"{path}: its observation statistics {statistics} (recorded in {SIDECAR_NAME}) are missing")
    digest = record.get(f"{key}_sha256")
    if digest is not None and file_sha256(statistics) != digest:
        raise ValueError(
            f"{statistics} changed since it was saved with {path.name} (its SHA-256 differs from the record)"
        )
    return statistics


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a file's bytes, in hex."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _sidecar_record(path: Path) -> dict[str, Any] | None:
    """``heartpole.json`` beside the model if it describes this model (by name and, if recorded, SHA-256)."""
    sidecar = path.parent / SIDECAR_NAME
    if not sidecar.is_file():
        return None
    try:
        record = json.loads(sidecar.read_text())
    except (OSError, ValueError):
        return None  # detect_algorithm reports an unreadable sidecar
    check_model_format(sidecar, record)
    if not isinstance(record, dict) or "vecnormalize" not in record:
        return None
    if record.get("model", path.name) != path.name:
        return None  # the record of another model in the same folder
    digest = record.get("model_sha256")
    if digest is not None and file_sha256(path) != digest:
        raise ValueError(
            f"{path} changed since {sidecar} recorded it (its SHA-256 differs), so its recorded statistics and env "
            f"may not fit it; to play it as a plain Stable-Baselines3 model, move it to a folder of its own"
        )
    return record


def detect_algorithm(path: str | Path) -> str:
    """``"ppo"``, ``"a2c"`` or ``"dqn"``: from ``heartpole.json`` beside the zip, else from the zip's data.

    Raises:
        ValueError: the sidecar or the zip cannot be read, or names no supported algorithm.
    """
    path = Path(path)
    sidecar = path.parent / SIDECAR_NAME
    if sidecar.is_file():
        return _algorithm_from_sidecar(sidecar)
    data = model_data(path)
    policy_class = data.get("policy_class")
    described = json.dumps(policy_class, allow_nan=False) if isinstance(policy_class, dict) else str(policy_class)
    if "dqn" in described.lower():
        return "dqn"
    if "ActorCriticPolicy" in described:
        return "ppo" if "clip_range" in data else "a2c"
    raise ValueError(f'{path}: cannot tell which algorithm saved this model; add {SIDECAR_NAME} with {{"algo": ...}}')


def _algorithm_from_sidecar(sidecar: Path) -> str:
    try:
        record = json.loads(sidecar.read_text())
    except (OSError, ValueError) as error:
        raise ValueError(f'{sidecar}: expected JSON like {{"algo": "ppo"}} ({one_line(error)})') from None
    check_model_format(sidecar, record)
    try:
        algo = record["algo"]
    except (KeyError, TypeError) as error:
        raise ValueError(f'{sidecar}: expected JSON like {{"algo": "ppo"}} ({one_line(error)})') from None
    if not isinstance(algo, str) or algo.lower() not in SB3_ALGORITHMS:
        raise ValueError(f"{sidecar}: unsupported algo {algo!r}; supported: {', '.join(SB3_ALGORITHMS)}")
    return algo.lower()


def _unpickle_model(path: Path, algo: str) -> BaseAlgorithm:
    """SB3's ``load``, which unpickles the zip's data: only with ``trust_pickles``."""
    try:
        import stable_baselines3 as sb3
    except ImportError:
        raise ValueError(
            f"{path}: loading a model needs Stable-Baselines3; install it with pip install 'heartpole[train]'"
        ) from None
    algorithms: dict[str, type[BaseAlgorithm]] = {"ppo": sb3.PPO, "a2c": sb3.A2C, "dqn": sb3.DQN}
    algorithm = algorithms[algo]
    try:
        return algorithm.load(path, device="cpu")
    except Exception as error:  # SB3 raises many kinds on a damaged file
        raise ValueError(f"{path}: cannot load it as a {algo.upper()} model ({one_line(error)})") from None


def _check_spaces(
    path: Path, model: SavedModel | BaseAlgorithm, dynamics: Dynamics, obs_shape: tuple[int, ...] | None = None
) -> None:
    obs_shape = (len(dynamics.variables),) if obs_shape is None else tuple(obs_shape)
    model_obs = tuple(getattr(model.observation_space, "shape", ()) or ())
    model_actions = getattr(model.action_space, "n", None)
    if model_obs != obs_shape or model_actions != len(dynamics.actions):
        raise ValueError(
            f"{path}: the model expects observations {model_obs} and {model_actions} actions, "
            f"but this env has observations {obs_shape} and {len(dynamics.actions)} actions"
        )


def _unpickle_normalizer(path: Path) -> Normalizer:
    """``pickle.load`` of a ``VecNormalize`` file, which can run code: only with ``trust_pickles``."""
    try:
        with path.open("rb") as handle:
            normalizer = pickle.load(handle)
        _normalization(normalizer)
    except Exception as error:  # unpickling can raise anything
        raise ValueError(f"{path}: not a VecNormalize file saved by VecNormalize.save ({one_line(error)})") from None
    return normalizer
