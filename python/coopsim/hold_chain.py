"""The closed chain of two arms welded to one body, for :mod:`coopsim.hold_model`: its constrained dynamics with
rigid welds (on the constraint manifold: independent joints by a pivoted QR, the dependent ones solved, the weld
wrenches the constraint's multipliers) and with the engine's soft welds (both arms' joints and the body as a free
body, each weld the engine's spring-damper). :func:`coopsim.linearize_hold` linearises them; see its module.
"""
from __future__ import annotations

import numpy as np

from ._core import cooperation_wrenches

def _skew(r):
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def _pivot_order(J, tol=1e-8):
    """(rank, pivots) of a column-pivoted QR of J (Businger-Golub: each step the column with the largest
    norm left after the chosen ones are projected out); rank counts the pivots above tol of the first."""
    R = np.array(J, float)
    cols = list(range(R.shape[1]))
    piv, first = [], None
    for _ in range(min(R.shape)):
        norms = np.linalg.norm(R[:, cols], axis=0)
        j = int(np.argmax(norms))
        if first is None:
            first = norms[j]
        if norms[j] <= tol * first:
            break
        c = cols.pop(j)
        piv.append(c)
        v = R[:, c] / norms[j]
        R = R - np.outer(v, v @ R)
    return len(piv), piv + cols


def _rotvec(R):
    """The rotation vector (3,) rad of a rotation matrix (3, 3)."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    th = np.arccos(c)
    if th < 1e-6:
        return 0.5 * w * (1.0 + th * th / 6.0)
    if np.pi - th < 1e-6:   # near a half turn: the axis from the symmetric part
        a = np.sqrt(np.maximum((np.diag(R) + 1.0) / 2.0, 0.0))
        k = int(np.argmax(a))
        a = (R[:, k] + R[k, :]) / (4.0 * a[k])
        a[k] = np.sqrt(max((R[k, k] + 1.0) / 2.0, 0.0))
        return th * a / np.linalg.norm(a) * (np.sign(a @ w) or 1.0)
    return th / (2.0 * np.sin(th)) * w


class _Arms:
    """What both chains hold of the two arms and the body: the robots, their joints at the point, each jaw's
    and clamp link's index, the free joints (all but the jaw, held at the grasp width), the body's mass and
    inertia, gravity and the vertical."""

    def _arms(self, robots, q, mass, inertia, gravity):
        self.r = robots
        self.q0 = [np.array(x, float) for x in q]
        self.jaw = [r.clamp.moving_joint - 1 for r in robots]
        self.link = [r.clamp.fixed_link for r in robots]
        self.free = [np.array([j for j in range(r.dof) if j != jw]) for r, jw in zip(robots, self.jaw)]
        self.na = len(self.free[0])
        self.n = self.na + len(self.free[1])
        self.mass, self.I_body = float(mass), np.asarray(inertia, float)
        self.g = np.asarray(gravity, float)
        self.up = -self.g / np.linalg.norm(self.g)


class _Chain(_Arms):
    """The rigid closed chain of two arms and one body at an operating point (see the module)."""

    def __init__(self, robots, q, points, body_pose, mass, inertia, gravity):
        self._arms(robots, q, mass, inertia, gravity)
        Ta, Tb = (robots[k].frames(self.q0[k])[self.link[k]] for k in (0, 1))
        self.P = [np.linalg.solve(T, np.r_[p, 1.0])[:3] for T, p in zip((Ta, Tb), points)]  # weld points, link frames
        self.X = np.linalg.solve(Ta, body_pose)        # the body in a's clamp link
        self.Y = np.linalg.solve(Ta, Tb)               # b's clamp link in a's
        self.R0 = np.asarray(body_pose, float)[:3, :3]
        self.Pb_in_a = (self.Y @ np.r_[self.P[1], 1.0])[:3]
        q = self.qfree0 = np.concatenate([self.q0[0][self.free[0]], self.q0[1][self.free[1]]])
        Jc = self.constraint_jacobian(q)
        self.rank, piv = _pivot_order(Jc)
        self.dep = np.sort(piv[:self.rank])
        self.ind = np.sort(piv[self.rank:])
        self.m = self.n - self.rank

    def split(self, qf):
        """Full joint vectors (jaws at the point's) from the free joints (n,)."""
        out = []
        for k, (lo, hi) in enumerate(((0, self.na), (self.na, self.n))):
            q = self.q0[k].copy()
            q[self.free[k]] = qf[lo:hi]
            out.append(q)
        return out

    def split_speed(self, qdf):
        out = []
        for k, (lo, hi) in enumerate(((0, self.na), (self.na, self.n))):
            qd = np.zeros(self.r[k].dof)
            qd[self.free[k]] = qdf[lo:hi]
            out.append(qd)
        return out

    def constraint(self, qf):
        qa, qb = self.split(qf)
        Ta = self.r[0].frames(qa)[self.link[0]]
        Tb = self.r[1].frames(qb)[self.link[1]]
        pb = (Tb @ np.r_[self.P[1], 1.0])[:3]
        pa = (Ta @ np.r_[self.Pb_in_a, 1.0])[:3]
        return np.r_[pb - pa, _rotvec(Tb[:3, :3] @ (Ta[:3, :3] @ self.Y[:3, :3]).T)]

    def constraint_jacobian(self, qf):
        qa, qb = self.split(qf)
        Ja = self.r[0].jacobian(qa, self.link[0], self.Pb_in_a)[:, self.free[0]]
        Jb = self.r[1].jacobian(qb, self.link[1], self.P[1])[:, self.free[1]]
        return np.hstack([-Ja, Jb])

    def solve(self, s):
        """The free joints (n,) on the manifold with the independent ones at s (m,), and J_c there."""
        qf = self.qfree0.copy()
        qf[self.ind] = s
        for _ in range(30):
            phi = self.constraint(qf)
            Jc = self.constraint_jacobian(qf)
            if np.abs(phi).max() < 1e-14:
                return qf, Jc
            qf[self.dep] -= np.linalg.lstsq(Jc[:, self.dep], phi, rcond=None)[0]
        if np.abs(phi).max() > 1e-10:
            raise ValueError(f"s: the closed chain has no configuration with these independent joints "
                             f"(constraint error {np.abs(phi).max():.3g})")
        return qf, Jc

    def null_map(self, Jc):
        """N (n, m): qd_free = N sd."""
        N = np.zeros((self.n, self.m))
        N[self.ind, np.arange(self.m)] = 1.0
        N[self.dep] = -np.linalg.lstsq(Jc[:, self.dep], Jc[:, self.ind], rcond=None)[0]
        return N

    def evaluate(self, z, u, lam_shift=None):
        """(zd (2m,), y (q,), lambda (12,), null (12, 6 - r)) at z = [s; sd], u (n,) the free joints'
        torques. lam_shift (12,): added to lambda (the weld wrenches' indeterminate part) before y."""
        m = self.m
        qf, Jc = self.solve(z[:m])
        qdf = self.null_map(Jc) @ z[m:]
        qs, qds = self.split(qf), self.split_speed(qdf)
        blocks_M, h, rows, bias, pts = [], [], [], [], []
        Ta = None
        for k in (0, 1):
            r, q, qd, f, l = self.r[k], qs[k], qds[k], self.free[k], self.link[k]
            blocks_M.append(r.mass_matrix(q)[np.ix_(f, f)])
            h.append(r.inverse_dynamics(q, qd, np.zeros(r.dof))[f])
            J = r.jacobian(q, l, self.P[k])
            T = r.frames(q)[l]
            if k == 0:
                Ta = T
            p = (T @ np.r_[self.P[k], 1.0])[:3]
            w = J[3:] @ qd
            # the weld point's bias acceleration from the TCP's (both on the clamp link)
            tcp = r.fk(q)[:3, 3]
            tb = r.tool_bias(q, qd)
            d = p - tcp
            bias.append(np.r_[tb[:3] + np.cross(tb[3:], d) + np.cross(w, np.cross(w, d)), tb[3:]])
            rows.append(J[:, f])
            pts.append(p)
        Tbody = Ta @ self.X
        c, R = Tbody[:3, 3], Tbody[:3, :3]
        # the body's twist, carried by a's clamp link
        Ja_c = rows[0]
        qa_d = qdf[:self.na]
        va = Ja_c @ qa_d
        w = va[3:]
        Iw = R @ self.I_body @ R.T
        nb = self.n + 6
        M = np.zeros((nb, nb))
        M[:self.na, :self.na], M[self.na:self.n, self.na:self.n] = blocks_M
        M[self.n:self.n + 3, self.n:self.n + 3] = self.mass * np.eye(3)
        M[self.n + 3:, self.n + 3:] = Iw
        hv = np.r_[h[0], h[1], -self.mass * self.g, np.cross(w, Iw @ w)]
        C = np.zeros((12, nb))
        Cdv = np.zeros(12)
        for k in (0, 1):
            rk = pts[k] - c
            WT = np.eye(6)
            WT[:3, 3:] = -_skew(rk)
            C[6 * k:6 * k + 6, (0 if k == 0 else self.na):(self.na if k == 0 else self.n)] = rows[k]
            C[6 * k:6 * k + 6, self.n:] = -WT
            Cdv[6 * k:6 * k + 6] = bias[k] - np.r_[np.cross(w, np.cross(w, rk)), np.zeros(3)]
        Su = np.r_[u, np.zeros(6)]
        Minv_rhs = np.linalg.solve(M, np.column_stack([Su - hv, C.T]))
        G = C @ Minv_rhs[:, 1:]
        G = 0.5 * (G + G.T)
        ev, V = np.linalg.eigh(G)
        keep = 6 + self.rank
        Vk, ek = V[:, -keep:], ev[-keep:]
        rhs = -Cdv - C @ Minv_rhs[:, 0]
        lam = Vk @ ((Vk.T @ rhs) / ek)
        vd = Minv_rhs[:, 0] + Minv_rhs[:, 1:] @ lam
        null = V[:, :12 - keep]
        zd = np.r_[z[m:], vd[:self.n][self.ind]]
        if lam_shift is not None:
            lam = lam + lam_shift
        y = self.outputs(c, R, pts, -lam[:6], -lam[6:])
        return zd, y, lam, null

    def outputs(self, c, R, pts, ha, hb):
        co = cooperation_wrenches(c, pts[0], ha, pts[1], hb, self.up)
        e = pts[1] - pts[0]
        e /= np.linalg.norm(e)
        nh = np.cross(self.up, e)
        nh /= np.linalg.norm(nh)
        nv = np.cross(e, nh)
        it = np.asarray(co.internal)
        return np.r_[c, _rotvec(R @ self.R0.T), co.squeeze, co.twist,
                     it[3:6] @ nh, it[3:6] @ nv, it[9:12] @ nh, it[9:12] @ nv,
                     it[0:3] @ nh, it[0:3] @ nv, co.load_share[0]]

    def statics(self):
        """Torques (n,) holding the chain at rest at the point with no internal wrench (the body's
        weight shared as held_body.hpp's metric shares it: the weld wrenches on the body are the
        external part of any balancing pair)."""
        qa, qb = self.q0
        Ta = self.r[0].frames(qa)[self.link[0]]
        Tb = self.r[1].frames(qb)[self.link[1]]
        pa, pb = (Ta @ np.r_[self.P[0], 1.0])[:3], (Tb @ np.r_[self.P[1], 1.0])[:3]
        c = (Ta @ self.X)[:3, 3]
        ha = np.r_[-self.mass * self.g, np.cross(c - pa, -self.mass * self.g)]   # a carries all, about pa
        hb = np.zeros(6)
        co = cooperation_wrenches(c, pa, ha, pb, hb, self.up)
        it = np.asarray(co.internal)
        ha, hb = ha - it[:6], hb - it[6:]
        out = []
        for k, (q, hk) in enumerate(((qa, ha), (qb, hb))):
            r = self.r[k]
            J = r.jacobian(q, self.link[k], self.P[k])
            out.append((r.gravity(q) + J.T @ hk)[self.free[k]])
        return np.concatenate(out), (ha, hb)



def _rotation(v):
    """The rotation matrix (3, 3) of a rotation vector v (3,) rad (Rodrigues)."""
    th = float(np.linalg.norm(v))
    K = _skew(v)
    if th < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + np.sin(th) / th * K + (1.0 - np.cos(th)) / th ** 2 * K @ K


class _SoftChain(_Arms):
    """The two arms, the body as a free body and each weld the engine's spring-damper (grasp.cpp, welds()):
    at the weld's point, with the reduced mass m = A_lin^-1, A_lin = 1/mass - S(r) I_w^-1 S(r) + (J M^-1 J^T)_lin
    and inertia i = A_rot^-1, A_rot = I_w^-1 + (J M^-1 J^T)_rot (J the clamp link's Jacobian at the weld's
    point, M the arm's mass matrix, jaw included; r from the body's centre to the weld's point; I_w the
    body's inertia in world axes), force m (omega^2 e_p + 2 omega / holders e_v) and moment
    i (omega^2 e_r + 2 omega / holders e_w) on the body, opposite on the clamp link (omega = weld_omega_dt / h,
    h the world step; e the clamp's target less the body's: position, rotation vector, velocities). The
    stiffness and damping are re-evaluated at each state, as the engine does at each world step. The welds'
    rest geometry (the anchors and the body's pose in the clamp link as grasped) is read back from the weld
    wrenches the simulation applies at the point: the stretch is what gives them."""

    def __init__(self, robots, q, qd, body_pose, body_twist, mass, inertia, gravity, points, welds, omega,
                 holders, moment):
        self._arms(robots, q, mass, inertia, gravity)
        self.omega, self.holders, self.moment = float(omega), float(holders), bool(moment)
        pose = np.asarray(body_pose, float)
        self.c0, self.R0 = pose[:3, 3].copy(), pose[:3, :3].copy()
        v, w = (np.asarray(x, float) for x in body_twist)
        self.anchor_link, self.anchor_body, self.weld_R = [], [], []
        for k in (0, 1):
            r, qk, qdk, l = robots[k], self.q0[k], np.asarray(qd[k], float), self.link[k]
            T = r.frames(qk)[l]
            p_body = np.asarray(points[k], float)
            rr = p_body - self.c0
            h = np.asarray(welds[k], float)
            cdamp = 2.0 * omega / holders
            p_target = p_body
            for _ in range(3):   # the Jacobian at the target, which the stretch moves by micrometres
                J = r.jacobian(qk, l, np.linalg.solve(T, np.r_[p_target, 1.0])[:3])
                mk, ik = self._gains(r, qk, J, rr, self.R0)
                # the stretch that gives the weld's wrench now: h = m (w^2 e_p + c e_v), c = 2 w / holders
                e_v = J[:3] @ qdk - (v + np.cross(w, rr))
                e_w = J[3:] @ qdk - w
                e_p = (np.linalg.solve(mk, h[:3]) - cdamp * e_v) / omega ** 2
                p_target = p_body + e_p
            e_r = (np.linalg.solve(ik, h[3:]) - cdamp * e_w) / omega ** 2 if moment else np.zeros(3)
            self.anchor_link.append(np.linalg.solve(T, np.r_[p_target, 1.0])[:3])
            self.anchor_body.append(self.R0.T @ (p_body - self.c0))
            self.weld_R.append(T[:3, :3].T @ _rotation(e_r) @ self.R0)   # the body in the clamp link, as grasped
        self.qfree0 = np.concatenate([self.q0[0][self.free[0]], self.q0[1][self.free[1]]])
        self.m = self.n + 6

    def _gains(self, r, q, J, rr, R):
        M = r.mass_matrix(q)
        A_robot = J @ np.linalg.solve(M, J.T)
        I_inv = R @ np.linalg.inv(self.I_body) @ R.T
        S = _skew(rr)
        A_lin = np.eye(3) / self.mass - S @ I_inv @ S + A_robot[:3, :3]
        A_rot = I_inv + A_robot[3:, 3:]
        return np.linalg.inv(A_lin), np.linalg.inv(A_rot)

    def weld_wrenches(self, qs, qds, c, R, v, w):
        """Each weld's wrench on the body (force N at the body's weld point, moment N m; world), the body's
        weld points, and the clamp links' Jacobians at the welds' targets (6, dof)."""
        out, pts, Js = [], [], []
        cdamp = 2.0 * self.omega / self.holders
        for k in (0, 1):
            r, q, qd, l = self.r[k], qs[k], qds[k], self.link[k]
            T = r.frames(q)[l]
            J = r.jacobian(q, l, self.anchor_link[k])
            p_target = (T @ np.r_[self.anchor_link[k], 1.0])[:3]
            p_body = c + R @ self.anchor_body[k]
            rr = p_body - c
            mk, ik = self._gains(r, q, J, rr, R)
            e_p = p_target - p_body
            e_r = _rotvec(T[:3, :3] @ self.weld_R[k] @ R.T)
            tw = J @ qd
            e_v = tw[:3] - (v + np.cross(w, rr))
            e_w = tw[3:] - w
            f = mk @ (self.omega ** 2 * e_p + cdamp * e_v)
            mu = ik @ (self.omega ** 2 * e_r + cdamp * e_w) if self.moment else np.zeros(3)
            out.append(np.r_[f, mu])
            pts.append(p_body)
            Js.append(J)
        return out, pts, Js

    def weld_gains(self):
        """Each weld's stiffness and damping at the point, ((6, 6), (6, 6)): force and moment on the body per
        stretch [e_p; e_r] (N/m, N m/rad) and per stretch rate [e_v; e_w] (N s/m, N m s/rad)."""
        out = []
        for k in (0, 1):
            r, q, l = self.r[k], self.q0[k], self.link[k]
            J = r.jacobian(q, l, self.anchor_link[k])
            mk, ik = self._gains(r, q, J, self.R0 @ self.anchor_body[k], self.R0)
            K, Cd = np.zeros((6, 6)), np.zeros((6, 6))
            K[:3, :3], Cd[:3, :3] = self.omega ** 2 * mk, 2.0 * self.omega / self.holders * mk
            if self.moment:
                K[3:, 3:], Cd[3:, 3:] = self.omega ** 2 * ik, 2.0 * self.omega / self.holders * ik
            out.append((K, Cd))
        return tuple(out)

    def equilibrium(self, u, h):
        """z (2m,) at rest under the torques u nearest the present configuration: Newton's steps on the
        accelerations (the least-norm step: the chain's neutral directions, e.g. the body's horizontal
        position, stay where they are), with the stiffness's Jacobian by central differences (step h)."""
        m = self.m
        z = np.r_[self.qfree0, np.zeros(6), np.zeros(m)]
        J = np.zeros((m, m))
        for j in range(m):
            e = np.zeros(2 * m)
            e[j] = h
            J[:, j] = (self.evaluate(z + e, u)[0][m:] - self.evaluate(z - e, u)[0][m:]) / (2 * h)
        for _ in range(6):
            acc = self.evaluate(z, u)[0][m:]
            z[:m] -= np.linalg.lstsq(J, acc, rcond=1e-9)[0]
        return z

    def split(self, qf):
        return _Chain.split(self, qf)

    def split_speed(self, qdf):
        return _Chain.split_speed(self, qdf)

    def evaluate(self, z, u, lam_shift=None):
        """(zd (2m,), y (q,), the weld wrenches (12,), no indeterminate part) at z = [q_free; c - c0;
        rotation vector of R R0^T; qd_free; v; w] (2m,), u (n,) the free joints' torques."""
        n, m = self.n, self.m
        qs = self.split(z[:n])
        qds = self.split_speed(z[m:m + n])
        c = self.c0 + z[n:n + 3]
        R = _rotation(z[n + 3:n + 6]) @ self.R0
        v, w = z[m + n:m + n + 3], z[m + n + 3:]
        hs, pts, Js = self.weld_wrenches(qs, qds, c, R, v, w)
        qdd = []
        for k in (0, 1):
            r, f = self.r[k], self.free[k]
            tau = np.full(r.dof, 0.0)
            tau[f] = u[:self.na] if k == 0 else u[self.na:]
            rhs = tau - r.inverse_dynamics(qs[k], qds[k], np.zeros(r.dof)) - Js[k].T @ hs[k]
            Mf = r.mass_matrix(qs[k])[np.ix_(f, f)]       # the jaw held at its width
            qdd.append(np.linalg.solve(Mf, rhs[f]))
        F = self.mass * self.g + hs[0][:3] + hs[1][:3]
        Iw = R @ self.I_body @ R.T
        Mom = hs[0][3:] + hs[1][3:] + np.cross(pts[0] - c, hs[0][:3]) + np.cross(pts[1] - c, hs[1][:3])
        vd = F / self.mass
        wd = np.linalg.solve(Iw, Mom - np.cross(w, Iw @ w))
        zd = np.r_[z[m:], qdd[0], qdd[1], vd, wd]
        ha, hb = hs
        y = _Chain.outputs(self, c, R, pts, ha, hb)
        return zd, y, np.r_[ha, hb], np.zeros((12, 0))
