#!/usr/bin/env bash
# A developer's build of the compiled module into the source tree, without installing anything:
# builds coopsim._core in build/dev (Release, incremental) and puts it into python/coopsim/, so that
# PYTHONPATH=python imports the tree as it is. Needs what scripts/setup.sh installs.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=$("${PYTHON:-python3}" -c 'import sys; print(sys.executable)')
[ -f build/dev/build.ninja ] || cmake -S . -B build/dev -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DPython_EXECUTABLE="$PY" -Dpybind11_DIR="$("$PY" -m pybind11 --cmakedir)" >/dev/null
cmake --build build/dev --target _core -j "${COOPSIM_BUILD_JOBS:-2}"
# installed atomically: copying over a module that running processes have loaded crashes them
install -m 755 build/dev/_core*.so python/coopsim/
