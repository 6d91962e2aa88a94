#!/usr/bin/env bash
# Build the documentation site strictly: any warning (a broken link, a cross-reference that resolves to
# nothing, a docstring that cannot be read) fails the build. Never add --quiet: it hides the warnings, and
# strict mode then counts none. CI and tests/test_docs_site.py run this script.
# mkdocs.yml's hook, scripts/docs_hooks.py, shows docstrings' >>> examples as code (Markdown would quote them).
# Usage: bash scripts/build_docs.sh [SITE_DIR]   (default: a temporary folder, removed afterwards)
set -euo pipefail
cd "$(dirname "$0")/.."
site=${1:-}
if [ -z "$site" ]; then
  site=$(mktemp -d)
  trap 'rm -rf "$site"' EXIT
fi
"${MKDOCS:-.venv/bin/mkdocs}" build --strict --site-dir "$site"
