"""The truth of an evaluation under ``people``: each episode's person's optimum, and the oracle regret.

Under a population one optimum compares a policy with no one in particular, so
[`evaluate`][heartpole.evaluation.evaluate] reports, for an env made with a finite cohort of ``people``,
the **oracle regret**: the mean over episodes of (that episode's person's optimal expected return - the
policy's expected-risk return in it), with a 95% interval
([`oracle_regret`][heartpole.optimum.oracle_regret]). [`people_truth`][heartpole.truth.people_truth] solves
each distinct person once (cached on disk, a progress bar while it solves);
[`oracle_fields`][heartpole.truth.oracle_fields] turns the episodes' persons and returns into the result's
fields.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole.optimum.people import split_people

if TYPE_CHECKING:
    from heartpole.dynamics import Dynamics
    from heartpole.optimum import PeopleOptimum

NO_SINGLE_OPTIMUM = (
    "under people each person has their own optimum, so a regret against one optimum compares with no one: "
    "see the oracle regret"
)
"""Why an evaluation under ``people`` has no ``regret`` (its ``no_regret_reason``)."""


def people_truth(
    env_id: str,
    env_kwargs: Mapping[str, Any] | None,
    *,
    show_progress: bool = False,
    dynamics: Dynamics | None = None,
) -> PeopleOptimum | str | None:
    """Each person's optimum of the env's ``people``: ``None`` without people, or a sentence saying why there
    is no oracle regret (a distribution of people, a person the solver does not cover).

    The first solve of the default cohort takes a minute or two (then loads from the cache in about a
    second); ``show_progress`` draws a bar on stderr (where stderr is a terminal) while it runs. ``dynamics``: the
    env's, where the caller has resolved ``env_id`` (each person's parameters start from it).

    Raises:
        ValueError, TypeError: a ``people`` that [`People.resolve`][heartpole.people.People.resolve] refuses.
    """
    from heartpole.optimum import NotCoveredError, solve_people

    people, _ = split_people(env_kwargs)
    if people is None:
        return None
    if not people.finite:
        return "the people are a distribution: only a finite cohort's people have their optima solved ahead"
    from heartpole.progress import Progress

    bar = Progress(len(people.cohort), "each person's optimum", enabled=None if show_progress else False)

    def advance(done: int, total: int) -> None:
        bar.total = total  # distinct people: equal ones are solved once
        bar.update(done - bar.done)

    try:
        return solve_people(people, env_id, env_kwargs, progress=advance, dynamics=dynamics)
    except NotCoveredError as error:
        return f"the optimum is not known here ({' '.join(str(error).split())})"
    finally:
        bar.close()


def oracle_fields(
    truth: PeopleOptimum | str | None, person: np.ndarray, expected_returns: np.ndarray
) -> dict[str, Any]:
    """The oracle-regret fields of an [`EvaluationResult`][heartpole.results.EvaluationResult] whose
    episodes had these persons and expected-risk returns: ``oracle_regret`` and ``oracle_regret_ci95`` with
    each person's optimum, ``no_oracle_regret_reason`` with a reason, nothing without people."""
    if truth is None:
        return {}
    if isinstance(truth, str):
        return {"no_oracle_regret_reason": truth}
    found = truth.regret(person, expected_returns)
    return {"oracle_regret": found.regret, "oracle_regret_ci95": found.ci95}
