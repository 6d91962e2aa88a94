"""An episode's length: HeartPole's ``max_steps``, Gymnasium's ``max_episode_steps``, and the spec that reports it.

HeartPole is its own time limit: every episode is truncated after ``max_steps`` decisions. So its registered
specs carry no ``max_episode_steps`` (``gymnasium.make`` would wrap a second, disagreeing ``TimeLimit`` around an
env made with another ``max_steps``); they declare the length in their kwargs, as ``max_steps``, and the envs
report it: [`OwnTimeLimit`][heartpole.time_limit.OwnTimeLimit] makes ``env.spec.max_episode_steps`` the env's
``max_steps``. ``max_episode_steps`` stays what it is in Gymnasium, a time limit: it may shorten an episode,
never lengthen it ([`episode_length`][heartpole.time_limit.episode_length]).
"""

from __future__ import annotations

import copy

from gymnasium.envs.registration import EnvSpec

from heartpole.parameters import MAX_STEPS, Params, check_integer


def episode_length(max_steps: int | None, max_episode_steps: int | None) -> int:
    """The episode length of an env built with HeartPole's ``max_steps`` and Gymnasium's ``max_episode_steps``.

    Either alone is the length (neither: 1000). Both: ``max_episode_steps`` is a time limit on an env of
    ``max_steps`` decisions, as Gymnasium's ``TimeLimit`` wrapper would be, so the shorter one, ``max_episode_steps``,
    when it is at most ``max_steps``; above it, ``ValueError`` (a time limit cannot lengthen the env's episodes,
    ``max_steps`` does). This is the case of ``gymnasium.make_vec(id, max_episode_steps=k)``, whose registered
    kwargs give ``max_steps``.

    >>> episode_length(None, 1500), episode_length(1000, 500), episode_length(None, None)
    (1500, 500, 1000)
    """
    if max_episode_steps is None:
        return Params.max_steps if max_steps is None else max_steps  # the env checks max_steps with its parameters
    limit = check_integer("max_episode_steps", max_episode_steps, 1, MAX_STEPS)
    if max_steps is None:
        return limit
    steps = check_integer("max_steps", max_steps, 1, MAX_STEPS)
    if limit > steps:
        raise ValueError(
            f"max_episode_steps={limit} is above max_steps={steps}, the env's episode length: a time limit only "
            f"shortens episodes; set the length with max_steps={limit}"
        )
    return limit


class OwnTimeLimit:
    """A HeartPole env's ``spec``: the spec it was made from, with ``max_episode_steps`` its own ``max_steps``.

    ``gymnasium.make`` and ``make_vec`` set ``env.unwrapped.spec`` after building the env (``make`` with
    ``max_episode_steps=None``, since the env is its own time limit); this setter keeps a copy whose
    ``max_episode_steps`` and ``kwargs["max_steps"]`` are the length the env truncates at (a ``max_episode_steps``
    kwarg is dropped: ``max_steps`` says it), so ``env.spec.max_episode_steps`` reports it and ``gymnasium.make``
    of the spec makes an env of the same length.
    """

    max_steps: int

    @property
    def spec(self) -> EnvSpec | None:
        """The spec this env was made from, its ``max_episode_steps`` this env's ``max_steps`` (``None``: made
        directly)."""
        return self.__dict__.get("_spec")

    @spec.setter
    def spec(self, spec: EnvSpec | None) -> None:
        if spec is not None:
            spec = copy.copy(spec)
            kwargs = {key: value for key, value in spec.kwargs.items() if key != "max_episode_steps"}
            spec.kwargs = {**kwargs, "max_steps": self.max_steps}
            spec.max_episode_steps = self.max_steps
        self.__dict__["_spec"] = spec
