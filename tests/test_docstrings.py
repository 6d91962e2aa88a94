"""The examples in the package's docstrings run and print what they show (doctest), so they cannot go stale.

Every module of ``src/heartpole`` with a ``>>>`` example is found here, none has to be listed; a module that
needs an optional extra which is not installed is skipped with the extra's name (CI installs them all).
The docs pages' examples are tests/test_docs_examples.py's.
"""

from __future__ import annotations

import doctest
import importlib
import io
from pathlib import Path

import gymnasium  # noqa: F401  (imported first here: on import it puts a warning filter before the suite's)
import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "heartpole"
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = sorted(module_name(path) for path in PACKAGE.rglob("*.py") if ">>> " in path.read_text())


def test_the_examples_are_found() -> None:
    assert {"heartpole", "heartpole.evaluation", "heartpole.stats", "heartpole.game"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    try:
        module = importlib.import_module(name)
    except ImportError as error:  # an optional extra: its module names the package, or says what to install
        missing = error.name or ""
        if missing.startswith("heartpole") or (not missing and "pip install" not in str(error)):
            raise
        pytest.skip(f"{name} needs an optional extra: {error}")
    examples = [test for test in doctest.DocTestFinder().find(module, name) if test.examples]
    assert examples, f"{name} has '>>> ' but no example doctest can find"
    report = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    for test in examples:
        runner.run(test, out=report.write)
    assert runner.failures == 0, report.getvalue()
