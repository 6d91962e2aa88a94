#!/usr/bin/env bash
# Build the sdist and wheel, check them with twine, install the wheel (not editable) into a fresh venv
# outside the source tree, and run the CLI and the README's quickstart there. CI calls this script.
# Usage: bash scripts/check_wheel.sh   (uses .venv for build and twine; installs them there if missing)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
python=${PYTHON:-.venv/bin/python}
"$python" -m pip install -q build twine
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$python" -m build -q --outdir "$work/dist" . >/dev/null 2>&1 || "$python" -m build --outdir "$work/dist" .
"$python" -m twine check --strict "$work"/dist/*
tar tzf "$work"/dist/heartpole-*.tar.gz > "$work/sdist.txt"
grep -q "/tests/tutorial_model.py\$" "$work/sdist.txt" \
  || { echo "check_wheel: the sdist lacks tests/tutorial_model.py" >&2; exit 1; }
for image in $(grep -o 'docs/images/[A-Za-z0-9_.-]*' README.md | sort -u); do
  grep -q "/$image\$" "$work/sdist.txt" \
    || { echo "check_wheel: the README shows $image, which the sdist lacks" >&2; exit 1; }
done
# The fresh venv's Python must be one every user can run (pyenv's lives under root's private home), so that
# the install can be tried as an unprivileged user below.
base=""
for candidate in python3 /usr/bin/python3 /usr/local/bin/python3; do
  path=$("$candidate" -c 'import sys; print(sys.executable)' 2>/dev/null) || continue
  if [ "$(id -u)" != 0 ] || runuser -u nobody -- "$path" -c 'import sys; assert sys.version_info >= (3, 10)' 2>/dev/null
  then base=$path; break; fi
done
[ -n "$base" ] || { echo "check_wheel: no Python >= 3.10 that an unprivileged user can run" >&2; exit 1; }
"$base" -m venv "$work/venv"
"$work/venv/bin/python" -m pip install -q "$work"/dist/heartpole-*.whl
cd "$work"  # away from the source tree, so only the installed wheel can be imported
"$work/venv/bin/python" -c "import heartpole, pathlib; assert 'site-packages' in heartpole.__file__, heartpole.__file__; \
assert (pathlib.Path(heartpole.__file__).parent / 'py.typed').is_file(); print('heartpole', heartpole.__version__)"
"$work/venv/bin/heartpole" --version
"$work/venv/bin/heartpole" evaluate --policy expert --episodes 64 >/dev/null
# The README's quickstart, exactly as written (the first python block after "## Quickstart").
awk '/^## Quickstart/{q=1} q&&/^```python/{p=1;next} p&&/^```/{exit} p' "$root/README.md" > quickstart.py
test -s quickstart.py || { echo "check_wheel: no quickstart found in README.md" >&2; exit 1; }
"$work/venv/bin/python" quickstart.py
# A read-only install used by an unprivileged user with no writable home (issue 23): numba can cache
# nowhere, so HeartPole compiles in memory and says so once, naming NUMBA_CACHE_DIR; with NUMBA_CACHE_DIR
# set, the compiled code is cached there. CI runs as root, which ignores file permissions: switch user.
if [ "$(id -u)" = 0 ]; then
  chmod 755 "$work"  # traversable; everything in it stays root's, read-only for nobody
  step='import gymnasium as gym, heartpole; e = gym.make("HeartPole-v0"); e.reset(seed=0); print("reward", e.step(1)[1])'
  as_nobody() { runuser -u nobody -- env -i PATH=/usr/bin:/bin HOME=/nonexistent "$@"; }
  out=$(as_nobody "$work/venv/bin/python" -W ignore::DeprecationWarning -c "$step" 2>&1) \
    || { echo "$out" >&2; echo "check_wheel: a read-only install fails for a user with no writable home" >&2; exit 1; }
  [ "$(grep -c NUMBA_CACHE_DIR <<<"$out")" = 1 ] && grep -q "^reward" <<<"$out" \
    || { echo "$out" >&2; echo "check_wheel: expected one warning naming NUMBA_CACHE_DIR, then a step" >&2; exit 1; }
  as_nobody "$work/venv/bin/heartpole" evaluate --policy expert --episodes 16 >/dev/null 2>&1 \
    || { echo "check_wheel: 'heartpole evaluate' fails for a user with no writable home" >&2; exit 1; }
  cache=$(mktemp -d); chown nobody "$cache"
  out=$(as_nobody NUMBA_CACHE_DIR="$cache" "$work/venv/bin/python" -W ignore::DeprecationWarning -c "$step" 2>&1)
  grep -q NUMBA_CACHE_DIR <<<"$out" && { echo "$out" >&2; echo "check_wheel: warned with a cache" >&2; exit 1; }
  find "$cache" -name '*.nbi' | grep -q . || { echo "check_wheel: nothing cached in NUMBA_CACHE_DIR" >&2; exit 1; }
  rm -rf "$cache"
  echo "check_wheel: read-only install as nobody: OK (compiled in memory with one warning; NUMBA_CACHE_DIR honoured)"
fi
echo "check_wheel: OK"
