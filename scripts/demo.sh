#!/usr/bin/env bash
# The main job, after setting up everything it needs: the cooperative task (three bars handed over and
# dropped into the inclined container), its plots, animation, browser replay, data and report in out/.
# Extra arguments go to `python -m coopsim.tasks.handover` (e.g. --cycles 1, --seed 4, --sweep 20).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export MPLBACKEND=Agg
exec "${PYTHON:-python3}" -m coopsim.tasks.handover --out out "$@"
