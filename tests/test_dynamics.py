"""Numeric dynamics against hand-derived references, physical invariants,
a second algorithm and finite differences.

Tolerances: hand-derived references 1e-12 (absolute, values of order 1);
finite differences use central differences with h = 1e-6, so their
truncation error is ~h^2 * third derivative and round-off ~eps / h: 1e-7
relative to the quantity's scale is the stated bound.
"""
from __future__ import annotations

import numpy as np
import pytest

import coopsim as cs
from conftest import FLEET_SEEDS, random_fleet, random_robot, random_state

H = 1e-6
FD_TOL = 1e-7


def pendulum(m=1.3, L=0.7, lc=0.4, Izz=0.05, g=9.81):
    dh = [[0.0, 0.0, L, 0.0]]
    com = [[0.0, 0.0, lc, 0.0]]
    I = np.diag([0.03, 0.04, Izz])
    return cs.Robot.from_dh(dh, com, [m], [I], joint_types="R", gravity=(0.0, -g, 0.0))


def test_pendulum_matches_hand_derivation():
    m, L, lc, Izz, g = 1.3, 0.7, 0.4, 0.05, 9.81
    r = pendulum(m, L, lc, Izz, g)
    for q in np.linspace(-3, 3, 13):
        qv, qd = np.array([q]), np.array([0.7])
        # M = m lc^2 + Izz; C = 0; G = m g lc cos q (gravity along -y, V = m g y)
        assert r.mass_matrix(qv)[0, 0] == pytest.approx(m * lc**2 + Izz, abs=1e-12)
        assert abs(r.coriolis(qv, qd)[0]) < 1e-12
        assert abs(r.coriolis_matrix(qv, qd)[0, 0]) < 1e-12
        assert r.gravity(qv)[0] == pytest.approx(m * g * lc * np.cos(q), abs=1e-12)
        T, V = r.energy(qv, qd)
        assert T == pytest.approx(0.5 * (m * lc**2 + Izz) * 0.49, abs=1e-12)
        assert V == pytest.approx(m * g * lc * np.sin(q), abs=1e-12)


def test_prismatic_joint_under_gravity():
    m, g = 2.5, 9.81
    # vertical slider with a tilted CoM row: only the mass matters along z
    r = cs.Robot.from_dh([[0.3, 0.1, 0.0, 0.0]], [[0.2, 0.05, 0.1, 0.4]], [m], [np.diag([0.1, 0.2, 0.25])],
                         joint_types="P", friction=[1.5])
    for q in (-0.5, 0.0, 0.8):
        qv, qd, qdd = np.array([q]), np.array([0.4]), np.array([-2.0])
        assert r.mass_matrix(qv)[0, 0] == pytest.approx(m, abs=1e-12)
        assert r.gravity(qv)[0] == pytest.approx(m * g, abs=1e-12)
        assert abs(r.coriolis(qv, qd)[0]) < 1e-12
        assert r.friction(qd)[0] == pytest.approx(1.5 * 0.4, abs=1e-15)
        # eq. (1): tau = M qdd + C + G + K qd
        assert r.inverse_dynamics(qv, qd, qdd)[0] == pytest.approx(m * -2.0 + m * g + 1.5 * 0.4, abs=1e-12)
        # free fall: qdd = -g - K qd / m under zero torque
        assert r.forward_dynamics(qv, qd, [0.0])[0] == pytest.approx(-g - 1.5 * 0.4 / m, abs=1e-12)


def planar_2link_reference(q, qd, m1, m2, l1, lc1, lc2, I1, I2, g):
    c2 = np.cos(q[1])
    M = np.array([[m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * c2) + I1 + I2,
                   m2 * (lc2**2 + l1 * lc2 * c2) + I2],
                  [m2 * (lc2**2 + l1 * lc2 * c2) + I2, m2 * lc2**2 + I2]])
    h = -m2 * l1 * lc2 * np.sin(q[1])
    C = np.array([[h * qd[1], h * (qd[0] + qd[1])], [-h * qd[0], 0.0]])
    G = np.array([(m1 * lc1 + m2 * l1) * g * np.cos(q[0]) + m2 * lc2 * g * np.cos(q[0] + q[1]),
                  m2 * lc2 * g * np.cos(q[0] + q[1])])
    return M, C, G


def test_planar_two_link_arm_matches_textbook(rng):
    m1, m2, l1, l2, lc1, lc2, I1, I2, g = 1.2, 0.8, 0.5, 0.4, 0.25, 0.2, 0.03, 0.02, 9.81
    r = cs.Robot.from_dh([[0, 0, l1, 0], [0, 0, l2, 0]], [[0, 0, lc1, 0], [0, 0, lc2, 0]], [m1, m2],
                         [np.diag([0.02, 0.015, I1]), np.diag([0.004, 0.018, I2])], joint_types="RR",
                         gravity=(0.0, -g, 0.0))
    for _ in range(50):
        q, qd = rng.uniform(-np.pi, np.pi, 2), rng.normal(size=2)
        M, C, G = planar_2link_reference(q, qd, m1, m2, l1, lc1, lc2, I1, I2, g)
        np.testing.assert_allclose(r.mass_matrix(q), M, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r.coriolis_matrix(q, qd), C, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r.coriolis(q, qd), C @ qd, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r.gravity(q), G, rtol=0, atol=1e-12)


def all_robots():
    yield cs.robots.scara1(backend="numeric")
    yield cs.robots.scara2(backend="numeric")
    yield from random_fleet()
    yield random_robot(1000, dof=6, mixed=True)
    yield random_robot(1001, dof=12, mixed=True)


ROBOTS = list(all_robots())
IDS = [r.name for r in ROBOTS]


def test_random_fleet_has_fifty_mixed_robots():
    """Every invariant below runs on at least 50 random robots, each with
    both revolute and prismatic joints (2 to 7 of them)."""
    fleet = [r for r in ROBOTS if r.name in {f"random{s}" for s in FLEET_SEEDS}]
    assert len(fleet) >= 50
    for r in fleet:
        assert 2 <= r.dof <= 7 and "R" in r.joint_types and "P" in r.joint_types, r.name
    # and they are different robots: DH tables and joint strings vary
    assert len({r.dh.tobytes() for r in fleet}) == len(fleet)
    assert len({r.joint_types for r in fleet}) >= 20


@pytest.fixture(params=range(len(ROBOTS)), ids=IDS)
def robot(request):
    return ROBOTS[request.param]


def test_mass_matrix_symmetric_positive_definite(robot, rng):
    for _ in range(5):
        q, _, _ = random_state(robot, rng)
        M = robot.mass_matrix(q)
        assert np.abs(M - M.T).max() <= 1e-14 * np.abs(M).max()
        assert np.linalg.eigvalsh(M).min() > 0


def test_kinetic_energy_equals_link_velocities(robot, rng):
    """0.5 qd^T M qd against sum of 0.5 m v^2 + 0.5 w^T I w, with the CoM
    velocities from finite differences of the CoM frames (second algorithm)."""
    q, qd, _ = random_state(robot, rng)
    Fp, Fm = robot.com_frames(q + H * qd), robot.com_frames(q - H * qd)
    F = robot.com_frames(q)
    T_ref = 0.0
    for i in range(robot.dof):
        v = (Fp[i, :3, 3] - Fm[i, :3, 3]) / (2 * H)
        Rdot = (Fp[i, :3, :3] - Fm[i, :3, :3]) / (2 * H)
        W = Rdot @ F[i, :3, :3].T
        w = np.array([W[2, 1], W[0, 2], W[1, 0]])
        Iw = F[i, :3, :3] @ robot.inertias[i] @ F[i, :3, :3].T
        T_ref += 0.5 * robot.masses[i] * v @ v + 0.5 * w @ Iw @ w
    T, _ = robot.energy(q, qd)
    assert T == pytest.approx(0.5 * qd @ robot.mass_matrix(q) @ qd, rel=1e-13)
    assert abs(T - T_ref) <= FD_TOL * max(T, 1e-3)


def test_mdot_minus_2c_is_skew(robot, rng):
    for _ in range(3):
        q, qd, _ = random_state(robot, rng)
        Mdot = (robot.mass_matrix(q + H * qd) - robot.mass_matrix(q - H * qd)) / (2 * H)
        S = Mdot - 2 * robot.coriolis_matrix(q, qd)
        # finite-difference round-off scales with |M| |qd| / h
        scale = max(np.abs(Mdot).max(), np.abs(robot.mass_matrix(q)).max() * np.abs(qd).max())
        assert np.abs(S + S.T).max() <= FD_TOL * scale


def test_mass_matrix_derivatives_match_finite_differences(robot, rng):
    q, _, _ = random_state(robot, rng)
    dM = robot.mass_matrix_derivatives(q)
    E = np.eye(robot.dof)
    num = np.array([(robot.mass_matrix(q + H * e) - robot.mass_matrix(q - H * e)) / (2 * H) for e in E])
    assert np.abs(dM - num).max() <= FD_TOL * max(np.abs(num).max(), np.abs(robot.mass_matrix(q)).max())


def test_coriolis_matrix_and_vector_agree_with_rnea(robot, rng):
    """Christoffel C (from dM/dq) times qd against RNEA's velocity terms."""
    q, qd, _ = random_state(robot, rng)
    c = robot.coriolis(q, qd)
    Cq = robot.coriolis_matrix(q, qd) @ qd
    assert np.abs(c - Cq).max() <= 1e-12 * max(1.0, np.abs(c).max())


def test_gravity_is_gradient_of_potential(robot, rng):
    q, _, _ = random_state(robot, rng)
    zero = np.zeros(robot.dof)
    V = lambda x: robot.energy(x, zero)[1]  # noqa: E731
    grad = np.array([(V(q + H * e) - V(q - H * e)) / (2 * H) for e in np.eye(robot.dof)])
    G = robot.gravity(q)
    assert np.abs(G - grad).max() <= FD_TOL * max(1.0, np.abs(G).max())


def test_inverse_of_forward_dynamics(robot, rng):
    for _ in range(5):
        q, qd, _ = random_state(robot, rng)
        tau = rng.normal(size=robot.dof) * 5
        qdd = robot.forward_dynamics(q, qd, tau)
        back = robot.inverse_dynamics(q, qd, qdd)
        assert np.abs(back - tau).max() <= 1e-10 * max(1.0, np.abs(tau).max())


def test_rnea_equals_lagrangian_form(robot, rng):
    """RNEA against M qdd + C(q, qd) qd + G + K qd from CRBA and Christoffel."""
    q, qd, qdd = random_state(robot, rng)
    tau = robot.inverse_dynamics(q, qd, qdd)
    lag = (robot.mass_matrix(q) @ qdd + robot.coriolis_matrix(q, qd) @ qd + robot.gravity(q) + robot.friction(qd))
    assert np.abs(tau - lag).max() <= 1e-12 * max(1.0, np.abs(tau).max())


def rotation_rate(R_plus, R_minus, R):
    W = (R_plus - R_minus) / (2 * H) @ R.T
    return np.array([W[2, 1], W[0, 2], W[1, 0]])


def test_jacobians_equal_finite_differences(robot, rng):
    q, _, _ = random_state(robot, rng)
    n = robot.dof
    link = int(rng.integers(1, n + 1))
    point = rng.uniform(-0.2, 0.2, 3)
    J = robot.jacobian(q, link=link, point=point)
    F = robot.frames(q)
    for j, e in enumerate(np.eye(n)):
        Fp, Fm = robot.frames(q + H * e), robot.frames(q - H * e)
        pp = Fp[link, :3, :3] @ point + Fp[link, :3, 3]
        pm = Fm[link, :3, :3] @ point + Fm[link, :3, 3]
        np.testing.assert_allclose(J[:3, j], (pp - pm) / (2 * H), atol=FD_TOL)
        np.testing.assert_allclose(J[3:, j], rotation_rate(Fp[link, :3, :3], Fm[link, :3, :3], F[link, :3, :3]),
                                   atol=FD_TOL)
    # tool Jacobian against the tool pose
    Jt = robot.tool_jacobian(q)
    T = robot.fk(q)
    for j, e in enumerate(np.eye(n)):
        Tp, Tm = robot.fk(q + H * e), robot.fk(q - H * e)
        np.testing.assert_allclose(Jt[:3, j], (Tp[:3, 3] - Tm[:3, 3]) / (2 * H), atol=FD_TOL)
        np.testing.assert_allclose(Jt[3:, j], rotation_rate(Tp[:3, :3], Tm[:3, :3], T[:3, :3]), atol=FD_TOL)


def rotation_log(R):
    """Rotation vector (axis times angle, angle < pi) of the rotation matrix R."""
    v = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s, c = np.linalg.norm(v), 0.5 * (np.trace(R) - 1.0)
    return v if s == 0.0 else v * (np.arctan2(s, c) / s)


def tool_displacement(robot, q_plus, q_minus):
    """TCP motion from pose q_minus to q_plus: position change and rotation
    vector (world frame), from forward kinematics alone."""
    Tp, Tm = robot.fk(q_plus), robot.fk(q_minus)
    return np.concatenate([Tp[:3, 3] - Tm[:3, 3], rotation_log(Tp[:3, :3] @ Tm[:3, :3].T)])


def tool_jacobian_fd(robot, q):
    """Tool Jacobian (6, n) by central differences of fk, independent of the
    engine's Jacobians."""
    return np.column_stack([tool_displacement(robot, q + H * e, q - H * e) / (2 * H) for e in np.eye(robot.dof)])


def test_tool_wrench_balanced_at_rest(robot, rng):
    """With tau = G - J^T F, J from finite differences of the TCP pose, the
    robot stays at rest under the TCP wrench F; and F does on the TCP the
    virtual work the engine's joint torques J^T F do on the joints.

    Tolerance: J_fd has truncation error ~h^2 and round-off ~eps |x| / h,
    ~1e-9 relative here, so 1e-6 of the size of the terms that cancel."""
    q, _, _ = random_state(robot, rng)
    n = robot.dof
    zero = np.zeros(n)
    F = rng.normal(size=6) * 3
    J = tool_jacobian_fd(robot, q)
    tau = robot.gravity(q) - J.T @ F
    qdd = robot.forward_dynamics(q, zero, tau, f_ext=F)
    # the torque left unbalanced, M qdd = (J - J_fd)^T F
    residual = robot.mass_matrix(q) @ qdd
    scale = (np.abs(J.T) @ np.abs(F)).max()
    assert np.abs(residual).max() <= 1e-6 * scale
    back = robot.inverse_dynamics(q, zero, zero, f_ext=F)
    assert np.abs(back - tau).max() <= 1e-6 * scale
    # virtual work over a small joint displacement 2 dq (central), in which
    # the TCP moves by dx: F . dx = (J^T F) . 2 dq up to O(|dq|^3)
    for _ in range(3):
        dq = rng.normal(size=n) * 1e-6
        dx = tool_displacement(robot, q + dq, q - dq)
        work = F @ dx
        joint_work = robot.external_torques(q, F) @ (2 * dq)
        assert abs(work - joint_work) <= 1e-6 * (np.abs(F) @ (np.abs(J) @ np.abs(2 * dq)))


def test_wrench_at_any_point_of_any_link(robot, rng):
    q, qd, qdd = random_state(robot, rng)
    n = robot.dof
    wrenches = [cs.Wrench(int(rng.integers(1, n + 1)), rng.uniform(-0.2, 0.2, 3), rng.normal(size=6))
                for _ in range(3)]
    expected = sum(robot.jacobian(q, w.link, w.point).T @ w.wrench for w in wrenches)
    np.testing.assert_allclose(robot.external_torques(q, wrenches), expected, rtol=0, atol=1e-12)
    tau = robot.inverse_dynamics(q, qd, qdd, f_ext=wrenches)
    np.testing.assert_allclose(tau, robot.inverse_dynamics(q, qd, qdd) - expected, rtol=0, atol=1e-11)
    np.testing.assert_allclose(robot.forward_dynamics(q, qd, tau, f_ext=wrenches), qdd, rtol=0, atol=1e-9)


def test_point_force_does_virtual_work():
    """A force at a point on the pendulum gives the torque r x F about the axis."""
    r = pendulum()
    q = np.array([0.3])
    F = np.array([0.0, 2.0, 0.0, 0.0, 0.0, 0.0])
    # point at the link's end: frame 1 origin, at L (cos q, sin q, 0)
    tau = r.external_torques(q, [cs.Wrench(1, [0.0, 0.0, 0.0], F)])
    assert tau[0] == pytest.approx(0.7 * np.cos(0.3) * 2.0, abs=1e-14)


def test_base_placement_moves_frames_not_dynamics(rng):
    r = cs.robots.scara1(backend="numeric")
    moved = r.with_base([0.75, 0.2, 0.0], 0.6)
    q, qd, qdd = random_state(r, rng)
    T0 = np.eye(4)
    T0[:3, :3] = [[np.cos(0.6), -np.sin(0.6), 0], [np.sin(0.6), np.cos(0.6), 0], [0, 0, 1]]
    T0[:3, 3] = [0.75, 0.2, 0.0]
    np.testing.assert_allclose(moved.fk(q), T0 @ r.fk(q), atol=1e-14)
    # gravity along z is invariant to a yaw and a translation
    np.testing.assert_allclose(moved.inverse_dynamics(q, qd, qdd), r.inverse_dynamics(q, qd, qdd), atol=1e-12)
