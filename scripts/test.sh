#!/usr/bin/env bash
# Set up everything the tests need on a fresh machine, then run the whole test suite.
# Usage: bash scripts/test.sh [pytest args]
set -euo pipefail
cd "$(dirname "$0")/.."
# SPIN (cross-check tests) and Graphviz (svg/png pictures) come from Debian's packages.
if ! command -v spin >/dev/null || ! command -v dot >/dev/null; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    (apt-get update -qq && apt-get install -y -qq spin graphviz gcc) >/dev/null 2>&1 \
      || echo "note: could not install spin/graphviz; tests that need them are skipped" >&2
  else
    echo "note: spin/graphviz missing and not root; tests that need them are skipped" >&2
  fi
fi
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then "$PY" -m venv .venv; fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null
.venv/bin/python -m pip install -q -e ".[sim,test,bench]"
exec .venv/bin/python -m pytest "$@"
