"""Linear models (cs.linearize): the continuous (A, B) from the dynamics' derivatives, the exact
Jacobians of RK4 and semi-implicit Euler steps against central differences of cs.rk4_step / euler_step
(and of a reference RK4 under a wrench), the loops closed by ComputedTorque (analytically
[[0, 1], [-kp, -kd]] with the exact model) and PID (its integral, velocity filter and last q in the
state, against central differences of its updates), robots beyond 12 states, bad input in one line."""
from __future__ import annotations

import numpy as np
import pytest

import coopsim as cs
from conftest import random_fleet
from test_derivatives import ARMS, _central, _example_robot_data, _one_line, _rel, _with_drives

SCARA = cs.robots.scara1(backend="numeric")


def _panda():
    rel, locked = ARMS["panda"]
    return cs.Robot.from_urdf(_example_robot_data(rel), locked=locked)


def _inside(robot, rng):
    """A state inside the joint limits (30 % to 70 % of each range, +-1 for unlimited joints)."""
    lim = np.array(robot.q_limits, float)
    lo, hi = np.maximum(lim[:, 0], -1.0), np.minimum(lim[:, 1], 1.0)
    q = lo + (hi - lo) * rng.uniform(0.3, 0.7, robot.dof)
    return q, 0.3 * rng.normal(size=robot.dof), 2.0 * rng.normal(size=robot.dof)


ROBOTS = [SCARA, _with_drives(SCARA, 3), cs.robots.scara2(), random_fleet()[1]]


@pytest.mark.parametrize("robot", ROBOTS, ids=[r.name for r in ROBOTS])
def test_continuous_model_is_the_dynamics_derivatives(robot):
    q, qd, tau = _inside(robot, np.random.default_rng(1))
    n = robot.dof
    m = cs.linearize(robot, q, qd, tau)
    dq, dqd, minv = robot.forward_dynamics_derivatives(q, qd, tau)
    np.testing.assert_array_equal(m.A[:n, :n], 0.0)
    np.testing.assert_array_equal(m.A[:n, n:], np.eye(n))
    np.testing.assert_array_equal(m.A[n:], np.hstack([dq, dqd]))
    np.testing.assert_array_equal(m.B, np.vstack([np.zeros((n, n)), minv]))
    np.testing.assert_allclose(m.x_next, np.r_[qd, robot.forward_dynamics(q, qd, tau)], rtol=1e-12, atol=1e-12)
    assert m.method == "continuous" and m.dt == 0.0 and m.states[0] == "q0" and m.states[n] == "qd0"
    xdot = lambda x: np.r_[x[n:], robot.forward_dynamics(x[:n], x[n:], tau)]
    assert _rel(m.A, _central(xdot, np.r_[q, qd])) < 1e-6


@pytest.mark.parametrize("method", ["rk4", "euler"])
@pytest.mark.parametrize("robot", ROBOTS + [_panda()], ids=[r.name for r in ROBOTS] + ["panda"])
def test_step_jacobians_equal_central_differences_of_the_step(robot, method):
    """A and B of one step (and of three) against central differences of cs.rk4_step / euler_step to
    1e-7 relative; x_next is the integrator's own result, bit for bit. The Panda's 14 states exceed the
    engine's 12-joint fixed-size matrices: the model's are dynamic."""
    rng = np.random.default_rng(2)
    q, qd, tau = _inside(robot, rng)
    n = robot.dof
    tau_ext = rng.normal(size=n)
    step = cs.rk4_step if method == "rk4" else cs.euler_step
    for dt, steps in ((2e-3, 1), (1e-3, 3)):
        m = cs.linearize(robot, q, qd, tau, dt, steps=steps, method=method, tau_ext=tau_ext)

        def phi(x, u=tau):
            a, b = x[:n], x[n:]
            for _ in range(steps):
                a, b = step(robot, a, b, u, dt, tau_ext)
            return np.r_[a, b]

        x0 = np.r_[q, qd]
        np.testing.assert_array_equal(m.x_next, phi(x0))
        assert _rel(m.A, _central(phi, x0)) < 1e-7
        assert _rel(m.B, _central(lambda u: phi(x0, u), tau)) < 1e-7
        assert m.A.shape == (2 * n, 2 * n) and m.B.shape == (2 * n, n) and m.steps == steps and m.method == method


def test_rk4_jacobians_under_wrenches_fixed_in_the_world():
    """With a wrench at the tool and wrenches on links (their points moving with the links), against a
    reference RK4 written with forward_dynamics(f_ext=...)."""
    robot = ROBOTS[1]
    n, dt = robot.dof, 2e-3
    q, qd, tau = _inside(robot, np.random.default_rng(3))
    for f_ext in (np.array([3.0, -2.0, 5.0, 0.3, -0.2, 0.4]),
                  [cs.Wrench(n - 1, [0.05, -0.02, 0.03], [1.0, 2.0, -3.0, 0.1, 0.2, 0.3])]):
        def f(x, u):
            return np.r_[x[n:], robot.forward_dynamics(x[:n], x[n:], u, f_ext)]

        def phi(x, u=tau):
            k1 = f(x, u)
            k2 = f(x + dt / 2 * k1, u)
            k3 = f(x + dt / 2 * k2, u)
            k4 = f(x + dt * k3, u)
            return x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

        x0 = np.r_[q, qd]
        m = cs.linearize(robot, q, qd, tau, dt, f_ext=f_ext, end_stops=False)
        np.testing.assert_allclose(m.x_next, phi(x0), rtol=1e-12, atol=1e-12)
        assert _rel(m.A, _central(phi, x0)) < 1e-7
        assert _rel(m.B, _central(lambda u: phi(x0, u), tau)) < 1e-7


def test_computed_torque_closes_the_loop_to_its_error_dynamics():
    """With the exact model, computed torque makes e'' + kd e' + kp e = 0 joint by joint: the continuous
    closed loop is [[0, 1], [-kp, -kd]] to round-off whatever the state; its discrete closed loop equals
    central differences of its update followed by RK4 steps."""
    robot = ROBOTS[1]
    n = robot.dof
    rng = np.random.default_rng(4)
    q, qd, _ = _inside(robot, rng)
    kp, kd = rng.uniform(20, 100, n), rng.uniform(5, 20, n)
    ct = cs.ComputedTorque(kp=kp, kd=kd)
    ct.reset(robot, 1e-3)  # for compute; linearize does not need it
    q_ref = q + 0.01 * rng.normal(size=n)
    m = cs.linearize(robot, q, qd, controller=ct, q_ref=q_ref, qd_ref=np.zeros(n), qdd_ref=np.zeros(n))
    expected = np.block([[np.zeros((n, n)), np.eye(n)], [-np.diag(kp), -np.diag(kd)]])
    assert np.abs(m.A - expected).max() < 1e-9 * np.abs(expected).max()
    np.testing.assert_allclose(m.tau0, ct.compute(0.0, q, qd, q_ref, np.zeros(n), np.zeros(n)), rtol=1e-12,
                               atol=1e-12)

    dt, steps = 1e-3, 2
    d = cs.linearize(robot, q, qd, dt=dt, steps=steps, controller=ct, q_ref=q_ref)

    def phi(x):
        tau = ct.compute(0.0, x[:n], x[n:], q_ref, qd, np.zeros(n))
        a, b = x[:n], x[n:]
        for _ in range(steps):
            a, b = cs.rk4_step(robot, a, b, tau, dt)
        return np.r_[a, b]

    x0 = np.r_[q, qd]
    np.testing.assert_array_equal(d.x_next, phi(x0))
    assert _rel(d.A, _central(phi, x0)) < 1e-7
    # closed around the point itself: the discrete loop is stable, its spectral radius exp(-dt steps w)-like
    assert np.abs(np.linalg.eigvals(cs.linearize(robot, q, np.zeros(n), dt=dt, controller=ct).A)).max() < 1.0


def test_pid_closes_the_loop_with_its_state():
    """The PID's integral, filtered velocity estimate and last measured q are states of the closed loop.
    Its columns are checked by perturbing the update before: its reference moves the integral only
    (dI = h dq_ref), its measured velocity the estimate only (the first update's), its measured q the
    last q and the integral (dI = -h dq)."""
    robot = SCARA
    n = robot.dof
    q0 = np.array([0.3, 0.5, 0.1, 0.2, 0.5, 0.02])
    qd0 = np.array([0.1, -0.2, 0.01, 0.3, 0.1, 0.0])
    qr, z = q0 + 0.01, np.zeros(n)
    dt, steps = 1e-3, 2
    h = dt * steps

    def pid(dq_prev=0.0, dqd_prev=0.0, dref_prev=0.0):
        c = cs.PID(kp=[50, 50, 200, 5, 5, 20], ki=5.0, kd=[5, 5, 5, 0.5, 0.5, 0.5], derivative_filter=0.004)
        c.reset(robot, h)
        c.compute(0.0, q0 - h * qd0 + dq_prev, qd0 + dqd_prev, qr + dref_prev, z, z)
        return c

    def zplus(dx=np.zeros(2 * n), **history):
        c = pid(**history)
        q, qd = q0 + dx[:n], qd0 + dx[n:]
        tau = c.compute(h, q, qd, qr, z, z)
        for _ in range(steps):
            q, qd = cs.rk4_step(robot, q, qd, tau, dt)
        return np.r_[q, qd, c.integral, c.velocity_estimate, q0 + dx[:n]]

    m = cs.linearize(robot, q0, qd0, dt=dt, steps=steps, controller=pid(), q_ref=qr, qd_ref=z, qdd_ref=z)
    assert m.A.shape == (5 * n, 5 * n) and m.states[2 * n] == "pid.integral0" and m.states[-1] == f"pid.q_previous{n - 1}"
    np.testing.assert_allclose(m.x_next, zplus(), rtol=1e-14, atol=1e-14)
    scale = np.abs(m.A).max()
    assert np.abs(m.A[:, :2 * n] - _central(zplus, np.zeros(2 * n))).max() < 1e-7 * scale
    e = 1e-6
    for key, dc in (("dref_prev", lambda u: np.r_[h * u, 0 * u, 0 * u]),
                    ("dqd_prev", lambda u: np.r_[0 * u, u, 0 * u]),
                    ("dq_prev", lambda u: np.r_[-h * u, 0 * u, u])):
        for u in np.eye(n):
            fd = (zplus(**{key: e * u}) - zplus(**{key: -e * u})) / (2 * e)
            assert np.abs(m.A[:, 2 * n:] @ dc(u) - fd).max() < 1e-7 * scale, key


def test_bad_input_is_named_in_one_line():
    r, n = SCARA, SCARA.dof
    q, qd, tau = _inside(r, np.random.default_rng(5))
    beyond = q.copy()
    beyond[5] = 0.2  # the jaw's range is [0, 0.05] m
    with pytest.raises(ValueError) as e:
        cs.linearize(r, beyond, qd, tau, 1e-3)
    _one_line(e, "joint 6", "beyond its limits", "end_stops=False")
    cs.linearize(r, beyond, qd, tau, 1e-3, end_stops=False)  # the model without the stops
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd)
    _one_line(e, "tau")
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd, tau, controller=cs.ComputedTorque(kp=1.0, kd=1.0))
    _one_line(e, "tau must be None")
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd, tau, -1e-3)
    _one_line(e, "dt")
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd, tau, 1e-3, steps=0)
    _one_line(e, "steps")
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd, tau, 1e-3, method="heun")
    _one_line(e, "method", "heun")
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q[:3], qd, tau)
    _one_line(e, "q")
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd, tau, q_ref=q)
    _one_line(e, "q_ref", "controller")
    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd, controller=cs.PID(kp=1.0, ki=0.0, kd=1.0))
    _one_line(e, "internal state", "dt")

    class Mine(cs.Controller):
        def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
            return np.zeros(n)

    with pytest.raises(ValueError) as e:
        cs.linearize(r, q, qd, dt=1e-3, controller=Mine())
    _one_line(e, "no linearisation", "A + B K")


def test_state_feedback_is_the_lqr_law_and_closes_the_loop_exactly():
    """cs.StateFeedback: tau = tau0 [+ G(q)] - K (x - x_ref); linearize closes the loop with it as
    A - B K (and + B dG/dq with gravity compensation, against central differences); an LQR from SciPy's
    Riccati solver on the step's (A, B) is stable and holds a SCARA under a 1 N push at the tool."""
    sl = pytest.importorskip("scipy.linalg")
    r, n = SCARA, SCARA.dof
    q0 = np.array([0.3, 0.5, 0.1, 0.2, np.pi / 2, 0.02])
    tau0 = r.gravity(q0)
    lin = cs.linearize(r, q0, np.zeros(n), tau0, dt=2e-4, steps=5)
    Q, R = np.diag([1e4] * n + [1.0] * n), 1e-2 * np.eye(n)
    P = sl.solve_discrete_are(lin.A, lin.B, Q, R)
    K = np.linalg.solve(R + lin.B.T @ P @ lin.B, lin.B.T @ P @ lin.A)
    lqr = cs.StateFeedback(K, tau0)
    cl = cs.linearize(r, q0, np.zeros(n), dt=2e-4, steps=5, controller=lqr)
    assert np.abs(cl.A - (lin.A - lin.B @ K)).max() < 1e-12 * np.abs(lin.A).max()
    assert np.abs(np.linalg.eigvals(cl.A)).max() < 1.0
    np.testing.assert_array_equal(cl.tau0, tau0)

    g = cs.StateFeedback(K, gravity_compensation=True)
    g.reset(r, 1e-3)
    x0 = np.r_[q0 + 0.01, np.zeros(n)]
    d = cs.linearize(r, x0[:n], x0[n:], dt=1e-3, controller=g, q_ref=q0, qd_ref=np.zeros(n))

    def phi(x):
        tau = g.compute(0.0, x[:n], x[n:], q0, np.zeros(n), np.zeros(n))
        return np.r_[cs.rk4_step(r, x[:n], x[n:], tau, 1e-3)]

    assert _rel(d.A, _central(phi, x0)) < 1e-7

    sim = cs.Simulation(dt=2e-4, control_every=5, log_every=50)
    sim.add_robot(r, lqr, cs.SetPoint(q0))
    sim.set_applied(0, wrenches=[cs.Wrench.at_tool([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])])
    log = sim.run(1.0)
    dy = r.fk(log.q)[:, 1, 3] - r.fk(q0)[1, 3]
    assert 1e-5 < np.abs(dy).max() < 2e-3  # the push moves the tool, the LQR holds it within 2 mm


def test_state_feedback_bad_input_and_pickling():
    import pickle
    r, n = SCARA, SCARA.dof
    with pytest.raises(ValueError) as e:
        cs.StateFeedback(np.zeros((n, n)))
    _one_line(e, "K", "(n, 2n)")
    with pytest.raises(ValueError) as e:
        cs.StateFeedback(np.full((n, 2 * n), np.nan))
    _one_line(e, "K", "finite")
    with pytest.raises(ValueError) as e:
        cs.StateFeedback(np.zeros((n, 2 * n)), np.zeros(3))
    _one_line(e, "tau0")
    sim = cs.Simulation()
    with pytest.raises(ValueError) as e:
        sim.add_robot(r, cs.StateFeedback(np.zeros((2, 4))), cs.SetPoint(np.zeros(n)))
    _one_line(e, "K", r.name)
    K = np.arange(2.0 * n * n).reshape(n, 2 * n)
    back = pickle.loads(pickle.dumps(cs.StateFeedback(K, np.ones(n), gravity_compensation=True)))
    np.testing.assert_array_equal(back.K, K)
    np.testing.assert_array_equal(back.tau0, np.ones(n))
    assert back.gravity_compensation


@pytest.mark.slow
def test_a_motion_planned_under_torque_limits_on_the_exact_step_jacobians():
    """examples/plan_under_torque_limits.py: sequential QPs (OSQP) on the exact Jacobians of the RK4 steps
    bring SCARA #1 from rest to rest at a goal 1.2 rad away in 0.35 s, its first joint's torque at its
    limit: the end state within 1e-6 of the goal in the engine's own rollout, no torque beyond a limit."""
    pytest.importorskip("osqp")
    import importlib.util
    import os

    path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples",
                        "plan_under_torque_limits.py")
    spec = importlib.util.spec_from_file_location("plan_under_torque_limits", path)
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)
    res = ex.plan()
    n = SCARA.dof
    X, taus, lim = res["states"], res["taus"], res["tau_max"]
    assert np.abs(X[-1, :n] - res["q_goal"]).max() < 1e-6 and np.abs(X[-1, n:]).max() < 1e-6
    assert np.all(np.abs(taus) <= lim) and np.isclose(np.abs(taus[:, 0]).max(), lim[0])
    assert all(s in ("solved", "solved inaccurate") for s in res["statuses"]) and res["statuses"][0] == "solved"
    assert res["merits"][-1] < 0.05 * res["merits"][0]
    # the plan replayed step by step by rk4_step reaches the same end
    q, qd = res["states"][0, :n], res["states"][0, n:]
    steps = int(round(res["times"][1] / ex.DT))
    for tau in taus:
        for _ in range(steps):
            q, qd = cs.rk4_step(SCARA, q, qd, tau, ex.DT, end_stops=False)
    np.testing.assert_allclose(np.r_[q, qd], X[-1], atol=1e-9)
