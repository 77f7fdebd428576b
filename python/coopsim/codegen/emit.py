"""C++ emission of a SymbolicModel: common subexpressions, no pow, sin/cos once per joint.

Every emitted function has the signature of ``coopsim::GeneratedDynamics``
(``cpp/include/coopsim/generated.hpp``): p is the robot's parameter vector
(19 per link, then gravity in frame 0) followed by the parameter polynomials
(kappa) that ``constants`` computed from it once, q and qd have n entries,
matrices are n x n column-major. Output is deterministic: same structure, generator and
sympy version give the same bytes.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.precedence import precedence

from .symbolic import PARAMS_PER_LINK, Coulomb, SymbolicModel, _cse_ops

__all__ = ["EmittedFunction", "emit_functions", "emit_derivatives", "emit_constants", "emit_solve", "FUNCTIONS",
           "DERIVATIVES", "SIN_COS", "COULOMB_SLOPE"]

# name, arguments (after p), outputs
FUNCTIONS = (
    ("mass_matrix", "const double* q, double* M"),
    ("coriolis", "const double* q, const double* qd, double* c"),
    ("coriolis_matrix", "const double* q, const double* qd, double* C"),
    ("gravity", "const double* q, double* g"),
    ("dynamics", "const double* q, const double* qd, double* M, double* h"),
)
# the inverse dynamics' derivatives (and M) at (q, qd, qdd); emitted where tractable (the collected form)
DERIVATIVES = ("derivatives",
               "const double* q, const double* qd, const double* qdd, double* dtau_dq, double* dtau_dqd, double* M")


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

    def _print_Mul(self, expr):
        # a coefficient of exactly +-1.0 (from a float structural constant) is no multiplication
        c, rest = expr.as_coeff_Mul()
        if c.is_Float and abs(float(c)) == 1.0 and rest != 1:
            body = self.parenthesize(rest, precedence(expr))
            return body if float(c) > 0 else f"-{body}"
        return super()._print_Mul(expr)

    def _print_Coulomb(self, expr):
        Fc, qd, vc = (self._print(a) for a in expr.args)
        return f"({Fc} > 0.0 ? {Fc}*std::tanh({qd}/{vc}) : 0.0)"

    def _print_CoulombSlope(self, expr):
        Fc, qd, vc = (self._print(a) for a in expr.args)
        return f"coulomb_slope({Fc}, {qd}, {vc})"

    def _print_Rational(self, expr):
        return repr(float(expr))

    def _print_Integer(self, expr):
        return f"{int(expr)}"

    def _print_Float(self, expr):
        return repr(float(expr))


#: sin and cos of one angle, emitted once at the top of every generated file (std::sin and
#: std::cos are the larger part of a SCARA's dynamics otherwise). fdlibm's kernels on
#: [-pi/4, pi/4] after a Cody-Waite reduction by pi/2 in three 33-bit parts (exact products
#: for |x| < 1e5); within 2 ulp of the exact values there (tests/test_codegen.py checks it
#: against mpmath), std::sin and std::cos beyond and for inf and nan.
SIN_COS = """\
// On x86-64 each function below is compiled twice, for the baseline x86-64 and for x86-64-v3
// (AVX2, FMA: about a quarter fewer instructions); the loader picks the one this CPU runs.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(COOPSIM_GENERATED_BASELINE_ONLY)
#define COOPSIM_GENERATED_TARGETS __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define COOPSIM_GENERATED_TARGETS
#endif

static inline void sin_cos(double x, double& s, double& c) {
  if (!(std::fabs(x) < 1e5)) {
    s = std::sin(x);
    c = std::cos(x);
    return;
  }
  const double shift = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  const double n = (x * 0.63661977236758134308 + shift) - shift;
  const long quadrant = static_cast<long>(n) & 3;
  const double r = ((x - n * 1.57079632673412561417e+00) - n * 6.07710050630396597660e-11) -
                   n * 2.02226624871116645580e-21;
  const double z = r * r, w = z * z;
  const double ps = 8.33333333332248946124e-03 + z * (-1.98412698298579493134e-04 + z * 2.75573137070700676789e-06) +
                    z * w * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10);
  const double sr = r + z * r * (-1.66666666666666324348e-01 + z * ps);
  const double pc = z * (4.16666666666666019037e-02 + z * (-1.38888888888741095749e-03 + z * 2.48015872894767294178e-05)) +
                    w * w * (-2.75573143513906633035e-07 + z * (2.08757232129817482790e-09 + z * -1.13596475577881948265e-11));
  const double hz = 0.5 * z, one_hz = 1.0 - hz;
  const double cr = one_hz + (((1.0 - one_hz) - hz) + z * pc);
  switch (quadrant) {
    case 0: s = sr; c = cr; break;
    case 1: s = cr; c = -sr; break;
    case 2: s = -sr; c = -cr; break;
    default: s = -cr; c = sr; break;
  }
}
"""


#: The Coulomb term's slope, emitted after SIN_COS in files with derivatives (the recursive
#: algorithm's formula, robot_derivatives.cpp).
COULOMB_SLOPE = """\
// d/dqd of F_c tanh(qd / v_c): F_c / v_c (1 - tanh^2(qd / v_c)); no tanh without Coulomb friction.
static inline double coulomb_slope(double Fc, double qd, double vc) {
  if (!(Fc > 0.0)) return 0.0;
  const double t = std::tanh(qd / vc);
  return Fc / vc * (1.0 - t * t);
}
"""


@dataclass
class EmittedFunction:
    name: str        # e.g. "mass_matrix"
    signature: str   # arguments after p
    body: str        # statements, indented
    operations: int  # arithmetic operations after cse (sympy count_ops), plus one per sin/cos


class _SharedCse:
    """One cse over the expressions of all functions; each function then emits only the
    temporaries its outputs need (cse once instead of once per function)."""

    def __init__(self, exprs, prefix):
        unique = list(dict.fromkeys(exprs))
        reps, reduced = sp.cse(unique, symbols=sp.numbered_symbols(prefix), order="canonical")
        self.reps = reps
        self.reduced = dict(zip(unique, reduced))
        self._defs = dict(reps)

    def needed(self, exprs):
        """Temporaries (symbol, expr) that the reduced `exprs` depend on, in definition order."""
        need, stack = set(), [s for e in exprs for s in self.reduced[e].free_symbols if s in self._defs]
        while stack:
            sym = stack.pop()
            if sym not in need:
                need.add(sym)
                stack.extend(s for s in self._defs[sym].free_symbols if s in self._defs)
        return [(sym, e) for sym, e in self.reps if sym in need]


def _body(model: SymbolicModel, outputs, names, out_cse):
    """Statements computing [(target, expr)]: sin/cos of the joints used, the parameter
    polynomials (kappa) used, read from p, then the outputs with kappa, sin/cos and qd as inputs."""
    exprs = [e for _, e in outputs]
    printer = _Printer(names)
    lines, ops = [], 0
    temps = out_cse.needed(exprs)
    used = set()
    for e in exprs:
        used |= out_cse.reduced[e].free_symbols
    for _, e in temps:
        used |= e.free_symbols
    # sin and cos of each revolute joint used, together, once, in joint order
    for i in range(model.n):
        syms = sorted((s for s in model.trig if model.trig[s][0] == i), key=lambda s: s.name)
        if not any(sym in used for sym in syms):
            continue
        (c,), (sn,) = ([t for t in syms if t.name.startswith(k)] for k in ("c_", "s_"))
        theta = model.trig[c][1]
        arg = f"q[{i}]" if theta == 0.0 else f"q[{i}] + {repr(theta)}"
        lines.append(f"  double {sn.name}, {c.name};")
        lines.append(f"  sin_cos({arg}, {sn.name}, {c.name});")
        ops += sum(sym in used for sym in syms)
    # displacement of each prismatic joint, offset included
    for sym, (i, d) in model.slides.items():
        if sym in used:
            lines.append(f"  const double {sym.name} = {names[d]} + q[{i}];")
            ops += 1
    # parameter polynomials: computed once by `constants`, read after the parameters
    base = _constants_offset(model)
    for j, k in enumerate(model.kappa):
        if k in used:
            lines.append(f"  const double {k.name} = p[{base + j}];")
    for sym, e in temps:
        lines.append(f"  const double {sym.name} = {printer.doprint(e)};")
        ops += int(sp.count_ops(e))
    # an output equal to an earlier one (M's mirror entries) is copied from it
    first = {}
    for (target, _), e in zip(outputs, exprs):
        red = out_cse.reduced[e]
        if not red.is_Number and red in first:
            lines.append(f"  {target} = {first[red]};")
            continue
        first.setdefault(red, target)
        lines.append(f"  {target} = {printer.doprint(red)};")
        ops += int(sp.count_ops(red))
    return "\n".join(lines), ops


def _names(model: SymbolicModel):
    names = {s: f"p[{i}]" for s, i in model.parameters.items()}
    for i in range(model.n):
        names[model.q[i]] = f"q[{i}]"
        names[model.qd[i]] = f"qd[{i}]"
        names[model.qdd[i]] = f"qdd[{i}]"
    for s in model.trig:
        names[s] = s.name
    for k in list(model.kappa) + list(model.slides):
        names[k] = k.name
    return names


def emit_functions(model: SymbolicModel) -> list:
    """The functions of GeneratedDynamics as EmittedFunction (bodies only): the five of FUNCTIONS,
    then ``derivatives`` where emit_derivatives gives it."""
    n = model.n
    # fixed order of derivation keeps kappa numbering, hence the output, deterministic
    M, G = model.M_kappa, model.G_kappa
    C, Cm, F = model.C_kappa, model.C_matrix_kappa, model.friction_emitted
    # C and G link by link (base-frame Jacobians, shared) are the same vectors;
    # they always win in the Jacobian form and on some collected robots
    links = [model.C_links[k] + model.G_links[k] for k in range(n)]
    if model.form == "jacobian" or _cse_ops(links) < _cse_ops([C[k] + G[k] for k in range(n)]):
        C, G = model.C_links, model.G_links
    if model.form == "jacobian":
        M = model.M_links
    M = M + model.armature  # reflected rotor inertia on the diagonal
    names = _names(model)

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
    outputs = {k: [(t, sp.sympify(e)) for t, e in v] for k, v in outputs.items()}
    out_cse = _SharedCse([e for fname, _ in FUNCTIONS for _, e in outputs[fname]], "x")
    out = []
    for fname, sig in FUNCTIONS:
        body, ops = _body(model, outputs[fname], names, out_cse)
        out.append(EmittedFunction(fname, sig, body, ops))
    deriv = emit_derivatives(model)
    if deriv is not None:
        out.append(deriv)
    return out


def emit_derivatives(model: SymbolicModel):
    """``derivatives(p, q, qd, qdd, dtau_dq, dtau_dqd, M)``: the inverse dynamics' derivatives
    (SymbolicModel.inverse_dynamics_derivatives, friction included) and M (armature included),
    each n x n column-major with [i + n k] = d tau_i / d x_k, as an EmittedFunction with a cse of
    its own (the other functions' bodies stay as they are). None in the Jacobian form, where the
    derivatives of general arms grow too large to be worth emitting (the engine's recursive
    algorithm is used there)."""
    if model.form != "collected":
        return None
    n = model.n
    dq, dqd = model.inverse_dynamics_derivatives
    M = model.M_kappa + model.armature

    def mat(target, A):
        return [(f"{target}[{i + n * j}]", sp.sympify(A[i, j])) for j in range(n) for i in range(n)]

    outputs = mat("dtau_dq", dq) + mat("dtau_dqd", dqd) + mat("M", M)
    body, ops = _body(model, outputs, _names(model), _SharedCse([e for _, e in outputs], "x"))
    return EmittedFunction(DERIVATIVES[0], DERIVATIVES[1], body, ops)


def _constants_offset(model: SymbolicModel) -> int:
    """Where the constants start in p: after the n link blocks and gravity."""
    return PARAMS_PER_LINK * model.n + 3


def emit_constants(model: SymbolicModel):
    """Body of ``void constants(const double* p, double* k)``: every parameter polynomial
    (kappa_j, in order) from the parameter vector, written to k[j]. The robot calls it
    once when its parameters are set and keeps k after p, where the other functions read
    it: a term that does not depend on the state is not recomputed at every call.
    Returns (body, number of constants, operation count)."""
    printer = _Printer(_names(model))
    # parameter polynomials in Horner form: about 40 % fewer operations on the SCARAs
    kdefs = {k: sp.horner(e) for k, e in model.kappa.items()}
    kappa_cse = _SharedCse(list(kdefs.values()), "a")
    lines, ops = [], 0
    for sym, e in kappa_cse.needed(list(kdefs.values())):
        lines.append(f"  const double {sym.name} = {printer.doprint(e)};")
        ops += int(sp.count_ops(e))
    for j, (k, e) in enumerate(kdefs.items()):
        red = kappa_cse.reduced[e]
        lines.append(f"  k[{j}] = {printer.doprint(red)};  // {k.name}")
        ops += int(sp.count_ops(red))
    if not lines:
        lines.append("  (void)p;\n  (void)k;")
    return "\n".join(lines), len(kdefs), ops


def emit_solve(model: SymbolicModel):
    """Body of ``bool solve(const double* M, double* x)``: x <- M^-1 x by an unrolled LDL^T
    factorisation that skips M's structural zeros and their fill-in; returns false (x
    undefined) when a pivot is not positive, i.e. M is not positive definite.
    Returns (body, operation count)."""
    n, M = model.n, model.M_kappa
    nz = {(i, j) for i in range(n) for j in range(n) if M[i, j] != 0}
    lines, ops = [], 0
    # u_ij = L_ij d_j (before the division), so L_ik L_jk d_k = l_ik u_jk
    L = {}  # (i, j), i > j -> name of L_ij when structurally nonzero
    for j in range(n):
        ks = [k for k in range(j) if (j, k) in L]
        lines.append(f"  const double d_{j} = " + " - ".join([f"M[{j + n * j}]"] + [f"l_{j}_{k}*u_{j}_{k}" for k in ks])
                     + ";")
        lines.append(f"  if (!(d_{j} > 0.0)) return false;")
        lines.append(f"  const double r_{j} = 1.0/d_{j};")
        ops += 2 * len(ks) + 1
        for i in range(j + 1, n):
            ki = [k for k in ks if (i, k) in L]
            if (i, j) not in nz and not ki:
                continue
            terms = [f"l_{i}_{k}*u_{j}_{k}" for k in ki]
            if (i, j) in nz:
                expr = " - ".join([f"M[{i + n * j}]"] + terms)
            else:
                expr = "-(" + " + ".join(terms) + ")"
            L[i, j] = f"l_{i}_{j}"
            lines.append(f"  const double u_{i}_{j} = {expr};")
            lines.append(f"  const double l_{i}_{j} = u_{i}_{j}*r_{j};")
            ops += 2 * len(ki) + 1
    # L y = b, then x = L^-T D^-1 y, in place
    for i in range(n):
        ks = [k for k in range(i) if (i, k) in L]
        if ks:
            lines.append(f"  x[{i}] -= " + " + ".join(f"{L[i, k]}*x[{k}]" for k in ks) + ";")
            ops += 2 * len(ks)
    for i in range(n):
        lines.append(f"  x[{i}] *= r_{i};")
        ops += 1
    for i in reversed(range(n)):
        ks = [k for k in range(i + 1, n) if (k, i) in L]
        if ks:
            lines.append(f"  x[{i}] -= " + " + ".join(f"{L[k, i]}*x[{k}]" for k in ks) + ";")
            ops += 2 * len(ks)
    lines.append("  return true;")
    return "\n".join(lines), ops
