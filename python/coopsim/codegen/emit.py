"""C++ emission of a SymbolicModel: common subexpressions, no pow, sin/cos once per joint.

Every emitted function has the signature of ``coopsim::GeneratedDynamics``
(``cpp/include/coopsim/generated.hpp``): p is the robot's parameter vector
(16 per link, then gravity in frame 0), q and qd have n entries, matrices are
n x n column-major. Output is deterministic: same structure, generator and
sympy version give the same bytes.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
from sympy.printing.c import C99CodePrinter

from .symbolic import SymbolicModel

__all__ = ["EmittedFunction", "emit_functions", "FUNCTIONS"]

# name, arguments (after p), outputs
FUNCTIONS = (
    ("mass_matrix", "const double* q, double* M"),
    ("coriolis", "const double* q, const double* qd, double* c"),
    ("coriolis_matrix", "const double* q, const double* qd, double* C"),
    ("gravity", "const double* q, double* g"),
    ("dynamics", "const double* q, const double* qd, double* M, double* h"),
)


class _Printer(C99CodePrinter):
    """C++ printer: symbols to array reads, small integer powers as products, floats round-trip."""

    def __init__(self, names):
        super().__init__({"strict": False})
        self._names = names

    def _print_Symbol(self, expr):
        return self._names.get(expr, expr.name)

    def _print_Pow(self, expr):
        b, e = expr.base, expr.exp
        if e.is_Integer and 2 <= int(e) <= 6:
            base = self.parenthesize(b, 100)  # always bracket compound bases
            return "*".join([base] * int(e)) if not b.is_Atom else "*".join([self._print(b)] * int(e))
        if e == -1:
            return f"1.0/{self.parenthesize(b, 100)}"
        if e.is_Integer and -6 <= int(e) <= -2:
            return "1.0/(" + "*".join([self.parenthesize(b, 100)] * (-int(e))) + ")"
        if e == sp.S.Half:
            return f"std::sqrt({self._print(b)})"
        raise ValueError(f"unexpected power in generated code: {expr}")

    def _print_Rational(self, expr):
        return repr(float(expr))

    def _print_Integer(self, expr):
        return f"{int(expr)}"

    def _print_Float(self, expr):
        return repr(float(expr))


@dataclass
class EmittedFunction:
    name: str        # e.g. "mass_matrix"
    signature: str   # arguments after p
    body: str        # statements, indented
    operations: int  # arithmetic operations after cse (sympy count_ops), plus one per sin/cos


def _numeric_constants(expr):
    """Irrational constants (sqrt(3)/2 of 30 degree angles) as 17-digit floats."""
    reps = {a: sp.Float(a.evalf(20), 17) for a in expr.atoms(sp.Pow, sp.Function, sp.NumberSymbol)
            if a.is_number and not a.is_Rational}
    return expr.xreplace(reps) if reps else expr


def _body(model: SymbolicModel, outputs, names):
    """Statements computing [(target, expr)] with one cse over all of them."""
    exprs = [_numeric_constants(sp.sympify(e)) for _, e in outputs]
    replacements, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("x"), order="canonical")
    used = set()
    for _, e in replacements:
        used |= e.free_symbols
    for e in reduced:
        used |= e.free_symbols
    printer = _Printer(names)
    lines = []
    ops = 0
    # sin/cos of each revolute joint once, in joint order
    for i in range(model.n):
        for sym, fn in ((s, s.name[0]) for s in sorted(model.trig, key=lambda s: s.name)
                        if model.trig[s][0] == i):
            if sym in used:
                theta = model.trig[sym][1]
                arg = f"q[{i}]" if theta == 0.0 else f"q[{i}] + {repr(theta)}"
                lines.append(f"  const double {sym.name} = std::{'cos' if fn == 'c' else 'sin'}({arg});")
                ops += 1
    for sym, e in replacements:
        lines.append(f"  const double {sym.name} = {printer.doprint(e)};")
        ops += int(sp.count_ops(e))
    for (target, _), e in zip(outputs, reduced):
        lines.append(f"  {target} = {printer.doprint(e)};")
        ops += int(sp.count_ops(e))
    return "\n".join(lines), ops


def _names(model: SymbolicModel):
    names = {s: f"p[{i}]" for s, i in model.parameters.items()}
    for i in range(model.n):
        names[model.q[i]] = f"q[{i}]"
        names[model.qd[i]] = f"qd[{i}]"
    for s in model.trig:
        names[s] = s.name
    return names


def emit_functions(model: SymbolicModel) -> list:
    """The five functions of GeneratedDynamics as EmittedFunction (bodies only)."""
    n, names = model.n, _names(model)
    M, G, C, Cm, F = model.M, model.G, model.C, model.C_matrix, model.friction

    def mat(target, A):
        return [(f"{target}[{i + n * j}]", A[i, j]) for j in range(n) for i in range(n)]

    def vec(target, v):
        return [(f"{target}[{i}]", v[i]) for i in range(n)]

    h = sp.Matrix([C[k] + G[k] + F[k] for k in range(n)])
    outputs = {
        "mass_matrix": mat("M", M),
        "coriolis": vec("c", C),
        "coriolis_matrix": mat("C", Cm),
        "gravity": vec("g", G),
        "dynamics": mat("M", M) + vec("h", h),
    }
    out = []
    for fname, sig in FUNCTIONS:
        body, ops = _body(model, outputs[fname], names)
        out.append(EmittedFunction(fname, sig, body, ops))
    return out
