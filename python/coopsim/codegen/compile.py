"""Generated dynamics for a robot defined at run time: generate, build with g++, load, attach."""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

import sympy as sp

from .files import GENERATOR_VERSION, runtime_source
from .symbolic import Structure, SymbolicModel, structure_of

__all__ = ["compile", "cache_dir", "structure_key"]

_FLAGS = ["-O2", "-std=c++17", "-shared", "-fPIC", "-fno-math-errno"]


def cache_dir() -> Path:
    """Build cache: $COOPSIM_CACHE_DIR, else $XDG_CACHE_HOME/coopsim, else ~/.cache/coopsim."""
    env = os.environ.get("COOPSIM_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "coopsim"


def structure_key(s: Structure, compiler: str) -> str:
    """Hash of everything the built library depends on: structure, generator, sympy, compiler, flags."""
    text = repr((s.joint_types, s.angles, GENERATOR_VERSION, sp.__version__, compiler, _FLAGS,
                 sysconfig.get_platform()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _compiler() -> str:
    cxx = os.environ.get("CXX") or shutil.which("g++") or shutil.which("c++")
    if not cxx:
        raise RuntimeError("coopsim.codegen.compile needs a C++ compiler: install g++ or set CXX")
    return cxx


def compile(robot, *, cache: str | os.PathLike | None = None, verbose: bool = False):  # noqa: A001
    """Generates closed-form dynamics for `robot`, builds them into a shared library and attaches them.

    robot: a coopsim.Robot with any R/P structure. The library depends only on
    the joint types and the angle columns of its DH and CoM tables; lengths,
    masses, inertias, friction and gravity are read at run time, so robots
    that differ only in those share one build.
    cache: folder for built libraries (default: ``cache_dir()``); a build is
    reused when the hash of the structure, generator version, sympy version
    and compiler matches.
    Returns the robot, now with ``robot.backend == "generated"``
    (``robot.set_backend("numeric")`` switches back). Raises ValueError for a
    robot that is not a coopsim.Robot, RuntimeError if the build fails.

    Cost: a 6-DOF arm takes tens of seconds the first time (sympy, then g++
    -O2), milliseconds from the cache. Closed forms win on robots with many
    parallel or perpendicular axes (the SCARAs: about 3x the numeric path);
    on a general 6R arm with alpha = +-pi/2 throughout, M, C and G take about
    6000 operations and the numeric recursive algorithms are faster (about
    1.5x on a PUMA-like arm): compare both backends before choosing.
    """
    from .. import _core

    if not isinstance(robot, _core.Robot):
        raise ValueError(f"robot must be a coopsim.Robot, got {type(robot).__name__}")
    cxx = _compiler()
    key = structure_key(structure_of(robot, name="robot"), cxx)
    s = structure_of(robot, name=f"gen_{key}")
    folder = Path(cache) if cache is not None else cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    lib = folder / f"coopsim_gen_{key}.so"
    t0 = time.perf_counter()
    ops_file = folder / f"coopsim_gen_{key}.ops"
    if not lib.exists() or not ops_file.exists():
        text, ops = runtime_source(s, SymbolicModel(s))
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory(dir=folder) as tmp:
            src = Path(tmp) / f"coopsim_gen_{key}.cpp"
            src.write_text(text, encoding="utf-8")
            out = Path(tmp) / lib.name
            res = subprocess.run([cxx, *_FLAGS, "-o", str(out), str(src)], capture_output=True, text=True)
            if res.returncode != 0:
                raise RuntimeError(f"building generated dynamics failed ({cxx}):\n{res.stderr[-4000:]}")
            shutil.copy(src, folder / src.name)  # kept next to the library for inspection
            (Path(tmp) / ops_file.name).write_text(str(ops))
            # atomic, operation count first: concurrent builds of one key are harmless
            os.replace(Path(tmp) / ops_file.name, ops_file)
            os.replace(out, lib)
        if verbose:
            print(f"coopsim.codegen: generated in {t1 - t0:.1f} s, built in {time.perf_counter() - t1:.1f} s: {lib}",
                  file=sys.stderr)
    ops = int(ops_file.read_text())
    if _core.generated_info(robot) is None or _core.generated_info(robot)["name"] != s.name:
        name = s.name
        try:
            _core.attach_builtin_generated(robot, name)
        except ValueError:
            angles = [v for row in s.angles for v in row]
            _core.load_generated_library(str(lib), name, s.dof, s.joint_types, angles, GENERATOR_VERSION, ops)
            _core.attach_builtin_generated(robot, name)
    robot.set_backend("generated")
    return robot
