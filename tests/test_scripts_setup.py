"""scripts/main.sh sets up only what the main job needs (the train extra); scripts/test.sh still installs every
extra (issue 43, What to build 7)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_main_sets_up_the_train_extra_and_the_tests_all_of_them() -> None:
    assert "bash scripts/setup.sh train\n" in (ROOT / "scripts" / "main.sh").read_text()
    assert "bash scripts/setup.sh\n" in (ROOT / "scripts" / "test.sh").read_text()
    setup = (ROOT / "scripts" / "setup.sh").read_text()
    assert 'extras="${1:-all}"' in setup and '-e ".[$extras]"' in setup
    assert "torch==2.13.0" in setup and "gym.make_vec" in setup  # the CPU build first; the numba precompile kept


def test_setup_refuses_extras_that_are_not_names_before_touching_anything(tmp_path: Path) -> None:
    (tmp_path / "scripts").mkdir()
    shutil.copy(ROOT / "scripts" / "setup.sh", tmp_path / "scripts" / "setup.sh")
    for bad in ("train]; rm -rf x", "Train", "train,,plot"):
        result = subprocess.run(["bash", str(tmp_path / "scripts" / "setup.sh"), bad], capture_output=True, text=True)
        assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert not (tmp_path / ".venv").exists()
