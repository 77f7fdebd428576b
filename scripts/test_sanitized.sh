#!/usr/bin/env bash
# The whole test suite against the engine and module built with AddressSanitizer and
# UndefinedBehaviorSanitizer (CMake's COOPSIM_SANITIZE; README, "Sanitizers and threads").
#
#   bash scripts/test_sanitized.sh              # after scripts/setup.sh (scripts/test.sh runs both)
#   bash scripts/test_sanitized.sh -k world     # extra arguments go to pytest
#   bash scripts/test_sanitized.sh -n 2         # on 2 worker processes (pytest-xdist; what CI does)
#   bash scripts/test_sanitized.sh --build-only # the sanitized module only, no tests
#
# It needs what scripts/setup.sh installs (compiler, Eigen, Bullet, the Python test dependencies,
# CMake, Ninja, pybind11) and runs it first unless COOPSIM_SKIP_SETUP=1. It builds the sanitized
# module in build/sanitize-asan (incrementally), stages a package in build/sanitize-asan/stage
# (python/coopsim and that module) and runs pytest on it, never touching the installed coopsim.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
BUILD_ONLY=0
if [ "${1:-}" = --build-only ]; then BUILD_ONLY=1; shift; fi
bash scripts/setup.sh
PY=$("${PYTHON:-python3}" -c 'import sys; print(sys.executable)')  # the interpreter itself, not a shim
SAN=address,undefined,float-cast-overflow
BUILD=build/sanitize-asan
STAGE=$BUILD/stage

echo "sanitized: building coopsim._core with -fsanitize=$SAN in $BUILD"
# a unity build (the engine in one translation unit, the bindings in another): Eigen's and
# pybind11's templates are instantiated once per target rather than once per file, half the time
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCOOPSIM_SANITIZE="$SAN" \
  -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=0 \
  -DPython_EXECUTABLE="$PY" -Dpybind11_DIR="$("$PY" -m pybind11 --cmakedir)" >/dev/null
cmake --build "$BUILD" --target _core -j "${COOPSIM_BUILD_JOBS:-2}"
[ "$BUILD_ONLY" = 1 ] && exit 0

rm -rf "$STAGE"
mkdir -p "$STAGE"
cp -r python/coopsim "$STAGE/coopsim"
find "$STAGE" -name __pycache__ -prune -exec rm -rf {} +
cp "$BUILD"/_core*.so "$STAGE/coopsim/"

CXX=${CXX:-g++}
ASAN_LIB=$("$CXX" -print-file-name=libasan.so)
UBSAN_LIB=$("$CXX" -print-file-name=libubsan.so)
[ -f "$ASAN_LIB" ] && [ -f "$UBSAN_LIB" ] || { echo "sanitized: no libasan/libubsan from $CXX" >&2; exit 1; }
# The interpreter is not instrumented, so the sanitizers' runtimes must be loaded before anything
# else (ASan insists on coming first). Every child process inherits this: Python children (examples,
# notebook kernels, Dask workers, the stub generator) need it to import the sanitized module;
# g++, ffmpeg and bash run fine with it; Chromium does not, and the browser tests launch it without.
export LD_PRELOAD="$ASAN_LIB:$UBSAN_LIB"
# detect_leaks=0: CPython does not free everything at exit (interned objects, static types, extension
# modules are never unloaded), so LeakSanitizer would report thousands of "leaks" that are not ours.
# Memory errors (overflows, use after free, double free, ...) stay fatal.
export ASAN_OPTIONS=detect_leaks=0:detect_stack_use_after_return=1:check_initialization_order=1:strict_init_order=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export PYTHONPATH="$ROOT/$STAGE${PYTHONPATH:+:$PYTHONPATH}"
export COOPSIM_SKIP_SETUP=1  # tests that run scripts/demo.sh must not install this tree over the environment's coopsim
export MPLBACKEND=Agg

# the tests must import the sanitized module, not the installed one
"$PY" - "$SAN" "$ROOT/$STAGE" <<'EOF'
import os, sys
import coopsim
from coopsim import _core
san, stage = sys.argv[1], sys.argv[2]
assert os.path.realpath(_core.__file__).startswith(os.path.realpath(stage)), _core.__file__
assert _core.build_sanitizers == san, f"coopsim._core.build_sanitizers = {_core.build_sanitizers!r}, not {san!r}"
print(f"sanitized: coopsim._core from {_core.__file__}, built with -fsanitize={_core.build_sanitizers}")
EOF
# --capture=sys: pytest captures the tests' output at the level of Python's sys.stdout and
# sys.stderr only, so that a sanitizer's report, written to file descriptor 2 by the process it
# then ends, reaches the terminal instead of a capture file that dies with it
exec "$PY" -m pytest --capture=sys "$@"
