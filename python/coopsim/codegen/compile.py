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
from typing import List, Optional

import sympy as sp

from .._core import Robot, compiled_generated_names, generated_cache_dir, generated_info, load_generated_library
from .files import GENERATOR_VERSION, runtime_source
from .symbolic import Structure, SymbolicModel, structure_of

__all__ = ["compile", "cache_dir", "structure_key", "info", "builtin_names", "load"]

_FLAGS = ["-O2", "-std=c++17", "-shared", "-fPIC", "-fno-math-errno"]


def cache_dir() -> Path:
    """Build cache: $COOPSIM_CACHE_DIR, else $XDG_CACHE_HOME/coopsim, else ~/.cache/coopsim.

    Libraries there are also found by name when a compiled robot is unpickled
    in another process (e.g. a worker of a process pool)."""
    d = generated_cache_dir()
    return Path(d) if d else Path.home() / ".cache" / "coopsim"


def info(robot) -> Optional[dict]:
    """The generated dynamics attached to `robot` (built into the engine or by :func:`compile`): a dict with
    name, dof, joint_types, angles, generator_version, operation_count, in_use and derivatives (whether
    it carries the dynamics' derivatives, used by Robot.inverse_dynamics_derivatives and
    forward_dynamics_derivatives); None for a robot without any."""
    if not isinstance(robot, Robot):
        raise ValueError(f"robot must be a coopsim.Robot, got {type(robot).__name__}")
    return generated_info(robot)


def builtin_names() -> List[str]:
    """The names of the generated dynamics compiled into the engine (the built-in SCARAs')."""
    return list(compiled_generated_names())


def load(path) -> str:
    """Loads a library of generated dynamics (``coopsim_<name>.so``, built by :func:`compile`) into this
    process, so that robots compiled with it elsewhere unpickle here; returns its name. ValueError for a
    file that is missing or not such a library."""
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path must be a file name, got {path!r}")
    return load_generated_library(os.fspath(path))


def structure_key(s: Structure, compiler: str) -> str:
    """The cache key: a hash of the structure (joint types and the angle columns of the DH and CoM
    tables), generator version, sympy version, compiler, flags and platform. Lengths, masses,
    inertias, friction, gravity, base and name are not in it: the library reads them at run time."""
    text = repr((s.joint_types, s.angles, GENERATOR_VERSION, sp.__version__, compiler, _FLAGS,
                 sysconfig.get_platform()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _compiler() -> str:
    cxx = os.environ.get("CXX") or shutil.which("g++") or shutil.which("c++")
    if not cxx:
        raise RuntimeError("coopsim.codegen.compile needs a C++ compiler: install g++ or set CXX")
    return cxx


def _compiler_id(cxx: str) -> str:
    """The compiler's path and version line: an upgraded compiler builds anew."""
    try:
        res = subprocess.run([cxx, "--version"], capture_output=True, text=True, timeout=30)
        version = res.stdout.splitlines()[0] if res.stdout else ""
    except (OSError, subprocess.SubprocessError):
        version = ""
    return f"{cxx} {version}".strip()


def _build(s: Structure, cxx: str, folder: Path, lib: Path, verbose: bool) -> None:
    t0 = time.perf_counter()
    text, _ = runtime_source(s, SymbolicModel(s))
    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        src = Path(tmp) / f"coopsim_{s.name}.cpp"
        src.write_text(text, encoding="utf-8")
        out = Path(tmp) / lib.name
        res = subprocess.run([cxx, *_FLAGS, "-o", str(out), str(src)], capture_output=True, text=True)
        if res.returncode != 0:
            raise RuntimeError(f"building generated dynamics failed ({cxx}):\n{res.stderr[-4000:]}")
        shutil.copy(src, folder / src.name)  # kept next to the library for inspection
        digest = Path(tmp) / "digest"
        digest.write_text(_digest(out) + "\n", encoding="ascii")
        os.replace(out, lib)  # atomic: concurrent builds of one key are harmless
        os.replace(digest, _digest_path(lib))
    if verbose:
        print(f"coopsim.codegen: generated in {t1 - t0:.1f} s, built in {time.perf_counter() - t1:.1f} s: {lib}",
              file=sys.stderr)


def _digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _digest_path(lib: Path) -> Path:
    return lib.with_name(lib.name + ".sha256")


def _is_ours(lib: Path) -> bool:
    """Whether `lib` is the library this cache built: its SHA-256 equals the one recorded at the build."""
    try:
        return _digest_path(lib).read_text(encoding="ascii").strip() == _digest(lib)
    except OSError:
        return False


def compile(robot, *, cache: str | os.PathLike | None = None, verbose: bool = False):  # noqa: A001
    """Generates closed-form dynamics for `robot`, builds them into a shared library and attaches them.

    robot: a coopsim.Robot with any R/P structure. The library depends only on
    the joint types and the angle columns of its DH and CoM tables; lengths,
    masses, inertias, friction and gravity are read at run time, so robots
    that differ only in those share one build.
    cache: folder for built libraries (default: ``cache_dir()``). The cache
    key is the structure (``structure_key``): a hash of the joint types and
    the angle columns, with the generator version, sympy version, compiler
    (the $CXX or g++ path and its version), flags and platform, never the lengths, masses or
    other run-time values. A robot with the key of an existing build reuses
    that library (``coopsim_gen_<key>.so``); another joint type or angle
    builds a new one. A robot pickled after compile() unpickles with its
    generated code in any process that finds the library in ``cache_dir()``
    (another `cache` folder: set COOPSIM_CACHE_DIR to it in that process).
    Returns a copy of the robot with the generated code attached and
    selected, ``backend == "generated"`` (robots are immutable: the one
    given is unchanged; ``with_backend("numeric")`` makes a numeric copy). Raises ValueError for a
    robot that is not a coopsim.Robot, RuntimeError if the build fails. A
    cached library that no longer loads, or whose SHA-256 differs from the
    one recorded when it was built (``<library>.sha256``: damaged, replaced
    or foreign), is built again rather than loaded. The engine loads no
    library that another user owns or may write, or that lies in a folder
    others may write to (unless sticky); such a cache gives ValueError.
    Nothing of the robot but its joint types and angle columns reaches the
    generated C++ (its name does not: the library is named by the key).

    Cost of the first build of a structure, measured on a 2-core machine
    (sympy dominates; g++ -O2 takes 2-5 s, about 20 s for general angles): a
    6-DOF R/P arm with alpha in {0, +-pi/2, pi} 10-20 s, a PUMA-like 6R arm
    (benchmarks/bench_codegen.py) about 19 s, 6-DOF arms with general angles
    1.5-2 min; a cached build loads in about 3 ms. Closed forms win
    on robots with many parallel or perpendicular axes (the SCARAs: about 3x
    the numeric path); on general arms the margin is small (a PUMA-like 6R
    arm: an operation count of 2375, forward dynamics from Python about 1.4x
    the numeric path's speed; arms with arbitrary angles can be slower than
    numeric): compare both backends before choosing.
    """
    if not isinstance(robot, Robot):
        raise ValueError(f"robot must be a coopsim.Robot, got {type(robot).__name__}")
    cxx = _compiler()
    key = structure_key(structure_of(robot, name="robot"), _compiler_id(cxx))
    s = structure_of(robot, name=f"gen_{key}")
    folder = Path(cache) if cache is not None else cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    lib = folder / f"coopsim_{s.name}.so"
    if not lib.exists() or not _is_ours(lib):
        # none yet, or a library this cache did not build (damaged, replaced, or foreign): built anew,
        # never loaded
        _build(s, cxx, folder, lib, verbose)
    try:
        name = load(lib)
    except ValueError:
        # a damaged cached library (e.g. truncated by a full disk): build it again, once
        _build(s, cxx, folder, lib, verbose)
        name = load(lib)
    return robot.with_generated(name)
