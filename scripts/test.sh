#!/usr/bin/env bash
# The whole test suite, after setting up everything it needs; then the engine under the sanitizers
# (README, "Sanitizers and threads"): the whole suite again against the engine and module built
# with AddressSanitizer + UndefinedBehaviorSanitizer, and run_batch with worlds on threads under
# ThreadSanitizer. Extra arguments go to both pytest runs; COOPSIM_SKIP_SANITIZERS=1 runs the plain
# suite only.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export MPLBACKEND=Agg
"${PYTHON:-python3}" -m pytest "$@"
if [ "${COOPSIM_SKIP_SANITIZERS:-0}" = 1 ]; then
  exit 0
fi
COOPSIM_SKIP_SETUP=1 bash scripts/test_sanitized.sh "$@"
COOPSIM_SKIP_SETUP=1 bash scripts/test_threads.sh
