"""The documentation site builds strictly, and the build fails on a broken reference (the check can fail)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mkdocstrings")

ROOT = Path(__file__).resolve().parents[1]
MKDOCS = str(Path(sys.executable).with_name("mkdocs"))


def build(root: Path, site: Path) -> subprocess.CompletedProcess[str]:
    """``scripts/build_docs.sh`` of the tree at ``root``, as CI runs it."""
    environment = {**os.environ, "MKDOCS": MKDOCS}
    command = ["bash", str(root / "scripts" / "build_docs.sh"), str(site)]
    return subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)


def copy_of_the_docs(destination: Path) -> Path:
    """What the site is built from: mkdocs.yml, docs/, the sources the API pages read, README and scripts."""
    destination.mkdir()
    for name in ("mkdocs.yml", "README.md", "CHANGELOG.md"):
        shutil.copy(ROOT / name, destination / name)
    for name in ("docs", "src", "scripts"):
        shutil.copytree(ROOT / name, destination / name, ignore=shutil.ignore_patterns("__pycache__"))
    return destination


def test_the_site_builds_strictly_without_a_warning(tmp_path: Path) -> None:
    done = build(ROOT, tmp_path / "site")
    assert done.returncode == 0, done.stderr[-3000:]
    assert "WARNING" not in done.stderr, done.stderr[-3000:]
    assert (tmp_path / "site" / "api" / "index.html").is_file()


@pytest.mark.parametrize(
    "where, breakage",
    [
        ("src/heartpole/evaluation.py", "See [the interval][heartpole.stats.no_such_function]."),
        ("docs/evaluation.md", "See [the missing page](no-such-page.md)."),
    ],
)
def test_a_broken_reference_fails_the_build(tmp_path: Path, where: str, breakage: str) -> None:
    root = copy_of_the_docs(tmp_path / "tree")
    path = root / where
    text = path.read_text()
    if where.endswith(".py"):  # into the module's docstring, which the API page renders
        first = text.index('"""') + 3
        text = text[:first] + breakage + "\n\n" + text[first:]
    else:
        text += "\n" + breakage + "\n"
    path.write_text(text)
    done = build(root, tmp_path / "site")
    assert done.returncode != 0, "a broken reference passed the strict build"
    assert "no_such_function" in done.stderr or "no-such-page.md" in done.stderr, done.stderr[-3000:]
