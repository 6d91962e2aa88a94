"""The recycler hands back a step's arrays only once nobody else holds them, and the vector env's episodes do
not depend on whether its caller keeps them."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import heartpole.arrays
from heartpole import kernel
from heartpole.arrays import LINE, PAGE, SLOTS, SPACING, Recycler, new_results, staggered


def make_arrays() -> tuple[np.ndarray, ...]:
    return np.zeros(4), np.zeros((2, 4), dtype=np.float32)


def test_arrays_nobody_holds_come_back_after_the_two_steps_a_loop_holds() -> None:
    recycler = Recycler(make_arrays)
    first, second = recycler(), recycler()
    assert first is not second
    first_id = [id(a) for a in first]
    del first
    third = recycler()  # the caller still holds `second`, as a loop holds its last step's results
    assert [id(a) for a in third] == first_id
    held = recycler()  # `second` and `third` are still held: new arrays
    assert not {id(a) for a in held} & {id(a) for a in (*second, *third)}
    newest = [id(a) for a in held]
    del second, third, held
    assert [id(a) for a in recycler()] == newest  # the newest of those kept (two), the likeliest in the caches


@pytest.mark.parametrize(
    "hold",
    [
        lambda arrays: arrays[0],
        lambda arrays: arrays[1].T,  # a view holds its base
        lambda arrays: arrays[1][0, 1:],
        lambda arrays: memoryview(arrays[0]),
        lambda arrays: {"info": arrays[1]},
        lambda arrays: np.frombuffer(arrays[0].data, dtype=np.uint8),
    ],
)
def test_arrays_held_in_any_way_never_come_back(hold) -> None:
    recycler = Recycler(make_arrays)
    held = hold(recycler())
    before = np.array(held, copy=True) if not isinstance(held, dict) else held["info"].copy()
    for _ in range(5):
        for array in recycler():
            array[...] = 7.0
    after = np.asarray(held) if not isinstance(held, dict) else held["info"]
    np.testing.assert_array_equal(after, before)


def test_the_tuple_held_alone_holds_its_arrays() -> None:
    """The recycler hands back the very tuple it made, not a new one: whoever holds the tuple holds its arrays."""
    recycler = Recycler(make_arrays)
    held = recycler()
    before = [array.copy() for array in held]
    for _ in range(5):
        again = recycler()
        assert again is not held
        for array in again:
            array[...] = 7.0
        del again, array
    assert [id(a) for a in recycler()] == [id(a) for a in recycler()]  # dropped at once: the same come back
    for array, value in zip(held, before):
        np.testing.assert_array_equal(array, value)


def test_a_copy_or_a_pickle_keeps_how_to_make_the_arrays_not_the_arrays() -> None:
    recycler = Recycler(make_arrays)
    recycler(), recycler()
    for twin in (copy.deepcopy(recycler), pickle.loads(pickle.dumps(recycler))):
        assert twin._kept == [] and twin._alone == ()
        arrays = twin()
        assert [a.shape for a in arrays] == [(4,), (2, 4)]


def flat(outputs: object) -> list[object]:
    """Copies of every array in a step's outputs (dicts by key, object arrays item by item) as nested lists."""
    if isinstance(outputs, dict):
        return [(key, flat(value)) for key, value in sorted(outputs.items())]
    if isinstance(outputs, (tuple, list)) or (isinstance(outputs, np.ndarray) and outputs.dtype == object):
        return [flat(value) for value in outputs]
    return None if outputs is None else np.asarray(outputs).tolist()


def run(mode: AutoresetMode, people: str | None, keep: bool) -> list[object]:
    """Copies of every step's outputs; with ``keep`` the caller also holds every step's own arrays."""
    env = gym.make_vec(
        "HeartPole-v0",
        num_envs=5,
        vectorization_mode="vector_entry_point",
        max_steps=4,
        autoreset_mode=mode,
        people=people,
    )
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    held, seen = [], []
    for _ in range(13):
        obs, reward, terminated, truncated, info = env.step(rng.integers(0, 4, size=5))
        seen.append(flat((obs, reward, terminated, truncated, info)))
        if keep:
            held.append((obs, reward, info))
    return seen


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("people", [None, "default"])
def test_episodes_are_the_same_whether_the_caller_keeps_its_arrays_or_drops_them(mode, people) -> None:
    assert run(mode, people, keep=True) == run(mode, people, keep=False)


@pytest.mark.parametrize("people", [None, "default"])
def test_a_loop_that_drops_each_steps_arrays_gets_two_sets_back_for_ever(people) -> None:
    env = gym.make_vec("HeartPole-v0", num_envs=3, vectorization_mode="vector_entry_point", people=people).unwrapped
    made = []
    make = env._results._make
    env._results._make = lambda: made.append(1) or make()
    obs, _ = env.reset(seed=0)
    for _ in range(30):  # as a training loop: the last step's arrays are held while the next is made
        obs, reward, terminated, truncated, info = env.step(np.zeros(3, dtype=np.int64))
    assert len(made) == 2
    for _ in range(30):  # and one that drops them at once
        env.step(np.zeros(3, dtype=np.int64))
    assert len(made) == 2


def test_staggered_arrays_start_where_asked_in_one_block_a_page_apart() -> None:
    specs = [((5,), np.float32), ((3, 7), np.uint32), ((0,), np.bool_), ((16384,), np.int32)]
    made = staggered(specs, 60)
    for k, ((shape, dtype), array) in enumerate(zip(specs, made)):
        assert array.shape == shape and array.dtype == dtype and array.flags.carray
        assert array.size == 0 or array.ctypes.data % PAGE == (60 + k * SPACING) * LINE % PAGE
    assert len({id(array.base) for array in made}) == 1
    assert made[0].base.nbytes == 7 * PAGE + 16384 * 4


@pytest.mark.parametrize("people", [None, "default"])
def test_the_loops_own_arrays_start_at_their_slots_when_made_copied_and_pickled(people) -> None:
    env = gym.make_vec("HeartPole-v0", num_envs=64, vectorization_mode="vector_entry_point", people=people)
    env.reset(seed=0)
    for made in (env.unwrapped, copy.deepcopy(env.unwrapped), pickle.loads(pickle.dumps(env.unwrapped))):
        arrays = {"states": made._envs, "generators": made._rng, "cells": made._cells}
        for slot, array in arrays.items():
            if array is not None:
                assert array.flags.carray and array.ctypes.data % PAGE == SLOTS[slot] * LINE % PAGE, slot
        assert (made._cells is None) == (people is None)


def test_a_steps_arrays_are_named_and_come_back_named() -> None:
    """new_results gives the loop's StepResults, each array named for what it holds (the OUTPUTS by their dtypes),
    and the recycler hands back the same kind of tuple when it reuses them as when it makes them."""
    results = new_results(100, 6)
    assert type(results) is kernel.StepResults
    assert results._fields == (*kernel.OUTPUTS, "observations", "actions")
    for name, dtype in kernel.OUTPUTS.items():
        assert getattr(results, name).dtype == dtype and getattr(results, name).shape == (100,), name
    assert results.observations.shape == (6, 100) and results.actions.dtype == kernel.ACTION_DTYPE
    recycler = Recycler(lambda: new_results(100, 6))
    made = recycler()
    made_ids = [id(a) for a in made]
    del made
    recycler()
    again = recycler()
    assert type(again) is kernel.StepResults and [id(a) for a in again] == made_ids  # reused, and named


def test_a_step_keeps_its_observations_in_a_block_of_their_own() -> None:
    reward, productivity, risk, attack, score, observed, actions = new_results(100, 6)
    assert observed.shape == (6, 100) and observed.base.nbytes == 3 * PAGE
    assert {id(a.base) for a in (reward, productivity, risk, attack, score, actions)} == {id(reward.base)}
    assert [a.dtype for a in (reward, attack, actions)] == [np.float32, np.bool_, np.int32]


def test_without_reference_counts_to_trust_nothing_comes_back(monkeypatch) -> None:
    monkeypatch.setattr(heartpole.arrays, "COUNTED", False)
    made = []
    recycler = Recycler(lambda: made.append(1) or make_arrays())
    for _ in range(4):
        recycler()  # dropped at once: CPython would hand the same arrays back
    assert len(made) == 4
