"""The simulation loop: log layout and decimation, zero-order hold, export
round trips, errors mid-run, divergence, pacing, batch runs, pickling."""
from __future__ import annotations

import concurrent.futures
import functools
import multiprocessing
import os
import pickle
import time

import numpy as np
import pytest

import coopsim as cs
from conftest import python_ran_during
from test_grasp import BOX, closing, scene  # a SCARA #1 closing its clamp on a box
from coopsim.log import log_schema

DT = 2e-4


def trajectory(robot: cs.Robot, duration: float = 1.0) -> cs.CubicTrajectory:
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    pts = np.array([mid - 0.1 * span, mid + 0.15 * span, mid - 0.05 * span])
    return cs.CubicTrajectory([0.0, duration / 2, duration], pts)


def pid(robot: cs.Robot, w: float = 40.0, **kw) -> cs.PID:
    J = np.maximum(np.diag(robot.mass_matrix(trajectory(robot).evaluate(0.0)[0])), 0.01)
    return cs.PID(J * w * w, J * w ** 3 / 10, 2 * J * w, **kw)


def make_sim(robot=None, controller=None, reference=None, **kw) -> cs.Simulation:
    robot = robot or cs.robots.scara1()
    sim = cs.Simulation(**kw)
    sim.add_robot(robot, controller or pid(robot), reference if reference is not None else trajectory(robot))
    return sim


QTY = ("q", "qd", "qdd", "tau", "q_ref", "qd_ref", "qdd_ref")


def assert_logs_equal(a: cs.SimulationLog, b: cs.SimulationLog):
    np.testing.assert_array_equal(a.t, b.t)
    assert len(a.robots) == len(b.robots)
    for ra, rb in zip(a.robots, b.robots):
        for qty in QTY:
            np.testing.assert_array_equal(getattr(ra, qty), getattr(rb, qty), err_msg=qty)


# ---- log layout ----

def test_log_shapes_and_contents():
    robot = cs.robots.scara1()
    traj = trajectory(robot)
    sim = make_sim(robot, reference=traj)
    log = sim.run(0.1, progress=False)
    rows = round(0.1 / DT) + 1
    assert len(log) == rows and sim.steps == rows - 1
    assert log.t.shape == (rows,)
    np.testing.assert_allclose(log.t, np.arange(rows) * DT, rtol=0, atol=1e-15)
    for qty in QTY:
        arr = getattr(log, qty)
        assert arr.shape == (rows, 6) and arr.dtype == np.float64, qty
    np.testing.assert_array_equal(log.error, log.q_ref - log.q)
    q_ref, qd_ref, _ = traj.evaluate(log.t)
    np.testing.assert_array_equal(log.q_ref, q_ref)
    np.testing.assert_array_equal(log.qd_ref, qd_ref)
    # row k: the acceleration of the held torque at (q_k, qd_k)
    for k in (0, 17, rows - 1):
        np.testing.assert_allclose(log.qdd[k], robot.forward_dynamics(log.q[k], log.qd[k], log.tau[k]),
                                   rtol=1e-9, atol=1e-9)
    # the state is the last row, and RK4 with the held torque joins consecutive rows
    q, qd = sim.state()
    np.testing.assert_array_equal(q, log.q[-1])
    np.testing.assert_array_equal(qd, log.qd[-1])
    q1, qd1 = cs.rk4_step(robot, log.q[10], log.qd[10], log.tau[10], DT)
    np.testing.assert_allclose(q1, log.q[11], rtol=0, atol=1e-14)
    np.testing.assert_allclose(qd1, log.qd[11], rtol=0, atol=1e-12)


def test_log_snapshots_are_fixed_read_only_views():
    sim = make_sim()
    a = sim.run(0.05, progress=False)
    q, t = a.q.copy(), a.t.copy()
    sim.run(0.3, progress=False)  # the log outgrows its storage and moves
    sim.reset()
    sim.run(0.01, progress=False)  # and starts over
    assert len(a) == 251
    np.testing.assert_array_equal(a.q, q)
    np.testing.assert_array_equal(a.t, t)
    with pytest.raises(ValueError, match="read-only"):
        a.q[0, 0] = 1.0
    assert len(sim.log) == 51
    # freed log memory is reused by later simulations, never memory a view still holds
    del sim
    for _ in range(4):
        make_sim(controller=cs.ComputedTorque(10.0, 5.0)).run(0.05, progress=False)
    np.testing.assert_array_equal(a.q, q)
    np.testing.assert_array_equal(a.t, t)


def test_log_decimation_keeps_every_nth_row_of_the_same_run():
    full = make_sim().run(0.2, progress=False)
    sim = make_sim(log_every=7)
    dec = sim.run(0.2, progress=False)
    assert len(dec) == 1000 // 7 + 1
    np.testing.assert_array_equal(dec.t, full.t[::7])
    for qty in QTY:
        np.testing.assert_array_equal(getattr(dec, qty), getattr(full, qty)[::7], err_msg=qty)
    # metrics still cover every step
    assert sim.metrics()[0].steps == 1001
    # log_every = 0: no log, metrics only
    sim = make_sim(log_every=0)
    assert len(sim.run(0.2, progress=False)) == 0
    assert sim.metrics()[0].steps == 1001


def test_controller_every_kth_step_holds_its_torque():
    robot = cs.robots.scara1()
    sim = make_sim(robot, pid(robot, w=15.0), control_every=5)
    log = sim.run(0.05, progress=False)
    tau = log.tau
    for k in range(len(tau)):
        np.testing.assert_array_equal(tau[k], tau[k - k % 5])
    assert np.any(tau[5] != tau[4])
    # a PID's integral advances by its period, 5 dt, at each update (steps 0, 5, .., 250)
    assert np.all(np.abs(tau) < sim.robots[0].tau_limits)  # no anti-windup hold in this run
    expected = (log.error[::5] * 5 * DT).sum(axis=0)
    np.testing.assert_allclose(sim.controllers[0].integral, expected, rtol=1e-12, atol=1e-18)


def test_incremental_stepping_equals_one_run():
    a = make_sim().run(0.1, progress=False)
    sim = make_sim()
    t = sim.step(0)
    assert t == 0.0 and len(sim.log) == 1  # the first row is written when the run starts
    for n in (1, 9, 90, 400):
        sim.step(n)
    sim.run(0.1, progress=False)
    assert sim.steps == 500
    assert_logs_equal(sim.log, a)


def test_run_to_a_time_in_the_past_is_refused_and_reset_restarts():
    sim = make_sim()
    sim.run(0.05, progress=False)
    with pytest.raises(ValueError, match="t_end"):
        sim.run(0.01, progress=False)
    sim.reset()
    assert sim.time == 0.0 and len(sim.log) == 0 and sim.stats is None
    assert_logs_equal(sim.run(0.05, progress=False), make_sim().run(0.05, progress=False))


def test_two_robots_evolve_independently():
    r1, r2 = cs.robots.scara1(), cs.robots.scara2(base_position=(1.0, 0.0, 0.0))
    both = cs.Simulation()
    both.add_robot(r1, pid(r1), trajectory(r1))
    both.add_robot(r2, cs.ComputedTorque(400.0, 40.0), trajectory(r2))
    log = both.run(0.1, progress=False)
    one = make_sim(r1, pid(r1)).run(0.1, progress=False)
    two = make_sim(r2, cs.ComputedTorque(400.0, 40.0)).run(0.1, progress=False)
    assert [r.name for r in log] == ["scara1", "scara2"]
    with pytest.raises(AttributeError, match=r"log\[i\]"):
        log.q
    for qty in QTY:
        np.testing.assert_array_equal(getattr(log[0], qty), getattr(one, qty))
        np.testing.assert_array_equal(getattr(log[1], qty), getattr(two, qty))


def test_set_point_and_python_references():
    robot = cs.robots.scara1()
    target = np.array([0.2, -0.1, 0.1, 0.3, 0.2, 0.02])

    class Hold(cs.Reference):
        dof = 6
        t_start = 0.0
        t_end = 0.0

        def evaluate(self, t):
            return target, np.zeros(6), np.zeros(6)

    logs = []
    for ref in (target, Hold()):
        sim = cs.Simulation()
        sim.add_robot(robot, pid(robot), ref, q0=np.zeros(6) + 0.01)
        logs.append(sim.run(0.2, progress=False))
    assert_logs_equal(*logs)
    assert np.all(logs[0].q_ref == target)


def test_log_keeps_the_reference_acceleration():
    """qdd_ref: the reference's acceleration at each logged time, also between controller updates and
    across a change of reference; a cubic's acceleration is the derivative of its velocity."""
    robot = cs.robots.scara1()
    traj = trajectory(robot)
    sim = make_sim(robot, reference=traj, log_every=3, control_every=4)
    assert [name for name, _ in log_schema()][-1] == "qdd_ref"
    sim.run(0.1, progress=False)
    later = cs.CubicTrajectory([0.0, 1.0], traj.evaluate([0.1, 0.9])[0])
    sim.set_reference(0, later)
    log = sim.run(0.2, progress=False)
    assert log.qdd_ref.shape == (len(log), 6) and log.qdd_ref.dtype == np.float64
    first = log.t <= 0.1 + 1e-12
    np.testing.assert_array_equal(log.qdd_ref[first], traj.evaluate(log.t[first])[2])
    # from the change on (the row at t = 0.1 is the old reference's, logged before it)
    np.testing.assert_array_equal(log.qdd_ref[~first], later.evaluate(log.t[~first])[2])
    # independent of evaluate's own acceleration: the central difference of its velocity (a cubic's
    # velocity is quadratic, so the difference is exact up to round-off)
    t, h = log.t[first][1:-1], 1e-4
    fd = (traj.evaluate(t + h)[1] - traj.evaluate(t - h)[1]) / (2 * h)
    np.testing.assert_allclose(log.qdd_ref[first][1:-1], fd, rtol=0, atol=1e-7)
    assert np.abs(log.qdd_ref[first]).max() > 0.1  # a moving reference: the test can fail



def test_the_defaults_are_the_engines():
    """Simulation.defaults(): the engine's SimulationOptions (the one source, checked against the compiled
    module in test_stubs.py), what coopsim.Simulation's signature shows; the grasp options left out are the
    engine's, and the engine checks the ones given."""
    import inspect

    d = cs.Simulation.defaults()
    assert d["dt"] == 2e-4 and d["integrator"] == "rk4" and d["grasp_options"]["hold_time"] == 2e-3
    opts = cs.Simulation(world=cs.World()).options
    assert opts == d
    params = inspect.signature(cs.Simulation.__init__).parameters
    for name, value in opts.items():
        if name != "grasp_options":
            assert value == params[name].default and type(value) is type(params[name].default), name
    assert sorted(opts["grasp_options"]) == sorted(
        ["hold_time", "gap", "penetration", "angle", "speed", "angular_speed", "open_margin", "slip",
         "weld_omega_dt", "release_time", "weld_moment"])
    given = cs.Simulation(world=cs.World(), grasp_options={"slip": 0.01}).options["grasp_options"]
    assert given == dict(opts["grasp_options"], slip=0.01)
    # one check of the grasp options, in the engine: the message names the option, its unit and value
    with pytest.raises(ValueError, match=r"grasp_options: slip must be >= 0 m, got -0\.5"):
        cs.Simulation(grasp_options={"slip": -0.5})
    with pytest.raises(ValueError, match="grasp_options: unknown option 'grip'"):
        cs.Simulation(grasp_options={"grip": 1.0})


# ---- export ----

def test_dataframe_and_csv_round_trip(tmp_path):
    log = make_sim(log_every=3).run(0.05, progress=False)
    df = log.to_dataframe()
    assert df.shape == (len(log), 1 + 9 * 6)  # t, then per joint q qd qdd tau tau_ext q_ref qd_ref qdd_ref e
    assert list(df.columns[:3]) == ["t", "scara1.q1", "scara1.q2"]
    np.testing.assert_array_equal(df["scara1.tau4"].to_numpy(), log.tau[:, 3])
    np.testing.assert_array_equal(df["scara1.e2"].to_numpy(), log.error[:, 1])
    path = tmp_path / "log.csv"
    assert log.to_csv(path) == str(path)
    back = cs.SimulationLog.read_csv(path)
    assert_logs_equal(back, log)
    assert back[0].name == "scara1"
    import pandas as pd

    pd.testing.assert_frame_equal(back.to_dataframe(), df, check_exact=True)
    # written through a temporary file renamed over the target: nothing else is left
    log.to_csv(path)
    assert sorted(os.listdir(tmp_path)) == ["log.csv"]


def test_excel_round_trip(tmp_path):
    r1, r2 = cs.robots.scara1(), cs.robots.scara1(base_position=(0.8, 0, 0))
    sim = cs.Simulation(log_every=25)
    sim.add_robot(r1, pid(r1), trajectory(r1))
    sim.add_robot(r2, cs.ComputedTorque(100.0, 20.0), trajectory(r2))
    log = sim.run(0.1, progress=False)
    path = tmp_path / "log.xlsx"
    log.to_excel(path)
    back = cs.SimulationLog.read_excel(path)
    assert [r.name for r in back] == ["scara1_0", "scara1_1"]  # same names made unique
    # the xlsx text of a float can be one unit in the last place off
    np.testing.assert_allclose(back.t, log.t, rtol=1e-15, atol=0)
    for a, b in zip(back, log):
        for qty in QTY:
            np.testing.assert_allclose(getattr(a, qty), getattr(b, qty), rtol=1e-15, atol=0, err_msg=qty)
    import openpyxl

    wb = openpyxl.load_workbook(path, read_only=True)
    assert wb.sheetnames == ["log", "info"]
    assert sorted(os.listdir(tmp_path)) == ["log.xlsx"]


def test_failed_write_leaves_no_file(tmp_path):
    log = make_sim().run(0.01, progress=False)
    target = tmp_path / "out.csv"
    target.write_text("old contents")

    class Boom(Exception):
        pass

    def fail(fraction):          # the writer stops in the middle, after a first block of rows
        raise Boom()

    with pytest.raises(Boom):
        log.to_csv(target, progress=fail)
    assert target.read_text() == "old contents"
    assert sorted(os.listdir(tmp_path)) == ["out.csv"]
    # a fresh output folder is made; a parent that is a file is an OSError naming it
    assert os.path.exists(log.to_csv(tmp_path / "new" / "out.csv"))
    with pytest.raises(OSError, match="out.csv"):
        log.to_csv(tmp_path / "out.csv" / "x.csv")


def test_paths_that_cannot_be_written_are_named(tmp_path, monkeypatch):
    log = make_sim().run(0.01, progress=False)
    # these named a temporary file the user never wrote ("Is a directory: '/tmp/.x.abc123.csv' -> '/tmp'"),
    # and the empty path made it in the working folder
    monkeypatch.chdir(tmp_path)
    for bad in (tmp_path, "", str(tmp_path) + os.sep, "a\0b.csv", b"run.csv", 5):
        with pytest.raises(ValueError, match="path must"):
            log.to_csv(bad)
    assert os.listdir(tmp_path) == []
    (tmp_path / "file").write_text("x")
    inside = tmp_path / "file" / "run.csv"
    with pytest.raises(OSError, match="cannot write the file") as e:
        log.to_csv(inside)
    assert e.value.filename == str(inside)
    # a name near the file system's limit of 255 bytes: its temporary file's name must fit too
    long = tmp_path / ("r" * 250 + ".csv")
    assert log.to_csv(long) == str(long) and sorted(os.listdir(tmp_path)) == ["file", long.name]


def test_plot_log_draws_one_panel_per_joint_with_dashed_references():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from coopsim.plotting import plot_log

    log = make_sim(log_every=10).run(0.1, progress=False)
    fig = plot_log(log)
    try:
        assert len(fig.axes) == 6
        for ax in fig.axes:
            styles = [ln.get_linestyle() for ln in ax.get_lines()]
            assert styles == ["-", "--"]
        np.testing.assert_array_equal(fig.axes[2].get_lines()[0].get_ydata(), log.q[:, 2])
        np.testing.assert_array_equal(fig.axes[2].get_lines()[1].get_ydata(), log.q_ref[:, 2])
    finally:
        plt.close(fig)
    fig = log.plot(quantity="tau", joints=[0, 3])
    try:
        assert len(fig.axes) == 2 and len(fig.axes[1].get_lines()) == 1
    finally:
        plt.close(fig)
    # with the joint types, each panel names its joint and unit
    for quantity, labels in (("q", ["θ1 (rad)", "d3 (m)"]), ("tau", ["tau θ1 (N m)", "tau d3 (N)"])):
        fig = log.plot(quantity=quantity, joints=[0, 2], joint_types="RRPRRP")
        try:
            assert [ax.get_ylabel() for ax in fig.axes] == labels
        finally:
            plt.close(fig)
    with pytest.raises(ValueError, match="quantity"):
        plot_log(log, quantity="force")


# ---- errors mid-run ----

class FailsAt(cs.Controller):
    """A PD controller that raises once at time t_fail."""

    def __init__(self, t_fail):
        super().__init__()
        self.t_fail = t_fail
        self.armed = True

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        if self.armed and t >= self.t_fail - 1e-12:
            self.armed = False
            raise KeyError("sensor lost")
        return 50.0 * (q_ref - q) + 5.0 * (qd_ref - qd)


def test_exception_mid_run_leaves_a_complete_log_up_to_that_step():
    robot = cs.robots.scara1()
    whole = make_sim(robot, FailsAt(1e9)).run(0.1, progress=False)
    sim = make_sim(robot, FailsAt(0.05))
    with pytest.raises(KeyError, match="sensor lost"):
        sim.run(0.1, progress=False)
    k = round(0.05 / DT)
    log = sim.log
    assert len(log) == k and sim.steps == k  # rows 0 .. k-1, state at step k
    for qty in QTY:
        np.testing.assert_array_equal(getattr(log, qty), getattr(whole, qty)[:k], err_msg=qty)
    # the failed update is retried: the run continues as if nothing happened
    sim.run(0.1, progress=False)
    assert_logs_equal(sim.log, whole)


def test_divergence_is_an_error_with_the_log_kept():
    r = cs.robots.scara1()
    # the same robot with unlimited actuators and absurd gains at a large step
    free = cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, joint_types=r.joint_types, name="free")
    sim = cs.Simulation(dt=5e-3)
    sim.add_robot(free, cs.PID(1e3, 0.0, 10.0, gravity_compensation=False), np.full(6, 0.1),
                  q0=np.full(6, 0.1 + 1e-9))
    with pytest.raises(cs.DivergenceError) as err:
        sim.run(1.0, progress=False)
    e = err.value
    assert isinstance(e, RuntimeError)
    assert e.step >= 3 and e.time == pytest.approx(e.step * 5e-3) and e.robot == 0
    msg = str(e)
    assert f"step {e.step}" in msg and "t = " in msg and "'free'" in msg and "q = [" in msg
    log = sim.log
    assert len(log) == e.step and log.t[-1] == pytest.approx((e.step - 1) * 5e-3)
    for qty in QTY:
        assert np.all(np.isfinite(getattr(log, qty))), qty
    assert sim.diverged and sim.time == log.t[-1]
    np.testing.assert_array_equal(sim.state()[0], log.q[-1])
    with pytest.raises(RuntimeError, match="diverged"):
        sim.step(1)
    sim.reset()
    assert not sim.diverged


def test_divergence_of_a_saturated_robot_against_its_end_stops():
    # actuators saturate, but a large step cannot integrate the stiff end stops
    r = cs.robots.scara1()
    sim = cs.Simulation(dt=2e-2)
    with pytest.warns(RuntimeWarning, match=r"end stops of robot 'scara1' have omega \* dt = 10"):
        sim.add_robot(r, cs.PID(1e6, 0.0, 1e4), r.q_limits[:, 1] + 0.5, q0=np.array([0, 0, 0.1, 0, 0.5, 0.02]))
    with pytest.raises(cs.DivergenceError, match="step") as err:
        sim.run(2.0, progress=False)
    assert "omega * dt = 10" in str(err.value) and "use dt <= 0.002 s" in str(err.value)
    log = sim.log
    assert len(log) >= 1 and all(np.all(np.isfinite(getattr(log, qty))) for qty in QTY)
    assert np.all(np.abs(log.tau) <= r.tau_limits)


def test_runaway_speed_and_non_finite_torque_are_divergence():
    robot = cs.robots.scara1()

    class Spin(cs.Controller):
        def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
            return np.array([30.0, 0, 0, 0, 0, 0])

    sim = make_sim(robot, Spin(), max_speed=5.0)
    with pytest.raises(cs.DivergenceError, match="max_speed"):
        sim.run(5.0, progress=False)
    assert np.all(np.abs(sim.log.qd) <= 5.0)

    class NaN(cs.Controller):
        def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
            return np.full(6, np.nan if t > 0.01 else 0.0)

    sim = make_sim(robot, NaN())
    with pytest.raises(cs.DivergenceError, match="non-finite torque"):
        sim.run(1.0, progress=False)
    assert np.all(np.isfinite(sim.log.tau))


# ---- time control ----

def test_paced_run_at_200_percent_takes_about_half_the_simulated_time():
    # the pacer's own clock, advanced only by its sleeps: what is checked is the pacing, not the machine
    clock = [0.0]

    def sleep(d):
        clock[0] += d

    sim = make_sim()
    pacer = cs.Pacer(speed=2.0, frame_rate=100, clock=lambda: clock[0], sleep=sleep)
    stats = sim.run_paced(0.6, pacer=pacer)
    assert sim.time == pytest.approx(0.6)
    assert stats.wall_time == pytest.approx(0.3, abs=0.011)  # half the simulated time, within a frame
    assert stats.real_time_factor == pytest.approx(0.6 / stats.wall_time)
    assert stats.real_time_factor == pytest.approx(2.0, rel=0.04)
    assert stats.steps == 3000 and stats.step_size == DT and stats.frames == pytest.approx(30, abs=1)
    assert stats.steps_per_second > 0


def test_pause_holds_simulated_time_still():
    sim = make_sim()
    seen = []

    def on_frame(s, pacer):
        seen.append((pacer.paused, s.time, time.perf_counter()))
        if len(seen) == 5:
            pacer.pause()
        elif len(seen) == 20:
            pacer.resume()

    pacer = cs.Pacer(speed=1.0, frame_rate=100)
    stats = sim.run_paced(0.3, on_frame=on_frame, pacer=pacer)
    paused = [(t, w) for p, t, w in seen if p]
    assert len(paused) == 15
    assert len({t for t, _ in paused}) == 1  # simulated time did not move
    assert paused[-1][1] - paused[0][1] > 0.1  # while the wall clock did
    assert sim.time == pytest.approx(0.3)
    assert stats.wall_time > 0.3 + 0.1


class FakeClock:
    """Wall time that moves only when the pacer sleeps."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now

    def sleep(self, s):
        assert s > 0
        self.now += s


def test_pacing_follows_the_speed_exactly_on_a_fake_clock():
    clock = FakeClock()
    pacer = cs.Pacer(speed=2.0, frame_rate=50.0, clock=clock, sleep=clock.sleep)
    sim = make_sim()
    seen = []

    def on_frame(s, p):
        seen.append((clock.now - 100.0, s.time))
        if len(seen) == 10:
            p.speed_percent = 400
        if len(seen) == 20:
            p.pause()
        if len(seen) == 30:
            p.speed = 1.0
            p.resume()

    stats = pacer.run(sim, 2.0, on_frame=on_frame)
    w, t = np.array(seen).T
    # frame k starts at wall k / 50 s and brings simulated time to speed x wall, to a step
    rate = np.diff(t) / np.diff(w)
    np.testing.assert_allclose(rate[:9], 2.0, atol=DT * 50 + 1e-12)
    np.testing.assert_allclose(rate[10:19], 4.0, atol=DT * 50 + 1e-12)
    np.testing.assert_array_equal(t[19:30], t[19])  # paused
    np.testing.assert_allclose(rate[30:-1], 1.0, atol=DT * 50 + 1e-12)
    assert sim.time == pytest.approx(2.0)
    assert stats.frames == len(seen) and stats.sim_elapsed == pytest.approx(2.0)
    assert stats.wall_time == pytest.approx(w[-1] + 0.02)


def test_pacer_speed_range_and_stop():
    p = cs.Pacer()
    for bad in (-0.1, 4.01, np.nan, "fast"):
        with pytest.raises(ValueError, match="speed"):
            p.speed = bad
    p.speed_percent = 400
    assert p.speed == 4.0
    with pytest.raises(ValueError, match="speed_percent"):
        p.speed_percent = "max"
    with pytest.raises(ValueError, match="frame_rate"):
        cs.Pacer(frame_rate=0)
    sim = make_sim()
    with pytest.raises(ValueError, match="never finish"):
        sim.run_paced(1.0, speed=0.0)
    stats = sim.run_paced(1.0, speed=4.0, frame_rate=200, on_frame=lambda s, pacer: s.time < 0.05)
    assert 0.0 < sim.time < 0.2 and stats.frames >= 1
    # speed 0 with a wall-clock limit: frames pass, time stays
    sim.run_paced(1.0, speed=0.0, max_wall_time=0.05)
    assert sim.time == stats.sim_time


def test_headless_run_statistics_and_progress_bar(capsys):
    sim = make_sim()
    sim.run(0.2, progress=True)
    err = capsys.readouterr().err
    assert "simulating" in err or "step" in err
    s = sim.stats
    assert s.steps == 1000 and s.sim_elapsed == pytest.approx(0.2) and s.frames == 0
    assert s.steps_per_second == pytest.approx(1000 / s.wall_time)
    assert s.real_time_factor == pytest.approx(0.2 / s.wall_time)
    assert "real-time factor" in str(s)
    sim.run(0.4, progress=False)
    assert capsys.readouterr().err == ""


def test_progress_bar_by_default_only_on_long_runs(capsys, monkeypatch):
    from coopsim import simulation

    monkeypatch.setattr(simulation, "_PROGRESS_DELAY", 0.0)  # show it at once rather than after a second
    sim = make_sim(log_every=0)
    sim.run((simulation._PROGRESS_MIN_STEPS - 1) * DT)
    assert capsys.readouterr().err == ""
    sim.run(sim.time + simulation._PROGRESS_MIN_STEPS * DT)
    assert "simulating" in capsys.readouterr().err


@pytest.mark.parametrize("how", ["run", "step"])
def test_run_releases_the_gil(how):
    # while the C++ loop runs, another Python thread gets to run: a held GIL
    # would keep it out (see python_ran_during)
    sim = make_sim(log_every=0)

    def call():
        if how == "run":
            sim.run(sim.time + 20.0, progress=False)
        else:
            sim.step(100_000)

    calls = python_ran_during(call)
    assert calls > 0, "no other Python thread ran during the loop: it holds the GIL"
    assert sim.time == pytest.approx(20.0 * calls)


def test_gil_check_fails_for_calls_that_hold_the_gil():
    # the check above fails for a call that holds the GIL however long it
    # takes: compiled code (numpy on Python objects) or Python code (which the
    # interpreter would otherwise interrupt every switch interval); it passes
    # for one that releases the GIL
    objects = np.ones(4_000_000, dtype=object)
    assert python_ran_during(lambda: objects.sum(), attempts=3) == 0
    assert python_ran_during(lambda: sum(i * i for i in range(1_000_000)), attempts=3) == 0
    assert python_ran_during(lambda: time.sleep(0.01)) > 0


# ---- batch runs ----

def gain_grid():
    robot = cs.robots.scara1()
    traj = trajectory(robot, 0.5)
    sims = []
    for kp in (100.0, 200.0, 400.0, 800.0):
        for kd in (5.0, 10.0, 20.0, 40.0):
            sim = cs.Simulation(log_every=5)
            sim.add_robot(robot, cs.PID(kp, kp / 10, kd), traj)
            sims.append(sim)
    return sims


def test_batch_of_16_equals_the_same_16_one_by_one():
    batch = gain_grid()
    w0 = time.perf_counter()
    logs = cs.run_batch(batch, 0.5, threads=2)
    wall = time.perf_counter() - w0
    assert len(logs) == 16
    # each run's statistics: its own steps and wall time, measured within the batch's (so not the
    # batch's own figure: a run's interval lies inside the call's, whatever the load)
    walls = [s.stats.wall_time for s in batch]
    assert all(s.stats.steps == 2500 and s.stats.sim_elapsed == pytest.approx(0.5) for s in batch)
    assert all(0 < w < wall for w in walls)
    singles = gain_grid()
    for a, sim in zip(logs, singles):
        assert_logs_equal(a, sim.run(0.5, progress=False))
    for sim_b, sim_s in zip(batch, singles):
        assert sim_b.time == sim_s.time
        np.testing.assert_array_equal(sim_b.metrics()[0].rms_error, sim_s.metrics()[0].rms_error)
    # different gains give different runs
    assert not np.array_equal(logs[0].q, logs[15].q)


class PD(cs.Controller):
    def __init__(self, kp):
        super().__init__()
        self.kp = kp

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        return self.kp * (q_ref - q) + 0.1 * self.kp * (qd_ref - qd)


def test_batch_with_python_controllers_on_threads():
    robot = cs.robots.scara1()
    target = np.array([0.2, 0.1, 0.1, 0.1, 0.5, 0.02])

    def build(k):
        sim = cs.Simulation()
        sim.add_robot(robot, PD(k), target)
        return sim

    gains = (10.0, 20.0, 30.0, 40.0)
    logs = cs.run_batch([build(k) for k in gains], 0.05, threads=2)
    for k, log in zip(gains, logs):
        assert_logs_equal(log, build(k).run(0.05, progress=False))


def test_batch_metrics_errors_and_checks():
    sims = gain_grid()[:3]
    bad = cs.Simulation(dt=5e-3)
    r = cs.robots.scara1()
    free = cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, joint_types=r.joint_types, name="free")
    bad.add_robot(free, cs.PID(1e3, 0.0, 10.0, gravity_compensation=False), np.full(6, 0.1),
                  q0=np.full(6, 0.1 + 1e-9))
    out = cs.run_batch(sims + [bad], 0.2, output="metrics", errors="return")
    assert isinstance(out[3], cs.DivergenceError)
    for m in out[:3]:
        assert m[0].name == "scara1" and m[0].rms_error.shape == (6,) and m[0].steps == 1001
    with pytest.raises(RuntimeError, match="has diverged"):
        cs.run_batch([bad], 0.3)  # refused until reset
    with pytest.raises(cs.DivergenceError) as err:
        cs.run_batch([pickle.loads(pickle.dumps(bad))], 0.3)
    assert "sims[0]" in "".join(getattr(err.value, "__notes__", ["sims[0]"]))
    shared = cs.PID(1.0, 0.0, 0.0)
    a, b = cs.Simulation(), cs.Simulation()
    a.add_robot(r, shared, np.zeros(6) + 0.01)
    b.add_robot(r, shared, np.zeros(6) + 0.01)
    with pytest.raises(ValueError, match="share a controller"):
        cs.run_batch([a, b], 0.1)
    with pytest.raises(ValueError, match="same simulation"):
        cs.run_batch([a, a], 0.1)
    with pytest.raises(ValueError, match="sims"):
        cs.run_batch([a, "b"], 0.1)
    with pytest.raises(ValueError, match="output"):
        cs.run_batch([a], 0.1, output="everything")
    with pytest.raises(ValueError, match="threads"):
        cs.run_batch([a], 0.1, threads=-1)


def test_simulation_description_pickles_and_runs_through_an_executor():
    sims = gain_grid()[:4]
    expected = [pickle.loads(pickle.dumps(s)).run(0.2, progress=False) for s in sims]
    sims[0].run(0.1, progress=False)  # state is not part of the description
    copy = pickle.loads(pickle.dumps(sims[0]))
    assert copy.time == 0.0 and copy.options == sims[0].options and copy.robots[0].name == "scara1"
    # spawn: workers start clean, whatever threads this process runs
    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=2, mp_context=ctx) as pool:
        got = list(pool.map(functools.partial(cs.simulate, t_end=0.2), sims))
    for a, b in zip(got, expected):
        assert_logs_equal(a, b)
    metrics = cs.simulate(pickle.loads(pickle.dumps(sims[1])), 0.2, output="metrics")
    direct = pickle.loads(pickle.dumps(sims[1]))
    direct.run(0.2, progress=False)
    np.testing.assert_array_equal(metrics[0].rms_error, direct.metrics()[0].rms_error)


# ---- argument checks ----

@pytest.mark.parametrize("kwargs, word", [
    (dict(dt=0.0), "dt"), (dict(dt=-1e-3), "dt"), (dict(dt=np.nan), "dt"),
    (dict(control_every=0), "control_every"), (dict(log_every=-1), "log_every"),
    (dict(max_speed=0.0), "max_speed"), (dict(max_position=-1.0), "max_position"),
    (dict(integrator="midpoint"), "integrator"),
])
def test_simulation_rejects_bad_options(kwargs, word):
    with pytest.raises(ValueError, match=word):
        cs.Simulation(**kwargs)


@pytest.mark.parametrize("kwargs", [dict(dt="small"), dict(control_every=1.5), dict(log_every="2"),
                                    dict(integrator=None), dict(max_speed=[1.0])])
def test_simulation_rejects_wrong_types_as_type_errors(kwargs):
    # wrong types are TypeErrors of one line naming the argument and the type expected, here as in
    # integrate() and rk4_step()
    (name, value), = kwargs.items()
    with pytest.raises(TypeError, match=rf"^Simulation\(\): {name} must be an? (float|int|str), got "
                                        rf"{type(value).__name__} "):
        cs.Simulation(**kwargs)
    robot = cs.robots.scara1()
    for call in (lambda: cs.integrate(robot, np.zeros(6), np.zeros(6), np.zeros(6), dt="small"),
                 lambda: cs.rk4_step(robot, np.zeros(6), np.zeros(6), np.zeros(6), dt="small")):
        with pytest.raises(TypeError, match=r"^(integrate|rk4_step)\(\): dt must be a float, got str 'small'$"):
            call()


def test_add_robot_and_run_reject_bad_arguments():
    robot = cs.robots.scara1()
    sim = cs.Simulation()
    with pytest.raises(ValueError, match="robot"):
        sim.add_robot("scara1", cs.PID(1.0, 0.0, 0.0), np.zeros(6))
    with pytest.raises(ValueError, match="controller"):
        sim.add_robot(robot, lambda *a: np.zeros(6), np.zeros(6))
    with pytest.raises(ValueError, match="reference"):
        sim.add_robot(robot, cs.PID(1.0, 0.0, 0.0), np.zeros(5))
    with pytest.raises(ValueError, match="reference"):
        sim.add_robot(robot, cs.PID(1.0, 0.0, 0.0), cs.CubicTrajectory([0, 1], np.zeros((2, 5))))
    with pytest.raises(ValueError, match="q0"):
        sim.add_robot(robot, cs.PID(1.0, 0.0, 0.0), np.zeros(6), q0=np.zeros(4))
    with pytest.raises(ValueError, match="qd0"):
        sim.add_robot(robot, cs.PID(1.0, 0.0, 0.0), np.zeros(6), qd0=np.full(6, np.nan))
    with pytest.raises(ValueError, match="no robot"):
        sim.run(0.1)
    pid_ = cs.PID(1.0, 0.0, 0.0)
    sim.add_robot(robot, pid_, np.zeros(6) + 0.01)
    with pytest.raises(ValueError, match="already driving"):
        sim.add_robot(robot, pid_, np.zeros(6) + 0.01)
    for bad in (np.nan, np.inf):
        with pytest.raises(ValueError, match="t_end"):
            sim.run(bad)
    for bad in ("1 s", None):
        with pytest.raises(TypeError, match="t_end"):
            sim.run(bad)
    with pytest.raises(ValueError, match="n must"):
        sim.step(-1)
    for bad in (10**19, 2.0, "3"):
        with pytest.raises(TypeError, match=r"^Simulation.step\(\): n (must be an int|is out of range), got "):
            sim.step(bad)
    with pytest.raises(ValueError, match="t_end"):
        sim.run_paced(np.nan)
    with pytest.raises(ValueError, match="t_end"):
        sim.run_paced("1 s")
    sim.step(3)
    with pytest.raises(ValueError, match="before the first step"):
        sim.add_robot(robot, cs.PID(1.0, 0.0, 0.0), np.zeros(6) + 0.01)
    with pytest.raises(ValueError, match="robot"):
        sim.state(3)


def test_a_log_too_large_for_memory_is_a_clear_error():
    sim = make_sim()
    with pytest.raises(MemoryError, match="log_every"):
        sim.run(1e12)  # 5e15 rows
    assert sim.steps == 0
    log = sim.run(0.01, progress=False)  # nothing was lost or half-made
    assert len(log) == 51


def test_a_reference_replaced_between_runs_acts_from_the_next_step():
    r = cs.robots.scara1()
    traj = trajectory(r)
    whole = cs.Simulation(dt=DT)
    whole.add_robot(r, pid(r), traj)
    split = cs.Simulation(dt=DT)
    split.add_robot(r, pid(r), cs.CubicTrajectory([0.0, 5.0], np.zeros((2, 6))), q0=traj.evaluate(0.0)[0])
    split.set_reference(0, traj)  # before the first step: acts at once
    split.run(0.3, progress=False)
    split.set_reference(0, trajectory(r))  # the same motion, a new object
    a, b = whole.run(1.0, progress=False), split.run(1.0, progress=False)
    np.testing.assert_array_equal(a.to_array(), b.to_array())
    # a new set point: the row at the switch shows the old reference, the next rows the new one
    q_new = traj.evaluate(1.0)[0] + 0.1
    q_new[5] = 0.03  # the jaw within its 5 cm
    split.set_reference(0, q_new)
    k = len(split.log.t)
    log = split.run(2.0, progress=False)
    np.testing.assert_array_equal(log.q_ref[k - 1], traj.evaluate(1.0)[0])
    np.testing.assert_array_equal(log.q_ref[k:], np.broadcast_to(q_new, log.q_ref[k:].shape))
    assert np.abs(log.q[-1] - q_new).max() < 2e-3
    assert isinstance(split.references[0], cs.SetPoint)
    with pytest.raises(ValueError, match="reference has 2 joints but robot 'scara1' has 6"):
        split.set_reference(0, cs.CubicTrajectory([0.0, 1.0], np.zeros((2, 2))))
    with pytest.raises(ValueError, match="reference"):
        split.set_reference(0, np.zeros(3))
    with pytest.raises(ValueError, match="robot must be an index"):
        split.set_reference(1, q_new)



@pytest.mark.parametrize("kind", ["pid", "computed_torque"])
def test_a_controller_replaced_in_a_run_drives_as_a_run_built_with_it(kind):
    # a set point, so the reference does not depend on the clock: a run switched at step k
    # must continue, from the step after the switch, exactly as a run started there with the
    # new controller (the new controller is reset at the switch: a PID's integral from zero)
    r = cs.robots.scara1()
    q_goal = trajectory(r).evaluate(0.5)[0]

    def new_controller():
        if kind == "pid":
            return pid(r, w=25.0)
        return cs.ComputedTorque(np.full(6, 900.0), np.full(6, 60.0))

    old = pid(r) if kind == "pid" else cs.ComputedTorque(400.0, 40.0)
    switched = cs.Simulation(dt=DT)
    switched.add_robot(r, old, q_goal, q0=trajectory(r).evaluate(0.0)[0])
    switched.step(300)
    tau_held = switched.torque(0)
    new = new_controller()
    switched.set_controller(0, new)
    assert switched.controllers[0] is new
    np.testing.assert_array_equal(switched.torque(0), tau_held)  # the torque held at the switch stays
    switched.step(1)  # the new controller computes from this step on
    q, qd = switched.state(0)
    fresh = cs.Simulation(dt=DT)
    fresh.add_robot(r, new_controller(), q_goal, q0=q, qd0=qd)
    switched.step(400)
    fresh.step(400)
    a, b = switched.log, fresh.log
    for name in ("q", "qd", "tau"):
        np.testing.assert_array_equal(getattr(a, name)[301:], getattr(b, name), err_msg=name)
    # the new gains act: the old controller would have driven another motion
    kept = cs.Simulation(dt=DT)
    kept.add_robot(r, pid(r) if kind == "pid" else cs.ComputedTorque(400.0, 40.0), q_goal,
                   q0=trajectory(r).evaluate(0.0)[0])
    kept.step(701)
    assert np.abs(kept.log.tau[301:] - a.tau[301:]).max() > 1e-3


def test_a_controller_replaced_before_the_first_step_acts_at_once_and_bad_ones_are_refused():
    r = cs.robots.scara1()
    built = make_sim(r, pid(r, w=25.0))
    replaced = make_sim(r)
    replaced.set_controller(0, pid(r, w=25.0))
    np.testing.assert_array_equal(built.run(0.05, progress=False).to_array(),
                                  replaced.run(0.05, progress=False).to_array())
    with pytest.raises(ValueError, match="kp"):
        replaced.set_controller(0, cs.PID(np.ones(2), 0.0, 1.0))
    small = cs.Robot.from_dh(r.dh[:2], r.com[:2], r.masses[:2], r.inertias[:2], joint_types="RR")
    with pytest.raises(ValueError, match="model has 2 joints but robot 'scara1' has 6"):
        replaced.set_controller(0, cs.ComputedTorque(1.0, 1.0, model=small))
    with pytest.raises(ValueError, match="controller must be a coopsim.Controller"):
        replaced.set_controller(0, None)
    with pytest.raises(ValueError, match="robot must be an index"):
        replaced.set_controller(1, pid(r))
    other = cs.Simulation(dt=DT)
    c0, c1 = pid(r), pid(r)
    other.add_robot(r, c0, trajectory(r))
    other.add_robot(r, c1, trajectory(r))
    with pytest.raises(ValueError, match="already driving robot 1"):
        other.set_controller(0, c1)
    other.set_controller(0, c0)  # its own controller again: allowed (reset)
    # a refused controller leaves the one in place and the run going
    other.run(0.01, progress=False)
    assert other.controllers[0] is c0 and other.controllers[1] is c1



def test_a_robot_replaced_in_a_run_keeps_its_state_and_drives_as_a_run_built_with_it():
    # the same SCARA with a longer first arm: its DH table and mass matrix change, q and qd stay,
    # the controller's model (the robot's own) follows; from the step after the switch the run
    # is exactly one started there with the new robot
    r, longer = cs.robots.scara1(), cs.robots.scara1(L1=0.35, L_base=0.45)
    q_goal = trajectory(r).evaluate(0.5)[0]
    q_start = trajectory(r).evaluate(0.0)[0]
    switched = cs.Simulation(dt=DT)
    switched.add_robot(r, cs.ComputedTorque(400.0, 40.0), q_goal, q0=q_start)
    switched.step(300)
    q, qd = switched.state(0)
    switched.set_robot(0, longer)
    got = switched.robots[0]
    assert not np.allclose(got.dh, r.dh) and np.array_equal(got.dh, longer.dh)
    assert got.dimensions["L1"] == 0.35 and not np.allclose(got.masses, r.masses)
    M = got.mass_matrix(q)
    np.testing.assert_array_equal(M, longer.mass_matrix(q))
    assert np.abs(M - r.mass_matrix(q)).max() > 1e-3
    qn, qdn = switched.state(0)
    np.testing.assert_array_equal(qn, q)
    np.testing.assert_array_equal(qdn, qd)
    switched.step(1)
    fresh = cs.Simulation(dt=DT)
    fresh.add_robot(longer, cs.ComputedTorque(400.0, 40.0), q_goal, q0=switched.state(0)[0],
                    qd0=switched.state(0)[1])
    switched.step(400)
    fresh.step(400)
    for name in ("q", "qd", "tau"):
        np.testing.assert_array_equal(getattr(switched.log, name)[301:], getattr(fresh.log, name), err_msg=name)
    # an explicit model stays the controller's: the run equals one built with the new robot and that model
    explicit = cs.Simulation(dt=DT)
    explicit.add_robot(r, cs.ComputedTorque(400.0, 40.0, model=r), q_goal, q0=q_start)
    explicit.step(300)
    explicit.set_robot(0, longer)
    explicit.step(1)
    fresh = cs.Simulation(dt=DT)
    fresh.add_robot(longer, cs.ComputedTorque(400.0, 40.0, model=r), q_goal, q0=explicit.state(0)[0],
                    qd0=explicit.state(0)[1])
    explicit.step(400)
    fresh.step(400)
    np.testing.assert_array_equal(explicit.log.tau[301:], fresh.log.tau)
    assert np.abs(explicit.log.tau[301:] - switched.log.tau[301:702]).max() > 1e-3   # the model matters
    switched.run(2.0, progress=False)   # the run goes on, to its goal
    assert not switched.diverged and np.abs(switched.state(0)[0] - q_goal).max() < 1e-3
    with pytest.raises(ValueError, match="robot must have the joints of robot 'scara1' \\(RRPRRP\\), got 'scara2'"):
        switched.set_robot(0, cs.robots.scara2())
    with pytest.raises(ValueError, match="robot must be an index"):
        switched.set_robot(1, longer)
    with pytest.raises(ValueError, match="robot must be a coopsim.Robot"):
        switched.set_robot(0, "scara1")
    np.testing.assert_array_equal(switched.robots[0].dh, longer.dh)


def test_a_robot_replaced_in_a_run_brings_its_new_boxes_into_the_world():
    # a small static box just beyond the second arm's end: the default SCARA misses it, one with
    # a longer second arm reaches into it at the same q; its link bodies take the new sizes and
    # poses, its exclusions are recomputed, the free body keeps its state
    r, longer = cs.robots.scara1(), cs.robots.scara1(L2=0.40)
    q = np.array([0.0, 0.0, 0.05, 0.0, np.pi / 2, 0.03])
    names = [b.name for b in r.boxes]
    k2 = names.index("link2")
    P, H = longer.shapes(q)
    spot = P[k2].copy()
    spot[:3, 3] = P[k2][:3, 3] + P[k2][:3, 0] * (H[k2][0] - 0.03)   # inside the longer link 2, near its end
    half = np.full(3, 0.005)
    P0, H0 = r.shapes(q)
    assert min(cs.box_distance(P0[b], H0[b], spot, half) for b in range(len(H0))) > 0.02
    world = cs.World()
    world.add_static_box("post", half, spot)
    crate_pose = np.eye(4)
    crate_pose[:3, 3] = [0.9, 0.9, 0.05]
    world.add_free_box("crate", [0.05, 0.05, 0.05], 1.0, crate_pose, velocity=[0.1, 0.0, 0.0])
    sim = cs.Simulation(dt=DT, world=world)
    sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), q)
    sim.step(50)
    assert not any("post" in (c.a, c.b) for c in sim.contacts())
    crate = sim.body_state("crate")
    sim.set_robot(0, longer)
    # the world's bodies of the robot: the new sizes at once, the crate untouched
    for b, name in enumerate(names):
        np.testing.assert_array_equal(world.body(f"scara1/{name}")["half_extents"], longer.boxes[b].half_extents)
    after = sim.body_state("crate")
    np.testing.assert_array_equal(after.position, crate.position)
    # at the same q, bit for bit, as the last step's: the new robot's frames, not those kept of the old
    Pq, _ = longer.shapes(sim.state(0)[0])
    for b in range(len(names)):
        np.testing.assert_allclose(sim.link_state(0, b).pose, Pq[b], atol=1e-12)
    sim.step(1)
    Pn, _ = longer.shapes(sim.state(0)[0])
    for b in range(len(names)):
        np.testing.assert_allclose(sim.link_state(0, b).pose, Pn[b], atol=1e-12)
    contacts = sim.contacts()
    assert any({c.a, c.b} == {"post", "scara1/link2"} for c in contacts)
    assert not any(c.kind == "self" for c in contacts)   # its touching boxes excluded anew
    sim.step(200)   # the run goes on
    assert not sim.diverged and sim.body_state("crate").position[0] > crate.position[0]
    # after reset() (the robots' bodies leave the world until the next first step) the robot
    # replaced again comes back with its own boxes
    sim.reset()
    sim.set_robot(0, r)
    sim.step(1)
    for b, name in enumerate(names):
        np.testing.assert_array_equal(world.body(f"scara1/{name}")["half_extents"], r.boxes[b].half_extents)
    assert not any("post" in (c.a, c.b) for c in sim.contacts())



def test_a_robot_holding_a_body_is_not_replaced():
    r, w = scene(BOX)
    sim = closing(r, w)
    sim.run(0.3, progress=False)
    assert sim.holding(0) == "box"
    with pytest.raises(ValueError, match="robot 0 holds a body: release it before replacing the robot"):
        sim.set_robot(0, cs.robots.scara1(L1=0.35))
    assert sim.robots[0].dimensions["L1"] == r.dimensions["L1"]
    sim.release(0)
    sim.set_robot(0, cs.robots.scara1(L1=0.35))   # let go: replaced
    sim.run(0.35, progress=False)
    assert sim.robots[0].dimensions["L1"] == 0.35 and not sim.diverged


# ---- the public calls that stand for the engine's ----

def test_advance_runs_as_run_does_without_building_the_log():
    a = make_sim()
    log_a = a.run(0.1, progress=False)
    b = make_sim()
    assert b.steps_until(0.1) == 500 and b.steps_until(0.0) == 0
    for t, steps in ((0.013, 65), (0.05, 185), (0.0501, 0), (0.1, 250)):     # steps rounded down
        before = b.steps
        assert b.steps_until(t) == steps
        assert b.advance(t) == b.time == pytest.approx(t, abs=DT)
        assert b.stats.sim_time == b.time and b.stats.steps == b.steps - before == steps
    assert b.steps == 500 and b.steps_until(0.1) == 0
    assert_logs_equal(b.log, log_a)
    with pytest.raises(ValueError):
        b.advance(0.05)                 # in the past
    with pytest.raises(ValueError):
        b.steps_until(float("nan"))


def test_contact_events_tau_ext_and_link_states_without_the_log():
    w = cs.World()
    w.add_static_box("wall", [0.3, 0.0025, 0.4], position=[0.45, 0.25, 0.4])    # the arm turns into it
    r = cs.robots.scara1()
    q0 = np.array([0.0, 0.3, 0.10, 0.0, np.pi / 2, 0.02])
    sim = cs.Simulation(dt=DT, world=w, log_every=10)
    turn = cs.CubicTrajectory([0.0, 0.6], np.array([q0, q0 + [1.2, 0, 0, 0, 0, 0]]))
    sim.add_robot(r, cs.PID(400.0, 0.0, 40.0), turn)
    sim.set_applied(0, forces=np.arange(6.0))
    np.testing.assert_array_equal(sim.tau_ext(0), np.arange(6.0))
    sim.clear_applied(0)
    sim.advance(0.4)
    ev = sim.contact_events()
    contacts = sim.log.contacts
    assert len(contacts) > 0 and list(ev["a"]) == list(contacts.a) and list(ev["b"]) == list(contacts.b)
    np.testing.assert_array_equal(ev["begin"], contacts["begin"].to_numpy())
    # the events from the first-th on: the tail of every event's columns (what a caller that looks after each
    # piece of a run asks for); the count itself gives empty columns; outside 0 .. count a one-line error
    n = len(ev["a"])
    for first in (0, n - 1, n):
        tail = sim.contact_events(first)
        assert set(tail) == set(ev) and tail["a"] == ev["a"][first:] and tail["kind"] == ev["kind"][first:]
        for k in ("begin", "end", "peak_force", "max_depth", "steps"):
            np.testing.assert_array_equal(tail[k], ev[k][first:])
    for bad in (-1, n + 1):
        with pytest.raises(ValueError, match=rf"first must be 0 \.\. {n} \(the events so far\), got {bad}"):
            sim.contact_events(bad)
    # each link box where the world holds it: at the robot's kinematics, as of the last world step
    P, _ = r.shapes(sim.state(0)[0])
    for k in range(len(r.boxes)):
        np.testing.assert_allclose(sim.link_state(0, k).pose, P[k], atol=1e-9)
    for bad in (len(r.boxes), -1, 1.0, True):
        with pytest.raises(ValueError, match="box"):
            sim.link_state(0, bad)
    assert make_sim().contact_events() == {}                     # no world, no events


def test_profiling_splits_the_steps_time():
    sim = make_sim()
    sim.set_profiling(True)
    sim.advance(0.05)
    p = sim.profile()
    assert {"controllers", "robots"} <= set(type(p).fields) and all(getattr(p, k) >= 0.0 for k in type(p).fields)
    assert p.robots > 0.0
    sim.set_profiling(False)
    with pytest.raises(ValueError, match="True or False"):
        sim.set_profiling("yes")


def test_advance_all_is_the_runs_one_by_one_on_threads():
    alone = [make_sim(dt=DT * k) for k in (1, 2)]
    for s in alone:
        s.run(0.05, progress=False)
    sims = [make_sim(dt=DT * k) for k in (1, 2)]
    errors = cs.Simulation.advance_all(sims, 0.05, threads=2)
    assert errors == [None, None]
    for s, a in zip(sims, alone):
        assert_logs_equal(s.log, a.log)
        assert s.stats.steps == a.steps and s.stats.wall_time > 0


def test_the_pacer_drives_anything_with_the_simulations_public_calls():
    clock = FakeClock()
    sim = make_sim()

    class Wrapped:        # a simulation seen only through the calls the pacer uses
        time = property(lambda self: sim.time)
        dt = property(lambda self: sim.dt)
        steps = property(lambda self: sim.steps)
        steps_until, step = sim.steps_until, sim.step
        stats = None

    w = Wrapped()
    stats = cs.Pacer(speed=4.0, frame_rate=50.0, clock=clock, sleep=clock.sleep).run(w, 0.2)
    assert sim.time == pytest.approx(0.2) and w.stats is stats and stats.sim_elapsed == pytest.approx(0.2)
    with pytest.raises(ValueError, match="coopsim.Simulation"):
        cs.Pacer().run(object(), 1.0)


def test_build_info():
    info = cs.build_info()
    assert set(info) == {"optimised", "sanitizers"}
    assert isinstance(info["optimised"], bool) and isinstance(info["sanitizers"], str)
    assert not (info["optimised"] and info["sanitizers"])       # a sanitized build is a Debug one


def test_speed_zero_is_a_pause():
    p = cs.Pacer(speed=1.0)
    assert not p.paused
    p.speed = 0.0
    assert p.paused            # the docs: speed 0 is a pause
    p.resume()
    assert p.paused            # still: the speed is 0
    p.speed = 0.5
    assert not p.paused
    p.pause()
    assert p.paused
    p.resume()
    assert not p.paused


def test_the_stats_report_the_frame_rate_reached_against_the_one_asked():
    clock = FakeClock()
    pacer = cs.Pacer(speed=1.0, frame_rate=50.0, clock=clock, sleep=clock.sleep)

    def slow_frame(s, p):
        clock.now += 0.05   # drawing a frame takes 50 ms: 20 frames per second at most
    stats = pacer.run(make_sim(), 0.5, on_frame=slow_frame)
    assert stats.frame_rate_asked == 50.0
    assert stats.frame_rate == pytest.approx(20.0, rel=1e-9)
    assert f"({stats.frame_rate:.1f}/s of 50/s asked)" in str(stats)
    fast = cs.Pacer(speed=1.0, frame_rate=50.0, clock=clock, sleep=clock.sleep).run(make_sim(), 0.5,
                                                                                       on_frame=lambda s, p: None)
    assert fast.frame_rate == pytest.approx(50.0, rel=1e-9)


def test_a_runaway_past_raised_limits_is_reported_with_its_state_and_step():
    # limits raised out of the way: the state grows until an RK4 stage evaluates the dynamics at q ~ 1e9, where
    # the mass matrix is lost to rounding; that is a runaway, not a robot without mass
    r = cs.robots.scara1()
    free = cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, joint_types=r.joint_types, name="free")
    sim = cs.Simulation(dt=5e-3, max_speed=1e300, max_position=1e300)
    sim.add_robot(free, cs.PID(1e3, 0.0, 10.0, gravity_compensation=False), np.full(6, 0.1),
                  q0=np.full(6, 0.1 + 1e-9))
    with pytest.raises(cs.DivergenceError) as err:
        sim.run(1.0, progress=False)
    msg, e = str(err.value), err.value
    assert f"simulation diverged at step {e.step}" in msg and "robot 0 'free': the state ran away: the rk4 stage" in msg
    assert "(a joint beyond 10000 rad/s or 1e+06 rad (m/s, m))" in msg
    assert "links without mass" not in msg and "not positive definite" not in msg
    assert np.all(np.isfinite(sim.log.q)) and len(sim.log) == e.step


def test_the_kinematics_kept_between_stages_give_the_steps_of_a_fresh_evaluation_bit_for_bit():
    # each robot's kinematics and mass matrix at q are kept in its workspace between the stages of a step (the
    # controller's, the world's, the integrator's first stage) and evaluated once: every step must be the one
    # RK4 and the controller give evaluated afresh, bit for bit (a numeric robot: the recursive algorithms)
    robot = cs.robots.scara1(backend="numeric")
    traj = trajectory(robot)
    world = cs.World(floor=True)
    sim = cs.Simulation(dt=DT, world=world)
    sim.add_robot(robot, cs.ComputedTorque(400.0, 40.0), traj)
    log = sim.run(0.05, progress=False)
    assert len(log) > 200 and not sim.contacts()
    fresh = cs.ComputedTorque(400.0, 40.0)
    fresh.reset(robot, DT)
    for k in range(len(log) - 1):
        tau = fresh.compute(log.t[k], log.q[k], log.qd[k], log.q_ref[k], log.qd_ref[k], log.qdd_ref[k])
        np.testing.assert_array_equal(tau, log.tau[k], err_msg=f"row {k}")
        q1, qd1 = cs.rk4_step(robot, log.q[k], log.qd[k], log.tau[k], DT)
        np.testing.assert_array_equal(q1, log.q[k + 1], err_msg=f"row {k}")
        np.testing.assert_array_equal(qd1, log.qd[k + 1], err_msg=f"row {k}")
