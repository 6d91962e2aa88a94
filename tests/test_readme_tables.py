"""scripts/readme_tables.py: marked README tables are replaced by the generated ones, nothing else."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("readme_tables", ROOT / "scripts" / "readme_tables.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_marked_blocks_are_replaced_and_the_rest_kept() -> None:
    script = _script()
    kept = "middle\n<!-- table:b -->\nstale\n<!-- /table:b -->\nend\n"
    text = "intro\n<!-- table:a -->\n| old |\n<!-- /table:a -->\n" + kept
    out = script.with_tables(text, {"a": "| new a |\n", "c": "| unused |\n"})
    assert out == "intro\n<!-- table:a -->\n| new a |\n<!-- /table:a -->\n" + kept


def test_the_readme_and_the_evaluation_page_mark_the_generated_tables() -> None:
    for page, names in (("README.md", ["baselines-v0"]), ("docs/evaluation.md", ["baselines-v0", "baselines-v1"])):
        text = (ROOT / page).read_text()
        for name in names:
            assert text.count(f"<!-- table:{name} -->") == 1 and text.count(f"<!-- /table:{name} -->") == 1


def test_training_table_from_a_seeds_run_or_a_solve_benchmark(tmp_path: Path) -> None:
    import json

    import pytest

    training = pytest.importorskip("heartpole.training")
    script = _script()
    runs = [{"seed": s, "heart_attacks_per_episode": 1.249, "score": 0.32 + s / 100, "mean_return": -124.6,
             "ci95": [-129.4, -119.7], "expected_return": -123.3, "wall_seconds": 60.0 + s, "solved": True}
            for s in (0, 1)]  # fmt: skip
    (tmp_path / "summary.json").write_text(json.dumps({"runs": runs, "aggregate": training.aggregate(runs),
                                                        "solved_seeds": 2}))  # fmt: skip
    table = script.training_table(tmp_path)
    assert "| 1 | 1.249 | 0.3300 | -124.6 [-129.4, -119.7] | -123.300 | 61 s | yes |" in table
    assert "IQM across 2 seeds" in table and "Solved: 2." in table
    (tmp_path / "results.md").write_text("| from solve.py |\n")
    assert script.training_table(tmp_path).endswith("| from solve.py |\n")
