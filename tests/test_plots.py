"""heartpole.plots: the model's figures follow the model, episodes are traced faithfully, curves and videos."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import heartpole  # noqa: E402
from heartpole import (  # noqa: E402
    model,
    parameters,  # noqa: E402
    plots,
)


def png_size(path: Path) -> tuple[int, int]:
    from PIL import Image

    with Image.open(path) as image:
        return image.size


def assert_nontrivial_png(path: Path, size: tuple[int, int]) -> None:
    from PIL import Image

    assert png_size(path) == size
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("RGB"))
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 50  # lines, text, colours: not a blank canvas
    assert (pixels < 128).any(axis=2).mean() > 0.01  # dark ink somewhere


def coffee(obs: np.ndarray) -> np.ndarray:
    return np.ones(len(obs), dtype=np.int64)


def cycle(obs: np.ndarray) -> np.ndarray:
    """Coffee, work, beer, then sleep once awake for 8 half-hours."""
    since = obs[:, 3].astype(int)
    return np.select([since >= 8, since == 1, since == 3], [3, 1, 2], 0)


def heavy(obs: np.ndarray) -> np.ndarray:
    """Coffee every half-hour, sleep after 10 hours awake: high blood pressure, heart attacks."""
    return np.where(obs[:, 3] >= 20, 3, 1)


def test_model_figures_draw_the_models_functions(tmp_path: Path) -> None:
    curves = {
        "heart_attack_risk": model.heart_attack_risk,
        "alertness_decay": model.alertness_decay,
        "crippling_anxiety": model.crippling_anxiety,
        "ballmer": model.ballmer,
    }
    for stem, function in curves.items():
        figure = plots.MODEL_FIGURES[stem](parameters.Params())
        line = figure.axes[0].lines[0]
        np.testing.assert_allclose(line.get_ydata(), function(np.asarray(line.get_xdata())))
    path = tmp_path / "risk.png"
    plots.save_figure(plots.heart_attack_risk_figure(), path)
    assert_nontrivial_png(path, (700, 450))


def test_a_change_to_the_model_shows_up_in_the_plots(monkeypatch: pytest.MonkeyPatch) -> None:
    before = plots.ballmer_figure().axes[0].lines[0].get_ydata()
    monkeypatch.setattr(model, "ballmer", lambda x: 0.5 * np.ones_like(x))
    after = plots.ballmer_figure().axes[0].lines[0].get_ydata()
    assert before.max() > 1.9 and np.all(after == 0.5)
    figure = plots.heart_attack_risk_figure(parameters.Params(heart_attack_proclivity=0.2))
    assert figure.axes[0].lines[0].get_ydata().max() == pytest.approx(0.2, abs=0.01)


def test_productivity_heat_map_is_the_model_on_a_grid(tmp_path: Path) -> None:
    figure = plots.productivity_figure()
    mesh = figure.axes[0].collections[0]
    values = np.asarray(mesh.get_array()).reshape(501, 301)
    alertness, intoxication = np.linspace(-0.5, 7.0, 301), np.linspace(0.0, 0.25, 501)
    np.testing.assert_allclose(values, model.productivity(alertness[None, :], intoxication[:, None]))
    path = tmp_path / "productivity.png"
    plots.save_figure(figure, path)
    assert_nontrivial_png(path, (750, 500))


def test_trace_records_the_episode_as_the_env_plays_it() -> None:
    trace = plots.trace_episode(cycle, seed=4, max_steps=40)
    assert trace.states.shape == (41, 6) and trace.actions.shape == (40,)
    assert trace.names == parameters.variable_names(parameters.V0_VARIABLES)
    assert trace.sleeps == (False, False, False, True)
    assert set(trace.actions.tolist()) == {0, 1, 2, 3}
    env = heartpole.HeartPole(max_steps=40)
    obs, _ = env.reset(seed=4)
    rewards = []
    for action in trace.actions:
        obs, reward, _, _, _ = env.step(int(action))
        rewards.append(reward)
    np.testing.assert_allclose(trace.states[-1], obs, rtol=1e-6)
    np.testing.assert_allclose(trace.rewards, rewards)
    assert trace.score[-1] == pytest.approx(obs[5] / obs[4], rel=1e-5)


def test_episode_dashboard_marks_sleep_and_heart_attacks(tmp_path: Path) -> None:
    trace = plots.trace_episode(heavy, seed=1, max_steps=80, heart_attack_proclivity=1.0)
    attacks, sleeps = int(trace.heart_attacks.sum()), int((trace.actions == 3).sum())
    assert attacks >= 1 and sleeps >= 2
    figure = plots.episode_figure(trace)
    assert len(figure.axes) == 5  # alertness, blood pressure, intoxication, score, actions
    for axes in figure.axes:
        red = [line for line in axes.lines if line.get_color() == plots.ATTACK_COLOR]
        vertical = [line for line in red if np.ptp(np.asarray(line.get_xdata(), dtype=float)) == 0]
        assert len(vertical) == attacks
        assert len([p for p in axes.patches if p.get_facecolor()[:3] != (1.0, 1.0, 1.0)]) >= sleeps
    path = tmp_path / "episode.png"
    plots.save_figure(figure, path)
    assert_nontrivial_png(path, (1200, 930))


def test_variant_variables_get_a_panel() -> None:
    pytest.importorskip("heartpole.registry")
    import gymnasium as gym

    if "HeartPole-v1" not in gym.registry:
        pytest.skip("no HeartPole-v1 registered")
    trace = plots.trace_episode(lambda obs: np.zeros(len(obs), dtype=np.int64), "HeartPole-v1", max_steps=5)
    extra = [name for name in trace.names if name not in parameters.variable_names(parameters.V0_VARIABLES)]
    assert len(plots.episode_figure(trace).axes) == 5 + len(extra)


def write_curve(path: Path, timesteps: list[int], returns: list[float]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [f"{t},{r},{1.5 - i * 0.1},{0.2 + i * 0.01}" for i, (t, r) in enumerate(zip(timesteps, returns))]
    path.write_text("timesteps,mean_return,heart_attacks,score\n" + "\n".join(rows) + "\n")


def test_learning_curves_single_run_and_seeds(tmp_path: Path) -> None:
    write_curve(tmp_path / "single" / "learning_curve.csv", [1000, 2000, 3000], [-300.0, -200.0, -150.0])
    found = plots.find_learning_curves(tmp_path / "single")
    assert list(found) == ["run"]
    curve = plots.read_learning_curve(found["run"])
    np.testing.assert_array_equal(curve["mean_return"], [-300.0, -200.0, -150.0])

    for seed, shift in ((2, 10.0), (0, -10.0), (10, 0.0)):
        write_curve(
            tmp_path / "multi" / f"seed_{seed}" / "learning_curve.csv",
            [0, 1000, 2000],
            [-300.0 + shift, -200.0 + shift, -100.0 + shift],
        )
    found = plots.find_learning_curves(tmp_path / "multi")
    assert list(found) == ["seed 0", "seed 2", "seed 10"]
    figure = plots.training_figure({k: plots.read_learning_curve(p) for k, p in found.items()})
    returns = figure.axes[0]
    np.testing.assert_allclose(returns.lines[0].get_ydata(), [-300.0, -200.0, -100.0])  # the mean
    band = returns.collections[0].get_paths()[0].vertices[:, 1]
    assert band.min() == pytest.approx(-310.0) and band.max() == pytest.approx(-90.0)
    path = tmp_path / "curve.png"
    plots.save_figure(figure, path)
    assert_nontrivial_png(path, (1200, 420))


def test_bad_learning_curves_raise_value_error(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("timesteps,mean_return\n1,2\n")
    (tmp_path / "b.csv").write_text("timesteps,mean_return,heart_attacks,score\n")
    (tmp_path / "c.csv").write_text("timesteps,mean_return,heart_attacks,score\n1,x,0,0\n")
    for name, words in (("a.csv", "missing column"), ("b.csv", "no rows"), ("c.csv", "not a number")):
        with pytest.raises(ValueError, match=words):
            plots.read_learning_curve(tmp_path / name)


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_videos_hold_one_frame_per_step(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"episode{suffix}"
    count = plots.write_video(plots.episode_frames(coffee, seed=0, max_steps=12), path, fps=8)
    assert count == 13  # the first state, then one frame per step
    if suffix == ".gif":
        from PIL import Image

        with Image.open(path) as image:
            assert image.n_frames == 13 and image.size == (600, 400)
    else:
        import imageio.v2 as imageio

        with imageio.get_reader(path) as reader:
            frames = [frame for frame in reader]
        assert len(frames) == 13 and frames[0].shape == (400, 600, 3)
        assert np.abs(frames[-1].astype(int) - frames[0]).mean() > 1  # the picture moves


def test_unsupported_video_type_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unsupported video type"):
        plots.write_video(iter([]), tmp_path / "x.avi")
    assert not list(tmp_path.iterdir())


def test_gymnasiums_record_video_works_with_the_plot_extra(tmp_path: Path) -> None:
    import gymnasium as gym

    pytest.importorskip("moviepy")  # RecordVideo's writer, installed by the plot extra
    env = gym.make("HeartPole-v0", render_mode="rgb_array", max_steps=12, max_episode_steps=12)
    folder = tmp_path / "videos"
    env = gym.wrappers.RecordVideo(env, str(folder), episode_trigger=lambda episode: True, disable_logger=True)
    env.reset(seed=0)
    truncated = False
    while not truncated:
        *_, truncated, _ = env.step(env.action_space.sample())
    env.close()
    videos = list(folder.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


def test_video_writers_are_checked_by_type(monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins

    real_import = builtins.__import__

    def without_pil(name: str, *args: object, **kwargs: object) -> object:
        if name == "PIL":
            raise ImportError("no PIL here")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(builtins, "__import__", without_pil)
    with pytest.raises(ImportError, match=r"^\.gif videos need Pillow$"):
        plots.require_video_writer(".gif")


def test_an_episode_longer_than_the_registered_limit_is_drawn_and_filmed_whole() -> None:
    """``max_steps`` above the spec's ``max_episode_steps``: gymnasium.make's TimeLimit stopped the episode at the
    registered length (``heartpole record --steps 2000`` filmed 1,000 decisions)."""
    from heartpole.plots import episode_frames, trace_episode
    from heartpole.policies import load_policy

    heartpole.register_variant("ShortPlotPole-v0", max_steps=5, replace=True)
    policy = load_policy("nothing", "ShortPlotPole-v0", env_kwargs={"max_steps": 9})
    assert len(trace_episode(policy, "ShortPlotPole-v0", 0, max_steps=9).actions) == 9
    assert sum(1 for _ in episode_frames(policy, "ShortPlotPole-v0", 0, max_steps=9)) == 10
