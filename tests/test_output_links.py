"""An ``--out`` that is a symbolic link is followed by every command: the files go where the link leads and the
link stays (``train`` used to replace the link by a folder while ``plot model`` wrote through it; issue 43,
item 10)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from heartpole.cli import main


def _link(tmp_path: Path, name: str, target: str) -> Path:
    link = tmp_path / name
    os.symlink(target, link)
    return link


def test_train_writes_through_a_linked_out_folder(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    (tmp_path / "disk").mkdir()
    link = _link(tmp_path, "runs", "disk")
    argv = ["train", "--timesteps", "64", "--n-envs", "2", "--eval-episodes", "2", "--out", str(link)]
    assert main(argv) == 0
    assert link.is_symlink() and os.readlink(link) == "disk"
    assert (tmp_path / "disk" / "model.zip").is_file()
    assert main([*argv, "--force"]) == 0  # replacing the run replaces the target's contents, never the link
    assert link.is_symlink() and (tmp_path / "disk" / "heartpole.json").is_file()


def test_plot_model_and_a_linked_file_write_through_the_link(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    (tmp_path / "figures").mkdir()
    folder = _link(tmp_path, "out", "figures")
    assert main(["plot", "model", "--out", str(folder)]) == 0
    assert folder.is_symlink() and any((tmp_path / "figures").glob("*.png"))
    (tmp_path / "kept.png").write_bytes(b"old")
    file_link = _link(tmp_path, "episode.png", "kept.png")
    assert main(["plot", "episode", "--policy", "expert", "--out", str(file_link), "--force"]) == 0
    assert file_link.is_symlink() and (tmp_path / "kept.png").read_bytes() != b"old"
