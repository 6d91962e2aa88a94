"""Loading a model runs no code from its files (heartpole.policies.untrusted and .rebuild): real runs load and
evaluate exactly as Stable-Baselines3's own loading does, old runs (a vecnormalize.pkl only) load through the
restricted unpickler, and crafted files (a vecnormalize.pkl, a model.zip's data, its policy.pth) run nothing and
are refused with a message saying how to opt in; a model trained under VecNormalize, copied without its
statistics, is not evaluated silently."""

from __future__ import annotations

import base64
import collections
import json
import os
import pickle
import shutil
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

import heartpole  # noqa: E402
from heartpole import training  # noqa: E402
from heartpole.cli import main  # noqa: E402
from heartpole.policies import load_policy  # noqa: E402
from heartpole.policies.rebuild import SavedModel, _pickle_imports  # noqa: E402
from heartpole.policies.saved import ModelPolicy, file_sha256  # noqa: E402
from heartpole.policies.untrusted import (  # noqa: E402
    UnsafeFileError,
    load_statistics,
    save_statistics,
    unpickle_statistics,
)

torch.set_num_threads(1)
pytestmark = pytest.mark.filterwarnings("ignore:.*is out of date.*:DeprecationWarning")
OBS = np.random.default_rng(0).uniform(0, [2, 3, 0.1, 40, 1500, 400], size=(512, 6)).astype(np.float32)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny real training run (PPO, VecNormalize on observations and rewards), as ``heartpole train`` writes it."""
    config = training.preset_config("default", "ppo", timesteps=1024, n_envs=4, seed=5)
    folder = tmp_path_factory.mktemp("safe") / "run"
    training.train_run(config, folder, eval_episodes=10)
    return folder


def _copy(run: Path, folder: Path) -> Path:
    shutil.copytree(run, folder)
    return folder / "model.zip"


def _sidecar(folder: Path, **changes: object) -> None:
    """Rewrite ``folder/heartpole.json`` with ``changes`` (None removes a key), as whoever wrote the files could."""
    record = json.loads((folder / "heartpole.json").read_text())
    for key, value in changes.items():
        if value is None:
            record.pop(key, None)
        else:
            record[key] = value
    (folder / "heartpole.json").write_text(json.dumps(record))


class Touch:
    """Unpickling this runs a shell command that creates ``marker``."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return os.system, (f"touch '{self.marker}'",)


def _trusted_the_old_way(path: Path) -> ModelPolicy:
    """The policy as HeartPole loaded it before: SB3's load and pickle.load (both unpickle)."""
    import stable_baselines3 as sb3

    with (path.parent / "vecnormalize.pkl").open("rb") as handle:
        normalizer = pickle.load(handle)
    return ModelPolicy(sb3.PPO.load(path, device="cpu"), normalizer)


# ------------------------------------------------------------------------------------------------------
# real files load without unpickling, and act exactly as before


def test_a_trained_run_loads_without_unpickling_and_evaluates_identically(run: Path, monkeypatch) -> None:
    import stable_baselines3 as sb3

    record = json.loads((run / "heartpole.json").read_text())
    assert record["vecnormalize_json"] == "vecnormalize.json"
    assert record["vecnormalize_json_sha256"] == file_sha256(run / "vecnormalize.json")
    old = _trusted_the_old_way(run / "model.zip")

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("unpickled")

    with monkeypatch.context() as patch:  # neither SB3's load nor pickle.load is called
        patch.setattr(sb3.PPO, "load", refuse)
        patch.setattr(pickle, "load", refuse)
        safe = load_policy(str(run / "model.zip"))
    assert isinstance(safe.model, SavedModel) and safe.normalizer_path == run / "vecnormalize.json"
    np.testing.assert_array_equal(safe.normalize(OBS), old.normalize(OBS))
    np.testing.assert_array_equal(safe(OBS), old(OBS))
    ours, theirs = (heartpole.evaluate(p, episodes=200, seed=3).to_dict() for p in (safe, old))
    for result in (ours, theirs):
        del result["policy"], result["seconds"]
    assert ours == theirs


def test_statistics_round_trip_exactly_through_json(run: Path) -> None:
    with (run / "vecnormalize.pkl").open("rb") as handle:
        normalizer = pickle.load(handle)
    for read in (load_statistics(run / "vecnormalize.json"), unpickle_statistics(run / "vecnormalize.pkl")):
        np.testing.assert_array_equal(read.mean, normalizer.obs_rms.mean)
        np.testing.assert_array_equal(read.var, normalizer.obs_rms.var)
        assert (read.count, read.epsilon, read.clip_obs, read.norm_obs) == (
            normalizer.obs_rms.count, normalizer.epsilon, normalizer.clip_obs, normalizer.norm_obs
        )  # fmt: skip
    normalizer.obs_rms.mean[0] = np.nan
    with pytest.raises(ValueError, match=r"nan.json: obs_mean is not finite"):
        save_statistics(normalizer, run.parent / "nan.json")


def test_an_old_run_with_only_the_pickle_loads_through_the_restricted_unpickler(
    run: Path, tmp_path, monkeypatch
) -> None:
    path = _copy(run, tmp_path / "old")
    (tmp_path / "old" / "vecnormalize.json").unlink()
    _sidecar(tmp_path / "old", vecnormalize_json=None, vecnormalize_json_sha256=None)
    old = _trusted_the_old_way(path)
    monkeypatch.setattr(pickle, "load", lambda *a, **k: pytest.fail("unpickled"))
    policy = load_policy(str(path))
    assert policy.normalizer_path == tmp_path / "old" / "vecnormalize.pkl"
    np.testing.assert_array_equal(policy(OBS), old(OBS))


@pytest.mark.parametrize("field", ["obs_mean", "epsilon", "norm_obs", "format"])
def test_a_statistics_file_with_wrong_values_names_the_file_and_field(run: Path, tmp_path, field: str) -> None:
    record = json.loads((run / "vecnormalize.json").read_text())
    record[field] = "x"
    (tmp_path / "vecnormalize.json").write_text(json.dumps(record))
    with pytest.raises(ValueError, match=rf"vecnormalize.json: .*{'format' if field == 'format' else field}"):
        load_statistics(tmp_path / "vecnormalize.json")


# ------------------------------------------------------------------------------------------------------
# crafted files run nothing


def test_a_malicious_vecnormalize_pkl_runs_nothing_and_is_refused(run: Path, tmp_path) -> None:
    marker = tmp_path / "PWNED"
    path = _copy(run, tmp_path / "evil")
    pkl = tmp_path / "evil" / "vecnormalize.pkl"
    pkl.write_bytes(pickle.dumps(Touch(marker)))
    (tmp_path / "evil" / "vecnormalize.json").unlink()
    _sidecar(tmp_path / "evil", vecnormalize_sha256=file_sha256(pkl), vecnormalize_json=None)
    with pytest.raises(UnsafeFileError, match=r"vecnormalize.pkl: .*would call posix.system.*--trust-pickles"):
        load_policy(str(path))
    assert not marker.exists()
    code = main(["evaluate", "--policy", str(path), "--episodes", "2"])
    assert code == 2 and not marker.exists()
    # the payload is live: opting in unpickles it (and then finds no VecNormalize in it)
    with pytest.raises(ValueError, match="not a VecNormalize file"):
        load_policy(str(path), trust_pickles=True)
    assert marker.exists()


def _poison_data(zip_path: Path, key: str, payload: bytes) -> None:
    """Replace the pickle of ``key`` in the zip's data with ``payload``, keeping the entry's plain fields."""
    with zipfile.ZipFile(zip_path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    data = json.loads(members["data"])
    data[key][":serialized:"] = base64.b64encode(payload).decode()
    members["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(zip_path, "w") as archive:
        for name, raw in members.items():
            archive.writestr(name, raw)


@pytest.mark.parametrize("protocol", [0, 2, 5])
def test_a_malicious_model_zip_runs_nothing_and_is_refused(run: Path, tmp_path, capsys, protocol: int) -> None:
    import stable_baselines3 as sb3

    marker = tmp_path / "PWNED"
    path = _copy(run, tmp_path / "evil")
    _poison_data(path, "observation_space", pickle.dumps(Touch(marker), protocol))
    _sidecar(tmp_path / "evil", model_sha256=file_sha256(path))
    with pytest.raises(UnsafeFileError, match=r"model.zip: its data entry 'observation_space' .* posix.system"):
        load_policy(str(path))
    assert main(["evaluate", "--policy", str(path), "--episodes", "2"]) == 2
    assert "--trust-pickles" in capsys.readouterr().err and not marker.exists()
    # opting in skips the tripwire, but the safe reader still needs none of the data's pickles
    assert load_policy(str(path), trust_pickles=True)(OBS).shape == (512,)
    assert not marker.exists()
    with pytest.raises(Exception):  # noqa: B017 - whatever SB3 makes of it: its own load runs the payload
        sb3.PPO.load(path)
    assert marker.exists()


def test_a_policy_pth_holding_more_than_tensors_runs_nothing_and_is_refused(run: Path, tmp_path) -> None:
    marker = tmp_path / "PWNED"
    path = _copy(run, tmp_path / "evil")
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    torch.save({"weight": Touch(marker)}, tmp_path / "w.pth")
    members["policy.pth"] = (tmp_path / "w.pth").read_bytes()
    with zipfile.ZipFile(path, "w") as archive:
        for name, raw in members.items():
            archive.writestr(name, raw)
    _sidecar(tmp_path / "evil", model_sha256=file_sha256(path))
    with pytest.raises(UnsafeFileError, match=r"policy.pth holds more than tensors.*--trust-pickles"):
        load_policy(str(path))
    assert not marker.exists()


def test_the_tripwire_reads_every_way_a_pickle_imports() -> None:
    for protocol in range(pickle.HIGHEST_PROTOCOL + 1):
        assert "posix.system" in _pickle_imports(pickle.dumps(Touch(Path("x")), protocol))
        plain = _pickle_imports(pickle.dumps([np.zeros(2), collections.deque([1.5])], protocol))
        assert plain and {name.split(".")[0] for name in plain} <= {"numpy", "collections", "copyreg", "_codecs"}


# ------------------------------------------------------------------------------------------------------
# B14: a model trained under VecNormalize, copied without its statistics


def test_a_model_copied_without_its_statistics_is_not_evaluated_silently(run: Path, tmp_path) -> None:
    (tmp_path / "alone").mkdir()
    shutil.copy(run / "model.zip", tmp_path / "alone" / "model.zip")
    with pytest.warns(UserWarning, match=r"trained on VecNormalize-wrapped envs .* acts on raw observations"):
        policy = load_policy(str(tmp_path / "alone" / "model.zip"))
    assert policy.normalizer_path is None


def test_a_model_trained_without_vecnormalize_loads_without_that_warning(tmp_path: Path) -> None:
    import stable_baselines3 as sb3

    model = sb3.PPO("MlpPolicy", heartpole.HeartPole(), n_steps=16, batch_size=16, policy_kwargs={"net_arch": [8]})
    model.learn(32)
    model.save(tmp_path / "m.zip")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        policy = load_policy(str(tmp_path / "m.zip"))
    expected, _ = model.predict(OBS, deterministic=True)
    np.testing.assert_array_equal(policy(OBS), expected)


PLAIN_SB3 = {
    "ppo": ("PPO", {}),
    "ppo unshared extractors": ("PPO", {"share_features_extractor": False}),
    "ppo pi and vf nets": ("PPO", {"net_arch": {"pi": [8], "vf": [16]}}),
    "ppo pi and vf nets unshared": ("PPO", {"net_arch": {"pi": [8], "vf": [16]}, "share_features_extractor": False}),
    "a2c": ("A2C", {}),
    "a2c unshared extractors": ("A2C", {"share_features_extractor": False, "activation_fn": torch.nn.Tanh}),
    "dqn": ("DQN", {"net_arch": [16]}),
}


@pytest.mark.parametrize("case", list(PLAIN_SB3))
def test_every_plain_sb3_model_acts_as_sb3s_own_predict(tmp_path: Path, case: str, capsys) -> None:
    """A plain SB3 model, whatever its policy keywords, loads (safe reader) and acts as ``model.predict(obs,
    deterministic=True)`` does, in memory (``ModelPolicy``'s fast path) and loaded from its zip."""
    import stable_baselines3 as sb3

    algo, kwargs = PLAIN_SB3[case]
    options = {"learning_starts": 0} if algo == "DQN" else {"n_steps": 16}
    model = getattr(sb3, algo)("MlpPolicy", heartpole.HeartPole(), policy_kwargs=kwargs, seed=3, **options)
    model.learn(32)
    model.save(tmp_path / "m.zip")
    expected, _ = model.predict(OBS, deterministic=True)
    np.testing.assert_array_equal(ModelPolicy(model)(OBS), expected)
    with warnings.catch_warnings():  # trained without VecNormalize: not taken for a model that was (a DQN was)
        warnings.filterwarnings("error", ".*trained on VecNormalize-wrapped envs", UserWarning)
        loaded = load_policy(str(tmp_path / "m.zip"))
    assert isinstance(loaded.model, SavedModel)
    np.testing.assert_array_equal(loaded(OBS), expected)
    assert main(["evaluate", "--policy", str(tmp_path / "m.zip"), "--episodes", "2"]) == 0, capsys.readouterr().err


# ------------------------------------------------------------------------------------------------------
# what the safe reader rebuilds, and what it leaves to trust_pickles


def test_a_recorded_activation_function_is_rebuilt(tmp_path: Path) -> None:
    import stable_baselines3 as sb3

    kwargs = {"net_arch": [8, 8], "activation_fn": torch.nn.ReLU}
    sb3.A2C("MlpPolicy", heartpole.HeartPole(), policy_kwargs=kwargs, seed=1).save(tmp_path / "m.zip")
    policy = load_policy(str(tmp_path / "m.zip"))
    assert isinstance(policy.model, SavedModel)
    assert isinstance(policy.model.policy.mlp_extractor.policy_net[1], torch.nn.ReLU)
    expected, _ = sb3.A2C.load(tmp_path / "m.zip").predict(OBS, deterministic=True)
    np.testing.assert_array_equal(policy(OBS), expected)


def test_a_model_the_safe_reader_cannot_rebuild_needs_trust_pickles(run: Path, tmp_path, capsys) -> None:
    path = _copy(run, tmp_path / "custom")
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    data = json.loads(members["data"])
    data["policy_class"]["__init__"] = "<function MyPolicy.__init__ at 0x0>"  # a policy class of one's own
    with zipfile.ZipFile(path, "w") as archive:
        for name, raw in {**members, "data": json.dumps(data).encode()}.items():
            archive.writestr(name, raw)
    _sidecar(tmp_path / "custom", model_sha256=file_sha256(path))
    with pytest.raises(UnsafeFileError, match=r"policy class \(.*MyPolicy.__init__\) is not the PPO MlpPolicy"):
        load_policy(str(path))
    trusted = load_policy(str(path), trust_pickles=True)  # SB3's own load, which unpickles
    assert not isinstance(trusted.model, SavedModel)
    np.testing.assert_array_equal(trusted(OBS), _trusted_the_old_way(path)(OBS))
    assert main(["evaluate", "--policy", str(path), "--episodes", "2"]) == 2
    assert "--trust-pickles" in capsys.readouterr().err
    assert main(["evaluate", "--policy", str(path), "--episodes", "2", "--trust-pickles"]) == 0


@pytest.mark.parametrize("protocol", range(pickle.HIGHEST_PROTOCOL + 1))
def test_the_restricted_unpickler_reads_every_protocol_and_refuses_hidden_calls(tmp_path: Path, protocol) -> None:
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    normalizer = VecNormalize(DummyVecEnv([heartpole.HeartPole]), clip_obs=3.0)
    normalizer.obs_rms.mean = np.arange(6.0)
    (tmp_path / "v.pkl").write_bytes(pickle.dumps(normalizer, protocol))
    np.testing.assert_array_equal(unpickle_statistics(tmp_path / "v.pkl").mean, normalizer.obs_rms.mean)
    marker = tmp_path / "PWNED"
    normalizer.ret_rms.extra = Touch(marker)  # a call hidden in an otherwise genuine file
    (tmp_path / "e.pkl").write_bytes(pickle.dumps(normalizer, protocol))
    with pytest.raises(UnsafeFileError, match=r"e.pkl: .*would call posix.system"):
        unpickle_statistics(tmp_path / "e.pkl")
    del normalizer.ret_rms.extra
    normalizer.obs_rms.mean = np.array([Touch(marker)] * 6, dtype=object)  # objects inside an array
    (tmp_path / "o.pkl").write_bytes(pickle.dumps(normalizer, protocol))
    with pytest.raises(ValueError, match=r"o.pkl: not a VecNormalize file"):
        unpickle_statistics(tmp_path / "o.pkl")
    assert not marker.exists()
