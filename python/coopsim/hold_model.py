"""Two arms holding one body, linearised: the rigid-weld closed chain on its constraint manifold.

Two robots with clamps hold one free body (a bar): each weld ties its clamp's link to the body at the weld's
point. The engine's welds are soft (grasp.hpp: 6-DOF spring-dampers ringing at weld_omega_dt / h, 1000 rad/s
at dt = 0.2 ms); here they are rigid, which is what the soft welds tend to below their own frequency. The
closed chain is

    arm a (its joints but the jaw, locked at the held width), the body (fixed in a's clamp link),
    arm b (its clamp link fixed in the body: the constraint Phi(q_a, q_b) = 0, six equations)

with the constraint's Jacobian J_c = [-J_a(p_b), J_b(p_b)] (6 x n, the twist of b's clamp link at b's weld
point less that of the same point carried by a's clamp link). Its rank r may be below 6: two SCARAs cannot
tilt their clamps about every horizontal axis, so some constraint directions are satisfied by both arms
alike and are redundant. A pivoted QR of J_c picks r dependent joints (the pivots) and leaves m = n - r
independent ones, s; the dependent joints are solved from s by Gauss-Newton on Phi (to 1e-14), the
velocities through the null space: qd = N(q) sd, N = [1; -J_dep^+ J_ind] (permuted). The state is
z = [s; sd] (2m), the input u both arms' joint torques but the jaws' (N m, N).

The dynamics (exact, evaluated at each z, u): the arms' M(q), bias b(q, qd) = inverse_dynamics(q, qd, 0)
(Coriolis, gravity, friction), the body's mass and inertia, and the weld wrenches lambda (12) as Lagrange
multipliers of C v = 0 (v = [qd_a; qd_b; body twist]; C (12 x (n + 6)), rows [J_k, -W_k^T] per weld):

    M vd + h = S^T u + C^T lambda,   C vd + Cd v = 0,
    lambda = (C M^-1 C^T)^+ (-Cd v - C M^-1 (S^T u - h)),

where ^+ keeps the 6 + r directions C spans. Where C has fewer (6 - r redundant constraints), the weld
wrenches are statically indeterminate along the null space of C^T: moments about axes that neither clamp
can turn about and the body cannot turn about either (for two SCARAs, a moment about a horizontal axis that
one weld applies and the other takes back). The pseudo-inverse resolves them by least norm, which splits
such a moment evenly between the welds (the null directions are moments only, so N and N m do not mix).
An output that changes along those directions is not determined by the rigid model:
HoldModel.determined says which (squeeze, load share and the body's pose always are; twist and bending
are where the clamps' joints can turn about them). In the engine the soft welds split them by their
stiffness.

The outputs y: the body's pose (the centre of mass, m; its rotation from the operating orientation as a
rotation vector, rad, world axes) and the internal wrench's parts as held_body.hpp defines them, computed by
coopsim.cooperation_wrenches from the two weld wrenches on the body: squeeze (N, compression > 0), twist
(N m), each weld's bending moment as two signed components across the line (N m; held_body's bending is
their norm), the shear force's two signed components (N; its shear is their norm), and a's load share.
The cross-line axes are n_h = up x e / |up x e| (horizontal) and n_v = e x n_h, e the unit vector from a's
weld point to b's.

The linear model is the Jacobian of (zd, y) in (z, u) at the operating point by central differences of
this exact constrained-dynamics function (steps h_state, h_torque); HoldModel.fd_error is the largest
change of its entries when the steps are doubled, relative to each matrix's largest entry (about 4 times
the error of the central differences). The analytic derivatives of each arm (forward_dynamics_derivatives)
do not give the closed chain's directly; the reduction is where the differences are taken.

Soft welds (linearize_hold(sim, welds="soft")): the system as the engine simulates it. The state is
z = [q_free; c - c0; theta; qd_free; v; w] (2m = 2 (n + 6)): both arms' free joints (the jaws held at the
width, as in the rigid model), the body's centre of mass (m) and its rotation from R0 (rotation vector,
rad, world axes), their speeds (rad/s, m/s; the body's velocity and angular velocity, world). Each weld is
grasp.cpp's spring-damper with the simulation's own values: omega = weld_omega_dt / (dt world_every), the
reduced mass m = A_lin^-1 and inertia i = A_rot^-1 between the body and the arm at the weld's point
(A = J M^-1 J^T of the arm, M with its jaw, plus the body's 1/mass - S(r) I_w^-1 S(r) and I_w^-1), the
stiffness omega^2 (m, i) and the damping 2 omega / holders (m, i), re-evaluated at each state as the engine
does at each step; weld_moment=False leaves the moments out. The welds' rest geometry (the anchors on the
clamp link and on the body, the body's orientation in the clamp link as grasped) is not exposed by the
engine: it is read back from the weld wrenches the simulation applies at the point (the stretch that gives
them, less the damping's part at the present speeds). The outputs are the rigid model's, from the two weld
wrenches: D = 0 (the torques reach the welds through the arms' motion only), every output determined. The
point is the equilibrium under u0 nearest the present state (Newton's least-norm steps: the chain's neutral
directions stay), so zd0 ~ 0. Its modes include the welds' own: for the two SCARAs' held bar the arms
swing against each other through the welds at 27 Hz, damping ratio 0.13, the squeeze's ring after a step,
which the rigid model has not.
"""
from __future__ import annotations

import dataclasses
from typing import List, Optional, Tuple

import numpy as np
from . import _checks
from ._core import CooperativeController, CubicTrajectory, Robot, SetPoint, World, box_inertia
from .hold_chain import _Chain, _SoftChain, _rotvec
from .planning import clamp_pose
from .robots import scara1, scara2
from .simulation import ComputedTorque, Simulation

__all__ = ["HoldModel", "HoldFeedback", "held_bar", "linearize_hold", "squeeze_after_push"]

_OUTPUTS = ["x", "y", "z", "rx", "ry", "rz", "squeeze", "twist", "bending_a_h", "bending_a_v", "bending_b_h",
            "bending_b_v", "shear_h", "shear_v", "load_share_a"]
_UNITS = ["m", "m", "m", "rad", "rad", "rad", "N", "N m", "N m", "N m", "N m", "N m", "N", "N", ""]


def _expm(M):
    """The matrix exponential (numpy only): scaling and squaring of a Taylor series (|M / 2^k| <= 1/2,
    24 terms: a relative error near the rounding's)."""
    norm = np.abs(M).sum(axis=1).max()
    k = max(0, int(np.ceil(np.log2(norm / 0.5)))) if norm > 0.5 else 0
    A = M / 2.0 ** k
    E = np.eye(len(M))
    term = np.eye(len(M))
    for i in range(1, 25):
        term = term @ A / i
        E = E + term
    for _ in range(k):
        E = E @ E
    return E


@dataclasses.dataclass
class HoldModel:
    """The linear model of two arms holding one body (coopsim.linearize_hold), at an operating point:

    continuous (dt == 0): zd = zd0 + A (z - z0) + B (u - u0),        y = y0 + C (z - z0) + D (u - u0);
    discrete (dt > 0, the torque held over dt): z+ = z0 + zd0 dt + A (z - z0) + B (u - u0), the same y
    (zd0 then z's mean rate over the period at the point).

    A (2m, 2m), B (2m, p), C (q, 2m), D (q, p): z = [s; sd] the independent joints and their speeds
    (rad, m; rad/s, m/s), u both arms' torques but the jaws' (N m, N), y the outputs (`outputs`, `units`).
    z0 (2m,), u0 (p,), y0 (q,): the point; zd0 (2m,) zd there (zero at an equilibrium). states, inputs:
    the names "a.q2", "b.qd1", ...; determined (q,) bool: the outputs the rigid model determines (see the
    module's docstring); q0 = (q_a, q_b) the arms' joints at the point (full, jaws included);
    joints = (free_a, free_b) the joints of each arm in u (indices); independent: (arm, joint) pairs of s;
    T (2n, 2m): the state's tangent map, [dq_free; dqd_free] = T (z - z0) (n = p free joints);
    fd_error: the central differences' measured error (relative, see the module); rank: the constraint's
    rank r; jaw_torques (tau_a_jaw, tau_b_jaw): what the jaws held at the point (N); constraint_jacobian
    J_c (6, n): the clamps' relative twist (b's clamp link less a's, at b's weld point; m/s, rad/s) per
    free joint speed, zero along the manifold (J_c T = 0). welds: "rigid" or "soft" (the module's
    docstring: the soft model's state is the free joints, the body's pose and their speeds; T selects the
    joints, q0 the joints at its equilibrium); weld_gains (soft): each weld's ((6, 6) stiffness N/m, N m/rad;
    (6, 6) damping N s/m, N m s/rad) at the point; body0 (soft): (c0 (3,) m, R0 (3, 3)), what the body's
    part of z is measured from."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    z0: np.ndarray
    u0: np.ndarray
    y0: np.ndarray
    zd0: np.ndarray
    dt: float
    states: List[str]
    inputs: List[str]
    outputs: List[str]
    units: List[str]
    determined: np.ndarray
    q0: Tuple[np.ndarray, np.ndarray]
    joints: Tuple[np.ndarray, np.ndarray]
    independent: List[Tuple[int, int]]
    T: np.ndarray
    fd_error: float
    rank: int
    jaw_torques: Tuple[float, float]
    constraint_jacobian: np.ndarray
    welds: str = "rigid"
    weld_gains: Optional[tuple] = None
    body0: Optional[Tuple[np.ndarray, np.ndarray]] = None

    def discretize(self, dt: float) -> "HoldModel":
        """The model of one period dt (s) with the torque held (zero-order hold, exact: the matrix
        exponential of [[A, B], [0, 0]] dt); C, D unchanged (the outputs at the sample). Continuous models
        only."""
        dt = _checks.positive(dt, "dt", unit="s")
        if self.dt != 0.0:
            raise ValueError(f"dt: the model is discrete already (dt = {self.dt:g} s)")
        n, p = self.B.shape
        E = np.zeros((n + p + 1, n + p + 1))
        E[:n, :n], E[:n, n:n + p], E[:n, -1] = self.A, self.B, self.zd0
        F = _expm(E * dt)
        return dataclasses.replace(self, A=F[:n, :n], B=F[:n, n:n + p], zd0=F[:n, -1] / dt, dt=dt)

    def lqr_weights(self, output_weights, torque_weights, state_weights=None):
        """The weights (Q, R, S) of an LQR that weighs the outputs: sum_k y_k' Qy y_k + u_k' R u_k
        (+ z_k' Qz z_k) around the point, y = C z + D u (the squeeze among them: its weight regulates it),
        is z' Q z + 2 z' S u + u' R' u with Q = C' Qy C + Qz, S = C' Qy D, R' = R + D' Qy D, for a Riccati
        solver: scipy.linalg.solve_discrete_are(d.A, d.B, Q, R', s=S) on d = model.discretize(period),
        then K = (R' + B' P B)^-1 (B' P A + S') and the law u = u0 - K (z - z0) (HoldFeedback).
        output_weights: (q,) or (q, q) or a dict {output name: weight} (the others 0), Qy in 1/unit^2
        (e.g. 1/(1 mm)^2 on x, y, z; 1/(0.05 N)^2 on the squeeze); an output the rigid model does not
        determine (`determined`) must weigh 0. torque_weights (p,) or (p, p): R (1/(N m)^2, 1/N^2);
        state_weights (2m,) or (2m, 2m): Qz (default 0)."""
        q, p, s = self.C.shape[0], self.B.shape[1], self.A.shape[0]
        if isinstance(output_weights, dict):
            unknown = sorted(set(output_weights) - set(self.outputs))
            if unknown:
                raise ValueError(f"output_weights: no output named {unknown[0]!r} "
                                 f"(the outputs: {', '.join(self.outputs)})")
            output_weights = [float(output_weights.get(n, 0.0)) for n in self.outputs]

        def square(w, n, what):
            w = _checks.real_array(w, what)
            if w.ndim == 0 or w.shape == (n,):
                w = np.diag(np.broadcast_to(w, (n,)))
            if w.shape != (n, n):
                raise ValueError(f"{what} must be a number, ({n},) or ({n}, {n}), got shape {w.shape}")
            return w

        Qy = square(output_weights, q, "output_weights")
        R = square(torque_weights, p, "torque_weights")
        Qz = np.zeros((s, s)) if state_weights is None else square(state_weights, s, "state_weights")
        if np.any(np.abs(Qy[~self.determined]).sum(axis=1) != 0):
            raise ValueError("output_weights: outputs the rigid model does not determine ("
                             + ", ".join(np.array(self.outputs)[~self.determined]) + ") must weigh 0")
        C, D = self.C, self.D
        return C.T @ Qy @ C + Qz, R + D.T @ Qy @ D, C.T @ Qy @ D

    def state(self, q_a, qd_a, q_b, qd_b, body=None) -> np.ndarray:
        """The model's state z (2m,) nearest (least squares through T) to the arms' joint states (each
        (n_k,), jaws included and ignored). Soft welds: body = (pose (4, 4), velocity (3,) m/s, angular
        velocity (3,) rad/s) the body's state, world (e.g. sim.body_state(name)'s); None: the body's part
        of z left at the point's."""
        z = self.z0 + self.state_map @ (self.joint_state(q_a, qd_a, q_b, qd_b) - self.x0)
        if self.welds == "soft" and body is not None:
            pose, v, w = (np.asarray(x, float) for x in body)
            n, m = len(self.joints[0]) + len(self.joints[1]), self.A.shape[0] // 2
            c0, R0 = self.body0
            z[n:n + 3] = pose[:3, 3] - c0
            z[n + 3:n + 6] = _rotvec(pose[:3, :3] @ R0.T)
            z[m + n:m + n + 3], z[m + n + 3:] = v, w
        return z

    def joint_state(self, q_a, qd_a, q_b, qd_b) -> np.ndarray:
        """x = [q_free; qd_free] (2n,) of both arms (jaws left out)."""
        fa, fb = self.joints
        return np.concatenate([np.asarray(q_a)[fa], np.asarray(q_b)[fb], np.asarray(qd_a)[fa],
                               np.asarray(qd_b)[fb]])

    @property
    def x0(self) -> np.ndarray:
        """[q_free; qd_free] (2n,) at the point (zero speeds)."""
        fa, fb = self.joints
        n = len(fa) + len(fb)
        return np.concatenate([self.q0[0][fa], self.q0[1][fb], np.zeros(n)])

    @property
    def state_map(self) -> np.ndarray:
        """P (2m, 2n) = T^+: z - z0 = P (x - x0) on the manifold (x = [q_free; qd_free])."""
        return np.linalg.pinv(self.T)

    def torques(self, u) -> Tuple[np.ndarray, np.ndarray]:
        """u (p,) as the two arms' full torque vectors, the jaws' set to jaw_torques (N)."""
        u = np.asarray(u, float)
        out = []
        for k, (q, f) in enumerate(zip(self.q0, self.joints)):
            t = np.full(len(q), self.jaw_torques[k])
            t[f] = u[:len(f)] if k == 0 else u[len(self.joints[0]):]
            out.append(t)
        return out[0], out[1]


def _holding(sim, a, b):
    """(robots, q, points, body pose, mass, inertia, gravity, jaw torques) of a Simulation's robots a and b
    holding one body now; ValueError naming what is wrong otherwise."""
    n = sim.robot_count
    for what, i in (("a", a), ("b", b)):
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < n:
            raise ValueError(f"{what} must be a robot index in [0, {n}), got {i!r}")
    if a == b:
        raise ValueError(f"b must be another robot than a, got a = b = {a}")
    for what, i in (("a", a), ("b", b)):
        if not sim.robots[i].clamp:
            raise ValueError(f"{what}: robot {i} ({sim.robots[i].name}) has no clamp")
        if sim.holding(i) is None:
            raise ValueError(f"{what}: robot {i} holds nothing")
    if sim.holding(a) != sim.holding(b):
        raise ValueError(f"robots {a} and {b} do not hold one body: {sim.holding(a)!r} and {sim.holding(b)!r}")
    lo, hi = min(a, b), max(a, b)
    co = sim.cooperation(lo, hi)
    points = (co.point_a, co.point_b) if a < b else (co.point_b, co.point_a)
    name = sim.holding(a)
    spec = sim.world.body(name)
    inertia = np.asarray(box_inertia(spec["mass"], *(2.0 * np.asarray(spec["half_extents"]))))
    pose = np.asarray(sim.body_state(name).pose)
    q = (np.asarray(sim.state(a)[0]), np.asarray(sim.state(b)[0]))
    jaws = tuple(float(sim.torque(i)[sim.robots[i].clamp.moving_joint - 1]) for i in (a, b))
    return (sim.robots[a], sim.robots[b]), q, points, pose, spec["mass"], inertia, sim.world.gravity, jaws


def _soft_chain(sim, a, b, robots, q, points, body_pose, body_mass, body_inertia, gravity):
    """The soft-weld chain of a Simulation's robots a and b at the present state: the welds' gains from the
    simulation's options (weld_omega_dt, the world step dt * world_every, weld_moment), their rest geometry
    from the weld wrenches it applies now (sim.weld_wrench) and the state's speeds."""
    opts = sim.options
    h = opts["dt"] * opts["world_every"]
    g = opts["grasp_options"]
    name = sim.holding(a)
    st = sim.body_state(name)
    holders = sum(1 for i in range(sim.robot_count) if sim.holding(i) == name)
    qd = (np.asarray(sim.state(a)[1]), np.asarray(sim.state(b)[1]))
    return _SoftChain(robots, q, qd, body_pose, (st.velocity, st.angular_velocity), body_mass, body_inertia,
                      gravity, points, (sim.weld_wrench(a), sim.weld_wrench(b)), g["weld_omega_dt"] / h, holders,
                      g["weld_moment"])


def linearize_hold(source, a: int = 0, b: int = 1, *, q=None, points=None, body_pose=None,
                   body_mass: Optional[float] = None, body_inertia=None, gravity=None, tau=None,
                   jaw_torques=(0.0, 0.0), dt: Optional[float] = None, h_state: Optional[float] = None,
                   h_torque: float = 1e-4, welds: str = "rigid") -> HoldModel:
    """The linear model of two robots welded to one rigid body, on the closed chain's constraint manifold
    (the module's docstring: coordinates, the weld wrenches' indeterminate part, outputs): a HoldModel.

    source: a coopsim.Simulation whose robots a and b (indices) hold one free body now (the point: their
    joints now, the body's pose, mass and box inertia, the welds' points, the world's gravity; the jaws'
    torques held now), or a pair of robots (with clamps) with q = (q_a, q_b) (each (n_k,), jaws at the
    held width), points = (p_a, p_b) the welds' points (3,) m, world, body_pose (4, 4), body_mass (kg),
    body_inertia (3, 3) kg m^2 about the centre of mass in the body's axes, gravity (3,) m/s^2 (default
    robot a's), jaw_torques (2,) N. tau: the torques at the point, (tau_a, tau_b) full (jaws ignored)
    or (p,) the free joints'; default: those holding the body at rest with no internal wrench (each arm's
    gravity torque plus J^T of its weld's share as held_body.hpp's metric shares the weight: the lever
    rule along the line between the welds). The point's speeds are zero. dt (s): the model discretized
    over dt with the torque held (HoldModel.discretize); None: continuous. h_state (rad, m, per s; default
    1e-6 rigid, 1e-8 soft), h_torque (N m, N): the central differences' steps. welds: "rigid" (the closed
    chain on its constraint manifold) or "soft" (the arms, the body as a free body and each weld the
    engine's spring-damper with the simulation's gains, at the equilibrium under tau nearest the present
    state; the source must be a Simulation: the module's docstring). The soft model's HoldModel has
    welds="soft", weld_gains (each weld's stiffness and damping (6, 6) at the point) and body0 (c0, R0).
    """
    h_state = (1e-8 if welds == "soft" else 1e-6) if h_state is None else _checks.positive(h_state, "h_state")
    h_torque = _checks.positive(h_torque, "h_torque")
    if welds not in ("rigid", "soft"):
        raise ValueError(f"welds must be 'rigid' or 'soft', got {welds!r}")
    is_sim = hasattr(source, "holding") and hasattr(source, "cooperation")
    if welds == "soft" and not is_sim:
        raise ValueError("welds: 'soft' needs a coopsim.Simulation as the source (the welds' rest geometry, "
                         "stiffness and damping are the simulation's)")
    if is_sim:
        robots, q, points, body_pose, body_mass, body_inertia, gravity, jaws = _holding(source, a, b)
    else:
        try:
            robots = tuple(source)
        except TypeError:
            raise ValueError(f"source must be a coopsim.Simulation or a pair of robots, "
                             f"got {type(source).__name__}") from None
        if len(robots) != 2 or not all(isinstance(r, Robot) for r in robots):
            raise ValueError(f"source must be a coopsim.Simulation or a pair of robots, got {len(robots)} "
                             f"items of types {[type(r).__name__ for r in robots]}")
        for what, r in zip("ab", robots):
            if not r.clamp:
                raise ValueError(f"source: robot {what} ({r.name}) has no clamp")
        if q is None or points is None or body_pose is None or body_mass is None or body_inertia is None:
            raise ValueError("q, points, body_pose, body_mass and body_inertia are needed with a pair of robots")
        q = tuple(_checks.real_array(x, "q") for x in q)
        for k, (r, x) in enumerate(zip(robots, q)):
            if x.shape != (r.dof,):
                raise ValueError(f"q[{k}] must have shape ({r.dof},), got {x.shape}")
        points = tuple(_checks.real_array(p, "points") for p in points)
        if len(points) != 2 or any(p.shape != (3,) for p in points):
            raise ValueError("points must be two points (3,) m")
        body_pose = _checks.real_array(body_pose, "body_pose")
        if body_pose.shape != (4, 4):
            raise ValueError(f"body_pose must have shape (4, 4), got {body_pose.shape}")
        body_mass = _checks.positive(body_mass, "body_mass", unit="kg")
        body_inertia = _checks.real_array(body_inertia, "body_inertia")
        if body_inertia.shape != (3, 3):
            raise ValueError(f"body_inertia must have shape (3, 3), got {body_inertia.shape}")
        gravity = robots[0].gravity_acceleration if gravity is None else _checks.real_array(gravity, "gravity")
        jaws = tuple(float(_checks.number(j, "jaw_torques")) for j in jaw_torques)
    if np.linalg.norm(gravity) == 0:
        raise ValueError("gravity must not be zero (the load share needs a vertical)")
    for k, (r, qk, p) in enumerate(zip(robots, q, points)):
        d = float(np.linalg.norm(r.fk(qk)[:3, 3] - p))
        if d > 0.05:   # a weld holds midway between the pads, at the clamp's tool centre point
            raise ValueError(f"points[{k}] is {d:.3g} m from robot {'ab'[k]}'s clamp (its tool centre point at q): "
                             f"the clamps do not hold the body there")
    ch = _Chain(robots, q, points, body_pose, body_mass, body_inertia, gravity)
    u0 = _torques(ch, tau)
    rigid = ch
    if welds == "soft":
        ch = _soft_chain(source, a, b, robots, q, points, body_pose, body_mass, body_inertia, gravity)
        z0 = ch.equilibrium(u0, h_state)
    else:
        z0 = np.r_[ch.qfree0[ch.ind], np.zeros(ch.m)]
    zd0, y0, lam0, null = ch.evaluate(z0, u0)

    def jac(hz, hu):
        cols_z = []
        for j in range(2 * ch.m):
            e = np.zeros(2 * ch.m)
            e[j] = hz
            fp, yp, _, _ = ch.evaluate(z0 + e, u0)
            fm, ym, _, _ = ch.evaluate(z0 - e, u0)
            cols_z.append(np.r_[fp - fm, yp - ym] / (2 * hz))
        cols_u = []
        for j in range(ch.n):
            e = np.zeros(ch.n)
            e[j] = hu
            fp, yp, _, _ = ch.evaluate(z0, u0 + e)
            fm, ym, _, _ = ch.evaluate(z0, u0 - e)
            cols_u.append(np.r_[fp - fm, yp - ym] / (2 * hu))
        return np.array(cols_z).T, np.array(cols_u).T

    Jz, Ju = jac(h_state, h_torque)
    Jz2, Ju2 = jac(2 * h_state, 2 * h_torque)
    s = 2 * ch.m
    blocks = [(Jz[:s], Jz2[:s]), (Ju[:s], Ju2[:s]), (Jz[s:], Jz2[s:]), (Ju[s:], Ju2[s:])]
    fd_error = max(np.abs(x - x2).max() / max(np.abs(x).max(), 1e-300) for x, x2 in blocks)
    # which outputs the indeterminate weld wrenches move
    det = np.ones(len(_OUTPUTS), bool)
    for v in null.T:
        scale = max(np.abs(lam0).max(), 1.0) * 1e-3
        _, yp, _, _ = ch.evaluate(z0, u0, lam_shift=scale * v)
        _, ym, _, _ = ch.evaluate(z0, u0, lam_shift=-scale * v)
        det &= np.abs(yp - ym) <= 2e-3 * scale   # moved by under 1e-3 of the indeterminate part's size
    names = [f"a.q{j + 1}" for j in ch.free[0]] + [f"b.q{j + 1}" for j in ch.free[1]]
    inputs = [n.replace(".q", ".tau") for n in names]
    common = dict(A=Jz[:s], B=Ju[:s], C=Jz[s:], D=Ju[s:], z0=z0, u0=u0, y0=y0, zd0=zd0, dt=0.0,
                  outputs=list(_OUTPUTS), units=list(_UNITS), q0=(ch.q0[0].copy(), ch.q0[1].copy()),
                  joints=(ch.free[0].copy(), ch.free[1].copy()), fd_error=float(fd_error), rank=rigid.rank,
                  jaw_torques=(float(jaws[0]), float(jaws[1])),
                  constraint_jacobian=rigid.constraint_jacobian(rigid.qfree0))
    if welds == "soft":
        common["q0"] = tuple(x.copy() for x in ch.split(z0[:ch.n]))   # the joints at the equilibrium
        body = ["body.x", "body.y", "body.z", "body.rx", "body.ry", "body.rz"]
        speeds = [n.replace(".q", ".qd") for n in names] + ["body.vx", "body.vy", "body.vz", "body.wx", "body.wy",
                                                            "body.wz"]
        # the tangent map selects the joints: [dq_free; dqd_free] = T (z - z0)
        T = np.zeros((2 * ch.n, 2 * ch.m))
        T[:ch.n, :ch.n] = np.eye(ch.n)
        T[ch.n:, ch.m:ch.m + ch.n] = np.eye(ch.n)
        model = HoldModel(**common, states=names + body + speeds, inputs=inputs, determined=det,
                          independent=[(0, int(j)) for j in ch.free[0]] + [(1, int(j)) for j in ch.free[1]], T=T,
                          welds="soft", weld_gains=ch.weld_gains(), body0=(ch.c0.copy(), ch.R0.copy()))
        return model if dt is None else model.discretize(dt)
    ind_names = [names[j] for j in ch.ind]
    # the tangent map: [dq_free; dqd_free] = T dz at the point
    N0 = ch.null_map(ch.constraint_jacobian(ch.qfree0))
    T = np.zeros((2 * ch.n, 2 * ch.m))
    T[:ch.n, :ch.m] = N0
    T[ch.n:, ch.m:] = N0
    model = HoldModel(
        **common, states=ind_names + [n.replace(".q", ".qd") for n in ind_names], inputs=inputs, determined=det,
        independent=[(0, int(ch.free[0][j])) if j < ch.na else (1, int(ch.free[1][j - ch.na])) for j in ch.ind],
        T=T)
    return model if dt is None else model.discretize(dt)


def _torques(ch: _Chain, tau) -> np.ndarray:
    if tau is None:
        return ch.statics()[0]
    if isinstance(tau, (tuple, list)) and len(tau) == 2 and np.ndim(tau[0]) == 1:
        ta, tb = (_checks.real_array(t, "tau") for t in tau)
        if ta.shape != (ch.r[0].dof,) or tb.shape != (ch.r[1].dof,):
            raise ValueError(f"tau must be (tau_a ({ch.r[0].dof},), tau_b ({ch.r[1].dof},)) or ({ch.n},), "
                             f"got shapes {ta.shape}, {tb.shape}")
        return np.r_[ta[ch.free[0]], tb[ch.free[1]]]
    t = _checks.real_array(tau, "tau")
    if t.shape != (ch.n,):
        raise ValueError(f"tau must be (tau_a, tau_b) or ({ch.n},) (the free joints'), got shape {t.shape}")
    return t


class HoldFeedback(CooperativeController):
    """The LQR's law for two arms holding one body (a coopsim.CooperativeController for
    sim.add_cooperative(law, [a, b])): u = u0 - K (z - z0), z the model's state from both arms' joints
    (HoldModel.state: least squares through the tangent map, so every joint's measurement counts), the jaws
    held at the model's jaw_torques. K (p, 2m): an LQR's gain (HoldModel.lqr_weights). constraint_damping (N s/m, N m s/rad: a
    number or (6,), linear then angular): a damper between the two clamps, -J_c^T c J_c qd, on their
    relative twist, which the rigid model holds at zero (so it changes neither the model nor the LQR's
    design) and the engine's soft welds do not: it damps the welds' own modes. Its work per update is one
    (p x 2n) product in numpy (the law's cross-arm gain needs both arms' states: no per-robot
    StateFeedback carries it).

    A soft-weld model (linearize_hold(..., welds="soft")): K (p, 2m) on its whole state, the body's part
    estimated, not measured: a steady-state Kalman filter on the model discretized at the law's period
    (set at reset) with both arms' joint states as the measurements, x_k = A x_k-1 + B du_k-1 + L (meas -
    T (A x_k-1 + B du_k-1)), then du = -K x_k. observer_weights = (W, V): the process noise's weights on the
    state (2m,) or (2m, 2m) and the measurements' (2n,) or (2n, 2n); default 1e-6 on the positions and 1 on
    the speeds (the unknown forces enter there), 1e-6 on the measurements. The model must be continuous."""

    def __init__(self, model: HoldModel, K, *, constraint_damping=0.0, observer_weights=None):
        super().__init__()
        self.model = model
        K = np.asarray(K, float)
        if K.shape != (model.B.shape[1], model.A.shape[0]):
            raise ValueError(f"K must have shape {(model.B.shape[1], model.A.shape[0])}, got {K.shape}")
        if model.dt != 0.0:
            raise ValueError(f"model must be the continuous model (dt = 0), got dt = {model.dt:g} s")
        self.K = K
        c = np.broadcast_to(np.asarray(constraint_damping, float), (6,)) if np.ndim(constraint_damping) <= 1 \
            else np.asarray(constraint_damping, float)
        if c.shape != (6,) or not np.all(np.isfinite(c)) or np.any(c < 0):
            raise ValueError(f"constraint_damping must be a number or (6,) finite and >= 0, got {constraint_damping!r}")
        self.constraint_damping = c
        Jc = model.constraint_jacobian
        n = Jc.shape[1]
        self._Jdamp = Jc.T @ (c[:, None] * Jc)   # the damper between the clamps: zero on the manifold
        self._x0 = model.x0
        fa, fb = model.joints
        self._fa, self._fb = fa, fb
        self._na = len(fa)
        self._n = n
        self._ta, self._tb = model.torques(model.u0)
        self.soft = model.welds == "soft"
        if self.soft:
            s = model.A.shape[0]
            # default: the unknown forces enter the speeds (1 per (rad/s)^2, (m/s)^2), the positions follow;
            # the joints' measurements trusted (1e-6)
            W = np.r_[np.full(s // 2, 1e-6), np.ones(s // 2)] if observer_weights is None \
                else np.asarray(observer_weights[0], float)
            V = np.full(2 * n, 1e-6) if observer_weights is None else np.asarray(observer_weights[1], float)
            W = np.diag(np.broadcast_to(W, (s,))) if W.ndim == 0 or W.shape == (s,) else W
            V = np.diag(np.broadcast_to(V, (2 * n,))) if V.ndim == 0 or V.shape == (2 * n,) else V
            if W.shape != (s, s) or V.shape != (2 * n, 2 * n):
                raise ValueError(f"observer_weights must be (W ({s},) or ({s}, {s}), V ({2 * n},) or "
                                 f"({2 * n}, {2 * n})), got shapes {W.shape}, {V.shape}")
            self._W, self._V = W, V
        elif observer_weights is not None:
            raise ValueError("observer_weights: only a model with welds='soft' has an observer")
        else:
            self._Kx = K @ model.state_map + np.hstack([np.zeros((len(K), n)), self._Jdamp])
        self._period = None

    def reset(self, robots, period):
        """The observer (soft welds) designed at the law's period (s): the model discretized over it, the
        joints' states measured; a steady-state Kalman filter's gain L (scipy.linalg.solve_discrete_are: SciPy is
        not among coopsim's own dependencies, `pip install scipy`)."""
        if not self.soft:
            return
        import scipy.linalg as sl
        d = self.model.discretize(period)
        Cm = self.model.T
        P = sl.solve_discrete_are(d.A.T, Cm.T, self._W, self._V)
        self._L = P @ Cm.T @ np.linalg.inv(Cm @ P @ Cm.T + self._V)
        self._d = d
        self._zhat = None
        self._du = np.zeros(len(self.K))
        self._period = period

    def compute(self, t, members):
        qa, qb = members[0].q, members[1].q
        x = np.concatenate([qa[self._fa], qb[self._fb], members[0].qd[self._fa], members[1].qd[self._fb]])
        dx = x - self._x0
        if self.soft:
            d, Cm = self._d, self.model.T
            if self._zhat is None:
                dz = np.linalg.pinv(Cm) @ dx      # the body's part at the point's (the welds relaxed)
            else:
                dz = d.A @ self._zhat + d.B @ self._du + d.zd0 * d.dt   # the prediction over the period
                dz = dz + self._L @ (dx - Cm @ dz)
            self._zhat = dz
            du = -self.K @ dz - self._Jdamp @ dx[self._n:]
            self._du = du
        else:
            du = -self._Kx @ dx
        ta, tb = self._ta.copy(), self._tb.copy()
        ta[self._fa] += du[:self._na]
        tb[self._fb] += du[self._na:]
        return [ta, tb]


def held_bar(*, control_every: int = 5, dt: float = 2e-4, log_every: int = 5, bar_mass: float = 0.3):
    """A Simulation in which both SCARAs hold one bar at rest: SCARA #1 (L_base 0.52 m) at the origin and
    #2 (L_base 0.38 m) at (0.75, 0, 0) close on a 0.35 x 0.02 x 0.02 m bar of bar_mass kg (centre
    (0.25, -0.15, 0.20) m, yaw 165 deg) 0.1 m either side of its centre and lift it 3 cm under independent
    computed torque (0.8 s; each then holds its set-point). dt (s), control_every, log_every: the
    simulation's. The scene of tests/test_cooperative_control.py, at the controllers' period control_every dt."""
    he, centre, yaw = np.array([0.175, 0.01, 0.01]), np.array([0.25, -0.15, 0.20]), np.radians(165.0)
    axis = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    r1, r2 = scara1(L_base=0.52), scara2(L_base=0.38, base_position=(0.75, 0, 0))

    def grip(r, p, **kw):
        for a in np.linspace(-np.pi, np.pi, 721):
            T = clamp_pose(r, p, a, **kw)
            if abs(T[:3, 0] @ axis) > 0.99999:
                T[:3, 3] = p + (0.015 - he[1] - 2e-4) * T[:3, 1]
                return r.ik(T, opening=0.03)
        raise RuntimeError("no clamp yaw along the bar")

    q1, q2 = grip(r1, centre + 0.1 * axis, pitch=np.pi / 2), grip(r2, centre - 0.1 * axis)
    P = np.eye(4)
    P[:3, :3] = [[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]]
    P[:3, 3] = centre
    w = World(gravity=(0, 0, -9.81))
    w.add_free_box("bar", he, bar_mass, P, friction=0.5)
    top = centre[2] - he[2]
    ped = np.eye(4)
    ped[:3, 3] = [centre[0], centre[1], top / 2]
    w.add_static_box("pedestal", [0.004, 0.004, top / 2], ped, friction=0.5)
    sim = Simulation(dt=dt, world=w, log_every=log_every, control_every=control_every)
    for r, q, z in ((r1, q1, 2), (r2, q2, 3)):
        b = q.copy()
        b[5] = 0.019
        d = b.copy()
        d[z] -= 0.03
        sim.add_robot(r, ComputedTorque(400.0, 40.0), CubicTrajectory([0, 0.02, 0.12, 0.17, 0.47],
                                                                         np.array([q, q, b, b, d])))
    sim.run(0.8, progress=False)
    if sim.holding(0) != "bar" or sim.holding(1) != "bar":
        raise RuntimeError("held_bar: the clamps did not grasp the bar")
    for i in (0, 1):
        sim.set_reference(i, SetPoint(sim.state(i)[0]))
    return sim


def squeeze_after_push(sim, law, *, force: float = 1.0, duration: float = 0.1, before: float = 0.5,
                       after: float = 0.5, a: int = 0, b: int = 1, band: float = 0.05, level: float = 0.05) -> dict:
    """Pushes the body robots a and b hold (sim: both hold it, e.g. held_bar()) under a cooperative law:
    the law takes over (sim.add_cooperative(law, [a, b])) and holds it for `before` s, then `force` N,
    horizontal, across the line between the welds, pushes the body's centre for `duration` s; the run goes
    on `after` s past the push. Returns a dict: t (s from the push's start), squeeze (N) per log row,
    peak (N, largest |squeeze| from the push on), settle (s after the push's end, when |squeeze| is last
    above band * peak, 0 if never), settle_abs (the same for `level` N, 0.05 N unless given: one band for
    laws whose peaks differ), torque_peak (both arms' largest
    change of each free joint's torque from the push on against just before it, N m, N; (p,)),
    bar_peak (m, the body's largest displacement from where it was at the push)."""
    force = _checks.number(force, "force", unit="N")
    duration = _checks.positive(duration, "duration", unit="s")
    before = _checks.positive(before, "before", unit="s")
    after = _checks.positive(after, "after", unit="s")
    band = _checks.number(band, "band", 0.0, 1.0)
    level = _checks.positive(level, "level", unit="N")
    name = sim.holding(a)
    co = sim.cooperation(min(a, b), max(a, b))
    if name is None or not co.holding:
        raise ValueError(f"sim: robots {a} and {b} do not hold one body")
    e = co.point_b - co.point_a
    g = np.asarray(sim.world.gravity, float)
    across = np.cross(g, e)
    across /= np.linalg.norm(across)
    sim.add_cooperative(law, [a, b])
    sim.run(sim.time + before, progress=False)
    ts = sim.time
    start = np.asarray(sim.body_state(name).position)
    sim.set_body_wrench(name, np.r_[force * across, 0.0, 0.0, 0.0])
    sim.run(ts + duration, progress=False)
    sim.set_body_wrench(name, np.zeros(6))
    log = sim.run(ts + duration + after, progress=False)
    t = np.asarray(log.t)
    k = t >= ts - 1e-9
    sq = np.asarray(log.cooperation(min(a, b), max(a, b))["squeeze"])[k]
    tt = t[k] - ts
    peak = float(np.abs(sq).max())

    def settle(level):
        out = np.nonzero((np.abs(sq) > level) & (tt >= duration))[0]
        return float(tt[out[-1]] - duration) if len(out) else 0.0

    robots = sim.robots
    taus = []
    for i in (a, b):
        f = [j for j in range(robots[i].dof) if j != robots[i].clamp.moving_joint - 1]
        tau = np.asarray(log[i].tau)[:, f]
        pre = tau[(t < ts) & (t > ts - 0.05)].mean(axis=0)
        taus.append(np.abs(tau[k] - pre).max(axis=0))
    p = np.asarray(log.bodies[name].position)[k]
    bar_peak = float(np.linalg.norm(p - start, axis=1).max())
    return dict(t=tt, squeeze=sq, peak=peak, settle=settle(band * peak), settle_abs=settle(level),
                torque_peak=np.concatenate(taus), bar_peak=bar_peak)
