"""Symbolic Lagrange-Euler dynamics and C++ code generation (the paper's section 5).

From a robot's DH and centre-of-mass tables, with symbolic lengths, masses,
inertias, friction and gravity, derive M(q), C(q, qd) (vector and Christoffel
matrix), G(q) and K qd, and emit C++ that reads the parameters at run time.

- ``derive(robot_or_structure)``: the SymbolicModel; ``model.M``, ``model.C``,
  ``model.C_matrix``, ``model.G``, ``model.friction`` are sympy matrices (use
  ``model.in_trig(expr)`` to show cos/sin of the joint angles, e.g. in LaTeX).
- ``compile(robot)``: generated code for any run-time robot, built with g++
  into a cached shared library and attached (``robot.backend == "generated"``);
  ``info(robot)`` the generated dynamics a robot carries, ``builtin_names()``
  those compiled into the engine, ``load(path)`` a library built elsewhere.
- ``python -m coopsim.codegen``: regenerates ``cpp/generated`` (scara1,
  scara2, registry.cpp) from the repository root; ``--check`` diffs instead.
"""
from .compile import builtin_names, cache_dir, compile, info, load  # noqa: A004
from .files import COMMAND, GENERATOR_VERSION
from .symbolic import Structure, SymbolicModel, derive, exact_angle, structure_of

__all__ = ["COMMAND", "GENERATOR_VERSION", "Structure", "SymbolicModel", "builtin_names", "cache_dir", "compile",
           "derive", "exact_angle", "info", "load", "structure_of"]
