"""HeartPole (the single env): Gymnasium API, reproducibility, copies, bad input, rendering, checkers."""

from __future__ import annotations

import copy
import pickle
import random
import tracemalloc
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded

import heartpole
from heartpole.env import LOG_MAX_STEPS, RESET_INFO

NAMES = ["alertness", "hypertension", "intoxication", "time_since_slept", "time_elapsed", "work_done"]


def trajectory(env: gym.Env, actions: list[int], seed: int | None = None) -> list[tuple]:
    out = []
    if seed is not None:
        obs, _ = env.reset(seed=seed)
        out.append((obs.tobytes(),))
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        out.append((obs.tobytes(), reward, terminated, truncated, info["heart_attack"]))
    return out


ACTIONS = np.random.default_rng(0).integers(0, 4, 700).tolist()


def test_import_registers_and_make_works() -> None:
    env = gym.make("HeartPole-v0")
    assert isinstance(env.unwrapped, heartpole.HeartPole)
    assert heartpole.HeartPoleEnv is heartpole.HeartPole
    vec = gym.make_vec("HeartPole-v0", num_envs=3, vectorization_mode="vector_entry_point")
    assert isinstance(vec, heartpole.HeartPoleVectorEnv) and vec.num_envs == 3


def test_the_tutorials_own_registration_line_works() -> None:
    gym.register("HeartPole-v0", entry_point="heartpole:HeartPole")
    env = gym.make("HeartPole-v0", heart_attack_proclivity=0.3, max_steps=50)
    assert env.unwrapped.heart_attack_proclivity == 0.3 and env.unwrapped.max_steps == 50
    heartpole.registry.register_envs()  # leave the registry as import set it
    gym.registry.pop("HeartPole-v0")
    heartpole.registry.register_envs()


def test_spaces_are_the_tutorials_in_float32_without_precision_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = heartpole.HeartPole()
    assert env.action_space == gym.spaces.Discrete(4)
    space = env.observation_space
    assert space.shape == (6,) and space.dtype == np.float32
    largest = np.finfo(np.float32).max  # the tutorial's infinite bounds, finite for Gymnasium's checker
    np.testing.assert_array_equal(space.low, [-largest, 0, 0, 0, 0, -largest])
    np.testing.assert_array_equal(space.high, [largest] * 6)
    assert [a.name for a in env.actions] == ["do_nothing", "drink_coffee", "drink_beer", "sleep"]


def test_reset_wakes_up_with_everything_else_at_zero() -> None:
    env = heartpole.HeartPole()
    obs, info = env.reset(seed=1)
    assert obs.dtype == np.float32 and obs in env.observation_space and info == RESET_INFO
    assert 0.7 <= obs[0] <= 1.3 and not obs[1:].any()


def test_step_returns_gymnasium_five_tuple_and_info() -> None:
    env = heartpole.HeartPole()
    env.reset(seed=2)
    obs, reward, terminated, truncated, info = env.step(1)
    assert obs in env.observation_space and obs.dtype == np.float32
    assert isinstance(reward, float) and terminated is False and truncated is False
    assert info["action_taken"] == 1 and env.action_names[1] == "drink_coffee"
    assert isinstance(info["heart_attack"], bool)
    assert 0 < info["heart_attack_risk"] < 0.5
    assert info["productivity"] == pytest.approx(info["score"])  # one half-hour worked so far
    assert env.state["time_elapsed"] == 1.0 and env.state["time_since_slept"] == 1.0


def test_sleep_takes_sixteen_half_hours_and_wakes_up() -> None:
    env = heartpole.HeartPole()
    env.reset(seed=3)
    env.step(1)
    before = env.state
    _, _, _, _, info = env.step(3)
    after = env.state
    assert info["action_taken"] == 3
    assert after["time_elapsed"] == before["time_elapsed"] + 17
    assert after["time_since_slept"] == 1.0
    if not info["heart_attack"]:
        assert after["hypertension"] == pytest.approx(before["hypertension"] * 0.97**17)


def test_rewards_telescope_to_final_score_minus_100_per_heart_attack() -> None:
    env = heartpole.HeartPole()
    env.reset(seed=4)
    total, attacks = 0.0, 0
    for action in ACTIONS:
        _, reward, _, _, info = env.step(action)
        total += reward
        attacks += info["heart_attack"]
    # the step computes in float32: 1000 rewards' rounding stays well under 1e-4
    assert total == pytest.approx(info["score"] - 100 * attacks, abs=1e-4)


def test_episode_is_truncated_at_max_steps_never_terminated() -> None:
    env = heartpole.HeartPole(max_steps=5)
    env.reset(seed=0)
    flags = [env.step(0)[2:4] for _ in range(7)]
    assert flags == [(False, False)] * 4 + [(False, True)] * 3
    env.reset()
    assert env.step(0)[3] is False


def test_default_episode_is_1000_steps() -> None:
    env = gym.make("HeartPole-v0")
    env.reset(seed=0)
    truncated_at = next(t for t in range(1, 1001) if env.step(3)[3])
    assert truncated_at == 1000


def test_same_seed_same_trajectory_bit_for_bit_and_other_seeds_differ() -> None:
    first = trajectory(heartpole.HeartPole(), ACTIONS, seed=7)
    second = trajectory(heartpole.HeartPole(), ACTIONS, seed=7)
    assert first == second
    assert trajectory(heartpole.HeartPole(), ACTIONS, seed=8) != first


def test_reset_without_seed_continues_the_stream() -> None:
    env = heartpole.HeartPole()
    env.reset(seed=5)
    a = env.reset()[0]
    b = env.reset()[0]
    assert a[0] != b[0]


def test_no_global_random_state_is_used_or_changed() -> None:
    np.random.seed(0)
    random.seed(0)
    numpy_state, python_state = np.random.get_state()[1].copy(), random.getstate()
    env = heartpole.HeartPole()
    run = trajectory(env, ACTIONS, seed=9)
    np.testing.assert_array_equal(np.random.get_state()[1], numpy_state)
    assert random.getstate() == python_state
    np.random.seed(123)
    random.seed(123)
    assert trajectory(heartpole.HeartPole(), ACTIONS, seed=9) == run


@pytest.mark.parametrize("clone", [copy.deepcopy, lambda env: pickle.loads(pickle.dumps(env))])
def test_copies_mid_episode_continue_identically(clone) -> None:
    env = heartpole.HeartPole()
    trajectory(env, ACTIONS[:246], seed=10)
    twin = clone(env)
    rest = ACTIONS[:256]
    assert trajectory(twin, rest) == trajectory(env, rest)


INVALID_ACTIONS = [
    4,
    -1,
    1.0,
    2.5,
    "1",
    None,
    [1],
    np.array([1]),
    np.array([[0]]),
    np.float32(1),
    True,
    np.array(1.0),
    np.bool_(True),
]


@pytest.mark.parametrize("action", INVALID_ACTIONS, ids=repr)
def test_invalid_action_raises_and_changes_nothing(action) -> None:
    env = heartpole.HeartPole()
    trajectory(env, ACTIONS[:30], seed=11)
    untouched = copy.deepcopy(env)
    with pytest.raises(ValueError, match=r"valid actions: 0 \(do_nothing\), 1 \(drink_coffee\)"):
        env.step(action)
    assert env.state == untouched.state
    assert trajectory(env, ACTIONS[:300]) == trajectory(untouched, ACTIONS[:300])


@pytest.mark.parametrize("action", [np.int64(2), np.int8(2), np.uint8(2), np.array(2), np.array(2, dtype=np.int16)])
def test_numpy_integer_actions_are_accepted(action) -> None:
    env, plain = heartpole.HeartPole(), heartpole.HeartPole()
    env.reset(seed=12)
    plain.reset(seed=12)
    assert env.step(action)[0].tobytes() == plain.step(2)[0].tobytes()


def test_step_before_reset_raises() -> None:
    with pytest.raises(ResetNeeded, match="reset"):
        heartpole.HeartPole().step(0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"heart_attack_proclivity": -0.1}, "heart_attack_proclivity"),
        ({"heart_attack_proclivity": 1.01}, "heart_attack_proclivity"),
        ({"max_steps": 0}, "max_steps"),
        ({"render_mode": "video"}, "render_mode"),
    ],
)
def test_invalid_constructor_arguments(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        heartpole.HeartPole(**kwargs)
    with pytest.raises(ValueError, match=message):
        gym.make("HeartPole-v0", **kwargs)


@pytest.mark.parametrize(
    "make, function",
    [
        (heartpole.HeartPole, "HeartPole.__init__"),
        (lambda **kw: gym.make("HeartPole-v0", **kw), "HeartPole.__init__"),
        (lambda **kw: gym.make("HeartPole-v1", **kw), "HeartPole.__init__"),
        (lambda **kw: heartpole.HeartPoleVectorEnv(2, **kw), "HeartPoleVectorEnv.__init__"),
        (
            lambda **kw: gym.make_vec("HeartPole-v0", 2, vectorization_mode="vector_entry_point", **kw),
            "HeartPoleVectorEnv.__init__",
        ),
    ],  # fmt: skip
)
def test_an_unexpected_keyword_is_pythons_type_error(make, function: str) -> None:
    """Libraries branch on Python's wording: TorchRL passes frameskip and drops it on exactly this TypeError."""
    with pytest.raises(TypeError, match=rf"^{function}\(\) got an unexpected keyword argument 'frameskip'; ") as e:
        make(frameskip=4)
    assert "decay_rate" in str(e.value) and "heart_attack_proclivity" in str(e.value)  # what is accepted
    with pytest.raises(TypeError, match=r"argument 'frameskip' \(and 'sleepiness'\); it accepts"):
        make(frameskip=4, sleepiness=3)


def first_heart_attack(env: heartpole.HeartPole) -> int:
    for t in range(1, 5000):
        if env.step(1)[4]["heart_attack"]:
            return t
    raise AssertionError("no heart attack in 5000 cups of coffee")


def test_ansi_render_tells_the_story_since_the_last_render() -> None:
    env = heartpole.HeartPole(render_mode="ansi")
    env.reset(seed=13)
    steps = first_heart_attack(env)
    text = env.render()
    assert text.count("Chosen action: drink_coffee") == steps
    assert text.count("HEART ATTACK") == 1
    assert "'hypertension': 0," in text.splitlines()[-1]  # reset by the attack
    assert env.render() == ""
    env.step(3)
    assert env.render().startswith("Chosen action: sleep\n")


def test_human_render_prints(capsys: pytest.CaptureFixture[str]) -> None:
    env = heartpole.HeartPole(render_mode="human")
    env.reset(seed=0)
    env.step(2)
    assert "Chosen action: drink_beer" in capsys.readouterr().out


def test_rgb_array_render_is_an_image() -> None:
    env = heartpole.HeartPole(render_mode="rgb_array")
    env.reset(seed=0)
    env.step(1)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 0


def test_text_log_stays_bounded_when_never_rendered() -> None:
    """The tutorial's log grew every step until render(); 200k steps here keep memory flat."""
    env = heartpole.HeartPole(render_mode="ansi", max_steps=10**9)
    env.reset(seed=14)
    tracemalloc.start()
    for _ in range(100_000):
        env.step(0)
    halfway = tracemalloc.get_traced_memory()[0]
    for _ in range(100_000):
        env.step(0)
    end = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    assert len(env._log) == LOG_MAX_STEPS
    assert end - halfway < 50_000, f"memory grew by {end - halfway} bytes over the second 100k steps"


def test_gymnasium_env_checker_passes_without_warnings() -> None:
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # Gymnasium's standard notice that a newer version (HeartPole-v1) exists is not about the env.
        warnings.filterwarnings("ignore", r".*The environment HeartPole-v0 is out of date", DeprecationWarning)
        check_env(gym.make("HeartPole-v0").unwrapped)  # made, so the checker also tries each render mode
        check_env(gym.make("HeartPole-v0", render_mode="ansi").unwrapped)


def test_stable_baselines3_env_checker_passes_without_warnings() -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(heartpole.HeartPole(), warn=True)


def test_reset_info_has_the_step_infos_keys_and_types() -> None:
    """``reset``'s info is a step's, with the values before any step: tools that record infos see one shape."""
    env = heartpole.HeartPole()
    _, info = env.reset(seed=0)
    stepped = env.step(2)[4]
    assert info == dict(RESET_INFO) and info is not RESET_INFO
    assert {key: type(value) for key, value in info.items()} == {key: type(value) for key, value in stepped.items()}
    assert stepped["action_taken"] == 2 and env.action_names[stepped["action_taken"]] == "drink_beer"
    assert env.action_names == tuple(action.name for action in env.actions)


@pytest.mark.filterwarnings("ignore:`code_permalink` is set to None:UserWarning")
def test_minaris_data_collector_records_infos(tmp_path, monkeypatch) -> None:
    """Minari's own ``DataCollector(record_infos=True)`` over ``gym.make("HeartPole-v0")`` (it checks that every
    step's info has reset's structure) records episodes whose infos hold the env's values."""
    minari = pytest.importorskip("minari")
    pytest.importorskip("jax")  # DataCollector's episode buffer needs it (minari[create])
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    env = minari.DataCollector(gym.make("HeartPole-v0", max_steps=5, max_episode_steps=5), record_infos=True)
    rng, taken, risks = np.random.default_rng(0), [], []
    for episode in range(3):
        env.reset(seed=episode)
        truncated = False
        while not truncated:
            taken.append(int(rng.integers(4)))
            *_, truncated, info = env.step(taken[-1])
            risks.append(info["heart_attack_risk"])
    dataset = env.create_dataset(
        "heartpole/v0/infos-test-v0",
        eval_env="HeartPole-v0",
        algorithm_name="random",
        author="HeartPole's tests",
        author_email="tests@example.org",
        description="Three random episodes of five steps.",
        ref_min_score=0.0,
        ref_max_score=1.0,
    )
    env.close()
    episodes = list(minari.load_dataset("heartpole/v0/infos-test-v0").iterate_episodes())
    assert dataset.total_episodes == len(episodes) == 3
    for i, episode in enumerate(episodes):
        assert sorted(episode.infos) == sorted(RESET_INFO)
        assert episode.infos["action_taken"].tolist() == [-1, *taken[5 * i : 5 * i + 5]]  # reset's -1, then the indices
        np.testing.assert_array_equal(episode.infos["action_taken"][1:], episode.actions)
        np.testing.assert_allclose(episode.infos["heart_attack_risk"][1:], risks[5 * i : 5 * i + 5])
        assert episode.infos["productivity"][0] == 0 and episode.infos["productivity"][1:].all()


def test_compiled_for_is_the_same_code_without_dispatch_and_plain_functions_stay() -> None:
    from heartpole import kernel
    from heartpole.env import compiled_for

    env = heartpole.HeartPole()
    env.reset(seed=13)
    arguments = env._kernel_arguments  # the generator state, packed tables, cells and spec
    direct = compiled_for(kernel.step_one, (env._envs, 0, *arguments))
    assert direct is not kernel.step_one  # numba's compiled entry point, not its dispatcher
    twin = copy.deepcopy(env)
    assert direct(env._envs, 2, *arguments) == kernel.step_one(twin._envs, 2, twin._rng, *arguments[1:])
    assert env._envs.tobytes() == twin._envs.tobytes() and env._rng.tobytes() == twin._rng.tobytes()

    def plain(*arguments: object) -> int:
        return len(arguments)

    assert compiled_for(plain, (1, 2)) is plain


@pytest.mark.parametrize("render_mode", [None, "ansi", "rgb_array"])
def test_a_copy_or_pickle_steps_its_own_state_not_the_originals(render_mode: str | None) -> None:
    """The step reuses a view of the state and the compiled step (planned at reset): a copy plans its own."""
    env = heartpole.HeartPole(render_mode=render_mode)
    trajectory(env, ACTIONS[:20], seed=14)
    for twin in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):
        before = env.state
        for action in ACTIONS[:30]:
            obs, *_ = twin.step(action)
            assert obs.tobytes() == np.array(list(twin.state.values()), dtype=np.float32).tobytes()
        assert env.state == before != twin.state  # the original did not move


def test_observations_are_fresh_arrays() -> None:
    env = heartpole.HeartPole()
    first, _ = env.reset(seed=15)
    second = env.step(0)[0]
    kept = second.copy()
    third = env.step(1)[0]
    second[:] = -1.0  # the caller's to change: neither the env nor later observations see it
    assert not np.shares_memory(second, third) and not np.shares_memory(first, second)
    assert env.step(0)[0].tobytes() != second.tobytes() and third.tobytes() != kept.tobytes()
