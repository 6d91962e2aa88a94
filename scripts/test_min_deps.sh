#!/usr/bin/env bash
# Test HeartPole with the lowest versions pyproject.toml allows: every ">=" lower bound of the runtime
# dependencies and of the train and plot extras becomes "==", installed once into .venv-min (reused while
# pyproject.toml is unchanged), then a quick subset of the tests runs there. CI calls this script.
# A bound that does not hold fails here. Usage: bash scripts/test_min_deps.sh [extra pytest arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv-min
pins=$(python3 - <<'PY'
import re, tomllib
project = tomllib.load(open("pyproject.toml", "rb"))["project"]
requirements = project["dependencies"] + project["optional-dependencies"]["train"] + project["optional-dependencies"]["plot"]
pins = []
for requirement in requirements:
    match = re.fullmatch(r"([A-Za-z0-9_.-]+)\s*>=\s*([0-9][0-9A-Za-z.]*)", requirement.strip())
    if not match:
        raise SystemExit(f"test_min_deps: {requirement!r} has no '>=' lower bound to test")
    pins.append(f"{match[1]}=={match[2]}")
print(" ".join(pins))
PY
)
stamp="$venv/pins.txt"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$pins" ]; then
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install -q torch==2.13.0  # the local CPU build first, as in scripts/setup.sh
  # shellcheck disable=SC2086
  "$venv/bin/python" -m pip install -q $pins "pytest>=7" "hypothesis>=6" "pexpect>=4.8"
  "$venv/bin/python" -m pip install -q --no-deps -e .
  echo "$pins" > "$stamp"
fi
[ "${1:-}" = "--setup-only" ] && exit 0  # .ci/run builds the venv while other tests run
# numba keeps one cache index per function and discards another numba version's: the lowest numba gets a cache
# of its own, or it and the dev venv would recompile each other's loops (side by side in .ci/run, even midway).
export NUMBA_CACHE_DIR="$venv/numba-cache"
echo "test_min_deps: $pins"
"$venv/bin/python" -m pip check
"$venv/bin/python" -m pytest -q -p no:cacheprovider -m "not slow" \
  tests/test_registry.py tests/test_env.py tests/test_vector.py tests/test_policies.py \
  tests/test_plots.py tests/test_cli_plot.py tests/test_training.py tests/test_training_adapter.py "$@"
