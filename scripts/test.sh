#!/usr/bin/env bash
# Set up everything the tests need on a fresh machine, then run the type checker
# (scripts/typecheck.sh) and the whole test suite.
# Usage: bash scripts/test.sh [pytest args]
set -euo pipefail
cd "$(dirname "$0")/.."
# SPIN (cross-check tests), Graphviz (svg/png pictures, the HTML report) and chromium with
# its driver (the HTML report's browser test, tests/test_html.py) come from Debian's packages.
if ! command -v spin >/dev/null || ! command -v dot >/dev/null || ! command -v chromium >/dev/null \
   || ! command -v chromedriver >/dev/null; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    (apt-get update -qq && apt-get install -y -qq spin graphviz gcc chromium chromium-driver) >/dev/null 2>&1 \
      || echo "note: could not install spin/graphviz/chromium; tests that need them are skipped" >&2
  else
    echo "note: spin/graphviz/chromium missing and not root; tests that need them are skipped" >&2
  fi
fi
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then "$PY" -m venv .venv; fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null
.venv/bin/python -m pip install -q -e ".[sim,test,bench]"
# bytecode for the sources, compiled once (about 1 s of CPU): the tests start many Python
# processes (the command line, pytest's workers, experiment workers), and where
# PYTHONDONTWRITEBYTECODE is set (it is on the machine of the README's figures) each of them
# compiled every module it imported from source again (0.3 s for btfsm sim); Python
# reads these files whatever the variable says (in __pycache__/, ignored by git)
.venv/bin/python -m compileall -q btfsm verify models sim tests scripts benchmarks >/dev/null
bash scripts/typecheck.sh
# the suite on every core (pytest-xdist; BTFSM_TEST_WORKERS=0 runs it in this one process)
exec .venv/bin/python -m pytest -n "${BTFSM_TEST_WORKERS:-auto}" "$@"
