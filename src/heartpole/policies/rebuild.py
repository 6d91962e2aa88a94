"""A Stable-Baselines3 ``model.zip`` read without unpickling: its plain JSON ``data``, its weights through
``torch.load(..., weights_only=True)``, and the ``MlpPolicy`` network rebuilt from the recorded
architecture (see [`heartpole.policies.untrusted`][heartpole.policies.untrusted] for the whole scheme).

As a tripwire, a zip whose ``data`` holds a pickle that imports from outside the libraries SB3 saves from
(``os.system``, say) is refused as crafted (`check_data_pickles`), although nothing in it would be run.
"""

from __future__ import annotations

import base64
import io
import json
import pickle
import pickletools
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole.policies.untrusted import TRUST_HINT, UnsafeFileError
from heartpole.registry import one_line

if TYPE_CHECKING:
    import torch


MAX_MEMBER_BYTES = 1 << 30
"""The largest file a model zip may unpack to (1 GiB): HeartPole's models are kilobytes to megabytes, and a zip
whose small entry unpacks to gigabytes would take the memory before anything could check it."""


def read_member(path: Path, member: str) -> bytes:
    """The bytes of ``member`` of the zip at ``path``, once its declared size is at most
    [`MAX_MEMBER_BYTES`][heartpole.policies.rebuild.MAX_MEMBER_BYTES] (``zipfile`` reads no more than it declares).

    Raises:
        ValueError: not a zip, no such member, or a member too large.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            size = archive.getinfo(member).file_size
            if size > MAX_MEMBER_BYTES:
                raise ValueError(
                    f"{path}: its {member} would unpack to {size:,} bytes, more than the {MAX_MEMBER_BYTES:,} a "
                    "model may take"
                )
            return archive.read(member)
    except (zipfile.BadZipFile, KeyError, OSError) as error:
        raise ValueError(f"{path}: not a Stable-Baselines3 model zip ({one_line(error)})") from None


def model_data(path: Path) -> dict[str, Any]:
    """The JSON ``data`` of an SB3 model zip, as plain JSON (its pickled entries stay base64 text).

    Raises:
        ValueError: not a zip with a JSON object as its ``data``.
    """
    raw = read_member(path, "data")
    try:
        data = json.loads(raw)
    except ValueError as error:
        raise ValueError(f"{path}: not a Stable-Baselines3 model zip ({one_line(error)})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: not a Stable-Baselines3 model zip (its data is not a JSON object)")
    return data


# the modules SB3 models' pickled data entries import from (schedules, spaces, buffers, deques, arrays, enums)
_DATA_MODULES = frozenset(
    {"stable_baselines3", "sb3_contrib", "heartpole", "gymnasium", "gym", "numpy", "torch", "collections",
     "cloudpickle", "copyreg", "types", "functools", "enum", "abc", "typing", "_codecs", "builtins"}
)  # fmt: skip
_DANGEROUS_BUILTINS = frozenset(
    {"eval", "exec", "compile", "__import__", "open", "getattr", "setattr", "delattr", "globals", "locals",
     "vars", "input", "breakpoint", "exit", "quit", "help", "__build_class__", "__loader__"}
)  # fmt: skip
_STRING_OPS = frozenset({"SHORT_BINUNICODE", "BINUNICODE", "BINUNICODE8", "UNICODE", "SHORT_BINSTRING", "BINSTRING"})
_MEMO_GETS = frozenset({"GET", "BINGET", "LONG_BINGET"})
_MEMO_PUTS = frozenset({"PUT", "BINPUT", "LONG_BINPUT"})


def check_data_pickles(path: Path, data: Mapping[str, Any]) -> None:
    """Refuse a zip whose ``data`` holds a pickle importing what SB3 never saves (``os.system``, say).

    The pickles are only parsed (``pickletools``), never run; HeartPole does not need them. This is a
    tripwire that names a crafted file as such, not the safety itself (which is never unpickling them).

    Raises:
        UnsafeFileError: an entry imports from outside `_DATA_MODULES`, a dangerous builtin, or names its
            import in a way this parser cannot follow.
    """
    for key, entry in data.items():
        blob = entry.get(":serialized:") if isinstance(entry, dict) else None
        if not isinstance(blob, str):
            continue
        try:
            imports = _pickle_imports(base64.b64decode(blob, validate=True))
        except Exception as error:  # noqa: BLE001 - any damage: the entry is not needed, but not trusted
            imports = [f"<unreadable pickle: {one_line(error)}>"]
        for name in imports:
            module, _, attribute = name.rpartition(".")
            root = module.split(".")[0]
            if root not in _DATA_MODULES or (module == "builtins" and attribute in _DANGEROUS_BUILTINS):
                raise UnsafeFileError(
                    f"{path}: its data entry {key!r} holds a pickle that would call {name} when loaded by "
                    f"Stable-Baselines3, which saves no such thing: the file looks crafted to run code; {TRUST_HINT}"
                )


def _pickle_imports(blob: bytes) -> list[str]:
    """Every ``module.name`` a pickle imports, from its opcodes (nothing is run); ``<unknown>`` where an
    import's name is not a string pushed just before it."""
    imports: list[str] = []
    memo: dict[int, object] = {}
    recent: list[object] = []  # what the last opcodes pushed: the strings STACK_GLOBAL pops
    for opcode, arg, _ in pickletools.genops(blob):
        name = opcode.name
        if name == "GLOBAL" or name == "INST":
            imports.append(str(arg).replace(" ", "."))
        elif name == "STACK_GLOBAL":
            module, attribute = (recent[-2], recent[-1]) if len(recent) >= 2 else (None, None)
            ok = isinstance(module, str) and isinstance(attribute, str)
            imports.append(f"{module}.{attribute}" if ok else "<unknown>.<an import this parser cannot follow>")
        elif name.startswith("EXT"):
            imports.append("<unknown>.<an extension-registry import>")
        if name == "MEMOIZE":
            memo[len(memo)] = recent[-1] if recent else None
        elif name in _MEMO_PUTS:
            memo[int(arg)] = recent[-1] if recent else None  # type: ignore[arg-type]
        elif name in _MEMO_GETS:
            recent.append(memo.get(int(arg)))  # type: ignore[arg-type]
        elif name in _STRING_OPS:
            recent.append(arg.decode("latin-1") if isinstance(arg, bytes) else arg)
        elif name not in {"FRAME", "PROTO", "MEMOIZE", "STOP"} and not name.endswith("PUT"):
            recent.append(None)
        del recent[:-2]
    return imports


def read_weights(path: Path, member: str = "policy.pth") -> dict[str, torch.Tensor]:
    """The tensors of ``member`` in the zip, read by ``torch.load(..., weights_only=True)``.

    Raises:
        UnsafeFileError: the weights file holds more than tensors (PyTorch's weights-only reader refused it).
        ValueError: no such member, or not a PyTorch file.
    """
    import torch

    raw = read_member(path, member)
    try:
        state = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as error:
        raise UnsafeFileError(
            f"{path}: its {member} holds more than tensors (PyTorch's weights-only reader says: "
            f"{one_line(error)[:300]}); {TRUST_HINT}"
        ) from None
    except Exception as error:  # noqa: BLE001 - a damaged file raises many kinds
        raise ValueError(f"{path}: its {member} is not a PyTorch weights file ({one_line(error)})") from None
    if not isinstance(state, dict) or not all(isinstance(value, torch.Tensor) for value in state.values()):
        raise ValueError(f"{path}: its {member} is not a dict of tensors (a network's state_dict)")
    return state


# ------------------------------------------------------------------------------------------------------
# rebuilding the network


_ACTIVATIONS = ("ReLU", "Tanh", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid", "Softplus", "SELU", "Mish")
_PLAIN_POLICY_KWARGS = frozenset({"net_arch", "ortho_init", "share_features_extractor", "normalize_images"})
_IGNORED_POLICY_KWARGS = frozenset({"optimizer_class", "optimizer_kwargs", ":type:", ":serialized:"})
# the MlpPolicy class of each algorithm, by module and the class that defines __init__ (the class's recorded
# __dict__ names it: '<function ActorCriticPolicy.__init__ at ...>'; CnnPolicy and the like define their own)
_POLICY_CLASSES = {"ppo": ("stable_baselines3.common.policies", "ActorCriticPolicy"),
                   "a2c": ("stable_baselines3.common.policies", "ActorCriticPolicy"),
                   "dqn": ("stable_baselines3.dqn.policies", "DQNPolicy")}  # fmt: skip


@dataclass
class SavedModel:
    """A saved SB3 model rebuilt without unpickling: its policy network (weights loaded, in evaluation mode),
    algorithm and spaces; ``predict`` is the policy's, as SB3's model's ``predict`` is."""

    policy: Any
    algo: str
    observation_space: Any
    action_space: Any

    def predict(self, observation: np.ndarray, /, *, deterministic: bool = False) -> tuple[np.ndarray, object]:
        """The policy's actions for ``observation`` (SB3's ``BasePolicy.predict``)."""
        actions, state = self.policy.predict(observation, deterministic=deterministic)
        return np.asarray(actions), state


def rebuild_model(path: Path, algo: str, data: Mapping[str, Any], net_arch: Sequence[int] | None) -> SavedModel:
    """The model saved at ``path``, rebuilt as an SB3 ``MlpPolicy`` of ``algo`` from the zip's plain data
    (``net_arch`` replaces its policy keyword arguments' when given: ``heartpole.json``'s record) with the
    weights of ``policy.pth``, which must fit it exactly.

    Raises:
        UnsafeFileError: the architecture or spaces are recorded only in pickles, or are not an MlpPolicy's.
        ValueError: the weights do not fit the rebuilt network (a damaged or mislabelled file).
    """
    import gymnasium as gym
    import torch

    recorded = data.get("policy_class")
    recorded = recorded if isinstance(recorded, dict) else {}
    module, name = _POLICY_CLASSES[algo]
    if recorded.get("__module__") != module or not str(recorded.get("__init__")).startswith(
        f"<function {name}.__init__"
    ):
        described = f"{recorded.get('__module__')}, {str(recorded.get('__init__', ''))[10:].split(' ')[0]}"
        raise UnsafeFileError(
            f"{path}: its policy class ({described}) is not the {algo.upper()} MlpPolicy ({module}.{name}) that "
            f"HeartPole rebuilds without unpickling; {TRUST_HINT}"
        )
    kwargs = _policy_kwargs(path, data.get("policy_kwargs"))
    if net_arch is not None:
        kwargs["net_arch"] = [int(n) for n in net_arch]
    obs_shape, actions = model_spaces(path, data)
    observation_space = gym.spaces.Box(-np.inf, np.inf, obs_shape, np.float32)
    action_space = gym.spaces.Discrete(actions)
    state = read_weights(path)
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.dqn.policies import DQNPolicy

    policy_class: type[DQNPolicy | ActorCriticPolicy] = DQNPolicy if algo == "dqn" else ActorCriticPolicy
    try:
        policy = policy_class(observation_space, action_space, lambda _: 0.0, **kwargs)
        policy.load_state_dict(state, strict=True)
    except (RuntimeError, TypeError, ValueError, AssertionError) as error:
        raise ValueError(
            f"{path}: its weights do not fit the {algo.upper()} MlpPolicy {kwargs} it records ({one_line(error)[:400]})"
        ) from None
    policy.set_training_mode(False)
    policy.to(torch.device("cpu"))
    return SavedModel(policy, algo, observation_space, action_space)


def model_spaces(path: Path, data: Mapping[str, Any]) -> tuple[tuple[int, ...], int]:
    """The observation shape and number of actions recorded in the zip's plain data.

    Raises:
        UnsafeFileError: not a ``Box`` and a ``Discrete`` space with plain shape and size fields.
    """
    obs, actions = data.get("observation_space"), data.get("action_space")
    try:
        assert isinstance(obs, dict) and "spaces.box.Box" in str(obs.get(":type:"))
        assert isinstance(actions, dict) and "spaces.discrete.Discrete" in str(actions.get(":type:"))
        shape = tuple(int(n) for n in obs["_shape"])
        count = int(str(actions["n"]))
        assert int(str(actions.get("start", 0))) == 0 and count >= 1 and all(n >= 1 for n in shape)
    except (AssertionError, KeyError, TypeError, ValueError):
        raise UnsafeFileError(
            f"{path}: its observation and action spaces are not recorded as a plain Box and Discrete, so HeartPole "
            f"cannot rebuild it without unpickling; {TRUST_HINT}"
        ) from None
    return shape, count


def _policy_kwargs(path: Path, recorded: object) -> dict[str, Any]:
    """The policy's keyword arguments from their plain record: the JSON values, and the activation function
    by its recorded class name (one of `_ACTIVATIONS`)."""
    import torch

    if recorded is None:
        return {}
    if not isinstance(recorded, dict):
        raise UnsafeFileError(f"{path}: its policy_kwargs are not recorded as plain JSON; {TRUST_HINT}")
    kwargs: dict[str, Any] = {}
    for key, value in recorded.items():
        if key in _IGNORED_POLICY_KWARGS:
            continue
        if key == "activation_fn" and isinstance(value, str):
            name = value.removeprefix("<class '").removesuffix("'>")
            module, _, cls = name.rpartition(".")
            if not module.startswith("torch.nn.modules.") or cls not in _ACTIVATIONS:
                raise UnsafeFileError(
                    f"{path}: its activation function {value} is not one HeartPole knows; {TRUST_HINT}"
                )
            kwargs[key] = getattr(torch.nn, cls)
        elif key in _PLAIN_POLICY_KWARGS and not (isinstance(value, str) and value.startswith("<")):
            kwargs[key] = value
        else:
            raise UnsafeFileError(
                f"{path}: its policy keyword {key!r} ({str(value)[:80]}) is not one HeartPole rebuilds without "
                f"unpickling; {TRUST_HINT}"
            )
    return kwargs
