#!/usr/bin/env bash
# Set up btfsm on a fresh machine, model-check the paper's ARIAC model and run a short
# simulation of it in the ARIAC kitting cell (models/scenes/ariac.yaml). Usage: bash scripts/quickstart.sh
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then "$PY" -m venv .venv; fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null
.venv/bin/python -m pip install -q -e ".[sim]"
B=.venv/bin/btfsm
set -x
$B check ariac-preemptive
$B check ariac-baseline
$B sim ariac-preemptive --k 1 --render out/cell.png
$B experiment --k 1 --k 20 --k 40 --workers 2 --out out/experiment
