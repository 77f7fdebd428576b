#!/usr/bin/env bash
# The engine's threads under ThreadSanitizer (README, "Sanitizers"): builds the engine and the
# native drivers of tests/native with COOPSIM_SANITIZE=thread in build/sanitize-tsan and runs them.
# batch_threads.cpp runs the task's scene (two SCARAs, the container, a bar grasped and carried)
# one by one and as batches on 2 and 3 threads, and fails unless every batch is bit-equal to the
# runs one by one; one_driver.cpp races two threads to advance one simulation of that scene and
# fails unless one runs and the other gets SimulationBusyError each time. ThreadSanitizer fails
# either on any data race among the engine's threads. least_norm.cpp, built with them, checks the
# object-level law's least-norm solvers against Eigen's complete orthogonal decomposition.
#
#   bash scripts/test_threads.sh              # after scripts/setup.sh (scripts/test.sh runs both)
#   bash scripts/test_threads.sh 8 2.0        # batch_threads: 8 runs of 2 s (default: 6 runs of 3 s)
#   bash scripts/test_threads.sh --build-only # build the drivers only
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_ONLY=0
if [ "${1:-}" = --build-only ]; then BUILD_ONLY=1; shift; fi
bash scripts/setup.sh
BUILD=build/sanitize-tsan

echo "threads: building tests/native/batch_threads.cpp, one_driver.cpp and least_norm.cpp with -fsanitize=thread in $BUILD"
# a unity build, as scripts/test_sanitized.sh
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCOOPSIM_SANITIZE=thread -DCOOPSIM_BUILD_PYTHON=OFF \
  -DCOOPSIM_BUILD_NATIVE_TESTS=ON -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=0 >/dev/null
cmake --build "$BUILD" --target coopsim_batch_threads coopsim_one_driver coopsim_least_norm -j "${COOPSIM_BUILD_JOBS:-2}"
[ "$BUILD_ONLY" = 1 ] && exit 0

# halt_on_error: the first race fails the run (exit 66)
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1"
"$BUILD/coopsim_least_norm"
"$BUILD/coopsim_one_driver"
exec "$BUILD/coopsim_batch_threads" "$@"
