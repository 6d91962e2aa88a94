"""Hostile and unlucky places to write (issue 35, rows A1-A4, A11, B3, B4): a full disk, a read-only file
system, a busy mount point, a symbolic link loop, a signal once the output is in place.

No tmpfs here (CI has none): a full disk is a writer raising ``OSError(ENOSPC)``, a read-only file system a
``mkdtemp``/``mkstemp`` raising ``EROFS``, a mount point ``os.path.ismount`` saying so and ``os.replace``
raising ``EBUSY``, as the real ones do.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest

from heartpole import files, paths
from heartpole.cli import main
from tests.signal_dispositions import as_in_a_terminal

# Tests here raise SIGTERM and SIGHUP in this process: at their terminal defaults whatever started the run (nohup).
pytestmark = pytest.mark.usefixtures("terminal_signals")


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def one_error(result: tuple[int, str, str], command: str, *words: str) -> str:
    code, _, err = result
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith(f"heartpole {command}: error:"), err
    for word in words:
        assert word in lines[0], err
    assert "Traceback" not in err
    return lines[0]


def tree(folder: Path) -> dict[str, bytes | None]:
    return {str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes() for p in sorted(folder.rglob("*"))}


def read_only(monkeypatch: pytest.MonkeyPatch, folder: Path) -> None:
    """``folder`` behaves as on a read-only file system: nothing can be made in it."""
    real_mkdtemp, real_mkstemp = tempfile.mkdtemp, tempfile.mkstemp

    def refuse(real: Any) -> Any:
        def made(*args: Any, dir: Any = None, **kwargs: Any) -> Any:  # noqa: A002 - tempfile's name
            if dir is not None and Path(dir) == folder:
                raise OSError(errno.EROFS, "Read-only file system", str(folder / ".optimum.npz.rehtgwtv.npz"))
            return real(*args, dir=dir, **kwargs)

        return made

    monkeypatch.setattr(tempfile, "mkdtemp", refuse(real_mkdtemp))
    monkeypatch.setattr(tempfile, "mkstemp", refuse(real_mkstemp))


# ------------------------------------------------------------------------------------------------------
# A1: a target that cannot be replaced; the work refused at the start, nothing left behind


def test_a_busy_target_leaves_no_hidden_folder_and_names_the_target(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target, new = tmp_path / "mnt", tmp_path / "new"
    target.mkdir()
    new.mkdir()
    (new / "x").write_text("new")
    real_replace = os.replace

    def busy(source: Any, destination: Any) -> None:
        if Path(source) == target:
            raise OSError(errno.EBUSY, "Device or resource busy", str(source), None, str(destination))
        real_replace(source, destination)

    monkeypatch.setattr(os, "replace", busy)
    with pytest.raises(OSError) as raised:
        files.replace_folder(new, target)
    assert raised.value.errno == errno.EBUSY and raised.value.filename == str(target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mnt", "new"]  # no .mnt.XXXXXXXX.old


def test_train_refuses_a_mount_point_before_training(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("stable_baselines3")
    mount = tmp_path / "mnt"
    mount.mkdir()
    real_ismount = os.path.ismount
    monkeypatch.setattr(os.path, "ismount", lambda p: Path(p) == mount or real_ismount(p))
    started = time.monotonic()
    line = one_error(run(capsys, "train", "--timesteps", "30000", "--out", str(mount)), "train", str(mount))
    assert "mount point" in line and "folder inside it" in line
    assert time.monotonic() - started < 60  # refused at the start, not after training
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mnt"]


def test_train_refuses_a_read_only_folder_before_training(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("stable_baselines3")
    read_only(monkeypatch, tmp_path)
    out = tmp_path / "run"
    result = run(capsys, "train", "--timesteps", "30000", "--out", str(out))
    one_error(result, "train", str(out), "Read-only file system")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------------------
# A2, A3, A4: a full disk met while writing


def test_an_mp4_ffmpeg_could_not_finish_is_never_reported_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """ffmpeg on a full disk: ``Error writing trailer``, a 32 kB file no player reads, and its exit status
    ignored by imageio. Here its output is cut as the full disk cut it."""
    pytest.importorskip("imageio_ffmpeg")
    import imageio.v2 as imageio

    real_get_writer = imageio.get_writer

    class Truncated:
        def __init__(self, path: Any, **kwargs: Any) -> None:
            self.path, self.writer = Path(path), real_get_writer(path, **kwargs)

        def __enter__(self) -> Any:
            return self.writer.__enter__()

        def __exit__(self, *exc: object) -> None:
            self.writer.__exit__(*exc)
            data = self.path.read_bytes()
            self.path.write_bytes(data[: len(data) // 2])  # no trailer: what ENOSPC left

    monkeypatch.setattr(imageio, "get_writer", Truncated)
    out = tmp_path / "tiny" / "x.mp4"
    result = run(capsys, "record", "--policy", "expert", "--steps", "60", "--out", str(out))
    one_error(result, "record", f"{out}: ffmpeg did not write a whole video")
    assert "wrote" not in result[1]
    assert list(tmp_path.iterdir()) == []  # no video, no temporary file, no folder made for it


@pytest.mark.parametrize("force", [False, True])
def test_a_gif_on_a_full_disk_is_one_line_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, force: bool
) -> None:
    pytest.importorskip("PIL")
    from heartpole.plots import video

    def full(frames: Any, path: Any, fps: float) -> int:
        Path(path).write_bytes(b"GIF89a" + bytes(100))  # some of it written, then the disk is full
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(video, "_write_gif", full)
    out = tmp_path / "x.gif"
    if force:
        out.write_bytes(b"the old gif")
    before = tree(tmp_path)
    argv = ["record", "--policy", "expert", "--steps", "5", "--out", str(out)] + (["--force"] if force else [])
    one_error(run(capsys, *argv), "record", f"cannot write {out}: No space left on device")
    assert tree(tmp_path) == before


def test_plot_model_on_a_full_disk_names_the_figure_not_its_temporary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("matplotlib")
    from heartpole import plots

    def full(figure: Any, path: Any) -> None:
        Path(path).write_bytes(b"\x89PNG")
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(plots, "save_figure", full)
    line = one_error(run(capsys, "plot", "model", "--out", str(tmp_path / "p")), "plot", "No space left on device")
    assert f"{tmp_path / 'p'}{os.sep}" in line and "/." not in line  # a figure's name, not .NAME.XXXX.png
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------------------------------
# B3, B4: a link loop, a read-only file system


def test_a_symbolic_link_loop_as_out_is_refused_before_the_evaluation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    loop = tmp_path / "bl"
    loop.symlink_to(loop)
    line = one_error(
        run(capsys, "baselines", "--episodes", "2", "--policy", "expert", "--out", str(loop)), "baselines", str(loop)
    )
    assert "symbolic link" in line and "File exists" not in line


def test_a_read_only_file_system_is_said_so_naming_the_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    read_only(monkeypatch, tmp_path)
    line = one_error(run(capsys, "optimum", "--check", "0", "--out", str(tmp_path)), "optimum", "Read-only file system")
    assert str(tmp_path / "optimum.npz") in line and "rehtgwtv" not in line and "permission" not in line
    # and where the write itself meets it, the output is named, not the temporary file
    with pytest.raises(OSError) as raised:
        files.write_text(tmp_path / "optimum.npz", "x")
    assert raised.value.errno == errno.EROFS and raised.value.filename == str(tmp_path / "optimum.npz")


def test_check_writable_passes_where_a_folder_can_be_written(tmp_path: Path) -> None:
    assert paths.check_writable(tmp_path / "new" / "deep" / "x.json") == tmp_path / "new" / "deep" / "x.json"
    assert list(tmp_path.iterdir()) == []  # the probe is gone, nothing made
    with pytest.raises(OSError) as raised:
        paths.check_writable(tmp_path / ("x" * 300))
    assert raised.value.errno == errno.ENAMETOOLONG
    # a name that is not UTF-8 (a legal Linux name: Python holds its byte as a surrogate) is written as it is
    odd = tmp_path / os.fsdecode(b"bad\xff")
    assert paths.check_writable(odd / "x.json") == odd / "x.json"


# ------------------------------------------------------------------------------------------------------
# A11: once the new output is in place, the command has succeeded


def test_a_signal_after_the_output_is_in_place_is_a_success(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("matplotlib")
    import heartpole.cli.plot as plot_command

    def interrupted(*args: object, **kwargs: object) -> None:
        signal.raise_signal(signal.SIGTERM)

    out = tmp_path / "figures"
    monkeypatch.setattr(plot_command, "print", interrupted, raising=False)  # the signal as it says "wrote"
    code, _, err = run(capsys, "plot", "model", "--out", str(out))
    assert code == 0, err
    assert "SIGTERM arrived after the output was written" in err
    assert len(list(out.glob("*.png"))) == 5


@pytest.mark.slow  # records a Minari dataset: about 9 s
def test_a_signal_after_a_dataset_is_in_place_is_a_success(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``heartpole dataset`` announces its dataset folder: a signal as it says ``recorded ...`` ends it with 0."""
    pytest.importorskip("minari")
    import heartpole.cli.offline as offline_command

    def interrupted(*args: object, **kwargs: object) -> None:
        signal.raise_signal(signal.SIGTERM)

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    monkeypatch.setattr(offline_command, "print", interrupted, raising=False)
    code, _, err = run(capsys, "dataset", "--policy", "random", "--episodes", "2")
    assert code == 0, err
    assert "SIGTERM arrived after the output was written" in err
    assert (tmp_path / "minari" / "heartpole" / "v0" / "random-v0" / "data" / "metadata.json").is_file()


@pytest.mark.slow  # imports Ray: several seconds
def test_a_signal_after_a_tune_search_is_in_place_is_a_success(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``heartpole tune`` announces --out: a signal as it prints its results ends it with 0, not with "interrupted;
    continue with --resume" and 128 + n (the search is complete and in place)."""
    pytest.importorskip("ray")
    import heartpole.cli.tune as tune_command
    from heartpole import files, scale

    def search(settings: object, folder: Path, **options: object) -> dict[str, object]:
        with files.folder_in_place(folder, keep=lambda path: True):
            (folder / "trials.csv").write_text("trial\n")
        return {"trials": 1}

    def interrupted(*args: object, **kwargs: object) -> None:
        signal.raise_signal(signal.SIGTERM)

    monkeypatch.setattr(scale, "tune_search", search)
    monkeypatch.setattr(scale, "can_resume", lambda folder: True)
    monkeypatch.setattr(tune_command, "print", interrupted, raising=False)
    out = tmp_path / "tune"
    code, _, err = run(capsys, "tune", "--trials", "1", "--json", "--out", str(out))
    assert code == 0, err
    assert "SIGTERM arrived after the output was written" in err
    assert (out / "trials.csv").is_file()


def test_a_signal_before_the_output_is_in_place_is_still_128_plus_n(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("matplotlib")
    from heartpole import plots

    def interrupted(*args: object, **kwargs: object) -> None:
        signal.raise_signal(signal.SIGHUP)

    monkeypatch.setattr(plots, "save_figure", interrupted)
    code, _, err = run(capsys, "plot", "model", "--out", str(tmp_path / "figures"))
    assert code == 128 + signal.SIGHUP and "interrupted by SIGHUP" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX signals")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_as_the_command_ends_is_a_success(tmp_path: Path, signum: int) -> None:
    """The issue's reproduction: the signal in the moment after ``wrote ...`` (Python shutting down)."""
    pytest.importorskip("matplotlib")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    command = [sys.executable, "-m", "heartpole", "plot", "model", "--out", str(tmp_path / "figures")]
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, preexec_fn=as_in_a_terminal
    )
    try:
        assert process.stdout is not None
        first = process.stdout.readline()
        assert first.startswith("wrote"), first + process.stderr.read() if process.stderr else ""
        process.send_signal(signum)
        out, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err
    assert len(list((tmp_path / "figures").glob("*.png"))) == 5
