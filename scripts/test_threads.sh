#!/usr/bin/env bash
# run_batch with worlds on several threads under ThreadSanitizer (README, "Sanitizers"): builds the
# engine and tests/native/batch_threads.cpp with COOPSIM_SANITIZE=thread in build/sanitize-tsan and
# runs it. The driver runs the task's scene (two SCARAs, the container, a bar grasped and carried)
# one by one and as batches on 2 and 3 threads, and fails unless every batch is bit-equal to the
# runs one by one; ThreadSanitizer fails it on any data race among the engine's threads.
#
#   bash scripts/test_threads.sh              # after scripts/setup.sh (scripts/test.sh runs both)
#   bash scripts/test_threads.sh 8 2.0        # 8 runs of 2 s (default: 6 runs of 3 s)
#   bash scripts/test_threads.sh --build-only # build the driver only
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_ONLY=0
if [ "${1:-}" = --build-only ]; then BUILD_ONLY=1; shift; fi
bash scripts/setup.sh
BUILD=build/sanitize-tsan

echo "threads: building tests/native/batch_threads.cpp with -fsanitize=thread in $BUILD"
# a unity build, as scripts/test_sanitized.sh
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCOOPSIM_SANITIZE=thread -DCOOPSIM_BUILD_PYTHON=OFF \
  -DCOOPSIM_BUILD_NATIVE_TESTS=ON -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=0 >/dev/null
cmake --build "$BUILD" --target coopsim_batch_threads -j "${COOPSIM_BUILD_JOBS:-2}"
[ "$BUILD_ONLY" = 1 ] && exit 0

# halt_on_error: the first race fails the run (exit 66)
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1"
exec "$BUILD/coopsim_batch_threads" "$@"
