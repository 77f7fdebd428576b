"""Symbolic Lagrange-Euler dynamics of a serial R/P robot from its DH and CoM tables.

Only the joint types and the angle columns (DH theta and alpha, CoM theta and
alpha) are fixed: they are the robot's *structure*. Every length (DH and CoM
d, a), mass, inertia entry, armature, friction coefficient (viscous K, Coulomb
F_c and its width v_c) and the gravity vector (in frame 0) stays a symbol, so
generated code reads them at run time.

Conventions are those of ``coopsim.Robot`` (``cpp/include/coopsim/robot.hpp``):
A_i = Rz(theta_i [+ q_i]) Tz(d_i [+ q_i]) Tx(a_i) Rx(alpha_i); the CoM row of
link i takes frame i-1 to the CoM frame of link i with q_i in the same slot;
the inertia tensor is about the CoM in the CoM frame.

Internally cos and sin of each revolute joint's DH angle theta_i + q_i are
the symbols ``c_i`` and ``s_i``, and a prismatic joint enters as e_i = d_i +
q_i (frames) and ec_i = dc_i + q_i (its CoM), which keeps every expression
polynomial in them; derivatives use d c_i/dq_i = -s_i, d s_i/dq_i = c_i and
d e_i/dq_i = d ec_i/dq_i = 1. Derivation
(tractable at 6 DOF): row i of M is assembled from the link Jacobians
expressed in DH frame i, where joint i's axis and origin do not depend on
q_i, so M_ij only contains q_(i+1) .. q_n and no identity c^2 + s^2 = 1 has
to be found by simplification:

    M = sum_l m_l Jv_l^T Jv_l + Jw_l^T R_l I_l R_l^T Jw_l
    Gamma_ijk = (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k) / 2,  C_kj = sum_i Gamma_ijk qd_i
    G = dV/dq,  V = -sum_l m_l g . c_l
    M += diag(armature),  friction = K qd + F_c tanh(qd / v_c)

Emitted form (``SymbolicModel.form``): on robots like the SCARAs each entry is
expanded, reduced with s_i^2 = 1 - c_i^2 and collected by monomial in the
joint functions, with every parameter polynomial named once (kappa_m); on
general arms, where that expansion grows, the Jacobian products are kept.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import cached_property

import sympy as sp

__all__ = ["Structure", "SymbolicModel", "exact_angle", "structure_of", "derive"]

# per link block of the parameter vector (cpp/include/coopsim/generated.hpp)
PARAMS_PER_LINK = 19
OFFSETS = dict(dh_theta=0, d=1, a=2, dh_alpha=3, com_theta=4, dc=5, ac=6, com_alpha=7, m=8,
               Ixx=9, Iyy=10, Izz=11, Ixy=12, Ixz=13, Iyz=14, K=15, Ia=16, Fc=17, vc=18)


class Coulomb(sp.Function):
    """Coulomb(F_c, qd, v_c) = F_c tanh(qd / v_c), emitted so that a joint without Coulomb
    friction (F_c = 0) costs no tanh."""

    nargs = 3

    def _eval_rewrite_as_tanh(self, Fc, qd, vc, **kwargs):
        return Fc * sp.tanh(qd / vc)


class CoulombSlope(sp.Function):
    """CoulombSlope(F_c, qd, v_c) = d Coulomb / d qd = F_c / v_c (1 - tanh^2(qd / v_c)), emitted as a
    call of the generated file's coulomb_slope (no tanh when F_c = 0)."""

    nargs = 3

    def _eval_rewrite_as_tanh(self, Fc, qd, vc, **kwargs):
        return Fc / vc * (1 - sp.tanh(qd / vc) ** 2)


def exact_angle(x: float) -> sp.Expr:
    """Exact sympy value of a structural angle (rad): k pi / 12 when within 1e-12, else the float."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"angle must be finite, got {x!r}")
    k = round(x / (math.pi / 12))
    if abs(x - k * math.pi / 12) <= 1e-12:
        return sp.Rational(k, 12) * sp.pi
    return sp.Float(repr(x), 17)


@dataclass(frozen=True)
class Structure:
    """What generated code is specialised to: joint types and the angle columns.

    name: identifier used in generated C++ (letters, digits, underscore).
    joint_types: e.g. "RRPRRP".
    angles: one (dh theta, dh alpha, com theta, com alpha) tuple per link, rad.
    """

    name: str
    joint_types: str
    angles: tuple

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"name must be a C identifier, got {self.name!r}")
        if not self.joint_types or any(c not in "RP" for c in self.joint_types):
            raise ValueError(f"joint_types must be a non-empty string of 'R'/'P', got {self.joint_types!r}")
        angles = tuple(tuple(float(v) for v in row) for row in self.angles)
        if len(angles) != len(self.joint_types) or any(len(r) != 4 for r in angles):
            raise ValueError(f"angles must have shape ({len(self.joint_types)}, 4), one row per joint")
        if not all(math.isfinite(v) for r in angles for v in r):
            raise ValueError("angles must be finite")
        object.__setattr__(self, "angles", angles)

    @property
    def dof(self) -> int:
        return len(self.joint_types)


def structure_of(robot, name: str | None = None) -> Structure:
    """Structure of a ``coopsim.Robot`` (or any object with dh, com, joint_types, name)."""
    dh, com = robot.dh, robot.com
    angles = tuple((float(dh[k][0]), float(dh[k][3]), float(com[k][0]), float(com[k][3]))
                   for k in range(len(robot.joint_types)))
    return Structure(name or robot.name, robot.joint_types, angles)


def _trig_const(fn, angle):
    """cos or sin of a structural angle: exact when rational (0, +-1), else a 17-digit float
    (sqrt(3)/2 of 30 degrees), so that expressions hold no irrational constants."""
    v = fn(angle)
    return v if v.is_Rational else sp.Float(v.evalf(20), 17)


def _rz(c, s):
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _rx(c, s):
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def _cross(u, v):
    return sp.Matrix([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]])


# terms after expansion (upper bound) above which the collected form is not tried:
# the SCARAs need about 5e3, a PUMA-like arm 5e4, arms with general angles 1e5 and more
_EXPAND_LIMIT = 20000


def _expanded_terms(e) -> int:
    """Upper bound of the number of terms of sympy.expand(e), without expanding."""
    if e.is_Add:
        return sum(_expanded_terms(a) for a in e.args)
    if e.is_Mul:
        out = 1
        for a in e.args:
            out *= _expanded_terms(a)
        return out
    if e.is_Pow and e.exp.is_Integer and e.exp > 0:
        return _expanded_terms(e.base) ** int(e.exp)
    return 1


def _cse_ops(exprs) -> int:
    reps, red = sp.cse(exprs, order="canonical")
    return int(sum(sp.count_ops(e) for _, e in reps) + sum(sp.count_ops(e) for e in red))


def _dot(u, v):
    return sum((u[i] * v[i] for i in range(3)), sp.Integer(0))


@dataclass
class _Link:
    kind: str
    q: sp.Symbol
    qd: sp.Symbol
    c: sp.Expr       # cos(theta + q) (revolute: symbol c_i; prismatic: constant)
    s: sp.Expr
    ca: sp.Expr      # cos/sin of alpha (exact)
    sa: sp.Expr
    d: sp.Expr       # d (+ q for prismatic)
    a: sp.Symbol
    Rc: sp.Matrix    # CoM frame rotation in frame i (constant)
    pc: sp.Matrix    # CoM position in frame i (constant)
    m: sp.Symbol
    I: sp.Matrix
    K: sp.Symbol
    Ia: sp.Symbol    # armature
    Fc: sp.Symbol    # Coulomb friction and its width
    vc: sp.Symbol


class SymbolicModel:
    """Lagrange-Euler model of one structure with symbolic parameters.

    Attributes (sympy; cos/sin of joint i are the symbols c_i, s_i, see
    ``in_trig``): M (n, n) inertia matrix, armature included; C (n,)
    Coriolis/centrifugal vector C(q, qd) qd; C_matrix (n, n) Christoffel form;
    G (n,) gravity vector; friction (n,) K qd + F_c tanh(qd / v_c); q, qd joint symbols; parameters: symbol -> index in
    the robot's parameter vector. The *_kappa forms name each parameter
    polynomial once (``kappa``), as the emitted code does.
    """

    def __init__(self, structure: Structure):
        self.structure = structure
        n = self.n = structure.dof
        self.q = [sp.Symbol(f"q_{i + 1}", real=True) for i in range(n)]
        self.qd = [sp.Symbol(f"qd_{i + 1}", real=True) for i in range(n)]
        self.g = sp.Matrix(sp.symbols("g_x g_y g_z", real=True))
        self.parameters: dict[sp.Symbol, int] = {}
        self.trig: dict[sp.Symbol, tuple[int, float]] = {}  # c_i/s_i -> (joint, DH theta offset)
        self.slides: dict[sp.Symbol, tuple] = {}  # e_i = d_i + q_i of prismatic joints -> (joint, d_i)
        base = PARAMS_PER_LINK * n
        for j, gs in enumerate(self.g):
            self.parameters[gs] = base + j
        self.links = [self._link(i) for i in range(n)]

    # ---------------------------------------------------------------- tables
    def _sym(self, name, i, key):
        s = sp.Symbol(f"{name}_{i + 1}", real=True)
        self.parameters[s] = PARAMS_PER_LINK * i + OFFSETS[key]
        return s

    def _link(self, i):
        kind = self.structure.joint_types[i]
        th, al, thc, alc = self.structure.angles[i]
        th_x, al_x, thc_x, alc_x = (exact_angle(v) for v in (th, al, thc, alc))
        q, qd = self.q[i], self.qd[i]
        d, a = self._sym("d", i, "d"), self._sym("a", i, "a")
        dc, ac = self._sym("dc", i, "dc"), self._sym("ac", i, "ac")
        m, K = self._sym("m", i, "m"), self._sym("K", i, "K")
        Ia, Fc, vc = self._sym("Ia", i, "Ia"), self._sym("Fc", i, "Fc"), self._sym("vc", i, "vc")
        Ixx, Iyy, Izz = (self._sym(k, i, k) for k in ("Ixx", "Iyy", "Izz"))
        Ixy, Ixz, Iyz = (self._sym(k, i, k) for k in ("Ixy", "Ixz", "Iyz"))
        I = sp.Matrix([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
        if kind == "R":
            c, s = sp.Symbol(f"c_{i + 1}", real=True), sp.Symbol(f"s_{i + 1}", real=True)
            self.trig[c] = (i, th)
            self.trig[s] = (i, th)
            dq = d
        else:
            c, s = _trig_const(sp.cos, th_x), _trig_const(sp.sin, th_x)
            # q enters as d + q (frames) and dc + q (the CoM) only: one symbol each
            dq = sp.Symbol(f"e_{i + 1}", real=True)
            self.slides[dq] = (i, d)
            self.slides[sp.Symbol(f"ec_{i + 1}", real=True)] = (i, dc)
        ca, sa = _trig_const(sp.cos, al_x), _trig_const(sp.sin, al_x)
        # CoM frame of link i in DH frame i: constant, since q enters both
        # rows in the same slot and Rz, Tz commute with each other
        dth = thc_x - th_x
        cd, sd = _trig_const(sp.cos, dth), _trig_const(sp.sin, dth)
        rx_t = _rx(ca, sa).T
        Rc = rx_t * _rz(cd, sd) * _rx(_trig_const(sp.cos, alc_x), _trig_const(sp.sin, alc_x))
        pc = rx_t * sp.Matrix([ac * cd - a, ac * sd, dc - d])
        return _Link(kind, q, qd, c, s, ca, sa, dq, a, Rc, pc, m, I, K, Ia, Fc, vc)

    def _chain(self, i):
        """Frames i..n expressed in DH frame i (0 = base): lists R[k], p[k] for k = i..n."""
        R, p = {i: sp.eye(3)}, {i: sp.zeros(3, 1)}
        for k in range(i + 1, self.n + 1):
            L = self.links[k - 1]
            Rl = _rz(L.c, L.s) * _rx(L.ca, L.sa)
            pl = sp.Matrix([L.a * L.c, L.a * L.s, L.d])
            R[k] = R[k - 1] * Rl
            p[k] = p[k - 1] + R[k - 1] * pl
        return R, p

    # ------------------------------------------------------------- dynamics
    @cached_property
    def M_jacobian(self) -> sp.Matrix:
        """M from the link Jacobians, unexpanded (the derivation's direct result)."""
        n = self.n
        M = sp.zeros(n, n)
        for i in range(1, n + 1):  # row i (1-based joint i) in DH frame i
            R, p = self._chain(i)
            Li = self.links[i - 1]
            # joint i's axis z_(i-1) and origin o_(i-1) seen from frame i
            axes = {i: (sp.Matrix([0, Li.sa, Li.ca]), -sp.Matrix([Li.a, Li.sa * Li.d, Li.ca * Li.d]))}
            for j in range(i + 1, n + 1):
                axes[j] = (R[j - 1][:, 2], p[j - 1])
            coms = {}
            for l in range(i, n + 1):
                L = self.links[l - 1]
                if l == i:  # constant in frame i
                    coms[l] = (p[l] + R[l] * L.pc, R[l] * L.Rc)
                else:
                    coms[l] = self._com((R[l], p[l], R[l - 1], p[l - 1]), l)
            for j in range(i, n + 1):
                total = sp.Integer(0)
                for l in range(j, n + 1):
                    L = self.links[l - 1]
                    cl, Rcl = coms[l]
                    Jv, Jw = [], []
                    for jj in (i, j):
                        z, o = axes[jj]
                        if self.links[jj - 1].kind == "R":
                            Jv.append(_cross(z, cl - o))
                            Jw.append(Rcl.T * z)  # in the CoM frame
                        else:
                            Jv.append(z)
                            Jw.append(None)
                    term = L.m * _dot(Jv[0], Jv[1])
                    if Jw[0] is not None and Jw[1] is not None:
                        term += _dot(Jw[0], L.I * Jw[1])
                    total += term
                M[i - 1, j - 1] = total
                M[j - 1, i - 1] = total
        return M

    @cached_property
    def potential_energy(self) -> sp.Expr:
        """V = -sum m_l g . c_l, g in frame 0 (J)."""
        R, p = self._chain(0)
        V = sp.Integer(0)
        for l in range(1, self.n + 1):
            L = self.links[l - 1]
            V -= L.m * _dot(self.g, self._com((R[l], p[l], R[l - 1], p[l - 1]), l)[0])
        return V

    def diff_q(self, expr: sp.Expr, k: int) -> sp.Expr:
        """d expr / d q_k (k 0-based), chain rule through c_k, s_k."""
        L = self.links[k]
        if L.kind == "R":
            return -L.s * sp.diff(expr, L.c) + L.c * sp.diff(expr, L.s)
        return sp.diff(expr, L.d) + sp.diff(expr, self._ec(k))  # e_k = d_k + q_k, ec_k = dc_k + q_k

    def _ec(self, k):
        return sp.Symbol(f"ec_{k + 1}", real=True)

    def _com(self, frames, l):
        """CoM of link l >= 1 in the chain's frame, from frame l (revolute) or frame l-1 (prismatic,
        so that dc + q stays one symbol); frames = (R_l, p_l, R_(l-1), p_(l-1)) in that frame.
        Returns (position, rotation of the CoM frame)."""
        L = self.links[l - 1]
        R_l, p_l, R_prev, p_prev = frames
        if L.kind == "R":
            return p_l + R_l * L.pc, R_l * L.Rc
        th, _, thc, _ = (exact_angle(v) for v in self.structure.angles[l - 1])
        ac = sp.Symbol(f"ac_{l}", real=True)
        cd, sd = _trig_const(sp.cos, thc - th), _trig_const(sp.sin, thc - th)
        local = _rz(_trig_const(sp.cos, th), _trig_const(sp.sin, th)) * sp.Matrix([ac * cd, ac * sd, self._ec(l - 1)])
        return p_prev + R_prev * local, R_l * L.Rc

    # ---- collected forms: polynomials in c_k, s_k (s_k of degree <= 1) and
    # prismatic e_k, ec_k whose coefficients are parameter polynomials, each named
    # once as a symbol kappa_m (see `kappa`); this is what is emitted.
    @cached_property
    def _gens(self):
        gens = []
        for k, L in enumerate(self.links):
            gens.extend([L.c, L.s] if L.kind == "R" else [L.d, self._ec(k)])
        return gens

    @cached_property
    def kappa(self) -> dict:
        """kappa_m -> parameter polynomial, in order of first use."""
        return {}

    def _kappa_of(self, coeff):
        """coeff (a parameter polynomial) as rational * kappa_m, or itself if a single product."""
        if not coeff.is_Add:
            return coeff
        content, prim = coeff.as_content_primitive()
        if prim.could_extract_minus_sign():
            content, prim = -content, -prim
        lookup = self.__dict__.setdefault("_kappa_lookup", {})
        sym = lookup.get(prim)
        if sym is None:
            sym = sp.Symbol(f"kappa_{len(lookup)}", real=True)
            lookup[prim] = sym
            self.kappa[sym] = prim
        return content * sym

    def _collect_impl(self, expr, name_coefficients=False):
        """expr reduced with s_k^2 = 1 - c_k^2 and collected by monomial in the joint functions."""
        gens = self._gens
        trig_pairs = [(gens.index(L.c), gens.index(L.s)) for L in self.links if L.kind == "R"]
        index = {g: k for k, g in enumerate(gens)}
        parts = {}  # monomial -> list of coefficient terms (summed once, at the end)
        for term in sp.Add.make_args(sp.expand(expr)):
            mon = [0] * len(gens)
            rest = []
            for f in sp.Mul.make_args(term):
                base, e = f.as_base_exp()
                k = index.get(base)
                if k is None:
                    rest.append(f)
                else:
                    mon[k] += int(e)
            parts.setdefault(tuple(mon), []).append(sp.Mul(*rest))
        terms = {mon: sp.Add(*c) for mon, c in parts.items()}
        for ic, is_ in trig_pairs:  # s^e -> s^(e-2) (1 - c^2), repeated
            changed = True
            while changed:
                changed = False
                for mon in sorted(terms):
                    if mon[is_] >= 2:
                        coeff = terms.pop(mon)
                        low = list(mon)
                        low[is_] -= 2
                        high = list(low)
                        high[ic] += 2
                        low, high = tuple(low), tuple(high)
                        terms[low] = terms.get(low, 0) + coeff
                        terms[high] = terms.get(high, 0) - coeff
                        changed = True
        out = sp.Integer(0)
        for mon in sorted(terms, reverse=True):
            coeff = sp.expand(terms[mon])
            if coeff == 0:
                continue
            if name_coefficients:
                coeff = self._kappa_of(coeff)
            out += coeff * sp.Mul(*[g ** e for g, e in zip(gens, mon)])
        return out

    @cached_property
    def form(self) -> str:
        """'collected' or 'jacobian': the form everything is derived and emitted in.

        Collecting by trig monomials pays off when the axes are mostly parallel
        or perpendicular to few others (SCARAs: fewer operations); on general
        arms (e.g. alpha = +-pi/2 throughout) the expanded polynomials grow
        faster than the Jacobian products, so the smaller M after cse decides.
        """
        n, Mj = self.n, self.M_jacobian
        # expanding is only tried when its size, bounded without expanding, stays moderate
        if sum(_expanded_terms(Mj[i, j]) for i in range(n) for j in range(i, n)) > _EXPAND_LIMIT:
            return "jacobian"
        M = sp.zeros(n, n)
        for i in range(n):
            for j in range(i, n):
                M[i, j] = M[j, i] = self._collect_impl(Mj[i, j], name_coefficients=True)
        upper = [M[i, j] for i in range(n) for j in range(i, n)]
        collected = _cse_ops(upper) + _cse_ops(list(self.kappa.values()))
        jacobian = _cse_ops([Mj[i, j] for i in range(n) for j in range(i, n)])
        if collected <= jacobian:
            self.__dict__["M_kappa"] = M
            return "collected"
        self.kappa.clear()
        self.__dict__.pop("_kappa_lookup", None)
        return "jacobian"

    def _collect(self, expr, name_coefficients=False):
        if self.form == "jacobian":
            return expr
        return self._collect_impl(expr, name_coefficients)

    @cached_property
    def M_kappa(self) -> sp.Matrix:
        """M collected (coefficients named by kappa), or M_jacobian, see `form`."""
        if self.form == "jacobian":
            return self.M_jacobian
        return self.__dict__["M_kappa"]

    @cached_property
    def G_kappa(self) -> sp.Matrix:
        self.M_kappa  # kappa numbering: M's coefficients first, always
        V = self._collect(self.potential_energy, name_coefficients=True)
        return sp.Matrix([self._collect(self.diff_q(V, k)) for k in range(self.n)])

    @cached_property
    def dM(self) -> list:
        """[dM/dq_k for k in 0..n-1] in kappa form, each symmetric (n, n)."""
        n, M = self.n, self.M_kappa
        out = []
        for k in range(n):
            D = sp.zeros(n, n)
            for i in range(n):
                for j in range(i, n):
                    D[i, j] = D[j, i] = self._collect(self.diff_q(M[i, j], k))
            out.append(D)
        return out

    @cached_property
    def christoffel(self) -> dict:
        """{(i, j, k): Gamma_ijk} for i <= j, kappa form; Gamma_ijk = Gamma_jik."""
        n, D = self.n, self.dM
        return {(i, j, k): self._collect((D[i][k, j] + D[j][k, i] - D[k][i, j]) / 2)
                for k in range(n) for i in range(n) for j in range(i, n)}

    @cached_property
    def C_matrix_kappa(self) -> sp.Matrix:
        n, Gm, qd = self.n, self.christoffel, self.qd
        C = sp.zeros(n, n)
        for k in range(n):
            for j in range(n):
                C[k, j] = sum((Gm[min(i, j), max(i, j), k] * qd[i] for i in range(n)), sp.Integer(0))
        return C

    @cached_property
    def C_kappa(self) -> sp.Matrix:
        """C(q, qd) qd = sum_ij Gamma_ijk qd_i qd_j, each pair once."""
        n, Gm, qd = self.n, self.christoffel, self.qd
        out = []
        for k in range(n):
            v = sp.Integer(0)
            for i in range(n):
                for j in range(i, n):
                    g = Gm[i, j, k]
                    if g != 0:
                        v += (g if i == j else 2 * g) * qd[i] * qd[j]
            out.append(v)
        return sp.Matrix(out)

    @cached_property
    def M_links(self) -> sp.Matrix:
        """M = sum_l m_l Jv_l^T Jv_l + Jw_l^T I_l Jw_l with every Jacobian in the base frame
        (Jw projected on the CoM frame); shares its terms with C_links and G_links. Emitted for
        M in the Jacobian form (general arms: up to half the operations of M_jacobian there)."""
        n = self.n
        R, p = self._chain(0)
        M = sp.zeros(n, n)
        for l in range(1, n + 1):
            L = self.links[l - 1]
            cl, Rc = self._com((R[l], p[l], R[l - 1], p[l - 1]), l)
            Jv, Jw = [], []
            for k in range(l):
                z, o = R[k][:, 2], p[k]
                revolute = self.links[k].kind == "R"
                Jv.append(_cross(z, cl - o) if revolute else z)
                Jw.append(Rc.T * z if revolute else None)
            for i in range(l):
                for j in range(i, l):
                    t = L.m * _dot(Jv[i], Jv[j])
                    if Jw[i] is not None and Jw[j] is not None:
                        t += _dot(Jw[i], L.I * Jw[j])
                    M[i, j] += t
        for i in range(n):
            for j in range(i):
                M[i, j] = M[j, i]
        return M

    @cached_property
    def G_links(self) -> sp.Matrix:
        """G = dV/dq = -sum_l m_l Jv_l^T g through the CoM Jacobians (dc_l/dq = Jv_l), in the
        base frame; shares its terms with C_links. Emitted for G in the Jacobian form."""
        n = self.n
        R, p = self._chain(0)
        out = [sp.Integer(0)] * n
        for l in range(1, n + 1):
            L = self.links[l - 1]
            cl, _ = self._com((R[l], p[l], R[l - 1], p[l - 1]), l)
            for k in range(l):
                z, o = R[k][:, 2], p[k]
                Jv = _cross(z, cl - o) if self.links[k].kind == "R" else z
                out[k] -= L.m * _dot(Jv, self.g)
        return sp.Matrix(out)

    @cached_property
    def C_links(self) -> sp.Matrix:
        """C(q, qd) qd link by link, the same Lagrangian terms without Christoffel symbols:

            sum_l m_l Jv_l^T (dJv_l/dt qd) + Jw_l^T (I_l (dJw_l/dt qd) + w_l x I_l w_l)

        (dM/dt qd - dT/dq with M = sum_l m_l Jv_l^T Jv_l + Jw_l^T I_l Jw_l). dJ/dt qd is the
        acceleration of the CoM (and angular acceleration) at qdd = 0, obtained from
        dz/dt = w x z joint after joint in the base frame; I_l in the CoM frame. Emitted for C
        in the Jacobian form, where it takes a fraction of the Christoffel sums' operations."""
        n, qd = self.n, self.qd
        R, p = self._chain(0)
        zero = sp.zeros(3, 1)
        w, wd, ao = zero, zero, zero  # of link l-1; ao: acceleration of its point o_(l-1)
        out = [sp.Integer(0)] * n
        for l in range(1, n + 1):
            L = self.links[l - 1]
            z = R[l - 1][:, 2]
            if L.kind == "R":
                w_l, wd_l = w + z * qd[l - 1], wd + _cross(w, z) * qd[l - 1]
                ab = ao
            else:  # o_(l-1) as a point of link l slides along z
                w_l, wd_l = w, wd
                ab = ao + 2 * _cross(w, z) * qd[l - 1]
            cl, Rc = self._com((R[l], p[l], R[l - 1], p[l - 1]), l)
            rc, r = cl - p[l - 1], p[l] - p[l - 1]
            ac = ab + _cross(wd_l, rc) + _cross(w_l, _cross(w_l, rc))  # dJv_l/dt qd
            wc, wdc = Rc.T * w_l, Rc.T * wd_l
            nc = L.I * wdc + _cross(wc, L.I * wc)  # moment about the CoM, CoM frame
            for k in range(l):
                zk, ok = R[k][:, 2], p[k]
                if self.links[k].kind == "R":
                    out[k] += L.m * _dot(_cross(zk, cl - ok), ac) + _dot(Rc.T * zk, nc)
                else:
                    out[k] += L.m * _dot(zk, ac)
            ao = ab + _cross(wd_l, r) + _cross(w_l, _cross(w_l, r))
            w, wd = w_l, wd_l
        return sp.Matrix(out)

    @cached_property
    def qdd(self) -> list:
        """Joint acceleration symbols qdd_1 .. qdd_n (the derivatives' argument)."""
        return [sp.Symbol(f"qdd_{i + 1}", real=True) for i in range(self.n)]

    @cached_property
    def inverse_dynamics_derivatives(self):
        """(dtau_dq, dtau_dqd), (n, n) each, [i, k] = d tau_i / d x_k, of the inverse dynamics
        tau = M(q) qdd + C(q, qd) qd + G(q) + K qd + F_c tanh(qd / v_c), in kappa form (qdd the
        symbols ``qdd``):

            d tau_i / d q_k  = sum_j dM_ij/dq_k qdd_j + sum_(a <= b) dGamma_abi/dq_k qd_a qd_b (x2 off
                               the diagonal) + d^2 V / dq_i dq_k
            d tau_i / d qd_k = 2 C_ik (the Christoffel matrix: C qd is quadratic in qd) + on the
                               diagonal K_i + F_c,i / v_c,i (1 - tanh^2(qd_i / v_c,i))

        The Christoffel symbols are differentiated one by one (each small) rather than C qd as a
        whole: fewer operations after cse and a third of the time. Tractable in the collected form
        (the SCARAs: seconds); in the Jacobian form of general arms it grows large (not emitted)."""
        n, qd, qdd = self.n, self.qd, self.qdd
        D, Gm, G = self.dM, self.christoffel, self.G_kappa
        H = {}  # the Hessian of V, symmetric: each entry once
        for i in range(n):
            for k in range(i, n):
                H[i, k] = H[k, i] = self._collect(self.diff_q(G[i], k))
        dq = sp.zeros(n, n)
        for i in range(n):
            for k in range(n):
                v = sum((D[k][i, j] * qdd[j] for j in range(n)), sp.Integer(0)) + H[i, k]
                for a in range(n):
                    for b in range(a, n):
                        g = Gm[a, b, i]
                        if g == 0:
                            continue
                        dg = self._collect(self.diff_q(g, k))
                        if dg != 0:
                            v += (dg if a == b else 2 * dg) * qd[a] * qd[b]
                dq[i, k] = v
        dqd = 2 * self.C_matrix_kappa
        for i, L in enumerate(self.links):
            dqd[i, i] += L.K + CoulombSlope(L.Fc, L.qd, L.vc)
        return dq, dqd

    @cached_property
    def friction_emitted(self) -> sp.Matrix:
        """K qd + Coulomb(F_c, qd, v_c) (n,), as emitted."""
        return sp.Matrix([L.K * L.qd + Coulomb(L.Fc, L.qd, L.vc) for L in self.links])

    @cached_property
    def friction(self) -> sp.Matrix:
        """K qd + F_c tanh(qd / v_c) (n,)."""
        return sp.Matrix([L.K * L.qd + L.Fc * sp.tanh(L.qd / L.vc) for L in self.links])

    @cached_property
    def armature(self) -> sp.Matrix:
        """diag(armature) (n, n): reflected rotor inertia added to M."""
        return sp.diag(*[L.Ia for L in self.links])

    def explicit(self, expr):
        """expr with every kappa_m replaced by its parameter polynomial and e_k by d_k + q_k."""
        return expr.xreplace(self.kappa).xreplace({e: d + self.q[i] for e, (i, d) in self.slides.items()})

    @cached_property
    def M(self) -> sp.Matrix:
        """Inertia matrix (n, n), armature included."""
        return self.explicit(self.M_kappa) + self.armature

    @cached_property
    def G(self) -> sp.Matrix:
        """Gravity vector dV/dq (n,)."""
        return self.explicit(self.G_kappa)

    @cached_property
    def C(self) -> sp.Matrix:
        """Coriolis and centrifugal vector C(q, qd) qd (n,)."""
        return self.explicit(self.C_kappa)

    @cached_property
    def C_matrix(self) -> sp.Matrix:
        """Christoffel matrix (n, n): C_kj = sum_i Gamma_ijk qd_i."""
        return self.explicit(self.C_matrix_kappa)

    # -------------------------------------------------------------- display
    def trig_substitutions(self) -> dict:
        """c_i -> cos(theta_i + q_i), s_i -> sin(theta_i + q_i) for display and textbook checks."""
        out = {}
        for sym, (i, th) in self.trig.items():
            ang = self.q[i] + exact_angle(th)
            out[sym] = sp.cos(ang) if sym.name.startswith("c_") else sp.sin(ang)
        return out

    def in_trig(self, expr):
        """expr with c_i, s_i replaced by cos/sin of the joint angles."""
        return expr.xreplace(self.trig_substitutions())

    def matrices(self, trig: bool = True) -> dict:
        """{'M', 'C', 'C_matrix', 'G', 'friction'}: sympy matrices for display (e.g. sympy.latex),
        with cos/sin of the joint angles when `trig`, else the symbols c_i, s_i."""
        out = dict(M=self.M, C=self.C, C_matrix=self.C_matrix, G=self.G, friction=self.friction)
        return {k: self.in_trig(v) for k, v in out.items()} if trig else out


def derive(structure_or_robot) -> SymbolicModel:
    """Symbolic model of a Structure or a coopsim.Robot (M, C, C_matrix, G, friction are lazy)."""
    s = structure_or_robot
    if not isinstance(s, Structure):
        # no C++ is written here: any robot name will do
        name = re.sub(r"\W", "_", s.name, flags=re.ASCII) or "robot"
        s = structure_of(s, name=name if not name[0].isdigit() else "_" + name)
    return SymbolicModel(s)
