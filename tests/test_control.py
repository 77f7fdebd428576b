"""Controllers: PID and computed torque tracking a cubic trajectory on both
SCARAs, a Python-subclassed controller against the built-in, saturation,
the controllers' formulas and their argument checks."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import coopsim as cs

ROBOTS = {"scara1": cs.robots.scara1, "scara2": cs.robots.scara2}

# stated tracking bounds (rad for revolute, m for prismatic joints)
PID_RMS_BOUND = 5e-3        # overall RMS over joints and time, PID with gravity compensation
PID_JOINT_RMS_BOUND = 1e-2  # any single joint
WRONG_MODEL_RMS_BOUND = 2e-2  # computed torque with masses x 1.2
T_END = 3.5                 # 3 s of motion, then 0.5 s holding the end point


def tracking_trajectory(robot: cs.Robot) -> cs.CubicTrajectory:
    """Four via-points spread over each joint's range, 1 s apart."""
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    pts = np.array([mid + f * span for f in (-0.1, 0.15, -0.2, 0.05)])
    return cs.CubicTrajectory([0.0, 1.0, 2.0, 3.0], pts)


def pid_for(robot: cs.Robot, traj: cs.CubicTrajectory, bandwidth: float = 50.0, **kw) -> cs.PID:
    """Per-joint gains from the largest diagonal inertia along the path (floor
    0.01 for the light wrist joints): kp = J w^2, kd = 2 J w, ki = kp w / 10."""
    J = np.max([np.diag(robot.mass_matrix(traj.evaluate(t)[0])) for t in np.linspace(0, 3, 31)], axis=0)
    J = np.maximum(J, 0.01)
    w = bandwidth
    return cs.PID(J * w * w, J * w ** 3 / 10, 2 * J * w, **kw)


def overall_rms(sim: cs.Simulation) -> float:
    m = sim.metrics()[0]
    return float(np.sqrt(np.mean(m.rms_error ** 2)))


def run(robot, controller, traj, t_end=T_END, **kw):
    sim = cs.Simulation(**kw)
    sim.add_robot(robot, controller, traj)
    sim.run(t_end, progress=False)
    return sim


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def tracking(request):
    """PID, exact computed torque and wrong-model computed torque on one SCARA."""
    make = ROBOTS[request.param]
    robot = make()
    traj = tracking_trajectory(robot)
    wrong = make(masses=robot.masses * 1.2)
    sims = {
        "pid": run(robot, pid_for(robot, traj), traj),
        "ct": run(robot, cs.ComputedTorque(900.0, 60.0), traj),
        "ct_wrong": run(robot, cs.ComputedTorque(900.0, 60.0, model=wrong), traj),
    }
    return robot, traj, sims


# ---- tracking ----

def test_pid_with_gravity_compensation_tracks_cubic_trajectory(tracking):
    robot, traj, sims = tracking
    sim = sims["pid"]
    m = sim.metrics()[0]
    assert m.steps == round(T_END / 2e-4) + 1
    assert overall_rms(sim) < PID_RMS_BOUND
    assert np.all(m.rms_error < PID_JOINT_RMS_BOUND), m.rms_error
    # the log agrees with the running metrics and the reference is the trajectory
    log = sim.log
    np.testing.assert_allclose(log.rms_error(), m.rms_error, rtol=1e-12)
    q_ref, qd_ref, _ = traj.evaluate(log.t)
    np.testing.assert_array_equal(log.q_ref, q_ref)
    np.testing.assert_array_equal(log.qd_ref, qd_ref)
    # gains within what the actuators give: no saturation on this path
    assert np.all(m.max_abs_tau < robot.tau_limits)


def test_pid_without_gravity_compensation_is_worse(tracking):
    robot, traj, sims = tracking
    sim = run(robot, pid_for(robot, traj, gravity_compensation=False), traj)
    assert overall_rms(sim) > overall_rms(sims["pid"])


def test_computed_torque_exact_model_at_least_10x_better_than_pid(tracking):
    _, _, sims = tracking
    ratio = overall_rms(sims["pid"]) / overall_rms(sims["ct"])
    assert ratio >= 10.0, ratio


def test_computed_torque_wrong_model_worse_than_exact_but_bounded(tracking):
    _, _, sims = tracking
    exact, wrong = overall_rms(sims["ct"]), overall_rms(sims["ct_wrong"])
    assert exact < wrong < WRONG_MODEL_RMS_BOUND, (exact, wrong)
    log = sims["ct_wrong"].log
    assert np.all(np.isfinite(log.q)) and np.all(np.isfinite(log.tau))


# ---- a Python controller against the built-in ----

class PythonPID(cs.Controller):
    """The built-in PID's formula in numpy, operation for operation."""

    def __init__(self, kp, ki, kd, derivative_filter):
        super().__init__()
        self.kp, self.ki, self.kd = (np.asarray(x, dtype=float) for x in (kp, ki, kd))
        self.tf = derivative_filter

    def reset(self, robot, period):
        self.robot = robot
        self.h = period
        self.tau_max = robot.tau_limits
        n = robot.dof
        self.I = np.zeros(n)
        self.v = np.zeros(n)
        self.q_prev = np.zeros(n)
        self.first = True

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        if self.first:
            self.v = qd.copy()
            self.first = False
        else:
            a = self.tf / (self.tf + self.h)
            self.v = a * self.v + (1.0 - a) * ((q - self.q_prev) / self.h)
        self.q_prev = q.copy()
        g = self.robot.gravity(q)
        e = q_ref - q
        u0 = self.kp * e + self.kd * (qd_ref - self.v)
        u0 = u0 + g
        I = self.I + e * self.h
        u = u0 + self.ki * I
        hold = ((u > self.tau_max) & (e > 0)) | ((u < -self.tau_max) & (e < 0))
        I = np.where(hold, self.I, I)
        imax = np.where(self.ki > 0, self.tau_max / np.where(self.ki > 0, self.ki, 1.0), np.inf)
        I = np.clip(I, -imax, imax)
        self.I = I
        return np.clip(u0 + self.ki * I, -self.tau_max, self.tau_max)


class PythonComputedTorque(cs.Controller):
    def __init__(self, kp, kd):
        super().__init__()
        self.kp, self.kd = kp, kd

    def reset(self, robot, period):
        self.robot = robot

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        v = qdd_ref + self.kd * (qd_ref - qd) + self.kp * (q_ref - q)
        return self.robot.inverse_dynamics(q, qd, v)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_python_subclassed_pid_gives_the_builtin_log(name):
    robot = ROBOTS[name]()
    traj = tracking_trajectory(robot)
    # strong gains and a step-like start so that saturation and anti-windup act
    kp = np.array([300.0, 200.0, 3000.0, 5.0, 5.0, 500.0])
    ki = kp * 5
    kd = kp / 20
    q0 = traj.evaluate(0.0)[0] + np.array([0.3, -0.3, 0.02, 0.4, 0.3, 0.01])
    logs = []
    for ctrl in (cs.PID(kp, ki, kd, derivative_filter=1e-3), PythonPID(kp, ki, kd, 1e-3)):
        sim = cs.Simulation(control_every=2)
        sim.add_robot(robot, ctrl, traj, q0=q0)
        logs.append(sim.run(0.3, progress=False))
    a, b = logs
    assert np.any(np.abs(a.tau) == robot.tau_limits), "saturation should be exercised"
    for qty in ("q", "qd", "qdd", "tau", "q_ref", "qd_ref"):
        np.testing.assert_allclose(getattr(b, qty), getattr(a, qty), rtol=0, atol=1e-12, err_msg=qty)


def test_python_subclassed_computed_torque_gives_the_builtin_log():
    robot = cs.robots.scara2()
    traj = tracking_trajectory(robot)
    logs = []
    for ctrl in (cs.ComputedTorque(400.0, 40.0), PythonComputedTorque(400.0, 40.0)):
        sim = cs.Simulation()
        sim.add_robot(robot, ctrl, traj, q0=traj.evaluate(0.0)[0] + 0.01)
        logs.append(sim.run(0.3, progress=False))
    for qty in ("q", "qd", "qdd", "tau"):
        np.testing.assert_allclose(getattr(logs[1], qty), getattr(logs[0], qty), rtol=0, atol=1e-12, err_msg=qty)


# ---- saturation ----

class Wild(cs.Controller):
    """Commands far beyond any actuator, alternating in sign."""

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        return np.full(q.shape, 1e6 * (-1) ** int(t / 0.01))


@pytest.mark.parametrize("make", [lambda: cs.PID(1e5, 1e5, 1e3), lambda: cs.ComputedTorque(1e6, 1e4), Wild])
@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_logged_torques_never_exceed_actuator_limits(name, make):
    robot = ROBOTS[name]()
    traj = tracking_trajectory(robot)
    sim = cs.Simulation(max_speed=1e6)
    sim.add_robot(robot, make(), traj, q0=traj.evaluate(0.0)[0] + 0.05)
    log = sim.run(0.2, progress=False)
    lim = robot.tau_limits
    assert np.all(np.abs(log.tau) <= lim)
    # and the limits are reached, so the bound is what held the torque
    assert np.any(np.abs(log.tau) == lim)
    assert np.all(sim.metrics()[0].max_abs_tau <= lim)


# ---- the formulas ----

def test_pid_terms(rng):
    robot = cs.robots.scara1()
    n = robot.dof
    kp, ki, kd = rng.uniform(1, 5, n), rng.uniform(1, 5, n), rng.uniform(0.1, 0.5, n)
    pid = cs.PID(kp, ki, kd, gravity_compensation=True, derivative_filter=0.0)
    h = 1e-3
    pid.reset(robot, h)
    q = np.array([0.1, 0.2, 0.1, 0.3, 0.4, 0.02])
    qd = rng.normal(size=n) * 0.1
    q_ref = q + 0.001
    tau = pid.compute(0.0, q, qd, q_ref, np.zeros(n), np.zeros(n))
    e = q_ref - q
    # first update: derivative from the measured velocity, integral e h
    np.testing.assert_allclose(tau, kp * e + ki * e * h - kd * qd + robot.gravity(q), rtol=1e-12)
    np.testing.assert_allclose(pid.integral, e * h)
    # second update: backward difference of the measured position
    q2 = q + qd * h
    tau2 = pid.compute(h, q2, qd, q_ref, np.zeros(n), np.zeros(n))
    e2 = q_ref - q2
    np.testing.assert_allclose(pid.velocity_estimate, (q2 - q) / h, rtol=1e-9)
    np.testing.assert_allclose(tau2, kp * e2 + ki * (e + e2) * h - kd * (q2 - q) / h + robot.gravity(q2),
                               rtol=1e-9)


def test_pid_derivative_filter_is_first_order_low_pass():
    robot = cs.robots.scara1()
    n, h, tf = robot.dof, 1e-3, 4e-3
    pid = cs.PID(0.0, 0.0, 1.0, gravity_compensation=False, derivative_filter=tf)
    pid.reset(robot, h)
    z = np.zeros(n)
    pid.compute(0.0, z, z, z, z, z)  # starts at the measured velocity 0
    # a ramp of slope 1: the estimate approaches 1 as 1 - a^k, a = tf / (tf + h)
    a = tf / (tf + h)
    for k in range(1, 30):
        pid.compute(k * h, z + k * h, z, z, z, z)
        np.testing.assert_allclose(pid.velocity_estimate, 1 - a ** k, rtol=1e-12)


def test_pid_anti_windup_bounds_the_integral():
    robot = cs.robots.scara1()
    n, h = robot.dof, 1e-3
    lim = robot.tau_limits
    pid = cs.PID(1e4, 10.0, 0.0, gravity_compensation=False)
    pid.reset(robot, h)
    z = np.zeros(n)
    ref = np.full(n, 1.0)  # kp e alone saturates every joint
    for k in range(2000):
        tau = pid.compute(k * h, z, z, ref, z, z)
    np.testing.assert_array_equal(tau, lim)
    # saturated in the direction of the error: the integral never grew
    np.testing.assert_array_equal(pid.integral, np.zeros(n))
    # without saturation it grows but |ki I| stops at integral_limit
    pid = cs.PID(0.0, 10.0, 0.0, gravity_compensation=False, integral_limit=0.5)
    pid.reset(robot, h)
    for k in range(2000):
        tau = pid.compute(k * h, z, z, ref, z, z)
    np.testing.assert_allclose(tau, np.full(n, 0.5))
    np.testing.assert_allclose(pid.integral, np.full(n, 0.05))


def test_pid_gravity_compensation_alone_holds_the_robot_still():
    robot = cs.robots.scara1()
    q = np.array([0.3, -0.5, 0.1, 0.2, 0.6, 0.02])
    sim = cs.Simulation()
    sim.add_robot(robot, cs.PID(0.0, 0.0, 0.0, gravity_compensation=True), q, q0=q)
    log = sim.run(0.5, progress=False)
    np.testing.assert_allclose(log.tau[0], robot.gravity(q), rtol=1e-12)
    assert np.max(np.abs(log.q - q)) < 1e-9
    # and without it the quill falls
    sim = cs.Simulation()
    sim.add_robot(robot, cs.PID(0.0, 0.0, 0.0, gravity_compensation=False), q, q0=q)
    assert np.max(np.abs(sim.run(0.5, progress=False).q - q)) > 1e-2


def test_computed_torque_formula(rng):
    robot = cs.robots.scara2()
    n = robot.dof
    kp, kd = rng.uniform(10, 50, n), rng.uniform(1, 5, n)
    wrong = cs.robots.scara2(masses=robot.masses * 1.2)
    for model in (None, wrong):
        ct = cs.ComputedTorque(kp, kd, model=model)
        ct.reset(robot, 2e-4)
        m = robot if model is None else wrong
        q = np.array([0.2, -0.3, 0.4, 0.1, 0.5, 0.02])
        qd, q_ref, qd_ref, qdd_ref = (rng.normal(size=n) * 0.1 for _ in range(4))
        tau = ct.compute(0.0, q, qd, q_ref, qd_ref, qdd_ref)
        v = qdd_ref + kd * (qd_ref - qd) + kp * (q_ref - q)
        expected = m.mass_matrix(q) @ v + m.coriolis(q, qd) + m.gravity(q) + m.friction(qd)
        np.testing.assert_allclose(tau, np.clip(expected, -robot.tau_limits, robot.tau_limits), rtol=1e-9,
                                   atol=1e-12)
    assert ct.model.masses == pytest.approx(robot.masses * 1.2)


def test_controllers_pickle():
    robot = cs.robots.scara1()
    pid = cs.PID([1.0, 2, 3, 4, 5, 6], 0.5, 0.1, gravity_compensation=False, derivative_filter=1e-3,
                 integral_limit=2.0, model=robot)
    p2 = pickle.loads(pickle.dumps(pid))
    for a in ("kp", "ki", "kd", "integral_limit"):
        np.testing.assert_array_equal(getattr(p2, a), getattr(pid, a))
    assert (p2.gravity_compensation, p2.derivative_filter) == (False, 1e-3)
    assert p2.model.name == "scara1"
    ct = pickle.loads(pickle.dumps(cs.ComputedTorque(4.0, 2.0, model=robot)))
    assert ct.kp.tolist() == [4.0] and ct.model.dof == 6
    py = pickle.loads(pickle.dumps(PythonComputedTorque(3.0, 1.0)))
    assert isinstance(py, PythonComputedTorque) and (py.kp, py.kd) == (3.0, 1.0)


# ---- argument checks ----

@pytest.mark.parametrize("kwargs, word", [
    (dict(kp=-1.0, ki=0.0, kd=0.0), "kp"),
    (dict(kp=1.0, ki=[1.0, -2.0], kd=0.0), "ki"),
    (dict(kp=1.0, ki=0.0, kd=np.nan), "kd"),
    (dict(kp=1.0, ki=0.0, kd=0.0, derivative_filter=-1e-3), "derivative_filter"),
    (dict(kp=1.0, ki=0.0, kd=0.0, integral_limit=-1.0), "integral_limit"),
    (dict(kp=np.ones((2, 2)), ki=0.0, kd=0.0), "kp"),
    (dict(kp="a lot", ki=0.0, kd=0.0), "kp"),
    (dict(kp=[], ki=0.0, kd=0.0), "kp"),
])
def test_pid_rejects_bad_gains(kwargs, word):
    with pytest.raises(ValueError, match=word):
        cs.PID(**kwargs)


def test_controllers_reject_mismatched_robots():
    robot = cs.robots.scara1()
    sim = cs.Simulation()
    with pytest.raises(ValueError, match="kp"):
        sim.add_robot(robot, cs.PID(np.ones(5), 0.0, 0.0), np.zeros(6))
    small = cs.Robot.from_dh(robot.dh[:2], robot.com[:2], robot.masses[:2], robot.inertias[:2], joint_types="RR")
    with pytest.raises(ValueError, match="model"):
        sim.add_robot(robot, cs.ComputedTorque(1.0, 1.0, model=small), np.zeros(6))
    with pytest.raises(ValueError, match="kd"):
        cs.ComputedTorque(1.0, -1.0)
    with pytest.raises(ValueError, match="model"):
        cs.ComputedTorque(1.0, 1.0, model="scara1")
    with pytest.raises(ValueError, match="q"):
        cs.PID(1.0, 0.0, 0.0).compute(0.0, np.zeros(3), np.zeros(2), np.zeros(3), np.zeros(3), np.zeros(3))


class NoCompute(cs.Controller):
    pass


class WrongShape(cs.Controller):
    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        return np.zeros(3)


class Returns(cs.Controller):
    def __init__(self, value):
        super().__init__()
        self.value = value

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        return self.value


def test_python_controller_errors_are_clear():
    robot = cs.robots.scara1()
    cases = [(NoCompute(), TypeError, "compute"), (WrongShape(), ValueError, "tau returned by compute"),
             (Returns(np.zeros(6, dtype=complex)), ValueError, "tau returned by compute must be .*real.*complex"),
             (Returns([0.0] * 5 + [None]), ValueError, "tau returned by compute must be .*real"),
             (Returns("zeros"), ValueError, "tau returned by compute must be .*real")]
    for ctrl, exc, word in cases:
        sim = cs.Simulation()
        sim.add_robot(robot, ctrl, np.zeros(6) + 0.01)
        with pytest.raises(exc, match=word):
            sim.run(0.01, progress=False)
