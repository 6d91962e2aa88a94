"""benchmarks/seeds_table.py: the docs' tables of 20 seeds are its output for the summaries kept in docs/results."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "seeds_table.py"
RESULTS = ROOT / "docs" / "results"
# (page, summaries, labels): each command the page shows, as it shows it
TABLES = [
    ("training.md", ["seeds-sb3-before.json", "seeds-sb3.json"], ["3e-4 constant (before)", "6e-4 annealed (now)"]),
    (
        "training.md",
        ["seeds-sb3-penalty10.json", "seeds-jax-penalty10.json"],
        ["default preset (SB3)", "JAX backend (--backend jax)"],
    ),
    (
        "jax.md",
        ["seeds-jax-before.json", "seeds-jax.json"],
        ["one threefry draw a step (before)", "the key's own bits (now)"],
    ),
]


def table(summaries: list[Path], labels: list[str]) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, str(SCRIPT), *map(str, summaries), "--labels", *labels]
    return subprocess.run(command, capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize(("page", "summaries", "labels"), TABLES, ids=[t[0] for t in TABLES])
def test_the_docs_show_the_table_the_script_prints(page: str, summaries: list[str], labels: list[str]) -> None:
    done = table([RESULTS / name for name in summaries], labels)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() in (ROOT / "docs" / page).read_text()


def test_the_counts_follow_each_seed_s_regret_interval(tmp_path: Path) -> None:
    """A seed turned unsolved in the file is counted and marked so (the script reads the file, not a copy)."""
    summary = json.loads((RESULTS / "seeds-sb3.json").read_text())
    summary["runs"][3].update(regret=0.0125, regret_ci95=[0.012, 0.013], solved=False)
    path = tmp_path / "summary.json"
    path.write_text(json.dumps(summary))
    done = table([path], ["changed"])
    assert done.returncode == 0, done.stderr
    assert "| 3 | **0.0125 [0.0120, 0.0130]** (not solved) |" in done.stdout
    assert "changed: 19 of 20 seeds solved" in done.stdout


def test_a_file_that_is_no_summary_is_refused_by_name(tmp_path: Path) -> None:
    path = tmp_path / "other.json"
    path.write_text('{"runs": []}')
    done = table([path], ["x"])
    assert done.returncode != 0
    assert f"{path} is not the summary.json of a `heartpole train --seeds` run" in done.stderr


def test_the_drinks_line_counts_the_seeds_that_drink(tmp_path: Path) -> None:
    summary = json.loads((RESULTS / "seeds-sb3.json").read_text())
    assert "no drinks in any seed's evaluation" in table([RESULTS / "seeds-sb3.json"], ["x"]).stdout
    summary["runs"][5]["drinks_per_episode"] = 0.25
    path = tmp_path / "summary.json"
    path.write_text(json.dumps(summary))
    done = table([path], ["x"])
    assert "1 of 20 seeds drink, drinks per episode median 0.000, 0.000 to 0.250" in done.stdout, done.stdout
