#!/usr/bin/env bash
# Installs everything coopsim needs on a fresh Debian machine, idempotently:
# Debian packages (compiler, Eigen, Bullet, pkg-config, chromium) through apt-get, then
# the package itself with its Python dependencies through pip. Re-running it
# skips what is already there and rebuilds incrementally in build/.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ "${COOPSIM_SKIP_SETUP:-0}" = 1 ]; then
  # a test of a private build (PYTHONPATH) must not install this tree over the environment's coopsim
  echo "setup: skipped (COOPSIM_SKIP_SETUP=1)"
  exit 0
fi

export PIP_ROOT_USER_ACTION=ignore PIP_DISABLE_PIP_VERSION_CHECK=1
PY=${PYTHON:-python3}

need=()
# chromium: the browser tests of view.replay_html (headless, through Playwright; no browser download)
for pkg in g++ pkg-config libeigen3-dev libbullet-dev chromium; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${need[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi

echo "setup: building and installing coopsim (incremental build in build/)"
# the build tools live in this environment rather than in a fresh isolated one
# per install, so that include paths stay put and re-builds only compile what changed
"$PY" -m pip install -q "scikit-build-core>=0.10" "pybind11==3.1.0" cmake ninja
"$PY" -m pip install -q --no-build-isolation ".[test,data,notebooks,teaching,cluster,live,gym]" -Cbuild-dir=build/{wheel_tag}
"$PY" -c "import coopsim, sys; assert coopsim._core.build_optimised, 'coopsim was not built optimised'; print('setup: coopsim', coopsim.__version__, 'ready')"
