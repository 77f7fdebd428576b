"""Batches and sweeps on a pool of threads give what the same work gives one item at a time: run_batch's
balanced pool (idle threads take the next simulation), forward_dynamics_batch's chunks (idle threads take the next
256 states; a failing state is the first failing row's error, never a crash), and the task sweeps' thread path (the
same rows as the serial sweep; a run that raises is that row's error). Speed is benchmarks/bench_scaling.py's."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import coopsim as cs
from coopsim.sweeps import OptionsRun, run_one

QTY = ("q", "qd", "qdd", "tau", "tau_ext", "q_ref", "qd_ref", "qdd_ref")


def trajectory(robot, duration):
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    return cs.CubicTrajectory([0.0, duration / 2, duration], np.array([mid - 0.1 * span, mid + 0.15 * span, mid]))


def diverging():
    """A PID far too stiff for dt = 5 ms on a robot without limits: its state runs away."""
    r = cs.robots.scara1()
    sim = cs.Simulation(dt=5e-3)
    free = cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, joint_types=r.joint_types, name="free")
    sim.add_robot(free, cs.PID(1e3, 0.0, 10.0, gravity_compensation=False), np.full(6, 0.1),
                  q0=np.full(6, 0.1 + 1e-9))
    return sim


def uneven_batch():
    """Runs of very different cost in one batch: replicas of one model (computed torque, each pushed by its own
    joint forces set after replicate), a SCARA #2 at a tenth of the step, a single cheap run at 2 ms, one that
    diverges, and more replicas after it."""
    r1, r2 = cs.robots.scara1(), cs.robots.scara2()
    base = cs.Simulation(dt=2e-4, log_every=5)
    base.add_robot(r1, cs.ComputedTorque(900.0, 60.0), trajectory(r1, 0.3))
    replicas = base.replicate(7)
    for k, sim in enumerate(replicas):
        sim.set_applied(0, forces=np.full(6, 0.05 * k))
    fine = cs.Simulation(dt=2e-5, log_every=50)
    fine.add_robot(r2, cs.ComputedTorque(400.0, 40.0), trajectory(r2, 0.3))
    coarse = cs.Simulation(dt=2e-3, log_every=1)
    coarse.add_robot(r1, cs.PID(400.0, 40.0, 20.0), trajectory(r1, 0.3))
    return replicas[:3] + [fine, coarse, diverging()] + replicas[3:]


def assert_same_run(a: cs.Simulation, b: cs.Simulation):
    assert a.time == b.time and a.steps == b.steps
    la, lb = a.log, b.log
    np.testing.assert_array_equal(la.t, lb.t)
    for ra, rb in zip(la.robots, lb.robots):
        for qty in QTY:
            np.testing.assert_array_equal(getattr(ra, qty), getattr(rb, qty), err_msg=qty)
    for ma, mb in zip(a.metrics(), b.metrics()):
        np.testing.assert_array_equal(ma.rms_error, mb.rms_error)
        np.testing.assert_array_equal(ma.max_abs_tau, mb.max_abs_tau)


@pytest.mark.parametrize("threads", [2, 3, 0])
def test_run_batch_on_a_balanced_pool_gives_the_runs_one_by_one(threads):
    batch = uneven_batch()
    out = cs.run_batch(batch, 0.3, threads=threads, output="none", errors="return")
    serial = uneven_batch()
    for k, sim in enumerate(serial):
        try:
            sim.run(0.3, progress=False)
        except cs.DivergenceError as e:
            assert k == 5 and isinstance(out[k], cs.DivergenceError) and str(out[k]) == str(e)
    assert [e is None for e in out] == [k != 5 for k in range(len(batch))]
    for a, b in zip(batch, serial):
        assert_same_run(a, b)
    # the replicas differ by their inputs only, and the inputs count
    assert not np.array_equal(batch[0].log.robots[0].q, batch[1].log.robots[0].q)


def test_run_batch_with_more_threads_than_runs_and_with_none():
    sims = uneven_batch()[:2]
    assert cs.run_batch(sims, 0.1, threads=16, output="none") == [None, None]
    assert all(s.time == pytest.approx(0.1) for s in sims)
    assert cs.run_batch([], 0.1, threads=4) == []


@pytest.mark.parametrize("n", [0, 1, 255, 256, 257, 1000 + 37])
def test_forward_dynamics_batch_in_chunks_on_any_threads_equals_one_by_one(n):
    robot = cs.robots.scara2()
    rng = np.random.default_rng(n)
    Q = rng.uniform(robot.q_limits[:, 0], robot.q_limits[:, 1], (n, robot.dof))
    QD, TAU = rng.normal(size=(n, robot.dof)), rng.normal(size=(n, robot.dof))
    single = np.array([robot.forward_dynamics(q, qd, tau) for q, qd, tau in zip(Q, QD, TAU)]).reshape(n, robot.dof)
    for threads in (1, 2, 3, 5, 0):
        np.testing.assert_array_equal(cs.forward_dynamics_batch(robot, Q, QD, TAU, threads=threads), single)


@pytest.mark.parametrize("threads", [1, 2, 4])
def test_a_failing_state_in_a_threaded_batch_is_the_first_failing_rows_error(threads):
    robot = cs.robots.scara1()
    n = 3000
    Q, QD, TAU = np.zeros((n, 6)), np.zeros((n, 6)), np.zeros((n, 6))
    for bad in (2900, 1700, 1701):  # forces that overflow; 1700 is the first, in the second half of the rows
        Q[bad], QD[bad] = 1e300, 1e300
    with pytest.raises(ValueError, match=r"^state 1700 \(row of q, qd, tau\): forward_dynamics: the mass matrix or "
                                         r"the forces overflow"):
        cs.forward_dynamics_batch(robot, Q, QD, TAU, threads=threads)
    # and the engine is fine afterwards
    assert cs.forward_dynamics_batch(robot, Q[:1000], QD[:1000], TAU[:1000], threads=threads).shape == (1000, 6)


def without_timing(df):
    return df.drop(columns=[c for c in ("wall_time", "worker") if c in df.columns])


def test_the_carry_sweep_on_threads_gives_the_rows_of_the_serial_sweep():
    C = pytest.importorskip("coopsim.tasks.carry")
    threaded = C.sweep_table(["ct"], ["none", "push"], [0, 1], threads=2, score_run=False)
    serial = C.sweep_table(["ct"], ["none", "push"], [0, 1], threads=1, score_run=False)
    pd.testing.assert_frame_equal(without_timing(threaded), without_timing(serial))
    assert threaded.error.isna().all() and threaded.success.astype(bool).all()
    # and each row is the run made alone, on this thread
    alone = run_one(C.CarryRun(controllers="ct", disturbance="push", seed=1, score_run=False))
    for k, v in alone.items():
        if k not in ("wall_time", "worker"):
            assert threaded[k].iloc[3] == v or (v != v and threaded[k].iloc[3] != threaded[k].iloc[3]), k


def test_the_handover_sweep_on_threads_gives_the_rows_of_the_serial_sweep():
    H = pytest.importorskip("coopsim.tasks.handover")
    runs = [H.TaskRun(seed=s) for s in (0, 3, 5)]
    threaded = cs.sweep(runs, threads=3)
    serial = cs.sweep(runs, threads=1)
    pd.testing.assert_frame_equal(without_timing(threaded), without_timing(serial))
    assert threaded.error.isna().all() and len(threaded) == 3


class Flaky(OptionsRun):
    """A sweep item that raises when told to (a bug in a task's code, not a failed run it reports)."""

    sweep_columns = ("value",)

    def sweep_run(self):
        if self.options.get("fail"):
            raise RuntimeError(f"item {self.options['k']} broke")
        sim = cs.Simulation(dt=1e-3, log_every=10)
        r = cs.robots.scara1()
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), trajectory(r, 0.05))
        sim.run(0.05, progress=False)
        return dict(value=self.options["k"] * 10, simulated_time=sim.time), sim


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_a_task_run_that_raises_on_a_thread_is_its_rows_error_and_the_sweep_goes_on(threads):
    items = [Flaky(k=k, fail=k in (1, 4)) for k in range(6)]
    df = cs.sweep(items, threads=threads)
    assert len(df) == 6 and list(df.index) == list(range(6))
    assert list(df.error.isna()) == [True, False, True, True, False, True]
    assert df.error[1] == "RuntimeError: item 1 broke" and df.error[4] == "RuntimeError: item 4 broke"
    assert list(df.value[[0, 2, 3, 5]]) == [0, 20, 30, 50]
    assert (df.steps[[0, 2, 3, 5]] == 50).all()
    # a task whose options are wrong is also a row (the task reports it, the run never starts)
    C = pytest.importorskip("coopsim.tasks.carry")
    df = cs.sweep([C.CarryRun(controllers="no such law", seed=0), Flaky(k=7)], threads=threads)
    assert isinstance(df.error[0], str) and "no such law" in df.error[0] and not df.success[0]
    assert pd.isna(df.error[1]) and df.value[1] == 70
