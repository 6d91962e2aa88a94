"""Reading a saved model without running code from it: the network's weights, its architecture and the
observation statistics, through formats that cannot execute anything.

A Stable-Baselines3 ``model.zip`` holds the network's weights (``policy.pth``, a PyTorch file) and a JSON
``data`` file in which some entries are cloudpickled Python objects; SB3's ``load`` unpickles them, and
unpickling can run any code the file's author chose. ``VecNormalize.save`` writes a pickle. Here nothing is
unpickled:

* the weights are read with ``torch.load(..., weights_only=True)``, which admits tensors and containers only;
* the network is rebuilt from the recorded architecture (``heartpole.json``'s ``net_arch``, else the plain
  JSON fields of the zip's ``data``: the policy's keyword arguments, the observation shape, the number of
  actions), and its weights must fit it exactly (``load_state_dict(strict=True)``);
* observation statistics come from ``vecnormalize.json`` (plain JSON, which ``heartpole train`` writes
  beside ``vecnormalize.pkl``) or, for older runs, from ``vecnormalize.pkl`` through a restricted unpickler
  that builds NumPy arrays and numbers and keeps every other object as inert attributes, refusing any
  reference to a function or class a ``VecNormalize`` file does not hold.

What cannot be read this way raises [`UnsafeFileError`][heartpole.policies.untrusted.UnsafeFileError], which
says why and how to opt in: ``--trust-pickles`` on the commands that load models, ``trust_pickles=True`` in
[`load_policy`][heartpole.policies.load_policy]. This module reads the statistics;
[`heartpole.policies.rebuild`][heartpole.policies.rebuild] the model zip.
"""

from __future__ import annotations

import json
import math
import pickle
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from heartpole import files
from heartpole.registry import one_line

TRUST_HINT = (
    "nothing from it was run. Load it only if you trust whoever made it: pass --trust-pickles (heartpole evaluate, "
    "compare, baselines, plot episode, record) or trust_pickles=True (heartpole.load_policy)"
)
"""The end of every refusal: that nothing ran, and how to opt in to unpickling."""
STATISTICS_FORMAT = "heartpole-vecnormalize/1"
"""The ``format`` of ``vecnormalize.json``, the observation statistics in plain JSON."""


class UnsafeFileError(ValueError):
    """A model or statistics file that HeartPole could read only by unpickling it (which can run code): it
    was refused, and nothing from it was run."""


# ------------------------------------------------------------------------------------------------------
# observation statistics


@dataclass(frozen=True)
class ObservationStatistics:
    """A ``VecNormalize``'s observation statistics, as [`ModelPolicy`][heartpole.policies.saved.ModelPolicy]
    applies them: ``(obs - mean) / sqrt(var + epsilon)`` clipped to ``[-clip_obs, clip_obs]``, when
    ``norm_obs``. ``obs_rms`` is the object itself (it has ``mean`` and ``var``, as SB3's ``RunningMeanStd``)."""

    mean: np.ndarray
    var: np.ndarray
    count: float
    epsilon: float
    clip_obs: float
    norm_obs: bool

    @property
    def obs_rms(self) -> ObservationStatistics:
        """The running mean and variance (this object), where SB3's ``VecNormalize`` keeps them."""
        return self


def save_statistics(normalizer: Any, path: str | Path) -> Path:
    """Write a ``VecNormalize``'s statistics to ``path`` as plain JSON (`STATISTICS_FORMAT`): the
    observations' mean, variance and count, ``epsilon``, ``clip_obs`` and ``norm_obs``, and the returns'
    statistics with ``norm_reward``, ``clip_reward`` and ``gamma`` (floats round-trip exactly).

    Raises:
        ValueError: a statistic that is not finite (JSON has no NaN or infinity; nor does a usable run).
    """
    obs, ret = normalizer.obs_rms, normalizer.ret_rms
    record = {
        "format": STATISTICS_FORMAT,
        "norm_obs": bool(normalizer.norm_obs),
        "clip_obs": float(normalizer.clip_obs),
        "epsilon": float(normalizer.epsilon),
        "obs_mean": np.asarray(obs.mean, dtype=np.float64).tolist(),
        "obs_var": np.asarray(obs.var, dtype=np.float64).tolist(),
        "obs_count": float(obs.count),
        "norm_reward": bool(normalizer.norm_reward),
        "clip_reward": float(normalizer.clip_reward),
        "gamma": float(normalizer.gamma),
        "ret_mean": float(np.asarray(ret.mean, dtype=np.float64).reshape(-1)[0]),
        "ret_var": float(np.asarray(ret.var, dtype=np.float64).reshape(-1)[0]),
        "ret_count": float(ret.count),
    }
    for key, value in record.items():
        if key != "format" and not np.isfinite(np.asarray(value, dtype=np.float64)).all():
            raise ValueError(f"cannot save the observation statistics as {path}: {key} is not finite ({value})")
    return files.write_json(path, record)


def load_statistics(path: str | Path) -> ObservationStatistics:
    """The observation statistics in ``vecnormalize.json`` (written by `save_statistics`).

    Raises:
        ValueError: not such a file, or values of the wrong kind or shape.
    """
    path = Path(path)
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise ValueError(f"{path}: not a {STATISTICS_FORMAT} statistics file ({one_line(error)})") from None
    if not isinstance(record, dict) or record.get("format") != STATISTICS_FORMAT:
        raise ValueError(f"{path}: not a {STATISTICS_FORMAT} statistics file (its 'format' differs)")
    return _statistics(path, record)


def unpickle_statistics(path: str | Path) -> ObservationStatistics:
    """The observation statistics in a ``vecnormalize.pkl`` saved by ``VecNormalize.save``, read by a
    restricted unpickler that runs no code from the file.

    Raises:
        UnsafeFileError: the pickle refers to a function or class a ``VecNormalize`` file does not hold.
        ValueError: not a ``VecNormalize`` file.
    """
    path = Path(path)
    try:
        with path.open("rb") as handle:
            loaded = _StatisticsUnpickler(handle, path).load()
    except UnsafeFileError:
        raise
    except Exception as error:  # a damaged pickle raises many kinds
        raise ValueError(f"{path}: not a VecNormalize file saved by VecNormalize.save ({one_line(error)})") from None
    if not isinstance(loaded, _Pickled) or loaded.pickled_name != _VECNORMALIZE:
        raise ValueError(f"{path}: not a VecNormalize file saved by VecNormalize.save (it holds something else)")
    state = loaded.__dict__
    rms = state.get("obs_rms")
    if not isinstance(rms, _Pickled) or rms.pickled_name != _RUNNING_MEAN_STD:
        raise ValueError(f"{path}: its observation statistics are not one RunningMeanStd (dict observations?)")
    fields = {
        "obs_mean": rms.__dict__.get("mean"),
        "obs_var": rms.__dict__.get("var"),
        "obs_count": rms.__dict__.get("count"),
        **{key: state.get(key) for key in ("epsilon", "clip_obs", "norm_obs")},
    }
    return _statistics(path, fields)


def _statistics(path: Path, record: Mapping[str, Any]) -> ObservationStatistics:
    """The checked statistics of ``record`` (from either file format)."""

    def number(key: str) -> float:
        value = record.get(key)
        if isinstance(value, np.ndarray) and value.shape == ():
            value = value.item()
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise ValueError(f"{path}: {key} must be a number, got {value!r}")
        if not math.isfinite(float(value)):
            raise ValueError(f"{path}: {key} must be finite, got {value!r}")
        return float(value)

    def vector(key: str) -> np.ndarray:
        value = record.get(key)
        try:
            array = np.asarray(value)
        except Exception:  # noqa: BLE001 - ragged lists and the like
            array = np.asarray(None)
        if array.ndim != 1 or array.dtype.kind not in "biuf" or not np.isfinite(array).all():
            raise ValueError(f"{path}: {key} must be a list of finite numbers, got {value!r}")
        return array.astype(np.float64)

    mean, var = vector("obs_mean"), vector("obs_var")
    if mean.shape != var.shape or (var < 0).any():
        raise ValueError(f"{path}: obs_mean and obs_var must have one entry per observation, variances >= 0")
    norm_obs = record.get("norm_obs", True)
    if not isinstance(norm_obs, (bool, np.bool_)):
        raise ValueError(f"{path}: norm_obs must be true or false, got {norm_obs!r}")
    return ObservationStatistics(
        mean, var, number("obs_count"), number("epsilon"), number("clip_obs"), bool(norm_obs)
    )  # fmt: skip


_VECNORMALIZE = "stable_baselines3.common.vec_env.vec_normalize.VecNormalize"
_RUNNING_MEAN_STD = "stable_baselines3.common.running_mean_std.RunningMeanStd"
_KEPT_AS_ATTRIBUTES = (_VECNORMALIZE, _RUNNING_MEAN_STD)
# what else VecNormalize.save pickles (the spaces and their random generators), kept as inert attributes
_INERT_PREFIXES = ("gymnasium.spaces.", "gym.spaces.", "numpy.random.")


# builtin types a pickle may construct: plain values, no callables (protocols 0 to 2 name them as globals)
_PLAIN_TYPES = (object, bytes, bytearray, set, frozenset, list, tuple, dict, complex, int, float, bool, str, slice)


class _Pickled:
    """An object of a pickled class, kept as its attributes only: constructing it runs nothing."""

    pickled_name = ""

    def __new__(cls, *args: object, **kwargs: object) -> _Pickled:
        return object.__new__(cls)

    def __init__(self, *args: object, **kwargs: object) -> None:
        pass

    def __setstate__(self, state: object) -> None:
        parts = state if isinstance(state, tuple) else (state,)
        for part in parts:
            if isinstance(part, dict):
                self.__dict__.update({key: value for key, value in part.items() if isinstance(key, str)})


def _plain_dtype(*args: object) -> np.dtype[Any]:
    """``numpy.dtype`` for numbers and booleans only (what a ``VecNormalize`` file's arrays are)."""
    if not args or not isinstance(args[0], str) or np.dtype(args[0]).kind not in "biufc":
        raise pickle.UnpicklingError(f"a dtype other than numbers: {args[:1]!r}")
    return np.dtype(*args)  # type: ignore[call-overload]  # (name, align, copy) as NumPy pickles it


def _reconstructor(cls: object, base: object, state: object) -> _Pickled:
    """``copyreg._reconstructor`` for the classes kept as attributes only (`_Pickled`), and nothing else."""
    if not (isinstance(cls, type) and issubclass(cls, _Pickled)) or base is not object:
        raise pickle.UnpicklingError(f"copyreg._reconstructor of {cls!r} from {base!r}")
    return cls()


def _from_buffer(buffer: object, dtype: object, shape: object, order: object) -> np.ndarray:
    """NumPy's ``_frombuffer`` (protocol 5's arrays) for arrays of numbers only."""
    if not isinstance(dtype, np.dtype) or dtype.kind not in "biufc" or not isinstance(buffer, (bytes, bytearray)):
        raise pickle.UnpicklingError(f"an array of {dtype!r} from {type(buffer).__name__}")
    array = np.frombuffer(buffer, dtype).copy()
    return array.reshape(shape, order="F" if order == "F" else "C")


def _latin1(text: object, encoding: object = "utf-8") -> bytes:
    """``_codecs.encode`` as pickle's protocols 0 to 2 use it for bytes: a string in latin-1, nothing else."""
    if not isinstance(text, str) or encoding != "latin1":
        raise pickle.UnpicklingError(f"_codecs.encode of {type(text).__name__} as {encoding!r}")
    return text.encode("latin1")


class _StatisticsUnpickler(pickle.Unpickler):
    """Builds NumPy arrays and numbers; keeps the classes a ``VecNormalize`` file holds as `_Pickled`
    attributes; refuses every other global (a function the file could call)."""

    # NumPy's own reconstructors, found through the objects whose pickles name them (their module is
    # numpy.core.multiarray in NumPy 1 and numpy._core.multiarray in NumPy 2; either may be in the file)
    _NUMPY: dict[str, Any] = {
        "numpy.ndarray": np.ndarray,
        "numpy.dtype": _plain_dtype,
        # how protocols 0 to 2 rebuild an object (named as Python 2 named them, as pickle writes them there)
        "copyreg._reconstructor": _reconstructor,
        "copy_reg._reconstructor": _reconstructor,
        **{f"{module}.{t.__name__}": t for module in ("builtins", "__builtin__") for t in _PLAIN_TYPES},
        "_codecs.encode": _latin1,  # how protocols 0 to 2 write bytes
        "multiarray._reconstruct": np.zeros(0).__reduce__()[0],
        "multiarray.scalar": np.float64(0).__reduce__()[0],
        "numeric._frombuffer": _from_buffer,  # protocol 5's arrays
    }

    def __init__(self, handle: Any, path: Path) -> None:
        super().__init__(handle)
        self._path = path
        self._classes: dict[str, type[_Pickled]] = {}

    def find_class(self, module: str, name: str) -> Any:
        """The object the pickle names, or `UnsafeFileError` for anything that could run code."""
        full = f"{module}.{name}"
        if module in ("numpy.core.multiarray", "numpy._core.multiarray", "numpy.core.numeric", "numpy._core.numeric"):
            full = f"{module.rpartition('.')[2]}.{name}"
        if full in self._NUMPY:
            return self._NUMPY[full]
        full = f"{module}.{name}"
        if full in _KEPT_AS_ATTRIBUTES or full.startswith(_INERT_PREFIXES):
            if full not in self._classes:
                self._classes[full] = type(name, (_Pickled,), {"pickled_name": full})
            return self._classes[full]
        raise UnsafeFileError(
            f"{self._path}: not a plain VecNormalize file: unpickling it would call {full}, and a VecNormalize file "
            f"holds only arrays and numbers; {TRUST_HINT}"
        )
