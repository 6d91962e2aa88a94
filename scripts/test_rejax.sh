#!/usr/bin/env bash
# rejax (a pure-JAX PPO library) trains on HeartPole's JAX env through heartpole.jax.LegacyStep, gymnax's older
# five-value step (docs/rejax.md). rejax is not an extra of HeartPole: it brings gymnax, whose pins
# (gymnasium<1.4, jax<0.12) must not be forced on HeartPole's users. So it gets a venv of its own, .venv-rejax
# (reused while pyproject.toml and this script are unchanged), with HeartPole's jax extra and rejax 0.1.3, the
# version LegacyStep was written for, and tests/test_jax_rejax.py runs there. CI calls this script.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv-rejax
stamp="$venv/inputs.sha256"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$(sha256sum pyproject.toml scripts/test_rejax.sh)" ]; then
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install -q -e ".[jax]" rejax==0.1.3 "pytest>=7"
  sha256sum pyproject.toml scripts/test_rejax.sh > "$stamp"
fi
[ "${1:-}" = "--setup-only" ] && exit 0  # .ci/run builds the venv while other tests run
"$venv/bin/python" -m pip check
"$venv/bin/python" -c "from importlib.metadata import version as v; print('test_rejax:', *(f'{p} {v(p)}' for p in ('rejax', 'gymnax', 'flax', 'optax', 'jax', 'gymnasium')))"
"$venv/bin/python" -m pytest -q -p no:cacheprovider tests/test_jax_rejax.py "$@"
