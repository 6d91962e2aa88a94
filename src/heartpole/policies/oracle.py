"""``oracle``: the policy that knows each episode's person and acts optimally for them.

It is [`OptimalPolicy`][heartpole.policies.OptimalPolicy] with one optimum per person of a finite cohort
([`PeopleOptimum`][heartpole.optimum.PeopleOptimum]): never drink; sleep when that person's own optimum does
([`PeopleOptimum.decide`][heartpole.optimum.people.PeopleOptimum.decide]).
It needs the decisions left and the person (``needs_person``: loops
call it as ``policy(obs, decisions_left, person=info["person"])`` through
[`act_batch`][heartpole.policies.act_batch]), so its oracle regret is about 0 by construction: it is the
yardstick oracle regret measures against, not an agent (a real agent does not see who it treats).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole.dynamics import Dynamics
from heartpole.policies.common import Actions, DecisionsLeft, Observations, PersonIndex, observation_batch

if TYPE_CHECKING:
    from heartpole.optimum import PeopleOptimum

NEEDS_COHORT = (
    "the oracle policy acts optimally for each person of a finite cohort: make the env with "
    "people='default' or people=People(cohort=[...])"
)


class OraclePolicy:
    """``oracle``: each env's person's optimal policy (see the module docstring).

    Args:
        dynamics: the env's dynamics; must be v0's actions and variables (as ``optimal``).
        optimum: each person's optimum, from [`solve_people`][heartpole.optimum.solve_people] (or use
            [`oracle_policy`][heartpole.policies.oracle.oracle_policy], which solves it for an env).

    Raises:
        ValueError: no ``optimum`` (the oracle needs a cohort's).
    """

    name = "oracle"
    needs_decisions_left = True
    needs_person = True

    def __init__(self, dynamics: Dynamics | None = None, optimum: PeopleOptimum | None = None) -> None:
        if optimum is None:
            raise ValueError(
                f"{NEEDS_COHORT}; build it with heartpole.policies.oracle_policy(env_id, env_kwargs) or "
                "load_policy('oracle', env_id, env_kwargs={'people': 'default'})"
            )
        dynamics = dynamics or Dynamics()
        self.optimum = optimum
        self.nothing = dynamics.action_index("do_nothing")
        self.sleep = dynamics.action_index("sleep")

    def __call__(
        self, obs: Observations, decisions_left: DecisionsLeft = None, *, person: PersonIndex = None
    ) -> Actions:
        obs = observation_batch(obs)
        if decisions_left is None or person is None:
            raise ValueError(
                "the oracle policy needs the decisions left and each env's person: call "
                "policy(obs, decisions_left, person=info['person']) (heartpole.policies.act_batch does it)"
            )
        who = np.broadcast_to(np.asarray(person, dtype=np.int64), (len(obs),))
        size = len(self.optimum.people.cohort)
        if len(who) and (who.min() < 0 or who.max() >= size):
            raise ValueError(
                f"the oracle policy knows the {size} people of its cohort (indices 0..{size - 1}), got person "
                f"indices {who.min()}..{who.max()} (-1 is a person drawn from a distribution: {NEEDS_COHORT})"
            )
        left = np.broadcast_to(np.asarray(decisions_left, dtype=np.int64), (len(obs),))
        sleeps = self.optimum.decide(who, obs, left)
        return np.where(sleeps, self.sleep, self.nothing).astype(np.int64)


def oracle_policy(
    env_id: str = "HeartPole-v0",
    env_kwargs: Mapping[str, Any] | None = None,
    dynamics: Dynamics | None = None,
    *,
    optimum: PeopleOptimum | None = None,
) -> OraclePolicy:
    """The ``oracle`` of the env ``env_id`` made with ``env_kwargs``, whose ``people`` must be a finite cohort;
    each person's optimum is solved once and cached (or give ``optimum``, solved already).

    Raises:
        ValueError: ``env_kwargs`` without ``people``, or a population that is a distribution (a person drawn
            from ranges has no optimum solved ahead: only a finite cohort's people do).
        heartpole.optimum.NotCoveredError: a person the solver does not cover.
    """
    from heartpole.optimum import solve_people, split_people

    people, _ = split_people(env_kwargs)
    if people is None or not people.finite:
        shown = "no people" if people is None else "a distribution of people"
        raise ValueError(f"{NEEDS_COHORT}; {env_id!r} was given {shown}")
    if optimum is None:
        optimum = solve_people(people, env_id, env_kwargs, dynamics=dynamics)
    return OraclePolicy(dynamics, optimum)
