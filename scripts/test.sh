#!/usr/bin/env bash
# Set up (if needed), lint, and run the default test suite (under 3 minutes on a 2-core machine): every test
# but those marked slow (the long statistical ones, and a large variant's compile). `bash scripts/test.sh -m slow`
# runs those; .ci/run runs both.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check src tests benchmarks scripts examples
.venv/bin/ruff format --check src tests benchmarks scripts examples
.venv/bin/mypy
.venv/bin/lint-imports --no-cache  # the layers of pyproject.toml: every import points down, no cycles
if [ "$#" -eq 0 ]; then
  set -- -m "not slow"
fi
# Two workers (the machine has 2 cores); the tests that start Ray share one (tests/conftest.py).
.venv/bin/python -m pytest -q -n 2 --dist loadgroup "$@"
