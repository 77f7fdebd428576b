#!/usr/bin/env bash
# The whole test suite, after setting up everything it needs.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export MPLBACKEND=Agg
exec "${PYTHON:-python3}" -m pytest "$@"
