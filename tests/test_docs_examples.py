"""The Python examples of README.md and the docs pages run as written, so they cannot go stale.

Each page's ```python blocks run in order in one namespace (a later block may use an earlier one's names),
in a fresh process, with Minari's and the optimum's folders in a temporary directory. A block preceded by
``<!-- no-test: reason -->`` is skipped for that reason (it trains for minutes, say); the reason is required.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"(<!-- no-test: (?P<reason>[^>]+) -->\n)?```python\n(?P<code>.*?)```", re.DOTALL)
NEEDS = {"offline.md": "minari", "jax.md": "jax", "training.md": "stable_baselines3"}


def examples(page: Path) -> list[str]:
    """The blocks of ``page`` that are to run, in order."""
    return [match["code"] for match in BLOCK.finditer(page.read_text()) if not match["reason"]]


def test_skipped_blocks_say_why() -> None:
    for page in PAGES:
        text = page.read_text()
        assert text.count("```python") == len(list(BLOCK.finditer(text))), f"{page.name}: a block the test cannot read"


@pytest.mark.slow
@pytest.mark.parametrize("page", [p for p in PAGES if examples(p)], ids=lambda p: p.name)
def test_the_examples_run(page: Path, tmp_path: Path) -> None:
    if page.name in NEEDS:
        pytest.importorskip(NEEDS[page.name])
    # The session's optimum cache (conftest): the people page's cohort is solved once per run, not per page.
    environment = {**os.environ, "MINARI_DATASETS_PATH": str(tmp_path / "minari")}
    if page.name == "offline.md":  # the page loads a dataset it tells the reader to record first
        record = [
            sys.executable,
            "-m",
            "heartpole",
            "dataset",
            "--policy",
            "reference",
            "--epsilon",
            "0.2",
            "--episodes",
            "20",
        ]
        subprocess.run(record, check=True, capture_output=True, env=environment)
    script = "\n\n".join(examples(page))
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, env=environment
    )
    assert result.returncode == 0, f"{page.name}'s examples failed:\n{result.stderr[-3000:]}"
