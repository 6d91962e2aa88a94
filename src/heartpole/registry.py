"""HeartPole's ids in Gymnasium's registry, and [`register_variant`][heartpole.registry.register_variant] for users' own
variants.

``import heartpole`` registers ``HeartPole-v0`` (the tutorial's) and ``HeartPole-v1`` (its homework), each
with a single-env entry point and a native vector entry point. A variant is v0 (or v1) with other actions,
state variables or parameters, registered under its own id and then used exactly like v0 and v1::

    import gymnasium as gym
    import heartpole
    from heartpole import Action

    walk = Action("take_a_walk", {"alertness": (0.1, 0.3)}, rest_half_hours=1,
                  fact="A 10-minute brisk walk raises energy for up to two hours (Thayer 1987).")
    heartpole.register_variant("WalkPole-v0", actions=[*heartpole.V0_ACTIONS, walk], max_steps=500)
    env = gym.make("WalkPole-v0")
    vec = gym.make_vec("WalkPole-v0", num_envs=64, vectorization_mode="vector_entry_point")

Everything is checked when the variant is defined, so a bad definition fails there with a ``ValueError``
that says what is wrong and what is accepted, never in the middle of an episode.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import fields
from typing import Any, cast

import gymnasium as gym
from gymnasium.envs.registration import EnvSpec, parse_env_id

from heartpole.actions import V0_ACTIONS, V1_ACTIONS, V1_VARIABLES, Action, as_action
from heartpole.dynamics import Dynamics
from heartpole.env import build_dynamics
from heartpole.parameters import V0_VARIABLES, Params, Variable, check_keywords
from heartpole.rates import best_known_rate as best_known_rate  # the rate the bar is measured against
from heartpole.solved import V0_BAR, V1_BAR, SolvedBar
from heartpole.solved import solved_bar as bar_of_params
from heartpole.time_limit import episode_length

V0_ID = "HeartPole-v0"
V1_ID = "HeartPole-v1"
BUILTIN_IDS = (V0_ID, V1_ID)

ENTRY_POINT = "heartpole.env:HeartPole"
VECTOR_ENTRY_POINT = "heartpole.vector:HeartPoleVectorEnv"
MO_ID = "mo-heartpole-v0"
"""HeartPole-v0 with a vector reward (productivity, health), for MO-Gymnasium (``heartpole.mo``)."""
MO_ENTRY_POINT = "heartpole.mo:MOHeartPole"
_BUILTINS: dict[str, dict[str, Any]] = {
    V0_ID: {"entry_points": (ENTRY_POINT, VECTOR_ENTRY_POINT)},
    V1_ID: {
        "actions": V1_ACTIONS,
        "variables": V1_VARIABLES,
        # v1's own classes carry its manual, bind its actions and variables and refuse others; nothing more
        "entry_points": ("heartpole.variants:HeartPoleV1", "heartpole.variants:HeartPoleV1VectorEnv"),
    },
}
"""HeartPole's own variants, defined as users define theirs (`define_variant`)."""
RESERVED_NAME = "HeartPole"
"""HeartPole's own name: ``HeartPole-vN`` ids are HeartPole's versions, never users' variants."""

BUILTIN_REWARD_THRESHOLDS = {V0_ID: V0_BAR.reward_threshold, V1_ID: V1_BAR.reward_threshold}
"""The reward thresholds of v0's and v1's specs, from their bars in [`heartpole.solved`][heartpole.solved]."""

# Gymnasium's id grammar ``[namespace/]name-vN``, with the version required and written without leading
# zeros (Gymnasium reads "-v01" as version 1 and would register the variant as "...-v1").
_ID = re.compile(r"(?:[\w:-]+/)?[A-Za-z][\w.-]*-v(?:0|[1-9][0-9]*)")

# Keyword arguments that belong to gymnasium.make / make_vec, not to a variant's definition.
_MAKE_TIME = {
    "render_mode": "gymnasium.make(..., render_mode=...)",
    "num_envs": "gymnasium.make_vec(..., num_envs=...)",
    "autoreset_mode": "gymnasium.make_vec(..., autoreset_mode=...)",
    "vectorization_mode": "gymnasium.make_vec(..., vectorization_mode=...)",
    "vector_kwargs": "gymnasium.make_vec",
    "wrappers": "gymnasium.make_vec",
}
PARAMETERS: tuple[str, ...] = tuple(f.name for f in fields(Params))
"""The parameters a variant may set: the fields of [`heartpole.Params`][heartpole.parameters.Params]."""

VARIABLE_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(Variable))

# The ids this module registered as users' variants: the only ones ``replace=True`` may redefine.
_variants: set[str] = set()


def register_envs() -> None:
    """Register ``HeartPole-v0`` and ``HeartPole-v1`` (single env and native vector env) unless registered, and
    ``mo-heartpole-v0`` (v0 with a vector reward, for MO-Gymnasium).

    Each spec declares its episode length as the env's own parameter, ``kwargs["max_steps"]`` (1000), and no
    ``max_episode_steps``: the env is its own time limit, so ``gymnasium.make`` wraps no ``TimeLimit`` around it
    and ``env.spec.max_episode_steps`` reports the env's ``max_steps`` (`heartpole.time_limit`). Each carries
    its ``reward_threshold`` ([`solved_bar`][heartpole.registry.solved_bar]). Gymnasium reads v1 as v0's successor
    and so would warn that ``HeartPole-v0`` "is out of date"; it is not (v1 is a richer variant, v0 stays the
    reference benchmark), and Gymnasium offers no per-id way to say so. So where the user's own warning filters
    say nothing about that warning, one filter ignores it, that message from Gymnasium's registration module
    alone; where they say something (``-W error::DeprecationWarning``, say),
    [`honour_version_warning_filters`][heartpole.registry.honour_version_warning_filters] makes them apply."""
    for env_id, definition in _BUILTINS.items():
        if env_id not in gym.registry:
            define_variant(env_id, **definition, reward_threshold=BUILTIN_REWARD_THRESHOLDS[env_id])
    if MO_ID not in gym.registry:  # v0 with a vector reward (heartpole.mo): MO-Gymnasium's env checker is off
        kwargs = {"max_steps": Params.max_steps}  # the env is its own time limit, as v0's
        gym.register(id=MO_ID, entry_point=MO_ENTRY_POINT, kwargs=kwargs, disable_env_checker=True)
    if honour_version_warning_filters() is None:
        warnings.filterwarnings("ignore", V0_WARNING, DeprecationWarning, re.escape(_WARNING_MODULE))


V0_WARNING = r".*The environment HeartPole-v0 is out of date"
"""A message pattern of Gymnasium's warning that ``HeartPole-v0`` "is out of date" (its text starts with colour
codes and ``WARN:``, hence the ``.*``)."""
_WARNING_MODULE = "gymnasium.envs.registration"  # where Gymnasium's warning is raised (its _find_spec)
# Python's own filters, last in the list at startup in this order (PEP 565); a match there is no wish of the
# user's. An equal filter of the user's (``-W ignore::DeprecationWarning``) takes a default's place in front.
_PYTHON_DEFAULTS = (
    ("default", None, DeprecationWarning, "__main__", 0),
    ("ignore", None, DeprecationWarning, None, 0),
    ("ignore", None, PendingDeprecationWarning, None, 0),
    ("ignore", None, ImportWarning, None, 0),
    ("ignore", None, ResourceWarning, None, 0),
)


def honour_version_warning_filters() -> str | None:
    """Make the user's own warning filters decide Gymnasium's "HeartPole-v0 is out of date" warning; the action
    taken (``"ignore"``, ``"error"``, ...), or ``None`` where the user's filters say nothing about it.

    Importing Gymnasium puts a ``"once"`` filter for DeprecationWarnings raised in Gymnasium's modules in front
    of every filter there is, so ``python -W ignore::DeprecationWarning``, ``PYTHONWARNINGS`` and a filter
    added before ``import gymnasium`` never reach the v0 warning, and every worker process (an async vector
    env's, SubprocVecEnv's, Ray's) prints it again. ``import heartpole`` (in every worker, where the env is
    made) looks through the filters behind Gymnasium's for the first that matches the v0 warning; if it is the
    user's (from ``-W``, ``PYTHONWARNINGS`` or their code), not one of Python's defaults, it adds one filter
    with that filter's action for the v0 warning alone. Without such a filter it changes nothing and returns
    ``None`` ([`register_envs`][heartpole.registry.register_envs] then ignores the warning).
    """
    from gymnasium.utils import colorize

    text = colorize(f"WARN: The environment {V0_ID} is out of date. You should consider upgrading to version `v1`.",
                    "yellow")  # fmt: skip
    filters = list(warnings.filters)
    start, expected = len(filters), list(_PYTHON_DEFAULTS)  # where Python's defaults begin
    while start > 0 and expected:
        if filters[start - 1] == expected.pop():
            start -= 1
    for index, (action, message, category, module, lineno) in enumerate(filters):
        if _is_gymnasiums(action, module):
            continue
        if not issubclass(DeprecationWarning, category) or lineno:
            continue
        if (message is None or message.match(text)) and (module is None or _module_matches(module)):
            if index >= start:
                return None  # Python's default: the user asked nothing
            if index == 0 or not any(_is_gymnasiums(f[0], f[3]) for f in filters[:index]):
                return action  # already in front of Gymnasium's: it applies as it is
            warnings.filterwarnings(cast(Any, action), V0_WARNING, DeprecationWarning, re.escape(_WARNING_MODULE))
            return action
    return None


def _is_gymnasiums(action: str, module: Any) -> bool:
    """Whether a filter is the one ``import gymnasium`` adds (``once`` for its own modules)."""
    pattern = getattr(module, "pattern", module)
    return action == "once" and isinstance(pattern, str) and pattern.startswith(r"^gymnasium")


def _module_matches(module: Any) -> bool:
    return bool(module.match(_WARNING_MODULE)) if hasattr(module, "match") else module == _WARNING_MODULE


def solved_bar(dynamics: Dynamics) -> SolvedBar:
    """The solved bar of the env with ``dynamics``: v0's issue-3 bar (<= 1.30 heart attacks, score >= 0.30)
    carried over to any variant by the same proportions ([`solved_bar`][heartpole.solved.solved_bar])."""
    return bar_of_params(dynamics.params, best_known_rate(dynamics))


def register_variant(
    id: str,
    actions: Sequence[Action | Mapping[str, Any]] | None = None,
    variables: Sequence[Variable | Mapping[str, Any]] | None = None,
    *,
    replace: bool = False,
    **params: Any,
) -> EnvSpec:
    """Define a HeartPole variant and register it with Gymnasium, for ``make`` and ``make_vec`` alike.

    Args:
        id: the new id, ``"Name-vN"`` (optionally ``"namespace/Name-vN"``): a name that starts with a
            letter, then ``-v`` and a version number, as Gymnasium spells ids.
        actions: the action set in action-index order, as [`heartpole.Action`][heartpole.actions.Action] objects or
            mappings of their fields (``{"name": ..., "effects": {...}, "rest_half_hours": ..., "sleeps": ..., "fact":
            ..., "source": ...}``). Default: v0's four. Start from ``heartpole.V0_ACTIONS`` or ``heartpole.V1_ACTIONS``
            to keep their indices.
        variables: the state variables in observation order: v0's six exactly
            (``heartpole.V0_VARIABLES``), then any that the actions need, as
            [`heartpole.Variable`][heartpole.parameters.Variable] objects or mappings of their fields. Each starts
            at 0, so 0 must lie within its bounds. Default: v0's six. ``heartpole.V1_VARIABLES`` adds v1's ``thc``.
        replace: redefine a variant this function registered before (handy when re-running a notebook).
            The built-in ``HeartPole-v0`` and ``HeartPole-v1`` and other packages' ids are never replaced.
        **params: [`heartpole.Params`][heartpole.parameters.Params] fields: ``heart_attack_proclivity``, ``max_steps``,
            ``decay_rate``, ``sleep_half_hours``, ``heart_attack_penalty``, ``wake_alertness``. They become
            the variant's defaults, which ``gymnasium.make(id, ...)`` can still override.

    Returns:
        The registered `gymnasium.envs.registration.EnvSpec`.

    Raises:
        ValueError: a malformed or taken id; an action or variable of the wrong type, shape or value, or
            with a missing or unknown field; duplicate names; an effect on a variable the variant lacks or
            that the step keeps itself; a parameter out of range.
        TypeError: a keyword argument that is not a parameter of a variant (Python's own wording).

    >>> import gymnasium as gym
    >>> import heartpole
    >>> tea = heartpole.Action("drink_tea", effects={"alertness": (0.0, 0.5), "hypertension": (0.0, 0.15)})
    >>> spec = register_variant("TeaPole-v0", [*heartpole.V0_ACTIONS, tea], max_steps=200, replace=True)
    >>> spec.kwargs["max_steps"], spec.max_episode_steps  # the env is its own time limit
    (200, None)
    >>> env = gym.make("TeaPole-v0")
    >>> env.action_space, env.unwrapped.actions[4].name, env.spec.max_episode_steps
    (Discrete(5), 'drink_tea', 200)
    """
    _check_id(id, replace)
    spec = define_variant(id, actions, variables, _params(params))
    _variants.add(id)
    return spec


def define_variant(
    env_id: str,
    actions: Sequence[Action | Mapping[str, Any]] | None = None,
    variables: Sequence[Variable | Mapping[str, Any]] | None = None,
    params: Mapping[str, Any] | None = None,
    *,
    entry_points: tuple[str, str] | None = None,
    reward_threshold: float | None = None,
) -> EnvSpec:
    """Check a variant's definition by building its [`Dynamics`][heartpole.dynamics.Dynamics] and register it:
    the one path of every variant, HeartPole's own v0 and v1 and users' (through
    `register_variant`, which checks their ids first).

    The spec's kwargs are the actions, the variables and ``params``, for the env constructors
    (``entry_points`` ``None``: ``heartpole.env:HeartPole`` and ``heartpole.vector:HeartPoleVectorEnv``), or
    ``params`` only for a variant's own constructors, which bind its actions and variables (v1's, whose spec
    so stays plain data); either way with ``max_steps``, the episode length, and no ``max_episode_steps``
    (`heartpole.time_limit`). ``reward_threshold`` defaults to the variant's
    `solved_bar`. Raises ``ValueError`` naming the id on a bad definition,
    leaving the registry as it was.
    """
    model_params = dict(params or {})
    try:
        action_set = _actions(actions)
        variable_set = _variables(variables)
        proclivity = model_params.pop("heart_attack_proclivity", Params.heart_attack_proclivity)
        max_steps = model_params.pop("max_steps", Params.max_steps)
        # The env's own constructor path: what passes here builds every env of the variant.
        dynamics = build_dynamics(proclivity, max_steps, action_set, variable_set, model_params)
    except ValueError as error:
        raise ValueError(f"HeartPole variant {env_id!r}: {error}") from None
    kwargs: dict[str, Any] = {**({"actions": action_set, "variables": variable_set} if entry_points is None else {})}
    kwargs.update(params or {})
    kwargs["max_steps"] = int(max_steps)  # the length, declared as the env's own parameter: no TimeLimit wrapper
    entry_point, vector_entry_point = entry_points or (ENTRY_POINT, VECTOR_ENTRY_POINT)
    replaced = gym.registry.pop(env_id, None)  # only a variant of ours, when replacing
    try:
        gym.register(
            id=env_id,
            entry_point=entry_point,
            vector_entry_point=vector_entry_point,
            kwargs=kwargs,
            reward_threshold=solved_bar(dynamics).reward_threshold if reward_threshold is None else reward_threshold,
        )
    except gym.error.Error as error:  # Gymnasium's own version rules, e.g. "Name" and "Name-v0" together
        if replaced is not None:
            gym.registry[env_id] = replaced
        raise ValueError(f"HeartPole variant {env_id!r}: {error}") from None
    return gym.spec(env_id)


def heartpole_ids() -> tuple[str, ...]:
    """The ids of HeartPole's envs in this process: ``HeartPole-v0``, ``HeartPole-v1`` and the variants
    [`register_variant`][heartpole.registry.register_variant] registered, in that order."""
    return (*BUILTIN_IDS, *sorted(i for i in _variants if i in gym.registry))


def check_heartpole_id(env_id: object, source: str) -> str:
    """``env_id``, read from ``source`` (a file, named in the message), if it is one of
    [`heartpole_ids`][heartpole.registry.heartpole_ids]; otherwise a ``ValueError`` naming the file, the id and the
    accepted ids.

    The check is a lookup in HeartPole's own ids and nothing more: Gymnasium would import the module of a
    ``"module:Name-v0"`` id, and make an env of any other registered id, so an id from a file someone else may
    have written is checked here before anything imports or makes it.
    """
    accepted = heartpole_ids()
    if not isinstance(env_id, str) or env_id not in accepted:
        raise ValueError(
            f"{source}: env id {env_id!r} is not a HeartPole env; accepted: {', '.join(accepted)} (nothing was "
            "imported or made)"
        )
    return env_id


# ------------------------------------------------------------------------------------------------------
# checks


def _check_id(env_id: object, replace: bool) -> None:
    if not isinstance(env_id, str) or not _ID.fullmatch(env_id):
        raise ValueError(
            f"a HeartPole variant id must look like 'Name-vN' or 'namespace/Name-vN' (a name starting with a "
            f"letter, of letters, digits, '_', '-' and '.', then '-v' and a version such as 0 or 12), e.g. "
            f"'MyPole-v0'; got {env_id!r}"
        )
    if not isinstance(replace, bool):
        raise ValueError(f"replace must be True or False, got {replace!r}")
    if env_id in BUILTIN_IDS:
        raise ValueError(f"{env_id!r} is built into HeartPole and cannot be redefined; give your variant its own id")
    namespace, name, _ = parse_env_id(env_id)
    if namespace is None and name == RESERVED_NAME:
        raise ValueError(
            f"{env_id!r}: '{RESERVED_NAME}-vN' ids are reserved for HeartPole's own versions (Gymnasium would "
            f"take a higher one for v0's successor); give your variant its own name, e.g. 'MyPole-v0'"
        )
    if env_id in gym.registry and not (replace and env_id in _variants):
        name, version = env_id.rsplit("-v", 1)
        hint = "pass replace=True to redefine it" if env_id in _variants else "it is not a HeartPole variant"
        raise ValueError(
            f"{env_id!r} is already registered ({hint}); choose another id, e.g. '{name}-v{int(version) + 1}'"
        )


def _actions(actions: object) -> tuple[Action, ...]:
    if actions is None:
        return V0_ACTIONS
    if isinstance(actions, (str, bytes, Mapping, Action)) or not isinstance(actions, Sequence):
        raise ValueError(
            "actions must be a list of heartpole.Action objects (or mappings of their fields), e.g. "
            f"[*heartpole.V0_ACTIONS, my_action]; got {type(actions).__name__} {actions!r}"
        )
    return tuple(as_action(definition, position) for position, definition in enumerate(actions))


def _variables(variables: object) -> tuple[Variable, ...]:
    if variables is None:
        return V0_VARIABLES
    if isinstance(variables, (str, bytes, Mapping, Variable)) or not isinstance(variables, Sequence):
        raise ValueError(
            "variables must be a list of heartpole.Variable objects (or mappings of their fields) starting "
            "with v0's six, e.g. (*heartpole.V0_VARIABLES, heartpole.Variable('stress', 0.0, decay=0.9)); "
            f"got {type(variables).__name__} {variables!r}"
        )
    return tuple(_variable(definition, position) for position, definition in enumerate(variables))


def _variable(definition: object, position: int) -> Variable:
    where = f"variable #{position}"
    if isinstance(definition, Mapping):
        unknown = [key for key in definition if key not in VARIABLE_FIELDS]
        if unknown:
            raise ValueError(f"{where} has unknown field(s) {unknown}; accepted fields are {list(VARIABLE_FIELDS)}")
        if "name" not in definition:
            raise ValueError(f"{where} is missing its 'name'; accepted fields are {list(VARIABLE_FIELDS)}")
        definition = Variable(**definition)
    if not isinstance(definition, Variable):
        raise ValueError(
            f"{where} must be a heartpole.Variable or a mapping with fields {list(VARIABLE_FIELDS)}, got "
            f"{type(definition).__name__} {definition!r}"
        )
    return definition  # a Variable checks its own fields when it is made


def _params(params: dict[str, Any]) -> dict[str, Any]:
    """The variant's parameters; ``TypeError`` (Python's, for an unexpected keyword) names any it does not take."""
    for name, where in _MAKE_TIME.items():
        if name in params:
            raise TypeError(
                f"register_variant() got an unexpected keyword argument {name!r}: it is chosen when making the "
                f"env, not when defining a variant; pass it to {where}"
            )
    if "max_episode_steps" in params:
        raise TypeError(
            "register_variant() got an unexpected keyword argument 'max_episode_steps': a variant's episode "
            "length is max_steps (its envs' spec.max_episode_steps reports it); "
            f"pass max_steps={params['max_episode_steps']!r}"
        )
    check_keywords("register_variant", params, ["id", "actions", "variables", "replace", *PARAMETERS])
    return dict(params)


def env_dynamics(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> Dynamics:
    """The [`Dynamics`][heartpole.dynamics.Dynamics] of the HeartPole env ``env_id`` built with ``env_kwargs``.

    ``max_episode_steps`` is a time limit on the env's ``max_steps`` (the registered one unless given), as
    ``gymnasium.make_vec`` gives it to the vector env ([`episode_length`][heartpole.time_limit.episode_length]):
    it may shorten the episodes, and one above ``max_steps`` is refused (``gymnasium.make`` would give it to a
    ``TimeLimit`` wrapper, which cannot lengthen them).

    Raises:
        ValueError: for an unknown id, a bad value, a ``max_episode_steps`` above ``max_steps``, or an env that is
            not a HeartPole.
        TypeError: for a keyword argument the env does not take, or a value of the wrong type.
    """
    kwargs = dict(env_kwargs or {})
    if "max_episode_steps" in kwargs:  # gym.make hands it to a TimeLimit only; the env takes it, as make_vec does
        registered = getattr(gym.registry.get(env_id), "kwargs", {}).get("max_steps")
        kwargs["max_steps"] = episode_length(kwargs.get("max_steps", registered), kwargs.pop("max_episode_steps"))
    try:
        with quiet_version_warnings():
            env = gym.make(env_id, **kwargs)
    except gym.error.Error as error:
        raise ValueError(f"unknown env {env_id!r} ({one_line(error)}); HeartPole envs: {_heartpole_ids()}") from None
    except TypeError as error:  # an unexpected keyword stays Python's TypeError, which callers branch on
        raise TypeError(f"env {env_id!r}: {_without_creator_tail(error)}") from None
    dynamics = getattr(env.unwrapped, "dynamics", None)
    env.close()
    if not isinstance(dynamics, Dynamics):
        raise ValueError(f"env {env_id!r} is not a HeartPole env; HeartPole envs: {_heartpole_ids()}")
    return dynamics


@contextmanager
def quiet_version_warnings() -> Iterator[None]:
    """Silence Gymnasium's "environment HeartPole-v0 is out of date" warning: evaluating v0 is deliberate."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*is out of date.*", category=DeprecationWarning)
        yield


def _without_creator_tail(error: BaseException) -> str:
    """``error``'s message without the tail Gymnasium's ``make`` adds ("was raised from the environment creator
    for ID with kwargs (...)"), which repeats what the caller gave."""
    return re.sub(r"\s*was raised from the environment creator for .*$", "", one_line(error))


def one_line(error: BaseException) -> str:
    """``error``'s message on one line, to quote inside another message."""
    return " ".join(str(error).split())


def _heartpole_ids() -> str:
    return ", ".join(sorted(i for i in gym.registry if i.startswith("HeartPole")))
