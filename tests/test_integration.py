"""Fixed-step integration: energy conservation, dissipation, order of
convergence, end stops and the batch entry point."""
from __future__ import annotations

import numpy as np
import pytest

import coopsim as cs
from conftest import FLEET_SEEDS, python_ran_during, random_robot

DT = 2e-4


def frictionless(name, **kw):
    make = getattr(cs.robots, name)
    return make(friction=np.zeros(6), backend="numeric", **kw)


def total_energy(robot, Q, QD):
    return np.array([sum(robot.energy(q, qd)) for q, qd in zip(Q, QD)])


MOVING = {
    "scara1": (np.array([0.3, -0.8, 0.1, 0.5, 0.6, 0.02]), np.array([1.5, -2.0, 0.2, 3.0, -1.0, 0.05])),
    "scara2": (np.array([0.3, -0.8, 0.5, 0.1, 0.5, 0.02]), np.array([1.5, -2.0, 1.0, 0.2, 3.0, 0.05])),
}


def energies(robot, Q, QD):
    """Kinetic and potential energy (m, 2) along a trajectory."""
    return np.array([robot.energy(q, qd) for q, qd in zip(Q, QD)])


@pytest.mark.parametrize("name", ["scara1", "scara2"])
@pytest.mark.parametrize("gravity", [True, False], ids=["gravity", "no-gravity"])
def test_rk4_conserves_energy_without_torque_or_friction(name, gravity):
    """Zero torque, zero friction, RK4 at 0.2 ms over 5 s: total energy
    constant to 1e-6 of the energy at the start, the potential referred to
    the start pose, i.e. of T0.

    End stops are off (they dissipate; lossless ones put a kink in the force
    that costs RK4 its order). No gravity direction then keeps the SCARAs
    bounded: the quill is vertical and the jaw slides horizontally, so one of
    them always falls. With gravity the quill falls ~120 m, exchanging ~1000 J
    against T0 < 1 J; T0 as the scale asks the kinetic and potential terms of
    the fall to cancel to ~1e-10 of themselves, far stricter than a scale of
    the energy exchanged."""
    g = (0.0, 0.0, -9.81) if gravity else (0.0, 0.0, 0.0)
    r = frictionless(name, gravity=g)
    q0, qd0 = MOVING[name]
    t, Q, QD = cs.integrate(r, q0, qd0, np.zeros(6), dt=DT, steps=25000, end_stops=False, record_every=50)
    assert t[-1] == pytest.approx(5.0)
    TV = energies(r, Q, QD)
    E = TV.sum(axis=1)
    T0 = TV[0, 0]
    assert T0 > 0.1  # a state that moves
    if gravity:
        assert np.ptp(TV[:, 1]) > 100 * T0  # the fall this scale is strict about
    else:
        assert np.all(TV[:, 1] == 0)
    assert np.abs(E - E[0]).max() <= 1e-6 * T0


def fleet_robot_and_state(seed, **kw):
    r = random_robot(seed, mixed=True, friction=False, **kw)
    rng = np.random.default_rng(seed)
    return r, rng.uniform(-1, 1, r.dof), rng.normal(size=r.dof)


@pytest.mark.parametrize("seed", FLEET_SEEDS)
def test_rk4_conserves_energy_random_robots_without_gravity(seed):
    """The random fleet (mixed R/P, any alpha), 5 s at 0.2 ms, zero torque
    and friction: without gravity the energy is kinetic only, so its
    conserved value T0 is the scale."""
    r, q0, qd0 = fleet_robot_and_state(seed, gravity=(0.0, 0.0, 0.0))
    t, Q, QD = cs.integrate(r, q0, qd0, np.zeros(r.dof), dt=DT, steps=25000, end_stops=False, record_every=50)
    assert t[-1] == pytest.approx(5.0)
    TV = energies(r, Q, QD)
    assert np.all(TV[:, 1] == 0)
    assert np.abs(TV[:, 0] - TV[0, 0]).max() <= 1e-6 * TV[0, 0]


@pytest.mark.parametrize("seed", FLEET_SEEDS)
def test_rk4_conserves_energy_random_robots_with_tilted_gravity(seed):
    """The random fleet with every alpha rounded to 0 or pi, so all joint axes
    stay parallel to the base z, and gravity tilted perpendicular to them:
    every prismatic axis is level with respect to gravity, nothing falls, the
    potential depends on the revolute angles only and is bounded (the arm
    swings as a pendulum).
    Scale: T0 plus the range of potential explored, the most energy the
    motion exchanges; 1e-6 of it over 5 s at 0.2 ms."""
    r, q0, qd0 = fleet_robot_and_state(seed)
    dh = r.dh.copy()
    dh[:, 3] = np.where(np.abs(dh[:, 3]) < np.pi / 2, 0.0, np.pi)
    angle = np.random.default_rng(seed).uniform(-np.pi, np.pi)
    g = 9.81 * np.array([np.cos(angle), np.sin(angle), 0.0])
    r = cs.Robot.from_dh(dh, r.com, r.masses, r.inertias, r.joint_types, gravity=g,
                         base_position=r.base_position, base_yaw=r.base_yaw, name=r.name)
    t, Q, QD = cs.integrate(r, q0, qd0, np.zeros(r.dof), dt=DT, steps=25000, end_stops=False, record_every=50)
    assert t[-1] == pytest.approx(5.0)
    TV = energies(r, Q, QD)
    E = TV.sum(axis=1)
    # nothing falls: each CoM stays within sum |a| + |a_com| of the first
    # axis, which bounds the potential's range a priori
    reach = np.cumsum(np.abs(dh[:, 2])) - np.abs(dh[:, 2]) + np.abs(r.com[:, 2])
    assert np.ptp(TV[:, 1]) <= 2 * 9.81 * (r.masses @ reach)
    # the level sliders coast: vertical motion decouples from the swinging,
    # with a constant mass matrix, so RK4 keeps their momenta (M qd)_j to round-off
    prismatic = np.array([c == "P" for c in r.joint_types])
    p = np.array([(r.mass_matrix(q) @ qd)[prismatic] for q, qd in zip(Q, QD)])
    assert np.abs(p - p[0]).max() <= 1e-12 * max(1.0, np.abs(p).max())
    scale = TV[0, 0] + np.ptp(TV[:, 1])
    assert np.abs(E - E[0]).max() <= 1e-6 * scale


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_friction_never_increases_energy(name):
    r = getattr(cs.robots, name)(backend="numeric")
    q0, qd0 = MOVING[name]
    t, Q, QD = cs.integrate(r, q0, qd0, np.zeros(6), dt=DT, steps=10000, end_stops=False, record_every=10)
    E = total_energy(r, Q, QD)
    dE = np.diff(E)
    # dissipation is K qd^2 >= 0; allow only round-off of the energy itself
    assert dE.max() <= 1e-12 * np.abs(E).max()
    assert E[-1] < E[0]


def final_state(robot, q0, qd0, dt, t_end, method="rk4"):
    steps = int(round(t_end / dt))
    _, Q, QD = cs.integrate(robot, q0, qd0, np.zeros(robot.dof), dt=dt, steps=steps, method=method,
                            end_stops=False, record_every=steps)
    return np.concatenate([Q[-1], QD[-1]])


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_rk4_is_fourth_order(name):
    """Halving dt divides the error by about 2^4 = 16."""
    r = frictionless(name)
    q0, qd0 = MOVING[name]
    ref = final_state(r, q0, qd0, 2.5e-4, 0.5)
    e1 = np.abs(final_state(r, q0, qd0, 4e-3, 0.5) - ref).max()
    e2 = np.abs(final_state(r, q0, qd0, 2e-3, 0.5) - ref).max()
    assert 13.0 < e1 / e2 < 19.0


def test_semi_implicit_euler_is_first_order():
    r = frictionless("scara2")
    q0, qd0 = MOVING["scara2"]
    ref = final_state(r, q0, qd0, 2.5e-4, 0.5)
    e1 = np.abs(final_state(r, q0, qd0, 2e-3, 0.5, "euler") - ref).max()
    e2 = np.abs(final_state(r, q0, qd0, 1e-3, 0.5, "euler") - ref).max()
    assert 1.6 < e1 / e2 < 2.4


def test_rk4_step_matches_integrate():
    r = cs.robots.scara1(backend="numeric")
    q, qd = MOVING["scara1"]
    tau = np.array([1.0, -0.5, 2.0, 0.1, 0.05, 0.0])
    q1, qd1 = cs.rk4_step(r, q, qd, tau, DT)
    _, Q, QD = cs.integrate(r, q, qd, tau, dt=DT, steps=1)
    np.testing.assert_array_equal(Q[-1], q1)
    np.testing.assert_array_equal(QD[-1], qd1)


def test_integrate_records_first_and_last_and_per_step_torques():
    r = cs.robots.scara2(backend="numeric")
    q, qd = MOVING["scara2"]
    tau = np.tile(np.array([0.5, 0.1, 0.0, 5.0, 0.0, 0.0]), (7, 1))
    t, Q, QD = cs.integrate(r, q, qd, tau, dt=DT, steps=7, record_every=3)
    np.testing.assert_allclose(t, [0, 3 * DT, 6 * DT, 7 * DT])
    qs, qds = q.copy(), qd.copy()
    for k in range(7):
        qs, qds = cs.rk4_step(r, qs, qds, tau[k], DT)
    np.testing.assert_array_equal(Q[-1], qs)


@pytest.mark.parametrize("name,joint", [("scara1", 2), ("scara2", 3)])
def test_quill_end_stop_bounds_penetration(name, joint):
    """The quill falls under gravity onto its lower end stop: it stops within
    a few millimetres of the limit and comes to rest there, never passing
    through."""
    r = getattr(cs.robots, name)(backend="numeric")
    q0 = np.zeros(6)
    q0[joint] = 0.05
    q0[5] = 0.02
    t, Q, QD = cs.integrate(r, q0, np.zeros(6), np.zeros(6), dt=DT, steps=10000, record_every=10)
    q_max = r.q_limits[joint, 1]
    # impact at about 2 m/s: penetration ~ v / (e w) = 1.5 mm at w = 500 rad/s
    assert Q[:, joint].max() < q_max + 2e-3
    assert abs(Q[-1, joint] - q_max) < 1e-4     # rests on the stop (static sag g / w^2)
    assert abs(QD[-1, joint]) < 1e-3
    # without end stops it falls through
    _, Qf, _ = cs.integrate(r, q0, np.zeros(6), np.zeros(6), dt=DT, steps=10000, end_stops=False,
                            record_every=10000)
    assert Qf[-1, joint] > q_max + 0.1


def test_end_stop_pushes_and_never_pulls():
    r = cs.robots.scara2(backend="numeric")
    q = np.array([0.0, 0.0, 0.0, 0.31, 0.0, 0.0])  # 1 cm beyond the quill's stroke
    assert r.end_stop_torques(q, np.zeros(6))[3] < 0
    # leaving the stop fast: damping would pull, the stop gives zero instead
    assert r.end_stop_torques(q, np.array([0, 0, 0, -10.0, 0, 0]))[3] == 0.0
    assert np.all(r.end_stop_torques(np.zeros(6) + [0, 0, 0, 0.1, 0, 0.01], np.ones(6)) == 0)


def test_batch_forward_dynamics_equals_single_calls():
    r = cs.robots.scara1(backend="numeric")
    rng = np.random.default_rng(3)
    N = 2000
    Q, QD, TAU = rng.uniform(-1, 1, (N, 6)), rng.normal(size=(N, 6)), rng.normal(size=(N, 6))
    out = cs.forward_dynamics_batch(r, Q, QD, TAU)
    single = np.array([r.forward_dynamics(q, qd, tau) for q, qd, tau in zip(Q, QD, TAU)])
    np.testing.assert_array_equal(out, single)
    np.testing.assert_array_equal(cs.forward_dynamics_batch(r, Q, QD, TAU, threads=1), out)


def test_divergence_is_reported_with_the_step():
    # absurd stiffness on the stop with a huge step makes the state blow up
    r = cs.robots.scara2(backend="numeric")
    q0 = np.array([0.0, 0.0, 0.0, 0.5, 0.0, 0.0])
    with pytest.raises((RuntimeError, ValueError), match="step"), pytest.warns(RuntimeWarning, match="end stops"):
        cs.integrate(cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, r.joint_types, q_limits=r.q_limits,
                                      end_stop_frequency=1e5), q0, np.zeros(6), np.zeros(6), dt=0.05,
                     steps=200)


def test_batch_forward_dynamics_releases_the_gil():
    robot = cs.robots.scara1()
    rng = np.random.default_rng(2)
    N = 400_000
    Q = rng.uniform(robot.q_limits[:, 0], robot.q_limits[:, 1], (N, 6))
    QD, TAU = rng.normal(size=(N, 6)), rng.normal(size=(N, 6))
    # another Python thread gets to run during the call (see python_ran_during)
    assert python_ran_during(lambda: cs.forward_dynamics_batch(robot, Q, QD, TAU, threads=1)) > 0


def test_a_runaway_is_reported_as_one_not_as_a_robot_without_mass():
    # torques far beyond the drives at a large step: the state runs away within the first steps, and an RK4
    # stage evaluated there finds the mass matrix lost to rounding; integrate applies tau as given (no
    # saturation at tau_limits), which is what lets it run away
    r = cs.robots.scara1()
    with pytest.warns(RuntimeWarning, match="end stops"):
        with pytest.raises(cs.DivergenceError) as err:
            cs.integrate(r, np.zeros(6), np.zeros(6), np.full(6, 1e12), dt=0.01, steps=200)
    msg = str(err.value)
    assert "the state ran away: the rk4 stage" in msg and "was evaluated at q = [" in msg and "qd = [" in msg
    assert "(a joint beyond 10000 rad/s or 1e+06 rad (m/s, m))" in msg or "(state is no longer finite)" in msg
    assert "links without mass" not in msg and "not positive definite" not in msg
    assert err.value.step == 1
    # tau is not saturated: tau at the limits moves the robot less than tau twice over them
    tl = r.tau_limits
    _, Q1, _ = cs.integrate(r, np.zeros(6), np.zeros(6), tl, dt=1e-3, steps=20, end_stops=False)
    _, Q2, _ = cs.integrate(r, np.zeros(6), np.zeros(6), 2 * tl, dt=1e-3, steps=20, end_stops=False)
    assert np.all(np.abs(Q2[-1]) > 1.5 * np.abs(Q1[-1]))


def test_a_singular_mass_matrix_at_a_sane_state_still_names_the_links_without_mass():
    dh = np.array([[0, 0.3, 0, np.pi / 2], [0, 0, 0.4, 0], [0, 0, 0.3, 0]])
    com = np.array([[0, 0, 0], [-0.2, 0, 0], [-0.15, 0, 0]])
    I = np.array([np.diag([0.01, 0.01, 0.01]), np.diag([0.01, 0.05, 0.05]), np.zeros((3, 3))])
    r = cs.Robot.from_dh(dh, com, [1.0, 2.0, 0.0], I, "RRR")
    with pytest.raises(cs.DivergenceError) as err:
        cs.integrate(r, np.array([0.25, -0.5, 0.75]), np.zeros(3), np.zeros(3), dt=1e-3, steps=10)
    msg = str(err.value)
    assert "the dynamics failed in the rk4 stage 1 (" in msg and "not positive definite at q = [0.25, -0.5, 0.75]" in msg
    assert "links without mass" in msg and "ran away" not in msg
