"""heartpole.jax.ppo: its parts against SB3/PyTorch, a smoke run whose outputs load, and the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

jax = pytest.importorskip("jax", reason="heartpole.jax needs the 'jax' extra: pip install 'heartpole[jax]'")
pytest.importorskip("stable_baselines3", reason="saving and evaluating needs the 'train' extra")
torch = pytest.importorskip("torch")

import jax.numpy as jnp  # noqa: E402

from heartpole import plots, training  # noqa: E402
from heartpole.cli import main  # noqa: E402
from heartpole.evaluation import evaluate  # noqa: E402
from heartpole.jax import export, ppo  # noqa: E402
from heartpole.policies import load_policy  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore:.*is out of date.*:DeprecationWarning")


def test_running_stats_match_sb3() -> None:
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    rng = np.random.default_rng(0)
    ours, theirs = ppo.RunningStats.start((3,)), RunningMeanStd(shape=(3,))
    for _ in range(5):
        batch = rng.normal(2.0, 3.0, size=(16, 3)).astype(np.float32)
        ours, _ = ours.update(jnp.asarray(batch)), theirs.update(batch)
    np.testing.assert_allclose(ours.mean, theirs.mean, rtol=1e-5)
    np.testing.assert_allclose(ours.var, theirs.var, rtol=1e-4)


def test_adam_step_matches_torch() -> None:
    """Clipping to the global norm, then PyTorch's Adam with eps 1e-5, as SB3's PPO does."""
    rng = np.random.default_rng(1)
    weights = rng.normal(size=(4, 3)).astype(np.float32)
    params, state = jnp.asarray(weights), ppo.adam_init(jnp.asarray(weights))
    tensor = torch.nn.Parameter(torch.tensor(weights))
    optimizer = torch.optim.Adam([tensor], lr=0.01, eps=1e-5)
    for _ in range(3):
        grad = rng.normal(size=(4, 3)).astype(np.float32)
        params, state = ppo.adam_step(params, jnp.asarray(grad), state, 0.01, 0.5)
        tensor.grad = torch.tensor(grad)
        torch.nn.utils.clip_grad_norm_([tensor], 0.5)
        optimizer.step()
    np.testing.assert_allclose(params, tensor.detach().numpy(), rtol=1e-5, atol=1e-6)


# Run in a child limited to 2 CPUs (XLA sizes its thread pool by them): the old batched QR hung there
# within about 20 calls, every time (7 of 7 runs on a 2-core machine); 300 calls take about a second.
_VMAPPED_INIT = """
import os
if hasattr(os, "sched_setaffinity"):  # Linux; before JAX starts its pool
    os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:2])
import jax, jax.numpy as jnp
from heartpole.jax import ppo
init = jax.jit(jax.vmap(lambda key: ppo.init_network(key, 6, 4, (64, 64))))
for i in range(300):
    jax.block_until_ready(init(jax.vmap(jax.random.key)(jnp.arange(2 * i, 2 * i + 2, dtype=jnp.uint32))))
"""


def test_vmapped_network_init_does_not_hang_on_two_cpus() -> None:
    try:
        subprocess.run([sys.executable, "-c", _VMAPPED_INIT], check=True, timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail("300 vmapped network initialisations did not finish in 120 s: the batched-QR hang is back")


def test_orthogonal_init_vmapped_equals_one_key_at_a_time() -> None:
    keys = jax.vmap(jax.random.key)(jnp.arange(3, dtype=jnp.uint32))
    batched = jax.jit(jax.vmap(lambda key: ppo.orthogonal(key, (64, 32), 2.0)))(keys)
    one_by_one = [jax.nn.initializers.orthogonal(2.0)(key, (64, 32), jnp.float32) for key in keys]
    np.testing.assert_array_equal(batched, np.stack(one_by_one))
    for matrix in np.asarray(batched) / 2.0:
        np.testing.assert_allclose(matrix.T @ matrix, np.eye(32), atol=1e-5)


def test_settings_from_the_default_preset_and_bad_configs() -> None:
    settings = ppo.PPOSettings.from_config(training.preset_config("default"))
    assert (settings.n_envs, settings.n_steps, settings.batch_size, settings.gamma) == (16, 128, 512, 0.95)
    assert settings.score_rate == 0.32 and settings.expected_risk and settings.num_updates == 196
    with pytest.raises(ValueError, match="PPO only"):
        ppo.PPOSettings.from_config(training.preset_config("tutorial"))
    auto = replace(training.SHAPED_REWARD, score_rate="auto")
    with pytest.raises(ValueError, match="score_rate='auto'"):
        ppo.PPOSettings.from_config(training.preset_config("default", reward=auto))


def test_the_jax_preset_and_an_annealed_learning_rate_as_sb3_schedules_it() -> None:
    config = training.preset_config("default", backend="jax", timesteps=10_000)
    assert config.hyperparameters == training.JAX_PPO_HYPERPARAMETERS
    assert training.preset_config("default", backend="jax").timesteps == training.JAX_PPO_TIMESTEPS
    assert training.preset_config("default", "a2c", backend="jax") == training.preset_config("default", "a2c")
    with pytest.raises(ValueError, match="unknown backend"):
        training.preset_config(backend="tpu")
    annealed = {**config.hyperparameters, "anneal_learning_rate": True, "learning_rate": 1e-3}
    config = replace(config, hyperparameters=annealed)
    settings = ppo.PPOSettings.from_config(config)
    model, venv = training.build_model(config)  # SB3 takes the same schedule
    venv.close()
    for update in range(settings.num_updates):
        left = 1.0 - (update + 1) * settings.rollout / config.timesteps  # SB3's progress after the rollout
        ours = float(ppo.learning_rate_at(settings, jnp.int32(update)))
        assert ours == pytest.approx(model.lr_schedule(left), rel=1e-6, abs=1e-12)
    assert float(ppo.learning_rate_at(settings, jnp.int32(settings.num_updates - 1))) == 0.0
    constant = replace(settings, anneal_learning_rate=False)
    assert ppo.learning_rate_at(constant, jnp.int32(5)) == settings.learning_rate


@pytest.mark.slow  # compiles and trains two seeds, about 10 s
def test_smoke_run_writes_what_heartpole_evaluate_reads(tmp_path, capsys) -> None:
    """Two seeds of a few thousand steps in one call: every file of the SB3 path, loadable, evaluable."""
    config = training.preset_config("default", timesteps=4096, n_envs=8, env_kwargs={"max_steps": 64})
    summary = export.train_seeds(config, [0, 1], tmp_path, eval_episodes=20)
    assert summary["seeds"] == [0, 1] and summary["compile_seconds"] > 0 and summary["train_seconds"] > 0
    assert set(summary["aggregate"]) >= {"heart_attacks_per_episode", "score", "mean_return"}
    assert json.loads((tmp_path / "summary.json").read_text())["backend"] == "jax"
    for seed in (0, 1):
        folder = tmp_path / f"seed_{seed}"
        for name in ("model.zip", "vecnormalize.pkl", "vecnormalize.json", "heartpole.json", "learning_curve.csv",
                     "evaluation.json"):  # fmt: skip
            assert (folder / name).is_file(), name
        curve = plots.read_learning_curve(folder / "learning_curve.csv")  # the one reader, the plots'
        assert len(curve["timesteps"]) == 4096 // (8 * 64) and curve["timesteps"][0] == 8 * 64
        policy = load_policy(str(folder / "model.zip"), "HeartPole-v0", env_kwargs={"max_steps": 64})
        assert policy(np.zeros((3, 6), np.float32)).shape == (3,)
        assert policy.normalizer_path == folder / "vecnormalize.json"  # read as plain JSON, not unpickled
    (tmp_path / "alone").mkdir()  # B14: copied without heartpole.json and the statistics, it is not used silently
    (tmp_path / "alone" / "model.zip").write_bytes((tmp_path / "seed_0" / "model.zip").read_bytes())
    with pytest.warns(UserWarning, match="trained on VecNormalize-wrapped envs"):
        load_policy(str(tmp_path / "alone" / "model.zip"), "HeartPole-v0", env_kwargs={"max_steps": 64})
    code = main(["evaluate", "--policy", str(tmp_path / "seed_0" / "model.zip"), "--episodes", "10"])
    assert code == 0 and "seed_0" in capsys.readouterr().out
    # evaluation.json (every seed evaluated on the device in one call) is heartpole evaluate's of the saved model
    for seed in (0, 1):
        saved = str(tmp_path / f"seed_{seed}" / "model.zip")
        on_device = json.loads((tmp_path / f"seed_{seed}" / "evaluation.json").read_text())
        numpy = evaluate(saved, episodes=20, seed=0, env_kwargs={"max_steps": 64}).to_dict()
        assert on_device["policy"] == saved and on_device["episodes"] == numpy["episodes"] == 20
        for column in ("expected_return", "score", "heart_attacks_per_episode", "sleeps_per_episode"):
            assert abs(on_device[column] - numpy[column]) <= 1e-4, (seed, column, on_device[column], numpy[column])


@pytest.mark.slow
def test_exported_model_acts_as_the_jax_network(tmp_path) -> None:
    """The SB3 model.zip holds the very weights: its greedy actions equal the JAX network's argmax."""
    config = training.preset_config("default", timesteps=1024, n_envs=8, env_kwargs={"max_steps": 32})
    env = ppo.HeartPoleJax.from_id("HeartPole-v0", max_steps=32)
    settings = ppo.PPOSettings.from_config(config)
    runner, _ = jax.jit(ppo.make_train(env, env.default_params, settings))(jax.random.key(3))
    export.export_sb3(config, runner, tmp_path)
    with pytest.warns(UserWarning, match=r"ignoring .*vecnormalize.json"):  # no heartpole.json records them
        policy = load_policy(str(tmp_path / "model.zip"), "HeartPole-v0")
    obs = np.random.default_rng(0).uniform(0, 5, size=(200, 6)).astype(np.float32)
    seen = policy.normalize(obs)
    logits, _ = ppo.policy_and_value(runner.network, jnp.asarray(seen))
    np.testing.assert_array_equal(policy(obs), np.asarray(jnp.argmax(logits, axis=1)))


@pytest.mark.slow
def test_each_seed_is_written_as_sb3_writes_it(tmp_path, monkeypatch) -> None:
    """Seeds copied to the host a chunk at a time (a chunk of one here) are the device's seeds, and the writer's
    model.zip, built from the first seed's archive, is SB3's own save of the same model: the same entries in the
    same order, the same bytes but for the weights, and each seed's own weights."""
    import zipfile

    from stable_baselines3.common.save_util import load_from_zip_file

    monkeypatch.setattr(export, "HOST_CHUNK", 1)
    config = training.preset_config("default", timesteps=1024, n_envs=8, env_kwargs={"max_steps": 32})
    trained = ppo.train_compiled(config, [3, 4])
    picked = list(export.on_host(trained))
    assert len(picked) == 2
    weights = []
    with export.SB3Writer(config) as writer:
        for i, (runner, curve) in enumerate(picked):
            device = jax.tree_util.tree_map(lambda x, i=i: x[i], (trained.runners.network, trained.ended))
            for a, b in zip(jax.tree_util.tree_leaves(runner.network), jax.tree_util.tree_leaves(device[0])):
                np.testing.assert_array_equal(a, b)
            assert curve == ppo.learning_curve(device[1], trained.settings)
            writer.write(runner, tmp_path / f"seed_{i}")
            ours, theirs = tmp_path / f"seed_{i}" / "model.zip", tmp_path / "sb3.zip"
            writer.model.save(theirs)
            with zipfile.ZipFile(ours) as mine, zipfile.ZipFile(theirs) as sb3:
                assert mine.namelist() == sb3.namelist() and export.POLICY_ENTRY in mine.namelist()
                for name in mine.namelist():
                    if name != export.POLICY_ENTRY:
                        assert mine.read(name) == sb3.read(name), name
            mine_params, sb3_params = load_from_zip_file(ours)[1], load_from_zip_file(theirs)[1]
            for name, tensor in sb3_params["policy"].items():
                assert torch.equal(mine_params["policy"][name], tensor), name
            weights.append(mine_params["policy"]["action_net.weight"])
    assert not torch.equal(*weights)  # two seeds, two networks


def test_cli_backend_jax_without_jax_says_what_to_install() -> None:
    code = (
        "import sys; sys.modules['jax'] = None\n"
        "from heartpole.cli import main\n"
        "sys.exit(main(['train', '--backend', 'jax', '--timesteps', '100']))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.strip() == (
        "heartpole train: error: --backend jax needs JAX, which this Python cannot import: pip install 'heartpole[jax]'"
    )


def test_cli_bad_backend_and_algorithm(capsys, tmp_path) -> None:
    assert main(["train", "--backend", "tensorflow", "--out", str(tmp_path / "a")]) == 2
    assert "unknown backend 'tensorflow'; choose one of sb3, jax" in capsys.readouterr().err
    assert main(["train", "--backend", "jax", "--algo", "dqn", "--out", str(tmp_path / "b")]) == 2
    assert "PPO only" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_training_runs_in_whole_update_pieces() -> None:
    assert ppo.chunk_size(196) == 7 and ppo.chunk_size(197) == 1 and ppo.chunk_size(5) == 1
    assert all(n % ppo.chunk_size(n) == 0 and n // ppo.chunk_size(n) >= min(n, 20) for n in range(1, 400))
