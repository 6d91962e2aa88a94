"""One writer at a time in a folder that work writes in place (heartpole.files.folder_lock): a second
``heartpole tune`` on the same ``--out`` is refused in one line, exit 2, and the first's folder is left as it was
(issue 43, item 6: both searches used to exit 0 and leave a folder mixing them)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from heartpole import files
from tests.test_files import tree

HOLD = textwrap.dedent("""
    import sys
    from heartpole import files
    with files.folder_lock(sys.argv[1]):
        print("held", flush=True)
        sys.stdin.read()  # until the test closes our stdin
""")


def holder(target: Path) -> subprocess.Popen[str]:
    """Another process holding the lock on ``target`` until its stdin is closed."""
    process = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(target)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    assert process.stdout is not None and process.stdout.readline() == "held\n"
    return process


def test_a_second_process_is_refused_while_the_first_holds_the_lock_and_not_after_it_died(tmp_path: Path) -> None:
    target = tmp_path / "parent" / "out"
    first = holder(target)
    try:
        with pytest.raises(files.FolderInUseError, match=f"{target} is being written by another process"):
            with files.folder_lock(target):
                pytest.fail("the block ran without the lock")
    finally:
        first.kill()
        first.wait(timeout=60)
    assert (target.parent / ".out.lock").exists()  # left by the killed holder, whose lock the kernel dropped
    with files.folder_lock(target):
        assert (target.parent / ".out.lock").exists()
    assert os.listdir(target.parent) == []  # the lock file is gone (the parent is the holder's: it stays)
    with files.folder_lock(tmp_path / "new" / "out"):
        pass
    assert os.listdir(tmp_path) == ["parent"]  # the parent a lock created is removed with it


# ------------------------------------------------------------------------------------------------------
# heartpole tune


def one_line_refusal(capsys: pytest.CaptureFixture[str], fragment: str) -> None:
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("heartpole tune: error:") and fragment in err[0], err
    assert captured.out == "", captured.out  # refused before announcing a search


@pytest.mark.parametrize("first_wrote", [False, True], ids=["first-just-started", "first-wrote-its-settings"])
def test_a_second_tune_on_a_folder_in_use_is_refused_and_the_first_keeps_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], first_wrote: bool
) -> None:
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("ray")
    pytest.importorskip("optuna")
    from heartpole import scale
    from heartpole.cli import main

    out = tmp_path / "tune"
    out.mkdir()
    if first_wrote:  # the first search's files so far; --force would replace them with the second search
        (out / scale.SEARCH_SETTINGS_FILE).write_text('{"first": true}\n')
        (out / "trials").mkdir()
    before = tree(out)
    # Small enough that, without the lock, the second search runs to its end (and this test fails).
    tiny = ["--trials", "1", "--seeds-per-trial", "1", "--timesteps", "512", "--n-envs", "2", "--eval-episodes", "2"]
    with files.folder_lock(out):  # the first tune's lock: another open file, so flock refuses this process too
        assert main(["tune", *tiny, *(["--force"] if first_wrote else []), "--out", str(out)]) == 2
        one_line_refusal(capsys, f"{out} is being written by another process")
        assert tree(out) == before
    assert sorted(os.listdir(tmp_path)) == ["tune"]


def test_tune_search_itself_refuses_a_folder_in_use_before_ray_starts(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    ray = pytest.importorskip("ray")
    pytest.importorskip("optuna")
    from heartpole import scale, training

    out = tmp_path / "tune"
    settings = scale.SearchSettings(training.preset_config(timesteps=512, n_envs=2), trials=1, seeds=(0,))
    with files.folder_lock(out):  # another search took the folder after the command's own check
        with pytest.raises(files.FolderInUseError, match="being written by another process"):
            scale.tune_search(settings, out)
        assert not ray.is_initialized() and not out.exists()
    assert os.listdir(tmp_path) == []
