"""``heartpole plot`` and ``heartpole record``: the files they write, and one clear line for bad input."""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from heartpole import plots  # noqa: E402
from heartpole.cli import main  # noqa: E402


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def image(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as picture:
        return np.asarray(picture.convert("RGB"))


def assert_error(result: tuple[int, str, str], command: str, words: str) -> None:
    code, _, err = result
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"heartpole {command}: error:") and words in lines[0], err


def test_plot_model_writes_every_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "plot", "model", "--out", str(tmp_path / "figures"))
    assert code == 0
    written = sorted(p.name for p in (tmp_path / "figures").iterdir())
    assert written == sorted(f"{stem}.png" for stem in plots.MODEL_FIGURES)
    for name in written:
        pixels = image(tmp_path / "figures" / name)
        assert pixels.shape[0] >= 450 and pixels.shape[1] >= 700 and pixels.std() > 10
        assert f"wrote {tmp_path / 'figures' / name}" in out


def test_plot_episode_of_a_builtin_policy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "episode.png"
    code, out, _ = run(
        capsys, "plot", "episode", "--policy", "reference", "--seed", "3", "--steps", "80", "--out", str(target)
    )
    assert code == 0 and out.strip() == f"wrote {target}"
    pixels = image(target)
    assert pixels.shape == (930, 1200, 3)
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 50


def test_plot_episode_of_a_saved_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    model = sb3.PPO("MlpPolicy", gym.make("HeartPole-v0"), n_steps=64, batch_size=64, device="cpu", seed=0)
    model.save(tmp_path / "model.zip")
    target = tmp_path / "model.png"
    code, _, err = run(
        capsys, "plot", "episode", "--policy", str(tmp_path / "model.zip"), "--steps", "30", "--out", str(target)
    )
    assert code == 0, err
    assert image(target).shape == (930, 1200, 3)


def test_plot_training_reads_the_seeds(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for seed in (0, 1):
        folder = tmp_path / "run" / f"seed_{seed}"
        folder.mkdir(parents=True)
        (folder / "learning_curve.csv").write_text(
            "timesteps,mean_return,heart_attacks,score\n"
            f"0,{-300 - seed},2.0,0.1\n5000,{-150 + seed},1.4,0.2\n10000,{-120 + seed},1.3,0.3\n"
        )
    code, out, _ = run(capsys, "plot", "training", str(tmp_path / "run"))
    target = tmp_path / "run" / "learning_curve.png"
    assert code == 0 and out.strip() == f"wrote {target}"
    assert image(target).shape == (420, 1200, 3)


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_record_writes_a_video(tmp_path: Path, capsys: pytest.CaptureFixture[str], suffix: str) -> None:
    target = tmp_path / f"day{suffix}"
    code, out, _ = run(capsys, "record", "--policy", "coffee", "--steps", "10", "--fps", "5", "--out", str(target))
    assert code == 0 and f"wrote {target} (11 frames" in out
    if suffix == ".gif":
        from PIL import Image

        with Image.open(target) as video:
            assert video.n_frames == 11 and video.size == (600, 400)
    else:
        import imageio.v2 as imageio

        with imageio.get_reader(target) as reader:
            assert sum(1 for _ in reader) == 11
    assert sorted(p.name for p in tmp_path.iterdir()) == [target.name]  # no temporary files left


# --------------------------------------------------------------------------------------------------------
# Bad input: one line, exit code 2, no files.
def test_unknown_policy_and_missing_model(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = str(tmp_path / "x.png")
    assert_error(run(capsys, "plot", "episode", "--policy", "sometimes", "--out", out), "plot", "unknown policy")
    missing = str(tmp_path / "nope.zip")
    assert_error(run(capsys, "plot", "episode", "--policy", missing, "--out", out), "plot", "not found")
    (tmp_path / "junk.zip").write_text("not a zip")
    assert_error(
        run(capsys, "record", "--policy", str(tmp_path / "junk.zip"), "--out", str(tmp_path / "x.mp4")), "record", "zip"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["junk.zip"]


WRITERS = {
    "plot model": lambda out: ["plot", "model", "--out", str(out)],
    "plot episode": lambda out: ["plot", "episode", "--policy", "expert", "--steps", "3", "--out", str(out / "e.png")],
    "record": lambda out: ["record", "--policy", "expert", "--steps", "3", "--out", str(out / "e.gif")],
    "baselines": lambda out: ["baselines", "--episodes", "2", "--out", str(out)],
}


@pytest.mark.parametrize("command", list(WRITERS))
def test_every_writer_creates_folders_and_replaces_files_only_with_force(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "no" / "such"
    old = os.umask(0o027)
    try:
        code, _, err = run(capsys, *WRITERS[command](out))
        assert code == 0, err
        written = sorted(p for p in out.rglob("*") if p.is_file())
        assert written
        for folder in (tmp_path / "no", out):
            assert folder.stat().st_mode & 0o777 == 0o750  # the umask's modes, as mkdir gives
        for path in written:
            assert path.stat().st_mode & 0o777 == 0o640
        before = {path: path.stat().st_mtime_ns for path in written}
        assert_error(run(capsys, *WRITERS[command](out)), command.split()[0], "exists; pass --force to replace it")
        assert {path: path.stat().st_mtime_ns for path in written} == before
        code, _, err = run(capsys, *WRITERS[command](out), "--force")
        assert code == 0, err
    finally:
        os.umask(old)


def test_train_output_folder_has_the_umasks_mode(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    from heartpole import training

    old = os.umask(0o027)
    try:
        with training.staged_output(tmp_path / "a" / "run") as staging:
            (staging / "heartpole.json").write_text("{}")
    finally:
        os.umask(old)
    assert (tmp_path / "a" / "run").stat().st_mode & 0o777 == 0o750  # was 0o700 (mkdtemp's)
    assert (tmp_path / "a").stat().st_mode & 0o777 == 0o750


def test_output_under_a_file_or_from_a_missing_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert_error(
        run(capsys, "plot", "episode", "--policy", "expert", "--out", str(blocker / "e.png")), "plot", "is a file"
    )
    assert_error(run(capsys, "plot", "model", "--out", str(blocker)), "plot", "is a file, expected a folder")
    assert_error(run(capsys, "plot", "training", str(tmp_path / "missing")), "plot", "no such folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_output_without_permission(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    real_mkdtemp = tempfile.mkdtemp

    def refused(*args: Any, dir: Any = None, **kwargs: Any) -> str:  # noqa: A002 - tempfile's name
        if dir is not None and Path(dir) == locked:
            raise PermissionError(errno.EACCES, "Permission denied", str(locked / ".x"))
        return real_mkdtemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkdtemp", refused)  # what a folder without write permission does (even as root)
    record = run(capsys, "record", "--policy", "expert", "--out", str(locked / "v.mp4"))
    assert_error(record, "record", f"cannot write {locked / 'v.mp4'}: Permission denied")
    assert_error(run(capsys, "plot", "model", "--out", str(locked)), "plot", "Permission denied")
    assert not list(locked.iterdir())


def test_unsupported_suffixes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert_error(run(capsys, "record", "--policy", "expert", "--out", str(tmp_path / "v.avi")), "record", "'.avi'")
    assert_error(run(capsys, "record", "--policy", "expert", "--out", str(tmp_path / "video")), "record", "(none)")
    assert_error(
        run(capsys, "plot", "episode", "--policy", "expert", "--out", str(tmp_path / "e.jpg")), "plot", "'.jpg'"
    )
    assert not list(tmp_path.iterdir())


def test_training_folder_without_curves_or_with_a_bad_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert_error(run(capsys, "plot", "training", str(tmp_path)), "plot", "no learning_curve.csv")
    (tmp_path / "learning_curve.csv").write_text("steps,reward\n1,2\n")
    assert_error(run(capsys, "plot", "training", str(tmp_path)), "plot", "missing column")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["learning_curve.csv"]


def test_a_failure_while_writing_leaves_no_partial_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken_writer(frames, path, fps=8.0):
        Path(path).write_bytes(b"half a video")
        raise RuntimeError("disk full")

    monkeypatch.setattr(plots, "write_video", broken_writer)
    with pytest.raises(RuntimeError, match="disk full"):
        main(["record", "--policy", "expert", "--steps", "3", "--out", str(tmp_path / "v.mp4")])
    assert not list(tmp_path.iterdir())


def test_missing_matplotlib_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def missing() -> None:
        raise ImportError("no matplotlib")

    monkeypatch.setattr(plots, "require_matplotlib", missing)
    assert_error(run(capsys, "plot", "model", "--out", str(tmp_path)), "plot", 'pip install "heartpole[plot]"')


def test_plot_without_a_figure_name_shows_usage(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["plot"])
    assert exit_info.value.code == 2
    assert "FIGURE" in capsys.readouterr().err
