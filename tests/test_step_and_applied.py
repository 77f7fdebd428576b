"""One step function for every integrator entry point, applied inputs in the
simulation state, and one simulation state for the robot it runs."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import coopsim as cs
from conftest import random_robot

DT = 2e-4


class Feed(cs.Controller):
    """Open loop: the torque row of the current step (zero-order hold)."""

    def __init__(self, U, dt):
        super().__init__()
        self.U, self.dt = U, dt

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        # the update after the last step computes the torque of a step not taken
        return self.U[min(int(round(t / self.dt)), len(self.U) - 1)]


def zero_controller():
    return cs.PID(0.0, 0.0, 0.0, gravity_compensation=False)


def robots():
    return [cs.robots.scara1(), cs.robots.scara2(), random_robot(7, mixed=True, dof=5)]


def start_state(robot):
    lo, hi = robot.q_limits.T
    bounded = np.isfinite(lo) & np.isfinite(hi)
    q = np.full(robot.dof, 0.3)
    lo, hi = lo[bounded], hi[bounded]
    q[bounded] = 0.5 * (lo + hi) + 0.1 * (hi - lo)
    qd = np.linspace(-0.4, 0.5, robot.dof)
    return q, qd


def torque_rows(robot, steps, seed=0):
    """Smooth torques within the actuator limits, one row per step."""
    rng = np.random.default_rng(seed)
    t = np.arange(steps)[:, None] * DT
    amp = np.minimum(robot.tau_limits, 2.0) * rng.uniform(0.1, 0.5, robot.dof)
    return amp * np.sin(2 * np.pi * (1.0 + 3.0 * rng.uniform(size=robot.dof)) * t + rng.uniform(0, 6, robot.dof))


@pytest.mark.parametrize("method", ["rk4", "euler"])
@pytest.mark.parametrize("index", range(3), ids=["scara1", "scara2", "random"])
def test_integrate_steps_and_simulation_agree_bit_for_bit(index, method):
    robot = robots()[index]
    q0, qd0 = start_state(robot)
    steps = 400
    U = torque_rows(robot, steps)
    _, Q, QD = cs.integrate(robot, q0, qd0, U, dt=DT, steps=steps, method=method)
    # the single-step functions, one call per step
    step = cs.rk4_step if method == "rk4" else cs.euler_step
    q, qd = q0, qd0
    for k in range(steps):
        q, qd = step(robot, q, qd, U[k], dt=DT)
        np.testing.assert_array_equal(q, Q[k + 1])
        np.testing.assert_array_equal(qd, QD[k + 1])
    # the simulation loop, the same torques through a controller
    sim = cs.Simulation(dt=DT, integrator=method)
    sim.add_robot(robot, Feed(U, DT), q0, q0=q0, qd0=qd0)
    sim.step(steps)
    log = sim.log
    np.testing.assert_array_equal(log.tau[:steps], U)
    np.testing.assert_array_equal(log.q, Q)
    np.testing.assert_array_equal(log.qd, QD)
    assert sim.integrator == method


def test_integrate_divergence_is_the_simulation_error_type():
    robot = cs.robots.scara1()
    q0, qd0 = start_state(robot)
    with pytest.raises(cs.DivergenceError, match="diverged at step 1") as e:
        cs.integrate(robot, q0, qd0 * 1e200, np.zeros(6), steps=3)
    assert isinstance(e.value, RuntimeError) and e.value.step == 1


# ---- applied inputs ----

def test_applied_link_wrench_gives_forward_dynamics_with_f_ext():
    robot = cs.robots.scara1()
    q0, qd0 = start_state(robot)
    w = cs.Wrench(3, [0.01, -0.02, -0.1], [1.5, -2.0, 3.0, 0.1, -0.2, 0.05])
    forces = np.array([0.2, -0.1, 0.5, 0.0, 0.01, -0.3])
    sim = cs.Simulation(dt=DT)
    sim.add_robot(robot, zero_controller(), q0, q0=q0, qd0=qd0)
    sim.set_applied(0, forces=forces, wrenches=[w])
    log = sim.run(0.02, progress=False)
    for k in (0, 1, 50, len(log) - 1):
        q, qd = log.q[k], log.qd[k]
        tau_ext = forces + robot.external_torques(q, [w])
        np.testing.assert_allclose(log.tau_ext[k], tau_ext, rtol=1e-13, atol=1e-13)
        expected = robot.forward_dynamics(q, qd, log.tau[k] + forces, f_ext=[w])
        np.testing.assert_allclose(log.qdd[k], expected, rtol=1e-10, atol=1e-10)
    applied = sim.applied(0)
    np.testing.assert_array_equal(applied["forces"], forces)
    assert len(applied["wrenches"]) == 1 and applied["wrenches"][0].link == 3
    # a wrench at the tool centre point maps like a (6,) f_ext
    tool = cs.Wrench.at_tool([0.0, 0.0, -5.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(robot.external_torques(q0, [tool]), robot.external_torques(q0, tool.wrench),
                               rtol=0, atol=1e-15)


@pytest.mark.parametrize("make", [cs.robots.scara1, cs.robots.scara2])
def test_a_tool_wrench_balancing_gravity_holds_the_robot_still(make):
    robot = make()
    q0, _ = start_state(robot)
    J, G = robot.tool_jacobian(q0), robot.gravity(q0)
    w = np.linalg.lstsq(J.T, G, rcond=None)[0]  # J^T w = G(q0) (SCARA #2's J is rank-deficient)
    np.testing.assert_allclose(J.T @ w, G, rtol=1e-12, atol=1e-12)
    sim = cs.Simulation(dt=DT)
    sim.add_robot(robot, zero_controller(), q0, q0=q0, qd0=np.zeros(robot.dof))
    sim.set_applied(0, wrenches=[cs.Wrench.at_tool(w)])
    log = sim.run(0.5, progress=False)
    assert np.max(np.abs(log.tau)) == 0.0
    np.testing.assert_allclose(log.tau_ext[0], robot.gravity(q0), rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(log.q - q0)) < 1e-9, np.max(np.abs(log.q - q0))
    assert np.max(np.abs(log.qd)) < 1e-8
    # without the wrench the same robot falls
    sim.reset()
    assert sim.applied(0)["wrenches"] == []
    falls = sim.run(0.1, progress=False)
    assert np.max(np.abs(falls.q - q0)) > 1e-3


def test_a_change_of_applied_inputs_between_runs_shows_in_the_log():
    robot = cs.robots.scara1()
    q0, qd0 = start_state(robot)
    sim = cs.Simulation(dt=DT)
    sim.add_robot(robot, zero_controller(), q0, q0=q0, qd0=qd0)
    sim.run(0.01, progress=False)
    f = np.array([0.0, 0.0, 2.0, 0.0, 0.0, 0.0])
    sim.set_applied(0, forces=f)
    log = sim.run(0.02, progress=False)
    t = log.t
    k = int(np.flatnonzero(t == t[50])[-1])
    # the row at t = 0.01 s with the old inputs, then a second row at that time with the new
    assert t[50] == t[51] and k == 51
    np.testing.assert_array_equal(log.tau_ext[50], np.zeros(6))
    np.testing.assert_array_equal(log.tau_ext[51], f)
    np.testing.assert_array_equal(log.q[50], log.q[51])
    assert log.qdd[51][2] > log.qdd[50][2]
    np.testing.assert_array_equal(log.tau_ext[52:], np.tile(f, (len(t) - 52, 1)))
    sim.clear_applied(0)
    np.testing.assert_array_equal(sim.applied(0)["tau_ext"], np.zeros(6))


def test_applied_inputs_reject_bad_values():
    robot = cs.robots.scara1()
    sim = cs.Simulation(dt=DT)
    sim.add_robot(robot, zero_controller(), np.zeros(6) + 0.01)
    with pytest.raises(ValueError, match="forces"):
        sim.set_applied(0, forces=np.zeros(5))
    with pytest.raises(ValueError, match="forces"):
        sim.set_applied(0, forces=np.full(6, np.nan))
    with pytest.raises(ValueError, match="link must be"):
        sim.set_applied(0, wrenches=[cs.Wrench(7, [0, 0, 0], np.zeros(6))])
    with pytest.raises(ValueError, match="wrenches"):
        sim.set_applied(0, wrenches=["not a wrench"])
    with pytest.raises(ValueError, match="robot"):
        sim.set_applied(1, forces=np.zeros(6))


# ---- one simulation state ----

def test_the_backend_a_simulation_runs_is_the_one_its_robot_reports():
    gen = cs.robots.scara1()
    num = gen.with_backend("numeric")
    assert gen.backend == "generated" and num.backend == "numeric"
    q0, qd0 = start_state(gen)
    U = torque_rows(gen, 300)
    runs = {}
    for robot in (gen, num):
        sim = cs.Simulation(dt=DT)
        sim.add_robot(robot, Feed(U, DT), q0, q0=q0, qd0=qd0)
        assert sim.robots[0].backend == robot.backend
        sim.step(300)
        _, Q, _ = cs.integrate(robot, q0, qd0, U, dt=DT, steps=300)
        np.testing.assert_array_equal(sim.log.q, Q)  # bit for bit the robot's own backend
        runs[robot.backend] = sim.log.q
    # the two backends agree to round-off but not bit for bit: the test tells them apart
    assert np.max(np.abs(runs["generated"] - runs["numeric"])) < 1e-10
    assert np.any(runs["generated"] != runs["numeric"])


def test_robots_are_immutable_so_a_running_simulation_cannot_change():
    robot = cs.robots.scara1()
    sim = cs.Simulation(dt=DT)
    sim.add_robot(robot, zero_controller(), np.zeros(6) + 0.01)
    for name, value in (("dh", np.zeros((6, 4))), ("masses", np.ones(6)), ("backend", "numeric"),
                        ("anything", 1)):
        with pytest.raises(AttributeError):
            setattr(robot, name, value)
    assert not hasattr(robot, "set_backend")
    masses = robot.masses
    masses[:] = 100.0  # a copy: the model keeps its own
    assert robot.masses[0] != 100.0
    heavier = robot.with_gravity([0, 0, -20.0])
    assert robot.gravity_acceleration[2] == -9.81 and heavier.gravity_acceleration[2] == -20.0
    assert sim.robots[0].gravity_acceleration[2] == -9.81
    np.testing.assert_array_equal(sim.robots[0].parameter_vector, robot.parameter_vector)


def test_a_pickled_simulation_keeps_robots_references_and_set_points():
    r1, r2 = cs.robots.scara1(), cs.robots.scara2(backend="numeric", base_position=(0.8, 0.0, 0.0))
    traj = cs.CubicTrajectory([0.0, 0.1], np.array([np.zeros(6), np.full(6, 0.01)]))
    sim = cs.Simulation(dt=DT, integrator="euler", log_every=5)
    sim.add_robot(r1, cs.PID(50.0, 0.0, 5.0), traj)
    sim.add_robot(r2, cs.ComputedTorque(100.0, 20.0), np.full(6, 0.02), qd0=np.full(6, 0.1))
    copy = pickle.loads(pickle.dumps(sim))
    assert copy.options == sim.options and copy.integrator == "euler"
    assert [r.backend for r in copy.robots] == ["generated", "numeric"]
    assert isinstance(copy.references[1], cs.SetPoint)
    np.testing.assert_array_equal(copy.references[1].q, np.full(6, 0.02))
    a, b = sim.run(0.05, progress=False), copy.run(0.05, progress=False)
    for ra, rb in zip(a, b):
        for name in cs.log.STORED:
            np.testing.assert_array_equal(getattr(ra, name), getattr(rb, name), err_msg=name)


def test_log_schema_is_defined_once_in_the_engine():
    names = [n for n, _ in cs.log.log_schema()]
    assert names == ["q", "qd", "qdd", "tau", "tau_ext", "q_ref", "qd_ref", "qdd_ref"]
    assert cs.log.QUANTITIES == tuple(names) + ("e",)
    sim = cs.Simulation(dt=DT)
    sim.add_robot(cs.robots.scara1(), zero_controller(), np.zeros(6) + 0.01)
    log = sim.run(0.001, progress=False)
    assert all(getattr(log[0], n).shape == (len(log.t), 6) for n in names)   # RobotLog takes no more, no less
    cols = log.to_dataframe().columns
    assert [c for c in cols if c.endswith("5") and c.startswith("scara1.")] == \
        [f"scara1.{n}5" for n in cs.log.QUANTITIES]
