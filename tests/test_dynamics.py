"""Dynamics: how actions become records, uniform columns and the single env's decay table.

That the single and batch paths agree is tested in test_vector.py and test_variants.py; that both follow
the tutorial, in test_faithfulness.py.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import heartpole
from heartpole import Action, Variable
from heartpole.actions import V0_ACTIONS, V1_ACTIONS, V1_VARIABLES
from heartpole.dynamics import DECAY_TABLE_SIZE
from heartpole.model import V0_VARIABLES, alertness_decay


@pytest.mark.parametrize(
    "actions, variables",
    [
        (V0_ACTIONS, V0_VARIABLES),
        (V1_ACTIONS, V1_VARIABLES),
        (
            (
                Action("a", {"alertness": (0, 1), "hypertension": (0, 1)}, sleeps=True),
                Action("b", {"hypertension": (0, 1), "intoxication": (0, 1)}),
                Action("c", {"intoxication": (0, 1), "extra": (0, 1)}),
            ),
            (*V0_VARIABLES, Variable("extra", 0.0, decay=0.5)),
        ),
    ],
    ids=["v0", "v1", "custom"],
)
def test_no_action_reads_one_uniform_column_twice(actions, variables) -> None:
    """Columns are shared between draws no action makes together; within an action every draw (its
    effects, waking up after sleep, the heart-attack coin) has its own column."""
    dynamics = heartpole.Dynamics(actions, variables=variables)
    for action in actions:
        columns = [dynamics.uniform_column[dynamics.names.index(name)] for name in action.effects]
        columns += [dynamics.wake_uniform] if action.sleeps else []
        columns += [dynamics.attack_uniform]
        assert len(set(columns)) == len(columns), action.name
        assert max(columns) < dynamics.num_uniforms
    assert dynamics.num_uniforms <= len(dynamics.random_variables) + 2


def test_v0_and_v1_need_four_columns() -> None:
    assert heartpole.Dynamics().num_uniforms == 4
    assert heartpole.Dynamics(V1_ACTIONS, variables=V1_VARIABLES).num_uniforms == 4


def test_the_decay_table_is_the_formula_at_whole_half_hours() -> None:
    dynamics = heartpole.Dynamics()
    for t in itertools.chain(range(0, 600), [DECAY_TABLE_SIZE - 1, DECAY_TABLE_SIZE, 5000.0]):
        assert dynamics._alertness_decay(float(t)) == alertness_decay(float(t))
    batch = np.arange(0, 2000, dtype=np.float32)
    np.testing.assert_array_equal(dynamics._alertness_decay(batch), alertness_decay(batch))


def test_batch_records_look_each_envs_action_up() -> None:
    dynamics = heartpole.Dynamics()
    actions = np.array([3, 0, 1, 2, 3, 1])
    record = dynamics.record(actions)
    single = [dynamics.record(int(a)) for a in actions]
    assert record.any_rest and record.any_wake
    np.testing.assert_array_equal(record.rest, [s.rest for s in single])
    np.testing.assert_array_equal(record.wakes, [s.wakes for s in single])
    np.testing.assert_array_equal(record.stays_awake, [s.stays_awake for s in single])
    only_coffee = dynamics.record(np.array([1, 1]))
    assert not only_coffee.any_rest and not only_coffee.any_wake
