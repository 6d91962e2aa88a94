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


def test_the_readme_marks_the_generated_tables() -> None:
    text = (ROOT / "README.md").read_text()
    for name in ("baselines-v0", "baselines-v1"):
        assert text.count(f"<!-- table:{name} -->") == 1 and text.count(f"<!-- /table:{name} -->") == 1
