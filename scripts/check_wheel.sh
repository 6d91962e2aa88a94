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
python3 -m venv "$work/venv"
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
echo "check_wheel: OK"
