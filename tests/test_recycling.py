"""The recycler hands back a step's arrays only once nobody else holds them, and the vector env's episodes do
not depend on whether its caller keeps them."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from heartpole.recycling import Recycler


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
    del second, third, held
    assert {id(a) for a in recycler()} <= set(first_id) | {id(a) for a in recycler._kept[0]}


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
