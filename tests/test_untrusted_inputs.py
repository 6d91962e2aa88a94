"""Nothing from a folder or file runs code by default: ``heartpole tune --resume`` refuses to unpickle Ray Tune's
saved search without ``--trust-pickles``."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
EVIL_MODULE = "import pathlib\npathlib.Path('imported.marker').write_text('evilmod ran')\n"


class Touch:
    """Unpickling this runs a shell command that creates ``marker``."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return os.system, (f"touch '{self.marker}'",)


def heartpole_in(cwd: Path, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``python -m heartpole ARGS`` run in ``cwd`` (where a hostile module may wait to be imported)."""
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "heartpole", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env=environment | (env or {}))  # fmt: skip


def one_line_refusal(done: subprocess.CompletedProcess[str], *fragments: str) -> str:
    """The refusal's one line (exit status 2), which holds every fragment."""
    assert done.returncode == 2, done.stderr[-3000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr[-3000:]
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


# ------------------------------------------------------------------------------------------------------
# tune --resume


def _hostile_search(folder: Path, marker: Path) -> None:
    """A search folder whose Ray Tune state runs a command when unpickled (tuner.pkl and the searcher's state)."""
    (folder / "search").mkdir(parents=True)
    from heartpole import training

    settings = {"base": training.preset_config("default", "ppo").to_dict(), "trials": 2, "seeds": [0],
                "eval_episodes": 4, "eval_seed": 0, "search_seed": 0}  # fmt: skip
    (folder / "search.json").write_text(json.dumps(settings))
    for name in ("tuner.pkl", "searcher-state-2026-01-01_00-00-00.pkl"):
        (folder / "search" / name).write_bytes(pickle.dumps(Touch(marker)))
    (folder / "search" / "experiment_state-2026-01-01_00-00-00.json").write_text("{}")


def test_tune_resume_refuses_the_folders_pickles_without_trust_pickles(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    marker, out = tmp_path / "ran.marker", tmp_path / "search"
    _hostile_search(out, marker)
    done = heartpole_in(tmp_path, "tune", "--resume", "--out", str(out))
    one_line_refusal(done, str(out / "search" / "tuner.pkl"), "--trust-pickles", "nothing from it was run")
    assert not marker.exists()


def test_tune_search_refuses_to_resume_without_trust_pickles(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    from heartpole import scale

    marker, out = tmp_path / "ran.marker", tmp_path / "search"
    _hostile_search(out, marker)
    with pytest.raises(scale.UntrustedSearchError, match=r"tuner\.pkl.*trust_pickles=True"):
        scale.tune_search(scale.read_settings(out), out, resume=True)
    assert not marker.exists()
