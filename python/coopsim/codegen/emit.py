"""C++ emission of a SymbolicModel: common subexpressions, no pow, sin/cos once per joint.

Every emitted function has the signature of ``coopsim::GeneratedDynamics``
(``cpp/include/coopsim/generated.hpp``): p is the robot's parameter vector
(19 per link, then gravity in frame 0) followed by the parameter polynomials
(kappa) that ``constants`` computed from it once, q and qd have n entries,
matrices are n x n column-major. Output is deterministic: same structure, generator and
sympy version give the same bytes.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.precedence import precedence

from .symbolic import PARAMS_PER_LINK, Coulomb, CoulombSlope, SymbolicModel, _cse_ops

__all__ = ["EmittedFunction", "emit_functions", "emit_derivatives", "emit_forward_derivatives", "emit_constants",
           "emit_solve", "FUNCTIONS", "DERIVATIVES", "FORWARD", "FORWARD4", "SIN_COS", "COULOMB_SLOPE", "LANES"]

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

    def __init__(self, names, lanes=False):
        super().__init__({"strict": False})
        self._names = names
        self._lanes = lanes  # for the templates: the Coulomb terms are variables computed before (calls)
        self.calls = {}      # Coulomb or CoulombSlope term -> the name of its variable

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
        if self._lanes:
            return self.calls[expr]
        Fc, qd, vc = (self._print(a) for a in expr.args)
        return f"({Fc} > 0.0 ? {Fc}*std::tanh({qd}/{vc}) : 0.0)"

    def _print_CoulombSlope(self, expr):
        if self._lanes:
            return self.calls[expr]
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


#: What the templates need beside sin_cos and coulomb_slope: four states in the lanes of a vector
#: (GCC's vector extensions: AVX2 registers in the x86-64-v3 clones, pairs of SSE2 ones in the
#: baseline), sin/cos and the friction's tanh lane by lane (by reference: a vector returned by value
#: has another ABI in each clone's target), the pivots' test.
LANES = """\
typedef double d4 __attribute__((vector_size(32)));  // four states, one per lane
typedef long long i4 __attribute__((vector_size(32)));

// sin_cos above in the four lanes at once, the same operations (the same results bit for bit); lane by
// lane where one is out of its range
static inline void sin_cos(const d4& x, d4& s, d4& c) {
  const i4 small = (x < 1e5) & (x > -1e5);
  if (!(small[0] & small[1] & small[2] & small[3])) {
    for (int l = 0; l < 4; ++l) {
      double sl, cl;
      sin_cos(x[l], sl, cl);
      s[l] = sl;
      c[l] = cl;
    }
    return;
  }
  const double shift = 6755399441055744.0;
  const d4 y = x * 0.63661977236758134308 + shift;  // its low mantissa bits: the quadrant
  const d4 n = y - shift;
  const i4 quadrant = (i4)y & 3;
  const d4 r = ((x - n * 1.57079632673412561417e+00) - n * 6.07710050630396597660e-11) -
               n * 2.02226624871116645580e-21;
  const d4 z = r * r, w = z * z;
  const d4 ps = 8.33333333332248946124e-03 + z * (-1.98412698298579493134e-04 + z * 2.75573137070700676789e-06) +
                z * w * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10);
  const d4 sr = r + z * r * (-1.66666666666666324348e-01 + z * ps);
  const d4 pc = z * (4.16666666666666019037e-02 + z * (-1.38888888888741095749e-03 + z * 2.48015872894767294178e-05)) +
                w * w * (-2.75573143513906633035e-07 + z * (2.08757232129817482790e-09 + z * -1.13596475577881948265e-11));
  const d4 hz = 0.5 * z, one_hz = 1.0 - hz;
  const d4 cr = one_hz + (((1.0 - one_hz) - hz) + z * pc);
  // quadrant 0: (sr, cr), 1: (cr, -sr), 2: (-sr, -cr), 3: (-cr, sr): swapped when odd, signs by bit 1
  const i4 odd = (quadrant & 1) != 0;
  const i4 ss = ((i4)sr & ~odd) | ((i4)cr & odd);
  const i4 cc = ((i4)cr & ~odd) | ((i4)sr & odd);
  const i4 sign = (i4)(-d4{});  // -0.0: the sign bit alone
  const i4 s_neg = ((quadrant & 2) != 0) & sign, c_neg = (((quadrant + 1) & 2) != 0) & sign;
  const i4 so = ss ^ s_neg, co = cc ^ c_neg;
  s = (d4)so;
  c = (d4)co;
}

// a, b, c, d (entries k..k+3 of four states' matrices, one state per lane) as four rows of four: state
// l's at out + l * stride
static inline void store4(const d4& a, const d4& b, const d4& c, const d4& d, double* out, int stride) {
  const d4 ab0 = __builtin_shuffle(a, b, i4{0, 4, 2, 6}), ab1 = __builtin_shuffle(a, b, i4{1, 5, 3, 7});
  const d4 cd0 = __builtin_shuffle(c, d, i4{0, 4, 2, 6}), cd1 = __builtin_shuffle(c, d, i4{1, 5, 3, 7});
  const d4 r0 = __builtin_shuffle(ab0, cd0, i4{0, 1, 4, 5}), r1 = __builtin_shuffle(ab1, cd1, i4{0, 1, 4, 5});
  const d4 r2 = __builtin_shuffle(ab0, cd0, i4{2, 3, 6, 7}), r3 = __builtin_shuffle(ab1, cd1, i4{2, 3, 6, 7});
  __builtin_memcpy(out, &r0, sizeof(d4));  // one unaligned store each
  __builtin_memcpy(out + stride, &r1, sizeof(d4));
  __builtin_memcpy(out + 2 * stride, &r2, sizeof(d4));
  __builtin_memcpy(out + 3 * stride, &r3, sizeof(d4));
}

static inline void coulomb(double Fc, double qd, double vc, double& r) { r = Fc > 0.0 ? Fc*std::tanh(qd/vc) : 0.0; }
static inline void coulomb(double Fc, const d4& qd, double vc, d4& r) {
  for (int l = 0; l < 4; ++l) {
    double rl;
    coulomb(Fc, qd[l], vc, rl);
    r[l] = rl;
  }
}
static inline void coulomb_slope(double Fc, double qd, double vc, double& r) { r = coulomb_slope(Fc, qd, vc); }
static inline void coulomb_slope(double Fc, const d4& qd, double vc, d4& r) {
  for (int l = 0; l < 4; ++l) r[l] = coulomb_slope(Fc, qd[l], vc);
}

// a pivot of the LDL^T factor against M's diagonal entry, as forward_dynamics' Cholesky: every lane
static inline bool pivot_ok(double d, double m) { return d > 1e-13 * m; }
static inline bool pivot_ok(const d4& d, const d4& m) {
  const auto k = d > 1e-13 * m;
  return k[0] && k[1] && k[2] && k[3];
}
"""


@dataclass
class EmittedFunction:
    name: str        # e.g. "mass_matrix"
    signature: str   # arguments after p
    body: str        # statements, indented
    operations: int  # arithmetic operations after cse (sympy count_ops), plus one per sin/cos
    template: str = ""    # a template on the state's scalar type the body calls (emitted before the functions)
    returns: str = "void"


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


def _trig_joints(model: SymbolicModel):
    """[(joint, s symbol, c symbol, DH theta offset)] of every joint with sin/cos, in joint order: the
    layout of the array sc (sc[2 k] = sin, sc[2 k + 1] = cos of the k-th) that dynamics_t fills and
    derivatives_t reads, so that a pass through both computes each sin/cos once."""
    out = []
    for i in range(model.n):
        syms = sorted((s for s in model.trig if model.trig[s][0] == i), key=lambda s: s.name)
        if syms:
            (c,), (sn,) = ([t for t in syms if t.name.startswith(k)] for k in ("c_", "s_"))
            out.append((i, sn, c, model.trig[c][1]))
    return out


def _body(model: SymbolicModel, outputs, names, out_cse, scalar=None, trig="compute"):
    """Statements computing [(target, expr)]: sin/cos of the joints used, the parameter
    polynomials (kappa) used, read from p, then the outputs with kappa, sin/cos and qd as inputs.
    scalar="T": the body of a template on the state's scalar type T (double, or four states in the
    lanes of a vector): what depends on the state is a T, what depends on the parameters only a
    double, an output of the parameters only is T{} + (...). trig="export": sin/cos of every joint
    computed and, when sc is not null, written into sc (_trig_joints' layout); "read": those used read
    from sc."""
    exprs = [e for _, e in outputs]
    lanes = scalar is not None
    printer = _Printer(names, lanes=lanes)
    lines, ops = [], 0
    temps = out_cse.needed(exprs)
    used = set()
    for e in exprs:
        used |= out_cse.reduced[e].free_symbols
    for _, e in temps:
        used |= e.free_symbols
    state = set(model.q) | set(model.qd) | set(model.qdd) | set(model.trig) | set(model.slides)
    st = scalar or "double"
    # sin and cos of each revolute joint used, together, once, in joint order
    exported = []
    for k, (i, sn, c, theta) in enumerate(_trig_joints(model)):
        if trig == "read":
            lines += [f"  const {st} {x.name} = sc[{2 * k + j}];" for j, x in enumerate((sn, c)) if x in used]
            continue
        if trig != "export" and sn not in used and c not in used:
            continue
        arg = f"q[{i}]" if theta == 0.0 else f"q[{i}] + {repr(theta)}"
        lines.append(f"  {st} {sn.name}, {c.name};")
        lines.append(f"  sin_cos({arg}, {sn.name}, {c.name});")
        exported += [f"sc[{2 * k}] = {sn.name};", f"sc[{2 * k + 1}] = {c.name};"]
        ops += (sn in used) + (c in used)
    if exported and trig == "export":
        lines.append("  if (sc) {")
        lines += ["    " + e for e in exported]
        lines.append("  }")
    # displacement of each prismatic joint, offset included
    for sym, (i, d) in model.slides.items():
        if sym in used:
            lines.append(f"  const {st} {sym.name} = {names[d]} + q[{i}];")
            ops += 1
    # parameter polynomials: computed once by `constants`, read after the parameters
    base = _constants_offset(model)
    for j, k in enumerate(model.kappa):
        if k in used:
            lines.append(f"  const double {k.name} = p[{base + j}];")
    if lanes:
        # the friction's tanh terms as variables, by overloads with an output argument (no vector returned
        # by value: its ABI differs between the clones' targets)
        terms = set()
        for e in [out_cse.reduced[x] for x in exprs] + [e for _, e in temps]:
            terms |= e.atoms(Coulomb, CoulombSlope)
        for t in sorted(terms, key=lambda t: (t.func.__name__, str(t.args))):
            name = f"{'cf' if t.func is Coulomb else 'cs'}_{len(printer.calls)}"
            printer.calls[t] = name
            fn = "coulomb" if t.func is Coulomb else "coulomb_slope"
            args = ", ".join(printer.doprint(a) for a in t.args)
            lines.append(f"  {scalar} {name};")
            lines.append(f"  {fn}({args}, {name});")
            state.add(sp.Symbol(name))
    for sym, e in temps:
        varies = bool(e.free_symbols & state)
        if varies:
            state.add(sym)
        lines.append(f"  const {st if varies else 'double'} {sym.name} = {printer.doprint(e)};")
        ops += int(sp.count_ops(e))
    # an output equal to an earlier one (M's mirror entries) is copied from it
    first = {}
    for (target, _), e in zip(outputs, exprs):
        red = out_cse.reduced[e]
        if not red.is_Number and red in first:
            lines.append(f"  {target} = {first[red]};")
            continue
        first.setdefault(red, target)
        text = printer.doprint(red)
        if lanes and not (red.free_symbols & state):
            text = f"{scalar}{{}} + ({text})"  # a parameter's value in every lane
        lines.append(f"  {target} = {text};")
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
        if fname == "dynamics":
            # a template on the scalar type: the forward derivatives evaluate it on four states at once
            body, ops = _body(model, outputs[fname], names, out_cse, scalar="T", trig="export")
            template = (f"template <class T>\n{_INLINE} void dynamics_t(const double* p, const T* q, const T* qd, "
                        f"T* M, T* h, T* sc = nullptr) {{\n{body}\n}}\n")
            call = "  dynamics_t(p, q, qd, M, h);"
            level = _level_base(model)
            if level is not None:
                # a base whose gravity is along its z axis (g_x = g_y = 0, as for every arm standing on the
                # floor): M and h without the terms of the horizontal components, which would multiply zeros
                zero, gx, gy = level
                lv = [(t, e.subs(zero)) for t, e in outputs[fname]]
                lv_body, lv_ops = _body(model, lv, names, _SharedCse([e for _, e in lv], "y"))
                template += (f"\n// dynamics_t where p's gravity is along z ({names[gx]} = {names[gy]} = 0): "
                             f"{lv_ops} operations\n"
                             f"{_INLINE} void dynamics_level(const double* p, const double* q, const double* qd, "
                             f"double* M, double* h) {{\n{lv_body}\n}}\n")
                call = (f"  if ({names[gx]} == 0.0 && {names[gy]} == 0.0)\n    dynamics_level(p, q, qd, M, h);\n"
                        f"  else\n  {call}")
            out.append(EmittedFunction(fname, sig, call, ops, template))
            continue
        body, ops = _body(model, outputs[fname], names, out_cse)
        out.append(EmittedFunction(fname, sig, body, ops))
    deriv = emit_derivatives(model)
    if deriv is not None:
        out.append(deriv)
        out.extend(emit_forward_derivatives(model))
    return out


def _level_base(model: SymbolicModel):
    """({g_x: 0, g_y: 0, and each parameter polynomial that vanishes with them: 0}, g_x, g_y) for dynamics_level,
    or None when no polynomial depends on g_x or g_y (nothing to leave out)."""
    gx, gy = model.g[0], model.g[1]
    zero = {gx: 0, gy: 0}
    found = False
    for k, poly in model.kappa.items():
        if poly.has(gx) or poly.has(gy):
            found = True
            if sp.expand(poly.subs({gx: 0, gy: 0})) == 0:
                zero[k] = 0
    return (zero, gx, gy) if found else None


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

    def mat(target, A, strided):
        at = (lambda i, j: f"{i}*RS + {j}*CS") if strided else (lambda i, j: f"{i + n * j}")
        return [(f"{target}[{at(i, j)}]", sp.sympify(A[i, j])) for j in range(n) for i in range(n)]

    # a template on the scalar type and on the layout of dtau_dq and dtau_dqd ([i RS + k CS]): the
    # forward derivatives write them into the rows they solve in place
    outputs = mat("dtau_dq", dq, True) + mat("dtau_dqd", dqd, True) + mat("M", M, False)
    body, ops = _body(model, outputs, _names(model), _SharedCse([e for _, e in outputs], "x"), scalar="T",
                      trig="read")
    # sin and cos of the joints (those dynamics_t computed, when the forward derivatives call both)
    template = (f"template <class T, int RS, int CS>\n{_INLINE} void derivatives_t(const double* p, const T* sc, "
                f"const T* q, const T* qd, const T* qdd, T* dtau_dq, T* dtau_dqd, T* M) {{\n{body}\n}}\n")
    joints = _trig_joints(model)
    entry = [f"  double {sn.name}, {c.name};\n  sin_cos({f'q[{i}]' if th == 0.0 else f'q[{i}] + {repr(th)}'}, "
             f"{sn.name}, {c.name});" for i, sn, c, th in joints]
    sc = ", ".join(f"{sn.name}, {c.name}" for _, sn, c, _ in joints)
    entry.append(f"  const double sc[] = {{{sc}}};" if joints else "  const double* sc = nullptr;")
    entry.append(f"  derivatives_t<double, 1, {n}>(p, sc, q, qd, qdd, dtau_dq, dtau_dqd, M);")
    return EmittedFunction(DERIVATIVES[0], DERIVATIVES[1], "\n".join(entry), ops, template)


#: the templates are inlined into each entry point (and so compiled for each target of its clones)
_INLINE = "static inline __attribute__((always_inline))"

# the forward dynamics' derivatives, one state and four states at once
FORWARD = ("forward_derivatives", "const double* q, const double* qd, const double* tau, double* dqdd_dq, "
                                  "double* dqdd_dqd, double* Minv, double* qdd")
FORWARD4 = ("forward_derivatives4", "const double* q, const double* qd, const double* tau, double* dqdd_dq, "
                                    "double* dqdd_dqd, double* Minv")


def _ldl_lines(model, typ, ok, pivot=None):
    """LDL^T of M (n x n column-major in M) unrolled, skipping M's structural zeros and their
    fill-in, as emit_solve: pivots d_j, their reciprocals r_j, L's entries l_i_j (typ each); a pivot
    not above 1e-13 M_jj (forward_dynamics' rule) clears `ok` (false when M is not positive
    definite), or pivot(j) gives the line that checks d_j. Returns (lines, {(i, j): name of L_ij}, operation count)."""
    n, Ms = model.n, model.M_kappa
    nz = {(i, j) for i in range(n) for j in range(n) if Ms[i, j] != 0}
    lines, L, ops = [], {}, 0
    for j in range(n):
        ks = [k for k in range(j) if (j, k) in L]
        lines.append(f"  const {typ} d_{j} = " + " - ".join([f"M[{j + n * j}]"] + [f"l_{j}_{k}*u_{j}_{k}" for k in ks])
                     + ";")
        lines.append(pivot(j) if pivot else f"  {ok} &= pivot_ok(d_{j}, M[{j + n * j}]);")
        lines.append(f"  const {typ} r_{j} = 1.0/d_{j};")
        ops += 2 * len(ks) + 1
        for i in range(j + 1, n):
            ki = [k for k in ks if (i, k) in L]
            if (i, j) not in nz and not ki:
                continue
            terms = [f"l_{i}_{k}*u_{j}_{k}" for k in ki]
            expr = (" - ".join([f"M[{i + n * j}]"] + terms) if (i, j) in nz else "-(" + " + ".join(terms) + ")")
            L[i, j] = f"l_{i}_{j}"
            lines.append(f"  const {typ} u_{i}_{j} = {expr};")
            lines.append(f"  const {typ} l_{i}_{j} = u_{i}_{j}*r_{j};")
            ops += 2 * len(ki) + 1
    return lines, L, ops


def _substitution_lines(n, L, row, scale, loop=""):
    """x <- L^-T D^-1 L^-1 x on rows row(i) (text), the scaling by D^-1 between the sweeps the
    lines scale(i) give."""
    lines = []
    for i in range(n):
        ks = [k for k in range(i) if (i, k) in L]
        if ks:
            lines.append(f"{loop}{row(i)} -= " + " + ".join(f"{L[i, k]}*{row(k)}" for k in ks) + ";")
    lines += [line for i in range(n) for line in scale(i)]
    for i in reversed(range(n)):
        ks = [k for k in range(i + 1, n) if (k, i) in L]
        if ks:
            lines.append(f"{loop}{row(i)} -= " + " + ".join(f"{L[k, i]}*{row(k)}" for k in ks) + ";")
    return lines


def _sparse_substitution_lines(n, L, nz, negate):
    """The substitutions of _substitution_lines on the rows Z[i][c] of many right-hand sides (columns c),
    each entry where it may not be zero only: nz[i] the columns where row i of the right-hand sides may
    not be zero (structurally), followed through the sweeps (fill-in); each row's update over runs of
    columns with the same rows to subtract, a loop each (vectorised across them). Scaled by -D^-1 on
    the columns below `negate`, by D^-1 on the others."""
    P = [set(nz[i]) for i in range(n)]
    lines = []

    def update(i, ks, coef):
        by_col = {c: tuple(k for k in ks if c in P[k]) for c in sorted(set().union(*(P[k] for k in ks)))}
        cols = [c for c in by_col if by_col[c]]
        runs = []
        for c in cols:
            if runs and runs[-1][1] == c and by_col[runs[-1][0]] == by_col[c]:
                runs[-1][1] = c + 1
            else:
                runs.append([c, c + 1])
        for a, b in runs:
            terms = " + ".join(f"{coef(k)}*Z[{k}][c]" for k in by_col[a])
            lines.append(f"for (int c = {a}; c < {b}; ++c) Z[{i}][c] -= {terms};")
        P[i] |= set(cols)

    def scale(i):
        for a, b, sign in ((0, negate, "-"), (negate, 3 * n, "")):
            cols = sorted(c for c in P[i] if a <= c < b)
            start = None
            for j, c in enumerate(cols):
                start = c if start is None else start
                if j + 1 == len(cols) or cols[j + 1] != c + 1:
                    lines.append(f"for (int c = {start}; c < {c + 1}; ++c) Z[{i}][c] *= {sign}r_{i};")
                    start = None

    for i in range(n):
        ks = [k for k in range(i) if (i, k) in L]
        if ks:
            update(i, ks, lambda k: L[i, k])
    for i in range(n):
        scale(i)
    for i in reversed(range(n)):
        ks = [k for k in range(i + 1, n) if (k, i) in L]
        if ks:
            update(i, ks, lambda k: L[k, i])
    return lines


def emit_forward_derivatives(model: SymbolicModel):
    """The forward dynamics' derivatives in one straight-line pass, as two EmittedFunctions:
    ``forward_derivatives(p, q, qd, tau, dqdd_dq, dqdd_dqd, Minv, qdd)`` (one state; results n x n
    column-major, qdd (n) written unless null) and ``forward_derivatives4(p, q, qd, tau, dqdd_dq,
    dqdd_dqd, Minv)`` (four states, one per lane of a vector: q, qd, tau (4, n) row-major, results
    (4, n, n) row-major as numpy's), both returning false when M is not positive definite (results
    undefined). One template on the scalar type does both: M and h (dynamics_t), M's LDL^T factor
    (structural zeros skipped), qdd = M^-1 (tau - h), the inverse dynamics' derivatives at qdd
    (derivatives_t) written into the rows of [dtau/dq, dtau/dqd, 1] (n x 3n), and the 3n right-hand
    sides solved with the same factor, -M^-1 folded into the scaling: [dqdd/dq, dqdd/dqd, M^-1]."""
    n = model.n
    W = 3 * n
    fac, L, ops = _ldl_lines(model, "T", "ok")
    sub_x = _substitution_lines(n, L, lambda i: f"x[{i}]", lambda i: [f"x[{i}] *= r_{i};"])
    # the rows of the 3n columns; dtau/dq and dtau/dqd scaled by -D^-1: the minus sign of -M^-1 dtau/dx.
    # One state: a loop over all columns each (vectorised across them); four states (a vector per
    # entry already): over the columns where they may not be zero only (dtau/dq's and dtau/dqd's
    # structural zeros, the identity's, and their fill-in), the same values
    sub_z = _substitution_lines(n, L, lambda i: f"Z[{i}][c]", lambda i: [
        f"for (int c = 0; c < {2 * n}; ++c) Z[{i}][c] *= -r_{i};",
        f"for (int c = {2 * n}; c < {W}; ++c) Z[{i}][c] *= r_{i};"], loop=f"for (int c = 0; c < {W}; ++c) ")
    dq, dqd = model.inverse_dynamics_derivatives
    nz = [{c for c in range(n) if dq[i, c] != 0} | {n + c for c in range(n) if dqd[i, c] != 0} | {2 * n + i}
          for i in range(n)]
    sparse = _sparse_substitution_lines(n, L, nz, 2 * n)
    K = 2 * len(_trig_joints(model))
    body = [f"  T M[{n * n}], h[{n}], x[{n}]" + (f", sc[{K}];" if K else ";"),
            "  dynamics_t(p, q, qd, M, h" + (", sc);" if K else ");"), "  bool ok = true;"] + fac
    body += ["  if (!ok) return false;", f"  for (int i = 0; i < {n}; ++i) x[i] = tau[i] - h[i];"]
    body += ["  " + line for line in sub_x]
    body += [f"  derivatives_t<T, {W}, 1>(p, {'sc' if K else 'nullptr'}, q, qd, x, &Z[0][0], &Z[0][{n}], M);",
             f"  for (int i = 0; i < {n}; ++i)", f"    for (int c = 0; c < {n}; ++c) Z[i][{2 * n} + c] = "
             "T{} + (i == c ? 1.0 : 0.0);"]
    body += ["  if constexpr (sizeof(T) == sizeof(double)) {"] + ["    " + line for line in sub_z]
    body += ["  } else {"] + ["    " + line for line in sparse] + ["  }"]
    body += [f"  for (int i = 0; i < {n}; ++i) qdd[i] = x[i];", "  return true;"]
    template = (f"template <class T>\n{_INLINE} bool forward_derivatives_t(const double* p, const T* q, const T* qd, "
                f"const T* tau, T (*Z)[{W}], T* qdd) {{\n" + "\n".join(body) + "\n}\n")
    one = "\n".join([
        f"  double Z[{n}][{W}], x[{n}];",
        "  if (!forward_derivatives_t(p, q, qd, tau, Z, qdd ? qdd : x)) return false;",
        f"  for (int i = 0; i < {n}; ++i)",
        f"    for (int c = 0; c < {n}; ++c) {{",
        f"      dqdd_dq[i * {n} + c] = Z[i][c];",
        f"      dqdd_dqd[i * {n} + c] = Z[i][{n} + c];",
        f"      Minv[i * {n} + c] = Z[i][{2 * n} + c];",
        "    }",
        "  return true;"])
    four = "\n".join([
        f"  d4 Q[{n}], QD[{n}], TAU[{n}], Z[{n}][{W}], x[{n}];",
        f"  for (int i = 0; i < {n}; ++i)",
        "    for (int l = 0; l < 4; ++l) {",
        f"      Q[i][l] = q[l * {n} + i];",
        f"      QD[i][l] = qd[l * {n} + i];",
        f"      TAU[i][l] = tau[l * {n} + i];",
        "    }",
        "  if (!forward_derivatives_t(p, Q, QD, TAU, Z, x)) return false;"]
        + [f"  store4(Z[{k // n}][{m * n + k % n}], Z[{(k + 1) // n}][{m * n + (k + 1) % n}], "
           f"Z[{(k + 2) // n}][{m * n + (k + 2) % n}], Z[{(k + 3) // n}][{m * n + (k + 3) % n}], {out} + {k}, {n * n});"
           for m, out in enumerate(("dqdd_dq", "dqdd_dqd", "Minv")) for k in range(0, n * n - 3, 4)]
        + ([f"  for (int l = 0; l < 4; ++l)",
            f"    for (int k = {n * n // 4 * 4}; k < {n * n}; ++k) {{",
            f"      dqdd_dq[l * {n * n} + k] = Z[k / {n}][k % {n}][l];",
            f"      dqdd_dqd[l * {n * n} + k] = Z[k / {n}][{n} + k % {n}][l];",
            f"      Minv[l * {n * n} + k] = Z[k / {n}][{2 * n} + k % {n}][l];",
            "    }"] if n * n % 4 else [])
        + ["  return true;"])
    sub_ops = sum((line.count("*") + line.count("-=")) * _trips(line) for line in sparse)
    return [EmittedFunction(FORWARD[0], FORWARD[1], one, ops + sub_ops, template, "bool"),
            EmittedFunction(FORWARD4[0], FORWARD4[1], four, ops + sub_ops, "", "bool")]


def _trips(loop: str) -> int:
    """The number of iterations of an emitted `for (int c = a; c < b; ++c)`."""
    a, b = re.match(r"for \(int c = (\d+); c < (\d+);", loop).groups()
    return int(b) - int(a)


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
    n = model.n
    lines, L, ops = _ldl_lines(model, "double", None, pivot=lambda j: f"  if (!(d_{j} > 0.0)) return false;")
    # L y = b, then x = L^-T D^-1 y, in place
    lines += _substitution_lines(n, L, lambda i: f"x[{i}]", lambda i: [f"  x[{i}] *= r_{i};"], loop="  ")
    ops += 4 * len(L) + n   # a multiply and an add per entry of L in each sweep, and the scaling
    lines.append("  return true;")
    return "\n".join(lines), ops
