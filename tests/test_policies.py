"""Built-in policies as callables on observation batches, and loading policies by name or model file."""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import heartpole
from heartpole.actions import V0_ACTIONS
from heartpole.dynamics import Dynamics
from heartpole.model import productivity
from heartpole.optimum import NotCoveredError
from heartpole.parameters import Params
from heartpole.policies import (
    BUILTIN_POLICIES,
    ExpertPolicy,
    RandomPolicy,
    ReferencePolicy,
    act_batch,
    load_policy,
    make_policy,
)
from heartpole.policies.saved import ModelPolicy, detect_algorithm
from heartpole.rates import best_known_rate, expert_rate
from heartpole.registry import env_dynamics

OBS = np.array(
    [
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],  # just woke up at the start
        [0.2, 0.5, 0.0, 20.0, 20.0, 12.0],  # tired
        [0.8, 1.0, 0.02, 5.0, 60.0, 30.0],  # slept before
    ],
    dtype=np.float32,
)


def test_the_builtins_are_the_documented_seven() -> None:
    assert list(BUILTIN_POLICIES) == ["random", "nothing", "coffee", "reference", "expert", "optimal", "oracle"]


@pytest.mark.parametrize("name", list(BUILTIN_POLICIES))
@pytest.mark.parametrize("env_id", ["HeartPole-v0", "HeartPole-v1"])
def test_builtins_map_a_batch_to_valid_integer_actions(name: str, env_id: str) -> None:
    if name == "optimal" and env_id == "HeartPole-v1":  # the solver covers v0's actions only
        with pytest.raises(NotCoveredError, match="HeartPole-v0's"):
            load_policy(name, env_id)
        return
    if name == "oracle":  # without people it has no one to know (tests/test_oracle.py tests it with people)
        with pytest.raises(ValueError, match="finite cohort.*was given no people"):
            load_policy(name, env_id)
        return
    policy = load_policy(name, env_id)
    dynamics = env_dynamics(env_id)
    num_actions, width = len(dynamics.actions), len(dynamics.variables)
    obs = np.zeros((3, width), dtype=np.float32)
    obs[:, : OBS.shape[1]] = OBS
    actions = act_batch(policy, obs, np.array([1000, 500, 3]))
    assert actions.shape == (3,) and actions.dtype.kind == "i"
    assert np.all((0 <= actions) & (actions < num_actions))


def test_builtins_find_their_actions_by_name() -> None:
    """With v0's actions in reverse order (sleep is 0, coffee 2), the built-ins still pick the right ones."""
    reverse = Dynamics(actions=tuple(reversed(V0_ACTIONS)))
    names = [a.name for a in reverse.actions]
    assert make_policy("coffee", reverse)(OBS).tolist() == [names.index("drink_coffee")] * 3
    assert make_policy("nothing", reverse)(OBS).tolist() == [names.index("do_nothing")] * 3
    expert = make_policy("expert", reverse)(OBS)
    assert [names[a] for a in expert] == ["do_nothing", "sleep", "do_nothing"]
    reference = make_policy("reference", reverse)(OBS)
    assert [names[a] for a in reference] == ["drink_coffee", "do_nothing", "do_nothing"]
    optimal = make_policy("optimal", reverse)(OBS, np.array([1000, 1000, 1000]))
    assert [names[a] for a in optimal] == ["do_nothing", "sleep", "do_nothing"]


def test_policies_refuse_a_single_observation() -> None:
    with pytest.raises(ValueError, match=r"shape \(n, obs_dim\)"):
        ExpertPolicy()(OBS[0])


def test_random_policy_is_seeded_uniform_and_leaves_global_state_alone() -> None:
    np.random.seed(0)
    before = np.random.get_state()[1].copy()
    obs = np.zeros((40_000, 7), dtype=np.float32)
    draws = RandomPolicy(heartpole.HeartPoleV1().dynamics, rng=np.random.default_rng(5))(obs)
    np.testing.assert_array_equal(np.random.get_state()[1], before)
    counts = np.bincount(draws, minlength=8)
    expected, sd = len(draws) / 8, math.sqrt(len(draws) * (1 / 8) * (7 / 8))
    assert np.all(np.abs(counts - expected) < 4 * sd)  # all eight of v1's actions, uniformly
    again = RandomPolicy(heartpole.HeartPoleV1().dynamics, rng=5)(obs)
    np.testing.assert_array_equal(draws, again)
    generator = np.random.default_rng(1)
    policy = RandomPolicy(rng=generator)
    first, second = policy(obs[:50]), policy(obs[:50])
    assert policy.rng is generator and not np.array_equal(first, second)


def test_reference_runs_the_published_33_step_cycle() -> None:
    """Decision k: coffee when k % 33 == 0, sleep when k % 33 == 32, else nothing, read from observations."""
    env = heartpole.HeartPoleVectorEnv(num_envs=3, max_steps=150)
    policy = ReferencePolicy(env.dynamics)
    obs, _ = env.reset(seed=0)
    for k in range(150):
        actions = policy(obs)
        expected = 1 if k % 33 == 0 else 3 if k % 33 == 32 else 0
        assert actions.tolist() == [expected] * 3, k
        obs, *_ = env.step(actions)


def test_expert_sleeps_exactly_when_the_coming_half_hour_earns_less_than_its_rate() -> None:
    expert = ExpertPolicy()
    obs = np.zeros((601, 6), dtype=np.float32)
    obs[:, 0] = np.linspace(-1.0, 2.0, 601)
    actions = expert(obs)
    assert set(actions.tolist()) == {0, 3}  # never a drink
    np.testing.assert_array_equal(actions == 3, productivity(obs[:, 0], obs[:, 2]) < expert.rate)
    tired = obs[actions == 3, 0]
    assert 0.37 < tired.max() < 0.39  # it sleeps once alertness falls below about 0.38


def test_expert_rate_is_a_fixed_point_that_follows_the_dynamics() -> None:
    rate = expert_rate(Params())
    assert 0.32 < rate < 0.335
    shorter, longer = expert_rate(Params(sleep_half_hours=8)), expert_rate(Params(sleep_half_hours=32))
    assert shorter > rate > longer  # cheaper sleep, higher long-run rate
    assert ExpertPolicy(rate=0.5).rate == 0.5


def test_the_best_known_rate_is_the_experts_and_none_without_its_actions() -> None:
    """The solved bar's rate (heartpole.rates, below the registry) and the expert's are one rule."""
    v0, v1 = env_dynamics("HeartPole-v0"), env_dynamics("HeartPole-v1")
    assert best_known_rate(v0) == ExpertPolicy(v0).rate == expert_rate(v0.params)
    assert best_known_rate(v1) == ExpertPolicy(v1).rate == ExpertPolicy.RATE_WITH_NAPS
    no_sleep = Dynamics(actions=tuple(a for a in V0_ACTIONS if a.name != "sleep"))
    assert best_known_rate(no_sleep) is None
    with pytest.raises(ValueError):
        ExpertPolicy(no_sleep)


# ------------------------------------------------------------------------------------------------------
# load_policy: names and files


def test_unknown_names_list_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="unknown policy 'expret'; built-in policies are random, nothing"):
        load_policy("expret")


def test_missing_and_corrupt_files_are_clear(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="model file not found"):
        load_policy(str(tmp_path / "missing.zip"))
    with pytest.raises(FileNotFoundError, match="is a folder; give the path of the model .zip"):
        load_policy(str(tmp_path))
    with pytest.raises(ValueError, match="unknown policy ''"):
        load_policy("")
    junk = tmp_path / "junk.zip"
    junk.write_bytes(b"not a zip at all")
    with pytest.raises(ValueError, match="not a Stable-Baselines3 model zip"):
        load_policy(str(junk))
    no_data = tmp_path / "empty.zip"
    with zipfile.ZipFile(no_data, "w") as archive:
        archive.writestr("policy.pth", b"")
    with pytest.raises(ValueError, match="not a Stable-Baselines3 model zip"):
        load_policy(str(no_data))


def test_a_named_pipe_given_as_a_model_is_not_a_regular_file(tmp_path: Path, capsys) -> None:
    import os
    import re

    from heartpole.cli import main

    pipe = tmp_path / "model.zip"
    os.mkfifo(pipe)  # said "model file not found"; opening it would wait for a writer forever
    with pytest.raises(ValueError, match=re.escape(f"{pipe} is not a regular file")):
        load_policy(str(pipe))
    assert main(["evaluate", "--policy", str(pipe), "--episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and f"{pipe} is not a regular file (a named pipe" in err, err


def test_sidecar_names_the_algorithm(tmp_path: Path) -> None:
    model = tmp_path / "model.zip"
    model.write_bytes(b"")
    (tmp_path / "heartpole.json").write_text(json.dumps({"algo": "DQN"}))
    assert detect_algorithm(model) == "dqn"
    (tmp_path / "heartpole.json").write_text(json.dumps({"algo": "sac"}))
    with pytest.raises(ValueError, match="unsupported algo 'sac'"):
        detect_algorithm(model)
    (tmp_path / "heartpole.json").write_text("{broken")
    with pytest.raises(ValueError, match="expected JSON like"):
        detect_algorithm(model)


def test_model_policy_normalises_like_vecnormalize() -> None:
    """VecNormalize's formula, clip((obs - mean) / sqrt(var + eps), -clip, clip), before predict."""
    seen = []

    class FakeModel:
        def predict(self, obs: np.ndarray, deterministic: bool = False) -> tuple[np.ndarray, None]:
            seen.append((obs, deterministic))
            return np.arange(len(obs)) % 4, None

    stats = SimpleNamespace(mean=np.arange(6.0), var=np.full(6, 4.0))
    normalizer = SimpleNamespace(obs_rms=stats, clip_obs=1.5, epsilon=1e-8, norm_obs=True)
    policy = ModelPolicy(FakeModel(), normalizer)
    actions = policy(OBS)
    assert actions.tolist() == [0, 1, 2] and seen[0][1] is True
    expected = np.clip((OBS - np.arange(6.0)) / np.sqrt(4.0 + 1e-8), -1.5, 1.5)
    np.testing.assert_allclose(seen[0][0], expected, rtol=1e-6)
    raw = ModelPolicy(FakeModel(), SimpleNamespace(norm_obs=False))
    raw(OBS)
    np.testing.assert_array_equal(seen[-1][0], OBS)


# ------------------------------------------------------------------------------------------------------
# real Stable-Baselines3 models (untrained: loading and acting is what is tested)


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    sb3 = pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    paths = {}
    for name, algo, make_env in [
        ("ppo", sb3.PPO, heartpole.HeartPole),
        ("a2c", sb3.A2C, heartpole.HeartPole),
        ("dqn", sb3.DQN, heartpole.HeartPole),
        ("v1", sb3.DQN, heartpole.HeartPoleV1),
    ]:
        folder = tmp_path_factory.mktemp(name)
        kwargs = {"learning_starts": 0} if algo is sb3.DQN else {"n_steps": 16}
        if algo is sb3.PPO:
            kwargs["batch_size"] = 16
        algo("MlpPolicy", make_env(), policy_kwargs={"net_arch": [8]}, seed=0, **kwargs).save(folder / "m.zip")
        paths[name] = folder / "m.zip"
    normalized = tmp_path_factory.mktemp("normalized")
    sb3.PPO.load(paths["ppo"]).save(normalized / "m.zip")
    vec = VecNormalize(DummyVecEnv([heartpole.HeartPole]), clip_obs=2.0)
    vec.obs_rms.mean, vec.obs_rms.var = np.array([1.0, 0.0, 0.0, 20.0, 500.0, 100.0]), np.full(6, 9.0)
    vec.save(str(normalized / "vecnormalize.pkl"))
    record = {"algo": "ppo", "model": "m.zip", "vecnormalize": "vecnormalize.pkl"}
    (normalized / "heartpole.json").write_text(json.dumps(record))
    paths["normalized"] = normalized / "m.zip"
    return paths


def test_a_model_zip_that_unpacks_too_large_is_refused_before_it_is_read(models, monkeypatch, tmp_path) -> None:
    from heartpole.policies import rebuild

    (tmp_path / "m.zip").write_bytes(models["ppo"].read_bytes())
    with zipfile.ZipFile(tmp_path / "m.zip") as archive:
        size = archive.getinfo("data").file_size
    monkeypatch.setattr(rebuild, "MAX_MEMBER_BYTES", size - 1)  # as a zip bomb's entry against the real limit
    read = []
    monkeypatch.setattr(zipfile.ZipFile, "read", lambda *args: read.append(args))
    with pytest.raises(ValueError, match=rf"its data would unpack to {size:,} bytes, more than the {size - 1:,}"):
        load_policy(str(tmp_path / "m.zip"))
    assert read == []


@pytest.mark.parametrize("name", ["ppo", "a2c", "dqn"])
def test_models_load_with_their_algorithm_and_act_deterministically(models: dict[str, Path], name: str) -> None:
    import stable_baselines3 as sb3

    assert detect_algorithm(models[name]) == name
    policy = load_policy(str(models[name]))
    model = getattr(sb3, name.upper()).load(models[name])
    obs = np.random.default_rng(0).normal(0, 3, (4096, 6)).astype(np.float32)
    expected, _ = model.predict(obs, deterministic=True)
    np.testing.assert_array_equal(policy(obs), expected)
    # PPO and A2C take the argmax of the actor's logits without SB3's distribution, DQN goes through predict
    assert (getattr(policy, "_greedy", None) is not None) == (name != "dqn")


def test_vecnormalize_recorded_with_the_model_is_applied(models: dict[str, Path]) -> None:
    import stable_baselines3 as sb3

    policy = load_policy(str(models["normalized"]))
    assert policy.normalizer_path == models["normalized"].parent / "vecnormalize.pkl"
    obs = np.random.default_rng(1).normal(0, 30, (64, 6)).astype(np.float32)
    mean = np.array([1.0, 0.0, 0.0, 20.0, 500.0, 100.0])
    normalized = np.clip((obs - mean) / np.sqrt(9.0 + 1e-8), -2.0, 2.0).astype(np.float32)
    expected, _ = sb3.PPO.load(models["normalized"]).predict(normalized, deterministic=True)
    np.testing.assert_array_equal(policy(obs), expected)


def _copy_model(models: dict[str, Path], folder: Path, record: dict | None) -> Path:
    folder.mkdir()
    (folder / "m.zip").write_bytes(models["normalized"].read_bytes())
    (folder / "vecnormalize.pkl").write_bytes((models["normalized"].parent / "vecnormalize.pkl").read_bytes())
    if record is not None:
        (folder / "heartpole.json").write_text(json.dumps(record))
    return folder / "m.zip"


@pytest.mark.parametrize(
    "record",
    [None, {"algo": "ppo"}, {"algo": "ppo", "model": "m.zip", "vecnormalize": None},
     {"algo": "ppo", "model": "other.zip", "vecnormalize": "vecnormalize.pkl"}],
    ids=["no-record", "no-entry", "recorded-none", "another-model"],
)  # fmt: skip
def test_vecnormalize_not_recorded_for_the_model_is_ignored_with_a_warning(models, tmp_path, record) -> None:
    import stable_baselines3 as sb3

    path = _copy_model(models, tmp_path / "run", record)
    with pytest.warns(UserWarning, match=r"ignoring .*vecnormalize.pkl: the model m.zip"):
        policy = load_policy(str(path))
    assert policy.normalizer_path is None
    obs = np.random.default_rng(1).normal(0, 30, (64, 6)).astype(np.float32)
    expected, _ = sb3.PPO.load(path).predict(obs, deterministic=True)
    np.testing.assert_array_equal(policy(obs), expected)


def test_recorded_vecnormalize_that_changed_or_vanished_is_refused(models, tmp_path) -> None:
    from heartpole.policies.saved import file_sha256

    # a model that changed since its record was written: not played without its statistics, refused
    record = {"algo": "ppo", "model": "m.zip", "model_sha256": "0" * 64, "vecnormalize": "vecnormalize.pkl"}
    path = _copy_model(models, tmp_path / "changed", record)
    with pytest.raises(ValueError, match=r"m.zip changed since .*heartpole.json recorded it"):
        load_policy(str(path))
    path = _copy_model(models, tmp_path / "run", None)
    record = {"algo": "ppo", "model": "m.zip", "vecnormalize": "vecnormalize.pkl", "vecnormalize_sha256": "0" * 64}
    (tmp_path / "run" / "heartpole.json").write_text(json.dumps(record))
    with pytest.raises(ValueError, match="changed since it was saved with m.zip"):
        load_policy(str(path))
    record["vecnormalize_sha256"] = file_sha256(tmp_path / "run" / "vecnormalize.pkl")
    (tmp_path / "run" / "heartpole.json").write_text(json.dumps(record))
    assert load_policy(str(path)).normalizer_path is not None
    (tmp_path / "run" / "vecnormalize.pkl").unlink()
    with pytest.raises(ValueError, match=r"observation statistics .* are missing"):
        load_policy(str(path))


def test_a_model_for_another_env_is_refused(models: dict[str, Path]) -> None:
    with pytest.raises(ValueError, match=r"expects observations \(7,\) and 8 actions"):
        load_policy(str(models["v1"]), "HeartPole-v0")
    assert load_policy(str(models["v1"]), "HeartPole-v1")(np.zeros((2, 7), dtype=np.float32)).shape == (2,)


def test_a_truncated_model_file_is_refused(models: dict[str, Path], tmp_path: Path) -> None:
    broken = tmp_path / "broken.zip"
    data = models["ppo"].read_bytes()
    broken.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="broken.zip"):
        load_policy(str(broken))
    (tmp_path / "vecnormalize.pkl").write_bytes(b"garbage")
    (tmp_path / "heartpole.json").write_text(json.dumps({"algo": "ppo", "vecnormalize": "vecnormalize.pkl"}))
    healthy = tmp_path / "healthy.zip"
    healthy.write_bytes(data)
    with pytest.raises(ValueError, match="not a VecNormalize file"):
        load_policy(str(healthy))


def _expert_rate_over_whole_episodes(params, grid: int = 400) -> float:
    """expert_rate's fixed point computed the direct way, over arrays of the whole episode's length."""
    from heartpole.model import alertness_decay, productivity

    low, high = params.wake_alertness
    wake = low + (high - low) * (np.arange(grid) + 0.5) / grid
    horizon = params.max_steps
    decay = np.concatenate([[0.0], np.cumsum(alertness_decay(np.arange(horizon - 1, dtype=np.float64)))])
    earned = productivity(wake[:, None] - decay[None, :], 0.0)
    rate = 0.0
    for _ in range(200):
        working = earned >= rate
        working[:, 0] = True
        length = np.where(working.all(axis=1), horizon, np.argmin(working, axis=1))
        work = np.where(np.arange(horizon)[None, :] < length[:, None], earned, 0.0).sum(axis=1)
        days = horizon / length.mean()
        new_rate = days * work.mean() / (horizon + params.sleep_half_hours * max(days - 1.0, 0.0))
        if abs(new_rate - rate) < 1e-12:
            break
        rate = new_rate
    return float(rate)


@pytest.mark.parametrize(
    "params",
    [Params(), Params(max_steps=1), Params(max_steps=2), Params(max_steps=20), Params(max_steps=3000),
     Params(wake_alertness=(4.0, 9.0)), Params(wake_alertness=(-1.0, -0.5)), Params(sleep_half_hours=0)],
    ids=lambda p: f"{p.max_steps}-{p.wake_alertness}-{p.sleep_half_hours}",
)  # fmt: skip
def test_expert_rate_equals_the_whole_episode_computation(params) -> None:
    assert expert_rate(params) == _expert_rate_over_whole_episodes(params)


def test_expert_rate_memory_does_not_grow_with_the_episode_length() -> None:
    import tracemalloc

    peaks = []
    for max_steps in (1_000, 1_000_000):
        expert_rate.cache_clear()
        tracemalloc.start()
        expert_rate(Params(max_steps=max_steps))
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] < 2 * peaks[0] + 1_000_000, peaks  # was 400 x max_steps float64 arrays: 3.2 GB each
