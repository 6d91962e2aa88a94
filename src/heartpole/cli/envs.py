"""``--env`` and ``--env-kwargs`` on the commands that play policies, and the env a model folder records.

A model folder written by ``heartpole train`` records the env id and keyword arguments it was trained on
([`heartpole.policies.trained_env`][heartpole.policies.trained_env]). ``evaluate``, ``compare``,
``baselines``, ``record`` and ``plot episode`` play a model on that env by default and say so in one line on
stderr; ``--env-kwargs`` overrides some of the recorded keyword arguments (the others stay), and ``--env`` given
on the command line wins over the record altogether (then only ``--env-kwargs`` gives keyword arguments).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import Any

from heartpole.cli.common import CommandError, env_id_type, error_line

DEFAULT_ENV = "HeartPole-v0"
ENV_KWARGS_HELP = (
    "the env's keyword arguments, as JSON ('{\"max_steps\": 200}') or NAME=VALUE pairs separated by commas "
    "(max_steps=200,heart_attack_proclivity=0.8); with a model whose folder records its env, these replace the "
    "recorded values of the same names"
)


def add_env_options(parser: argparse.ArgumentParser, *, kwargs: bool = True) -> None:
    """``--env ID`` (default: the env a model's folder records, else HeartPole-v0) and, with ``kwargs``,
    ``--env-kwargs``."""
    parser.add_argument(
        "--env",
        default=None,
        type=env_id_type,
        metavar="ID",
        help=f"env id (default: the env a model's folder records, else {DEFAULT_ENV}); wins over the record",
    )
    if kwargs:
        parser.add_argument("--env-kwargs", type=env_kwargs_type, default=None, metavar="KWARGS", help=ENV_KWARGS_HELP)


def parse_env_kwargs(text: str, option: str = "--env-kwargs") -> dict[str, Any]:
    """``text`` as keyword arguments: a JSON object, or ``NAME=VALUE`` pairs separated by commas, each value
    read as JSON where it parses (``0.8``, ``true``, ``[1, 2]``) and as text otherwise (``people=default``).

    Raises:
        ValueError: naming ``option``, for anything else.
    """
    stripped = text.strip()
    if stripped.startswith("{"):
        try:
            value = json.loads(stripped)
        except ValueError as error:
            raise ValueError(f"{option}: not a JSON object ({error_line(error)}): {text!r}") from None
        if not isinstance(value, dict):
            raise ValueError(f"{option}: expected a JSON object, got {text!r}")
        return value
    kwargs: dict[str, Any] = {}
    for item in filter(None, (part.strip() for part in stripped.split(","))):
        name, sep, raw = item.partition("=")
        name = name.strip()
        if not sep or not name.isidentifier():
            raise ValueError(
                f"{option} takes JSON or NAME=VALUE pairs such as max_steps=200,people=default; got {item!r}"
            )
        try:
            kwargs[name] = json.loads(raw)
        except ValueError:
            kwargs[name] = raw.strip()
    return kwargs


def env_kwargs_type(text: str) -> dict[str, Any]:
    """argparse type of ``--env-kwargs``: [`parse_env_kwargs`][heartpole.cli.envs.parse_env_kwargs]."""
    try:
        return parse_env_kwargs(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error).removeprefix("--env-kwargs: ")) from None


def choose_env(args: argparse.Namespace, specs: Sequence[str]) -> tuple[str, dict[str, Any]]:
    """The env id and keyword arguments the policies ``specs`` play, from ``args.env``, ``args.env_kwargs`` and
    the env the models' folders record, said in one line on stderr when a record decides.

    Raises:
        CommandError: a record that cannot be used, models whose folders record different envs (without
            ``--env``), or a keyword given by both ``--env-kwargs`` and ``--people`` (or ``--observe-traits``)
    """
    from heartpole.policies.trained_env import trained_env

    override: dict[str, Any] = dict(getattr(args, "env_kwargs", None) or {})
    joined_kwargs(override, {name: True for name in PEOPLE_OPTIONS if getattr(args, name, None) not in (None, False)})
    try:
        recorded = [(spec, env) for spec in specs if (env := trained_env(spec)) is not None]
    except ValueError as error:
        raise CommandError(error_line(error)) from None
    if args.env is not None:
        for spec, env in recorded:
            if (env.env_id, env.env_kwargs) != (args.env, override):
                print(f"note: {spec} was trained on {env.describe()} ({env.source}); playing --env {args.env}"
                      f"{f' with {override}' if override else ''} as given", file=sys.stderr)  # fmt: skip
        return checked_env(args.env, override)
    if not recorded:
        return checked_env(DEFAULT_ENV, override)
    first_spec, first = recorded[0]
    for spec, env in recorded[1:]:
        if (env.env_id, env.env_kwargs) != (first.env_id, first.env_kwargs):
            raise CommandError(
                f"{first_spec} was trained on {first.describe()} and {spec} on {env.describe()}; "
                "give --env (and --env-kwargs) to choose the env they play"
            )
    kwargs = {**first.env_kwargs, **override}
    shown = f"{first.env_id} with {kwargs}" if kwargs else first.env_id
    overridden = f" (--env-kwargs replacing {sorted(override)})" if override else ""
    chosen = checked_env(first.env_id, kwargs)
    print(f"playing {shown} as recorded in {first.source}{overridden}", file=sys.stderr)
    return chosen


PEOPLE_OPTIONS = {"people": "--people", "observe_traits": "--observe-traits"}
"""The env keywords the people options give, with their options."""


def joined_kwargs(env_kwargs: dict[str, Any], people: dict[str, Any]) -> dict[str, Any]:
    """``--env-kwargs``' keywords with those of ``--people`` and ``--observe-traits`` (``people``); a keyword both
    give is a one-line [`CommandError`][heartpole.cli.common.CommandError], as Python refuses a keyword argument
    given twice."""
    twice = [name for name in PEOPLE_OPTIONS if name in env_kwargs and name in people]
    if twice:
        options = " and ".join(PEOPLE_OPTIONS[name] for name in twice)
        raise CommandError(
            f"--env-kwargs gives {', '.join(twice)} and so does {options}; give each once (drop "
            f"{', '.join(f'{name}=' for name in twice)} from --env-kwargs, or {options})"
        )
    return {**env_kwargs, **people}


def checked_env(env_id: str, kwargs: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """``(env_id, kwargs)`` once the env is known to take them: a keyword it does not take or a bad value is a
    one-line [`CommandError`][heartpole.cli.common.CommandError] before any work (``evaluate``'s and ``train``'s
    ``--env-kwargs``); a ``max_episode_steps`` becomes the ``max_steps`` it makes, so that a model folder records
    the length itself (under a later ``max_steps`` it would shorten that silently)."""
    from heartpole.registry import env_dynamics

    if kwargs:
        try:
            dynamics = env_dynamics(env_id, kwargs)
        except (ValueError, TypeError) as error:
            raise CommandError(f"env {env_id} with {kwargs}: {error_line(error)}") from None
        if "max_episode_steps" in kwargs:
            kwargs = {k: v for k, v in kwargs.items() if k != "max_episode_steps"}
            kwargs["max_steps"] = int(dynamics.params.max_steps)
    return env_id, kwargs
