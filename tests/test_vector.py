"""HeartPoleVectorEnv: Gymnasium's vector conventions, autoreset, reproducibility and bad input.

That its dynamics equal the single env's in distribution is tested in test_faithfulness.py.
"""

from __future__ import annotations

import copy
import re
import weakref

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import heartpole
import heartpole.arrays
from heartpole.env import RESET_INFO
from heartpole.vector import INFO_DTYPES, INFO_KEYS


def make(num_envs: int = 4, **kwargs) -> heartpole.HeartPoleVectorEnv:
    return gym.make_vec("HeartPole-v0", num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def test_batched_spaces_and_shapes() -> None:
    env = make(5, max_steps=20, heart_attack_proclivity=0.2)
    assert env.single_action_space == gym.spaces.Discrete(4)
    assert env.action_space == gym.spaces.MultiDiscrete([4] * 5)
    assert env.observation_space.shape == (5, 6) and env.observation_space.dtype == np.float32
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert env.dynamics.params.heart_attack_proclivity == 0.2 and env.max_steps == 20
    obs, info = env.reset(seed=0)
    assert obs.shape == (5, 6) and obs.dtype == np.float32 and obs in env.observation_space
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert reward.shape == terminated.shape == truncated.shape == (5,) and reward.dtype == np.float32
    for key in ("heart_attack", "heart_attack_risk", "productivity", "score"):
        assert info[key].shape == (5,) and info["_" + key].all()


def test_reset_seed_reproduces_and_envs_are_independent() -> None:
    actions = np.random.default_rng(0).integers(0, 4, (50, 8))

    def run(seed: int) -> list[bytes]:
        env = make(8)
        out = [env.reset(seed=seed)[0].tobytes()]
        out += [env.step(a)[0].tobytes() for a in actions]
        return out

    assert run(3) == run(3)
    assert run(3) != run(4)
    obs, _ = make(8).reset(seed=3)
    assert len(set(obs[:, 0].tolist())) == 8  # each env wakes up with its own alertness


def test_next_step_autoreset_restarts_an_env_on_the_step_after_truncation() -> None:
    env = make(3, max_steps=3)
    env.reset(seed=1)
    for _ in range(2):
        assert not env.step(np.array([1, 2, 0]))[3].any()
    obs, reward, terminated, truncated, _ = env.step(np.array([1, 2, 0]))
    assert truncated.all() and not terminated.any() and obs[:, 4].min() >= 3
    truncated[:], terminated[:] = False, True  # the caller's arrays: the env does not read them back
    obs, reward, terminated, truncated, info = env.step(np.array([3, 3, 3]))  # actions ignored
    assert not truncated.any() and (reward == 0).all()
    assert all((info[k] == v).all() and info["_" + k].all() for k, v in RESET_INFO.items())  # reset()'s values
    assert (obs[:, 1:] == 0).all() and ((obs[:, 0] >= 0.7) & (obs[:, 0] <= 1.3)).all()
    obs, *_ = env.step(np.array([0, 0, 0]))
    assert (obs[:, 4] == 1).all()


def test_same_step_autoreset_reports_the_final_observation() -> None:
    env = heartpole.HeartPoleVectorEnv(2, max_steps=2, autoreset_mode=AutoresetMode.SAME_STEP)
    assert env.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    env.reset(seed=2)
    env.step(np.array([0, 0]))
    obs, _, _, truncated, info = env.step(np.array([0, 1]))
    assert truncated.all() and info["_final_obs"].all() and info["final_obs"].dtype == object
    assert [last[4] for last in info["final_obs"]] == [2, 2]  # two half-hours worked
    assert (obs[:, 4] == 0).all()  # already the next episode
    assert info["final_info"]["score"].shape == (2,) and info["final_info"]["_score"].all()
    np.testing.assert_array_equal(info["final_info"]["action_taken"], [0, 1])
    np.testing.assert_array_equal(info["action_taken"], [-1, -1])  # the new episodes' reset() values


def test_info_has_the_single_envs_keys_with_action_indices() -> None:
    env = make(3)
    env.reset(seed=0)
    info = env.step(np.array([2, 0, 3]))[4]
    single = heartpole.HeartPole()
    single.reset(seed=0)
    single_info = single.step(2)[4]
    assert {k for k in info if not k.startswith("_")} == set(single_info) == set(RESET_INFO)
    np.testing.assert_array_equal(info["action_taken"], [2, 0, 3])
    assert single_info["action_taken"] == 2 and env.action_names[info["action_taken"][0]] == "drink_beer"
    assert all(info["_" + k].all() for k in info if not k.startswith("_"))


BAD_ACTIONS = [
    (np.array([0, 1, 2]), "shape"),
    (np.array([[0, 1, 2, 3]]), "shape"),
    (np.array([0.0, 1.0, 2.0, 3.0]), "dtype"),
    (np.array([0, 1, 2, 4]), "values"),
    (np.array([0, -1, 2, 3]), "values"),
    (np.array([0, -1, 2, 3], dtype=np.int8), "values"),  # converted to int64 first: still negative
    (np.array([0, 1, 2, 2**64 - 1], dtype=np.uint64), "values"),  # wraps to -1 as int64, huge again in the check
    (np.array([0, 1, 2, 2**63 + 2], dtype=np.uint64), "values"),
    (np.array([0, 1, 2, 4], dtype=np.uint8), "values"),
    (["a", "b", "c", "d"], "dtype"),
    (3, "shape"),
]


@pytest.mark.parametrize("actions, what", BAD_ACTIONS, ids=[w + str(i) for i, (_, w) in enumerate(BAD_ACTIONS)])
def test_bad_action_batches_raise_and_change_nothing(actions, what: str) -> None:
    env = make(4)
    env.reset(seed=5)
    env.step(np.array([1, 1, 2, 3]))
    untouched = copy.deepcopy(env)
    with pytest.raises(ValueError, match=f"integer array of shape \\(4,\\) with values in 0..3; got {what}"):
        env.step(actions)
    np.testing.assert_array_equal(env.state, untouched.state)
    good = np.array([0, 1, 2, 3])
    assert env.step(good)[0].tobytes() == untouched.step(good)[0].tobytes()


def test_actions_of_any_integer_type_and_layout_step_as_int64_ones_do() -> None:
    base = np.array([3, 0, 2, 1])
    read_only = base.copy()
    read_only.flags.writeable = False
    given = [
        base.astype(np.int8),
        base.astype(np.uint16),
        base.astype(np.uint64),
        np.repeat(base, 2)[::2],  # not contiguous
        read_only,
        base.astype(">i8"),  # big-endian
        base.tolist(),
    ]
    reference = make(4)
    reference.reset(seed=2)
    reference.step(base)
    expected = reference.step(base)
    for actions in given:
        env = make(4)
        env.reset(seed=2)
        env.step(base)  # the compiled loop is planned for C-contiguous int64 actions
        obs, reward, _, _, info = env.step(actions)
        np.testing.assert_array_equal(obs, expected[0])
        np.testing.assert_array_equal(reward, expected[1])
        assert info["action_taken"].tolist() == base.tolist() and info["action_taken"].dtype == np.int32


def test_step_before_reset_and_bad_construction() -> None:
    with pytest.raises(gym.error.ResetNeeded):
        heartpole.HeartPoleVectorEnv(2).step(np.array([0, 0]))
    with pytest.raises(ValueError, match="num_envs"):
        heartpole.HeartPoleVectorEnv(0)
    with pytest.raises(ValueError, match="autoreset_mode must be one of .'NextStep', 'SameStep', 'Disabled'."):
        heartpole.HeartPoleVectorEnv(2, autoreset_mode="disabled")
    with pytest.raises(ValueError, match="max_steps"):
        heartpole.HeartPoleVectorEnv(2, max_steps=0)


def test_observations_are_copies_in_cartpoles_column_major_layout() -> None:
    env = make(5)
    obs, _ = env.reset(seed=0)
    for _ in range(2):
        np.testing.assert_array_equal(obs, env.state.T)
        assert obs.shape == (5, 6) and obs.dtype == np.float32 and obs.flags.f_contiguous
        assert env.observation_space.contains(obs)
        obs[:] = 99.0  # the caller owns its observations
        assert not np.any(env.state == 99.0)
        obs = env.step(np.array([0, 1, 2, 3, 1]))[0]


@pytest.mark.parametrize("people", [None, "default"])
def test_an_observation_handed_out_stays_as_it_was_through_later_steps_and_restarts(people) -> None:
    env = make(7, max_steps=3, people=people)  # the loop writes each step's observations into a fresh array
    handed = [env.reset(seed=0)[0]]
    for t in range(8):  # restarts (NEXT_STEP) at steps 4 and 8
        handed.append(env.step(np.arange(7) % 4)[0])
        if t == 5:
            handed.append(env.reset(seed=1, options={"reset_mask": np.arange(7) < 3})[0])
    kept = [obs.copy() for obs in handed]
    env.step(np.arange(7) % 4)
    env.reset(seed=2)
    for obs, copy_of_it in zip(handed, kept):
        np.testing.assert_array_equal(obs, copy_of_it)
    assert len({id(obs) for obs in handed}) == len(handed) and not any(
        np.shares_memory(a, b) for i, a in enumerate(handed) for b in handed[i + 1 :]
    )


TAKEN_BACK = ("obs", "reward", *INFO_KEYS)
"""The arrays of a step that a later one may take back (the class docstring's contract)."""


def held_step(env: heartpole.HeartPoleVectorEnv, actions: np.ndarray) -> dict[str, np.ndarray]:
    """One step's arrays that a later step may take back, by name, after the env has taken back arrays before."""
    for _ in range(3):
        env.step(actions)  # dropped at once: from here on each step hands back the arrays of an earlier one
    obs, reward, _, _, info = env.step(actions)
    return {"obs": obs, "reward": reward, **{key: info[key] for key in INFO_KEYS}}


def weakly(arrays: dict[str, np.ndarray]) -> dict[str, weakref.ref[np.ndarray]]:
    """Weak references to ``arrays`` but the observations (``obs`` is a transposed view, made anew at each step, of
    the array the env takes back: a weak reference to it dies with it)."""
    return {name: weakref.ref(array) for name, array in arrays.items() if name != "obs"}


@pytest.mark.skipif(not heartpole.arrays.COUNTED, reason="arrays are taken back only where reference counts tell")
@pytest.mark.parametrize("people", [None, "default"])
@pytest.mark.parametrize("hold", ["reference", "view", "one view"])
def test_a_steps_arrays_keep_their_values_through_later_steps_while_held(hold: str, people) -> None:
    env = make(6, people=people)
    env.reset(seed=0)
    actions = np.arange(6) % 4
    arrays = held_step(env, actions)
    values = {name: array.copy() for name, array in arrays.items()}
    if hold == "reference":
        held = {name: (array, values[name]) for name, array in arrays.items()}
    elif hold == "view":
        held = {name: (array[1:], values[name][1:]) for name, array in arrays.items()}
    else:  # a view of the observations alone holds every array of the step: the others watched weakly
        held = {"obs": (arrays["obs"][1:], values["obs"][1:])}
    watched = weakly(arrays)
    del arrays
    for _ in range(6):
        env.step(actions)  # each step's arrays dropped at once, as a loop that copies what it keeps
    for name, (array, value) in held.items():
        np.testing.assert_array_equal(array, value, err_msg=name)
    assert set(held) | set(watched) == set(TAKEN_BACK)
    for name, reference in watched.items():
        array = reference()  # alive while the env keeps it to take back (None: gone, and no step wrote to it)
        if array is not None:
            np.testing.assert_array_equal(array, values[name], err_msg=name)


@pytest.mark.skipif(not heartpole.arrays.COUNTED, reason="arrays are taken back only where reference counts tell")
def test_a_weak_reference_alone_does_not_hold_a_steps_arrays() -> None:
    env = make(6)
    env.reset(seed=0)
    actions = np.arange(6) % 4
    watched = weakly(held_step(env, actions))
    obs, reward, _, _, info = env.step(actions)  # takes back the arrays nothing holds: the step before's
    later = weakly({"obs": obs, "reward": reward, **{key: info[key] for key in INFO_KEYS}})
    assert all(watched[name]() is later[name]() is not None for name in TAKEN_BACK[1:])


def test_step_and_reset_leave_the_callers_actions_and_returned_info_alone() -> None:
    env = make(4, max_steps=3, render_mode="rgb_array", heart_attack_proclivity=1.0)
    always_sleep = np.full(4, 3, dtype=np.intp)  # the dtype the env works in: no conversion copies it
    infos = []
    for episode in range(2):
        env.reset(seed=episode)
        for _ in range(3):
            infos.append(env.step(always_sleep)[4])
    assert always_sleep.tolist() == [3, 3, 3, 3]
    kept = [info["heart_attack"].copy() for info in infos]
    env.reset(seed=5)
    assert all((info["heart_attack"] == k).all() for info, k in zip(infos, kept))
    env.step(always_sleep)
    always_sleep[:] = 9  # the caller reuses its array; the env's frames must not read it
    assert len(env.render()) == 4


def test_same_step_autoreset_forgets_the_ended_episode_for_rendering(monkeypatch) -> None:
    drawn = []
    monkeypatch.setattr(heartpole.vector.rendering, "draw_frame", lambda state, **kw: drawn.append(kw))
    env = heartpole.HeartPoleVectorEnv(
        1, max_steps=2, render_mode="rgb_array", autoreset_mode=AutoresetMode.SAME_STEP, heart_attack_proclivity=1.0
    )
    env.reset(seed=0)
    env.step(np.array([2]))
    env.render()
    assert drawn[-1]["action"] == "drink_beer" and drawn[-1]["step"] == 1
    *_, truncated, _ = env.step(np.array([2]))  # ends the episode; the env restarts within the step
    assert truncated[0]
    env.render()
    assert drawn[-1] == {**drawn[-1], "action": None, "heart_attack": False, "heart_attacks": 0, "step": 0}


# ---------------------------------------------------------------------------------------------------------
# Gymnasium's vector contract, side by side with SyncVectorEnv over HeartPole's single env.
#
# SyncVectorEnv seeds sub-env i with seed + i and its autoresets draw new keys, where the native env keys env i
# by the i-th draw of one generator and continues its counters through autoresets: with random dynamics the
# two agree bit for bit on env 0's first episode only (tested below on v0). On a configuration whose
# dynamics use no random number (no heart attacks, a fixed wake-up alertness, actions of fixed amounts) they
# must agree exactly on everything, through any autoresets and masked resets: that tests the semantics.
STEADY = {
    "heart_attack_proclivity": 0.0,
    "wake_alertness": (1.0, 1.0),
    "actions": [
        heartpole.Action("do_nothing"),
        heartpole.Action("fixed_coffee", {"alertness": (0.5, 0.5), "hypertension": (0.3, 0.3)}),
        heartpole.Action("fixed_beer", {"alertness": (-0.25, -0.25), "intoxication": (0.02, 0.02)}),
        heartpole.Action("sleep", sleeps=True),
    ],
}
MODES = list(AutoresetMode)


def twins(num_envs: int, mode: AutoresetMode, **kwargs) -> tuple[heartpole.HeartPoleVectorEnv, gym.vector.VectorEnv]:
    """The native vector env and SyncVectorEnv over the single env, alike."""
    native = heartpole.HeartPoleVectorEnv(num_envs, autoreset_mode=mode, **kwargs)
    sync = gym.vector.SyncVectorEnv([lambda: heartpole.HeartPole(**kwargs)] * num_envs, autoreset_mode=mode)
    return native, sync


def assert_same_info(ours: dict, theirs: dict) -> None:
    """The same keys, masks and values (every entry, masked or not; values of the same kind: the native env
    keeps float32 and int32 where SyncVectorEnv batches Python numbers as float64 and int64)."""
    assert sorted(ours) == sorted(theirs)
    for key, expected in theirs.items():
        if key == "final_obs":  # object arrays: the last observations, None elsewhere
            assert ours[key].dtype == object and len(ours[key]) == len(expected)
            for mine, last in zip(ours[key], expected):
                assert (mine is None) == (last is None)
                if last is not None:
                    assert mine.dtype == last.dtype and np.array_equal(mine, last)
        elif isinstance(expected, dict):
            assert_same_info(ours[key], expected)
        else:
            assert ours[key].shape == expected.shape and ours[key].dtype.kind == expected.dtype.kind, key
            np.testing.assert_array_equal(ours[key], expected, err_msg=key)


def assert_same(ours: tuple, theirs: tuple) -> None:
    """Two ``reset`` or ``step`` results alike: observations, rewards, flags and infos."""
    assert len(ours) == len(theirs)
    for mine, expected in zip(ours[:-1], theirs[:-1]):
        assert mine.shape == expected.shape and mine.dtype.kind == expected.dtype.kind
        np.testing.assert_array_equal(mine, expected)
    assert_same_info(ours[-1], theirs[-1])


def random_mask(rng: np.random.Generator, num_envs: int, share: float) -> np.ndarray:
    """A random reset mask with at least one True."""
    mask = rng.random(num_envs) < share
    mask[rng.integers(num_envs)] = True
    return mask


@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
@pytest.mark.parametrize("seed", range(3))
def test_every_autoreset_mode_and_masked_reset_matches_sync_vector_env(mode: AutoresetMode, seed: int) -> None:
    """Random actions and random masked resets (with and without seeds), 120 steps of episodes of 4: the
    native env answers everything as SyncVectorEnv does, in every autoreset mode."""
    num_envs, rng = 5, np.random.default_rng(seed)
    native, sync = twins(num_envs, mode, max_steps=4, **STEADY)
    assert native.metadata["autoreset_mode"] == sync.metadata["autoreset_mode"] == mode
    assert_same(native.reset(seed=seed), sync.reset(seed=seed))
    truncated = np.zeros(num_envs, dtype=bool)
    masked_resets = ended_resets = 0
    for _ in range(120):
        must = truncated if mode == AutoresetMode.DISABLED else np.zeros(num_envs, dtype=bool)
        if must.any() or rng.random() < 0.15:
            mask = must | random_mask(rng, num_envs, 0.3) if rng.random() < 0.5 or not must.any() else must
            reset_seed = None if rng.random() < 0.5 else int(rng.integers(100))
            ours = native.reset(seed=reset_seed, options={"reset_mask": mask.copy()})
            assert_same(ours, sync.reset(seed=reset_seed, options={"reset_mask": mask.copy()}))
            masked_resets += 1
        actions = rng.integers(0, 4, num_envs)
        ours = native.step(actions)
        assert_same(ours, sync.step(actions))
        truncated = ours[3]
        ended_resets += truncated.sum()
    assert masked_resets >= 10 and ended_resets >= 20  # both paths were taken, often


@pytest.mark.parametrize("mode", MODES, ids=[m.name for m in MODES])
def test_env_0s_first_episode_on_v0_is_sync_vector_envs_bit_for_bit(mode: AutoresetMode) -> None:
    """The real, random v0: env 0 (seeded alike in both) agrees bit for bit until its episode ends, the last
    observation and info too (SAME_STEP's ``final_obs``/``final_info``), and every info has the same keys."""
    max_steps, rng = 60, np.random.default_rng(1)
    native, sync = twins(3, mode, max_steps=max_steps, heart_attack_proclivity=1.0)
    ours, theirs = native.reset(seed=11), sync.reset(seed=11)
    np.testing.assert_array_equal(ours[0][0], theirs[0][0])
    attacks = 0
    for t in range(max_steps):
        actions = rng.choice(4, size=3, p=[0.04, 0.9, 0.03, 0.03])  # mostly coffee: heart attacks happen
        ours, theirs = native.step(actions), sync.step(actions)
        if t < max_steps - 1 or mode != AutoresetMode.SAME_STEP:
            np.testing.assert_array_equal(ours[0][0], theirs[0][0])
        for mine, expected in zip(ours[1:4], theirs[1:4]):
            assert mine[0] == expected[0]
        assert sorted(ours[4]) == sorted(theirs[4])
        for key in INFO_KEYS:
            assert ours[4][key][0] == theirs[4][key][0]
        attacks += theirs[4]["heart_attack"][0]
    assert ours[3].all() and attacks > 0  # the episode ended; the coin was flipped with and came up
    if mode == AutoresetMode.SAME_STEP:
        np.testing.assert_array_equal(ours[4]["final_obs"][0], theirs[4]["final_obs"][0])
        for key in INFO_KEYS:
            assert ours[4]["final_info"][key][0] == theirs[4]["final_info"][key][0]


BAD_MASKS = [
    ([True] * 4, TypeError, "must be a numpy array"),
    (np.ones(3, dtype=bool), ValueError, "must have shape `(4,)`, got (3,)"),
    (np.ones((4, 1), dtype=bool), ValueError, "must have shape `(4,)`, got (4, 1)"),
    (np.ones(4, dtype=int), TypeError, "must have `dtype=np.bool_`, got int64"),
    (np.zeros(4, dtype=bool), ValueError, "at least one True value"),
]


@pytest.mark.parametrize("mask, error, message", BAD_MASKS, ids=["list", "short", "2d", "ints", "none"])
def test_a_bad_reset_mask_is_refused_as_gymnasium_refuses_it_and_changes_nothing(mask, error, message) -> None:
    native, sync = twins(4, AutoresetMode.NEXT_STEP, max_steps=5)
    native.reset(seed=0)
    sync.reset(seed=0)
    native.step(np.array([1, 2, 3, 0]))
    untouched = copy.deepcopy(native)
    with pytest.raises(error, match=re.escape(message)) as raised:
        native.reset(seed=3, options={"reset_mask": mask})
    with pytest.raises(Exception) as expected:
        sync.reset(options={"reset_mask": mask})
    if expected.type is not AssertionError:  # Gymnasium >= 1.2 raises these errors; 1.1 asserted
        assert (raised.type, str(raised.value)) == (expected.type, str(expected.value))
    np.testing.assert_array_equal(native.state, untouched.state)
    assert native.np_random.bit_generator.state == untouched.np_random.bit_generator.state
    actions = np.array([3, 2, 1, 0])
    assert native.step(actions)[0].tobytes() == untouched.step(actions)[0].tobytes()


def test_a_masked_reset_draws_the_keys_a_full_reset_gives_and_leaves_the_other_envs_alone() -> None:
    """v0: envs reset by mask with seed s start as after ``reset(seed=s)``; the others go on bit for bit, as
    if nothing had happened, and the options the caller passed are left as they were."""
    rng = np.random.default_rng(2)
    actions = rng.integers(0, 4, (40, 4))
    plain, masked = make(4, max_steps=25), make(4, max_steps=25)
    first, _ = plain.reset(seed=5)
    masked.reset(seed=5)
    for a in actions[:10]:
        plain.step(a)
        masked.step(a)
    mask = np.array([False, True, False, True])
    options = {"reset_mask": mask, "other": 1}
    obs, info = masked.reset(seed=5, options=options)
    assert options == {"reset_mask": mask, "other": 1} and mask.tolist() == [False, True, False, True]
    np.testing.assert_array_equal(obs[mask], first[mask])  # the keys reset(seed=5) drew for envs 1 and 3
    for key in INFO_KEYS:
        np.testing.assert_array_equal(info["_" + key], mask)
        assert (info[key][mask] == RESET_INFO[key]).all()
    fresh = make(4, max_steps=25)
    fresh.reset(seed=5)
    ended = np.zeros(4, dtype=bool)
    for a in actions[10:]:  # through the unmasked envs' autoreset at step 25 and the masked ones' at 35
        out, again, new = plain.step(a), masked.step(a), fresh.step(a)
        np.testing.assert_array_equal(again[0][~mask], out[0][~mask])
        np.testing.assert_array_equal(again[0][mask], new[0][mask])
        np.testing.assert_array_equal(again[3], np.where(mask, new[3], out[3]))
        ended |= again[3]
    assert ended.all()


def test_next_step_restarts_some_envs_while_the_others_step_as_when_all_restart_together() -> None:
    """v0: an env whose episode ended restarts on the next step with the same random numbers whether the
    other envs step meanwhile (their episodes were reset later) or restart with it."""
    rng = np.random.default_rng(3)
    together, apart, late = make(3, max_steps=6), make(3, max_steps=6), make(3, max_steps=6)
    for env in (together, apart, late):
        env.reset(seed=9)
    ended = []
    for step in range(16):
        actions = rng.integers(0, 4, 3)
        if step == 2:  # env 2 starts a new episode, 2 steps after envs 0 and 1 (all of them, in `late`)
            apart.reset(options={"reset_mask": np.array([False, False, True])})
            late.reset(options={"reset_mask": np.array([True, True, True])})  # the same key for env 2
        out, again, later = together.step(actions), apart.step(actions), late.step(actions)
        for i, reference in ((0, out), (1, out), (2, later)):
            assert again[0][i].tobytes() == reference[0][i].tobytes() and again[1][i] == reference[1][i]
            assert again[3][i] == reference[3][i]
        ended.append(again[3].tolist())
    # envs 0 and 1 restarted at step 6 while env 2 stepped, and env 2 at step 8 while they stepped
    assert [step for step, flags in enumerate(ended) if any(flags)] == [5, 7, 12, 14]


def test_disabled_autoreset_refuses_to_step_an_ended_episode_until_it_is_reset() -> None:
    native, sync = twins(3, AutoresetMode.DISABLED, max_steps=2, **STEADY)
    native.reset(seed=0)
    sync.reset(seed=0)
    for _ in range(2):
        *_, truncated, _ = native.step(np.array([1, 1, 1]))
        sync.step(np.array([1, 1, 1]))
    assert truncated.all()
    untouched = copy.deepcopy(native)
    with pytest.raises(AssertionError):
        sync.step(np.array([0, 0, 0]))
    with pytest.raises(heartpole.vector.EpisodeEndedError, match=r"envs \[0, 1, 2\] have ended.*reset_mask"):
        native.step(np.array([0, 0, 0]))
    assert issubclass(heartpole.vector.EpisodeEndedError, (AssertionError, gym.error.ResetNeeded))
    np.testing.assert_array_equal(native.state, untouched.state)
    np.testing.assert_array_equal(native._rng, untouched._rng)
    native.reset(options={"reset_mask": np.array([True, True, False])})
    with pytest.raises(heartpole.vector.EpisodeEndedError, match=r"envs \[2\]"):
        native.step(np.array([0, 0, 0]))
    native.reset(options={"reset_mask": np.array([False, False, True])})
    assert not native.step(np.array([0, 0, 0]))[3].any()


def test_same_step_counts_an_episodes_last_step_once() -> None:
    """Summing the top-level ``heart_attack`` and ``productivity`` over the steps, and reading ``final_info``
    for the episodes' last steps (as SyncVectorEnv's users do), counts every step once."""
    n, max_steps = 256, 20
    env = heartpole.HeartPoleVectorEnv(
        n, max_steps=max_steps, heart_attack_proclivity=1.0, autoreset_mode=AutoresetMode.SAME_STEP
    )
    reference = heartpole.HeartPoleVectorEnv(n, max_steps=max_steps, heart_attack_proclivity=1.0)  # NEXT_STEP
    env.reset(seed=4)
    reference.reset(seed=4)
    coffee = np.ones(n, dtype=int)
    totals, expected = np.zeros(2), np.zeros(2)
    for _ in range(max_steps):
        info, seen = env.step(coffee)[4], reference.step(coffee)[4]
        totals += info["heart_attack"].sum(), info["productivity"].sum()
        expected += seen["heart_attack"].sum(), seen["productivity"].sum()
    final = info["final_info"]
    totals += final["heart_attack"].sum(), final["productivity"].sum()
    np.testing.assert_array_equal(totals, expected)
    assert expected[0] > 0 and final["heart_attack"].any()  # heart attacks happened, on the last step too
    assert (info["action_taken"] == -1).all() and (info["productivity"] == 0).all()  # the new episodes' reset values


def test_reset_info_has_the_step_infos_keys_and_dtypes() -> None:
    env = make(3)
    obs, info = env.reset(seed=0)
    stepped = env.step(np.array([0, 1, 2]))[4]
    assert sorted(info) == sorted(stepped) == sorted([*INFO_KEYS, *("_" + k for k in INFO_KEYS)])
    for key in INFO_KEYS:
        assert info[key].dtype == stepped[key].dtype == INFO_DTYPES[key] and info["_" + key].all()
        assert (info[key] == RESET_INFO[key]).all()


STEP_NAMES = {"observation", "action", "reward", "done", "terminated", "truncated", "next"}
"""Names of a step's own values, which TorchRL keeps in the same tensordict as the info keys."""


def test_no_info_key_is_named_like_a_steps_own_values() -> None:
    """TorchRL's batched envs put every info key beside the step's own values: an ``info["action"]`` took the
    place of TorchRL's ``action`` and failed in tensordict (size 3 against 4)."""
    env = make(2, max_steps=1, autoreset_mode=AutoresetMode.SAME_STEP)
    _, reset_info = env.reset(seed=0)
    info = env.step(np.array([0, 1]))[4]
    single = heartpole.HeartPole()
    keys = {*reset_info, *info, *info["final_info"], *single.reset(seed=0)[1], *single.step(0)[4]}
    assert keys >= set(INFO_KEYS) and not keys & STEP_NAMES


@pytest.mark.parametrize("vectorization", ["sync", "native SAME_STEP", "native DISABLED"])
def test_torchrls_batched_gym_wrapper_reads_the_infos(vectorization: str) -> None:
    """Where TorchRL is installed (it is no dependency): ``GymWrapper`` over a vector env rolls out through
    episode ends, registering the info keys (it reads none in DISABLED mode, where it resets the ended envs
    with ``reset_mask`` itself)."""
    pytest.importorskip("torchrl")
    from torchrl.envs import GymWrapper

    kwargs = {"num_envs": 4, "max_steps": 5}
    if vectorization == "sync":
        sync = {"vectorization_mode": "sync", "vector_kwargs": {"autoreset_mode": AutoresetMode.SAME_STEP}}
        env = gym.make_vec("HeartPole-v0", **sync, max_episode_steps=5, **kwargs)
    else:
        env = make(autoreset_mode=AutoresetMode[vectorization.split()[1]], **kwargs)
    rollout = GymWrapper(env).rollout(12, break_when_any_done=False)
    assert tuple(rollout.batch_size) == (4, 12)
    read = {"heart_attack", "score", "action_taken"} & set(rollout["next"].keys())
    assert len(read) == (0 if vectorization.endswith("DISABLED") else 3)
    assert rollout["next", "truncated"].sum() == 8  # two episode ends for each env


@pytest.mark.parametrize("people", [None, "default", "distribution"])
def test_heart_attack_proclivity_is_each_envs_own(people: str | None) -> None:
    """``heart_attack_proclivity`` is the number each env's step computes its risk with (its person's): with the
    state, ``exact_risk`` gives the step's reported risk to float32 rounding."""
    from heartpole.people import People, Uniform
    from heartpole.rewards import exact_risk

    population = People(heart_attack_proclivity=Uniform(0.2, 0.8)) if people == "distribution" else people
    env = heartpole.HeartPoleVectorEnv(64, people=population)
    env.reset(seed=5)
    proclivity = env.heart_attack_proclivity
    assert proclivity.dtype == np.float32 and proclivity.shape == (64,)
    assert (people is None) == bool(np.all(proclivity == np.float32(0.5)))
    for _ in range(50):
        _, _, _, _, info = env.step(np.ones(64, dtype=np.int64))  # coffee: blood pressure rises
        pressure = env.variable("hypertension")
        assert np.array_equal(pressure, env.state[1])
        risk = exact_risk(pressure, env.heart_attack_proclivity, info["heart_attack_risk"], info["heart_attack"])
        np.testing.assert_allclose(risk, info["heart_attack_risk"], rtol=1e-6)
