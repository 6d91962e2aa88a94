"""Nothing from a folder or file runs code or imports a module by default: ``heartpole tune --resume`` refuses to
unpickle Ray Tune's saved search without ``--trust-pickles``, and an env id read from a file (a preset's, a
dataset's metadata) must be one of HeartPole's registered ids before anything imports or makes it."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

import heartpole
from heartpole.registry import check_heartpole_id

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


# ------------------------------------------------------------------------------------------------------
# env ids from files

EVIL_ID = "evilmod:HeartPole-v0"


def _evil_cwd(tmp_path: Path) -> Path:
    """A folder holding ``evilmod.py``, which leaves ``imported.marker`` when imported."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    (cwd / "evilmod.py").write_text(EVIL_MODULE)
    return cwd


def test_check_heartpole_id_accepts_heartpoles_ids_only() -> None:
    assert check_heartpole_id("HeartPole-v1", "f.json") == "HeartPole-v1"
    heartpole.register_variant("TrustPole-v0", replace=True)
    assert check_heartpole_id("TrustPole-v0", "f.json") == "TrustPole-v0"
    for bad in (EVIL_ID, "CartPole-v1", None, 3):
        with pytest.raises(ValueError, match=r"^f\.json: env id .* is not a HeartPole env; accepted: HeartPole-v0, "):
            check_heartpole_id(bad, "f.json")


def test_a_presets_env_id_imports_nothing(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    cwd = _evil_cwd(tmp_path)
    preset = cwd / "p.json"
    preset.write_text(json.dumps({"format": "heartpole-preset/1", "config": {"algo": "ppo", "env_id": EVIL_ID}}))
    done = heartpole_in(cwd, "train", "--preset", "p.json", "--out", str(tmp_path / "run"))
    one_line_refusal(done, "p.json", repr(EVIL_ID), "accepted: HeartPole-v0, HeartPole-v1")
    assert not (cwd / "imported.marker").exists() and not (tmp_path / "run").exists()


@pytest.mark.parametrize("key", ["env_id", "env_spec"])
def test_a_datasets_env_imports_nothing(tmp_path: Path, key: str) -> None:
    pytest.importorskip("minari")
    cwd = _evil_cwd(tmp_path)
    data = tmp_path / "minari" / "heartpole" / "v0" / "evil-v0" / "data"
    data.mkdir(parents=True)
    spec = {"id": "HeartPole-v0", "entry_point": "evilmod:make", "additional_wrappers": [], "kwargs": {}}
    metadata = {"env_id": EVIL_ID} if key == "env_id" else {"env_id": "HeartPole-v0", "env_spec": json.dumps(spec)}
    (data / "metadata.json").write_text(json.dumps({"dataset_id": "heartpole/v0/evil-v0", **metadata}))
    done = heartpole_in(cwd, "ope", "--dataset", "heartpole/v0/evil-v0", "--policy", "expert",
                        env={"MINARI_DATASETS_PATH": str(tmp_path / "minari")})  # fmt: skip
    fragments = [repr(EVIL_ID), "accepted: HeartPole-v0"] if key == "env_id" else ["'evilmod:make'"]
    one_line_refusal(done, str(data / "metadata.json"), *fragments)
    assert not (cwd / "imported.marker").exists()
