#!/usr/bin/env bash
# The whole test suite, after setting up everything it needs; then the engine under the sanitizers
# (README, "Sanitizers and threads"): the suite's tests not marked slow again against the engine and module
# built with AddressSanitizer + UndefinedBehaviorSanitizer, on 2 worker processes, and run_batch with
# worlds on threads under ThreadSanitizer. The sanitizers' builds run at the lowest priority while
# the plain suite runs, on the core it leaves idle. Extra arguments go to both pytest runs;
# COOPSIM_SKIP_SANITIZERS=1 runs the plain suite only.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export MPLBACKEND=Agg

sanitizers=1
[ "${COOPSIM_SKIP_SANITIZERS:-0}" = 1 ] && sanitizers=0
builds=
if [ "$sanitizers" = 1 ]; then
  mkdir -p build
  # its own process group (setsid), so that an early exit stops the compilers too
  setsid nice -n 19 bash -c 'COOPSIM_SKIP_SETUP=1 bash scripts/test_sanitized.sh --build-only &&
                             COOPSIM_SKIP_SETUP=1 bash scripts/test_threads.sh --build-only' \
    >build/sanitizer-builds.log 2>&1 &
  builds=$!
  trap '[ -n "$builds" ] && kill -- -"$builds" 2>/dev/null; true' EXIT
fi

"${PYTHON:-python3}" -m pytest "$@"
[ "$sanitizers" = 1 ] || exit 0

echo "test: waiting for the sanitizers' builds (log: build/sanitizer-builds.log)"
if ! wait "$builds"; then
  builds=
  cat build/sanitizer-builds.log
  echo "test: the sanitizers' builds failed" >&2
  exit 1
fi
builds=
# -p no:benchmark: pytest-benchmark, where installed, refuses to run beside xdist
# the tests not marked slow: the slow ones (notebooks, a browser, process pools, run-time compiles) drive the
# same engine paths as the rest from Python, at twice the cost under the sanitizers
COOPSIM_SKIP_SETUP=1 bash scripts/test_sanitized.sh -n 2 --dist loadfile -p no:benchmark -m "not slow" "$@"
COOPSIM_SKIP_SETUP=1 bash scripts/test_threads.sh
