"""The stamp of an output: what made it, so that a result can be traced back and run again.

:func:`stamp` is written into every ``report.json`` of the tasks' command lines (the handover's, the carry's and
their sweeps', through :func:`coopsim.tasks.handover.report.write_report`): coopsim's version, the git commit of
the checkout it ran from (None when it is not a checkout or git is missing), how the engine was built (compiler,
flags, build type, optimised, sanitizers, Eigen's and pybind11's versions), Python's and numpy's versions, the
platform and machine, the seed and every argument.
"""
from __future__ import annotations

import datetime
import os
import platform
import subprocess
import sys
from typing import Optional

import numpy as np

from ._core import build_optimised, build_sanitizers, build_toolchain

__all__ = ["git_commit", "stamp"]

#: the package's folder; a checkout has it at <root>/python/coopsim
_PACKAGE = os.path.dirname(os.path.abspath(__file__))


def _checkout_root() -> Optional[str]:
    """The root of the source checkout this package runs from (<root>/python/coopsim with <root>/.git), or None
    (an installed package)."""
    root = os.path.dirname(os.path.dirname(_PACKAGE))
    if os.path.basename(os.path.dirname(_PACKAGE)) != "python" or not os.path.exists(os.path.join(root, ".git")):
        return None
    return root


def git_commit(root: Optional[str] = None) -> Optional[dict]:
    """The checkout's commit: dict(commit (40 hex digits), dirty (bool: files changed since it)), or None when
    the package does not run from a git checkout, git is missing or fails (never raises). `root`: the checkout's
    folder (default the one this package runs from)."""
    root = _checkout_root() if root is None else root
    if root is None:
        return None
    try:
        head = subprocess.run(["git", "-C", root, "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return None
        status = subprocess.run(["git", "-C", root, "status", "--porcelain", "--untracked-files=no"],
                                capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):        # no git, or it hangs
        return None
    commit = head.stdout.strip()
    if len(commit) != 40:
        return None
    return dict(commit=commit, dirty=bool(status.stdout.strip()) if status.returncode == 0 else None)


def _plain(x):
    """Arguments as JSON's values: tuples as lists, paths and other objects as text, numpy scalars as numbers."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, set, range)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if x is None or isinstance(x, (bool, int, float, str)):
        return x
    return str(x)


def stamp(*, seed=None, arguments: Optional[dict] = None) -> dict:
    """The stamp of an output (plain values, JSON-ready):

    - coopsim: the package's version; git: :func:`git_commit` (commit, dirty) or None;
    - build: the engine's build (the engine's ``build_toolchain()``: compiler, compiler_version, build_type,
      flags, cxx_standard, eigen, pybind11; and optimised, sanitizers);
    - python (version), numpy (version), platform (``platform.platform()``), machine (e.g. 'x86_64'),
      processors (``os.cpu_count()``);
    - seed: the seed (or seeds) of the output as given; arguments: every argument of the command line or call
      (a dict), as given;
    - written: the local time it was made, ISO 8601 with its UTC offset."""
    version = getattr(sys.modules.get(__package__), "__version__", None)   # the package's, imported before this
    build = dict(build_toolchain(), optimised=bool(build_optimised), sanitizers=str(build_sanitizers))
    return dict(coopsim=version, git=git_commit(), build=build,
                python=platform.python_version(), python_implementation=platform.python_implementation(),
                numpy=np.__version__, platform=platform.platform(), machine=platform.machine(),
                processors=os.cpu_count(), executable=sys.executable, seed=_plain(seed),
                arguments=_plain(dict(arguments or {})),
                written=datetime.datetime.now().astimezone().isoformat(timespec="seconds"))
