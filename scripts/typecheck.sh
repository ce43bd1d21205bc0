#!/usr/bin/env bash
# The type checker on the whole product: mypy (pinned in the test extra; configured in
# pyproject.toml's [tool.mypy]) on the package btfsm with its folders verify/, models/ and
# sim/ mapped in as btfsm.verify, btfsm.models and btfsm.sim (as pyproject's package-dir
# installs them), through a tree of symbolic links under build/typecheck/.
# Usage: bash scripts/typecheck.sh [mypy args]
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
tree=build/typecheck
rm -rf "$tree"
mkdir -p "$tree/btfsm"
for entry in btfsm/*; do ln -s "$root/$entry" "$tree/btfsm/"; done
for pkg in verify models sim; do ln -s "$root/$pkg" "$tree/btfsm/$pkg"; done
cd "$tree"
exec "$root/.venv/bin/python" -m mypy --config-file "$root/pyproject.toml" --cache-dir "$root/build/mypy_cache" -p btfsm "$@"
