#!/usr/bin/env bash
# The main job, after setting up everything it needs; writes into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export MPLBACKEND=Agg
exec "${PYTHON:-python3}" examples/gravity_demo.py --out out "$@"
