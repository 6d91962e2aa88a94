#!/usr/bin/env bash
# HeartPole's JAX env inside gymnax's own wrappers. gymnax is not an extra of HeartPole: gymnax 1.0.1 pins
# gymnasium<1.4 and jax<0.12, which must not be forced on HeartPole's users. So it gets a venv of its own,
# .venv-gymnax (reused while pyproject.toml is unchanged), with HeartPole's jax extra and whatever Gymnasium
# gymnax allows, and the gymnax cases run there: tests/test_jax_env.py's and tests/test_jax_spaces.py's
# (PureJaxRL's PPO setup, GymnaxToGymWrapper, GymnaxToVectorGymWrapper, gymnax's own space classes, and no
# gymnax import for a program that does not use it). CI calls this script.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv-gymnax
stamp="$venv/pyproject.sha256"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$(sha256sum pyproject.toml)" ]; then
  rm -rf "$venv"
  python3 -m venv "$venv"
  # six: gymnax 1.0.1 imports it (gymnax/utils/load_mnist.py) without declaring it
  "$venv/bin/python" -m pip install -q -e ".[jax]" gymnax six "pytest>=7"
  sha256sum pyproject.toml > "$stamp"
fi
[ "${1:-}" = "--setup-only" ] && exit 0  # .ci/run builds the venv while other tests run
"$venv/bin/python" -m pip check
"$venv/bin/python" -c "from importlib.metadata import version as v; print('test_gymnax:', *(f'{p} {v(p)}' for p in ('gymnax', 'gymnasium', 'jax')))"
"$venv/bin/python" -m pytest -q -p no:cacheprovider tests/test_jax_env.py tests/test_jax_spaces.py -k gymnax "$@"
