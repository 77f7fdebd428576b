"""coopsim.sweep: one table of per-run metrics in grid order on threads, a process pool and a Dask cluster;
errors as rows; a worker killed mid-sweep loses no row; a sweep cut short returns what finished. The process pools
and the Dask cluster take seconds to start: their tests are slow; the threads' tests are the fast loop's."""
from __future__ import annotations

import concurrent.futures
import logging
import multiprocessing
import os
import signal

import numpy as np
import pandas as pd
import pytest

import coopsim as cs

T_END = 0.4


def trajectory(robot: cs.Robot, duration: float = T_END) -> cs.CubicTrajectory:
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    return cs.CubicTrajectory([0.0, duration / 2, duration], np.array([mid - 0.1 * span, mid + 0.15 * span, mid]))


ROBOT = cs.robots.scara1()
TRAJ = trajectory(ROBOT)
GRID = dict(kp=[400.0, 1600.0, 6400.0], kd=[20.0, 80.0])


def make(kp, kd, dt=2e-4):
    sim = cs.Simulation(dt=dt, log_every=10)
    sim.add_robot(ROBOT, cs.PID(kp, kp / 10, kd), TRAJ)
    return sim


def diverging():
    """A PID far too stiff for dt = 5 ms on a robot without limits: its state runs away."""
    sim = cs.Simulation(dt=5e-3)
    free = cs.Robot.from_dh(ROBOT.dh, ROBOT.com, ROBOT.masses, ROBOT.inertias, joint_types=ROBOT.joint_types,
                            name="free")
    sim.add_robot(free, cs.PID(1e3, 0.0, 10.0, gravity_compensation=False), np.full(6, 0.1),
                  q0=np.full(6, 0.1 + 1e-9))
    return sim


def metric_columns(df):
    return [c for c in df.columns if c.startswith(("rms_error_", "max_error_", "peak_tau_"))]


def process_pool():
    # spawn: workers start clean, whatever threads this process runs
    return concurrent.futures.ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn"))


def test_grid_order_columns_and_metrics_equal_one_by_one():
    df = cs.sweep(make, T_END, grid=GRID, threads=2)
    assert list(df.index) == list(range(6)) and df.index.name == "run"
    assert list(df[["kp", "kd"]].itertuples(index=False, name=None)) == [(kp, kd) for kp in GRID["kp"]
                                                                           for kd in GRID["kd"]]
    assert df.error.isna().all() and (df.steps == 2000).all() and np.allclose(df.simulated_time, T_END)
    assert (df.wall_time > 0).all()
    assert len(metric_columns(df)) == 3 * 6
    for row, (kp, kd) in zip(df.itertuples(), df[["kp", "kd"]].itertuples(index=False, name=None)):
        sim = make(kp, kd)
        sim.run(T_END, progress=False)
        m = sim.metrics()[0]
        np.testing.assert_array_equal(df.loc[row.Index, [f"rms_error_0_{j}" for j in range(6)]].to_numpy(float),
                                      m.rms_error)
        np.testing.assert_array_equal(df.loc[row.Index, [f"peak_tau_0_{j}" for j in range(6)]].to_numpy(float),
                                      m.max_abs_tau)
    # stiffer gains track better
    assert df.rms_error_0_3.iloc[0] > df.rms_error_0_3.iloc[2] > df.rms_error_0_3.iloc[4] > 0
    # a list of simulations with its own grid columns, and the logs kept on request
    sims = [make(100.0, 5.0), make(400.0, 80.0)]
    kept = cs.sweep(sims, T_END, grid=[dict(label="soft"), dict(label="stiff")], keep_logs=True, threads=1)
    assert list(kept.label) == ["soft", "stiff"] and len(kept.log[1].t) == 201
    np.testing.assert_array_equal(kept.loc[1, metric_columns(kept)].to_numpy(float),
                                  df.loc[1, metric_columns(df)].to_numpy(float))


@pytest.mark.parametrize("executor", [None, pytest.param("pool", marks=pytest.mark.slow)])
def test_a_diverging_run_is_a_row_with_its_error_and_the_others_are_unaffected(executor):
    sims = [make(100.0, 5.0), diverging(), make(400.0, 20.0)]
    clean = cs.sweep([make(100.0, 5.0), make(400.0, 20.0)], T_END)
    if executor == "pool":
        with process_pool() as pool:
            df = cs.sweep(sims, T_END, executor=pool)
    else:
        df = cs.sweep(sims, T_END)
    assert len(df) == 3
    assert df.error[1].startswith("DivergenceError: ") and "step" in df.error[1], df.error[1]
    assert 0 < df.simulated_time[1] < T_END  # metrics up to the failure
    assert df.error[[0, 2]].isna().all()
    pd.testing.assert_frame_equal(df.loc[[0, 2], metric_columns(df)].reset_index(drop=True),
                                  clean[metric_columns(clean)].reset_index(drop=True))


def test_task_runs_report_success_step_and_reason_and_an_unreachable_bar_is_a_row():
    H = pytest.importorskip("coopsim.tasks.handover")
    runs = [cs.TaskRun(seed=0), cs.TaskRun(bars=[H.bar_on_floor(1.5, 0.3, 0.5)]),
            cs.TaskRun(cycles=1, container_shift=(0.1, 0.0, 0.05))]
    df = cs.sweep(runs, threads=2)
    assert list(df.success) == [True, False, False]
    assert df.step[1] == "planning" and df.error[1].startswith("IKError: SCARA #2, planning the pick of bar")
    assert df.step[2] == "to container" and df.reason[2] == "forbidden contact between container_top and scara1/link6"
    assert df.error[[0, 2]].isna().all()  # a failed cycle is a result, not an error
    assert df.simulated_time[0] > 10 and df.bar_x[0] == pytest.approx(H.random_bar(0)[0, 3])
    assert np.isfinite(df.loc[0, metric_columns(df)].to_numpy(float)).all() and len(metric_columns(df)) == 36


class Gate(cs.Controller):
    """Holds its run at the first control step until `event` is set: an Event the test controls (a
    multiprocessing manager's on a process pool; on Dask, the name of a distributed.Event). A run
    behind a closed gate cannot finish, however fast or loaded the machine is."""

    def __init__(self, event):
        super().__init__()
        self.event = event

    def compute(self, t, q, qd, q_ref, qd_ref, qdd_ref):
        event = self.event
        if isinstance(event, str):
            import distributed

            event = distributed.Event(event)
        event.wait()
        return np.zeros(len(q))


def gated(event):
    sim = cs.Simulation(log_every=10)
    sim.add_robot(ROBOT, Gate(event), TRAJ)
    return sim


# the runs that finish take a few ms each; the timeout gives them this long (s), far beyond what load
# stretches them to, while the gated runs cannot finish before the test opens the gate, after the sweep
# has returned: the timeout must fire, whatever the machine's speed
TIMEOUT = 10.0


@pytest.mark.slow
def test_a_sweep_cut_short_returns_what_finished():
    seen = []
    with multiprocessing.get_context("spawn").Manager() as manager, process_pool() as pool:
        gate = manager.Event()
        cs.sweep([make(100.0, 5.0), make(100.0, 5.0)], 0.01, executor=pool)  # the workers are up
        try:
            sims = [make(100.0, 5.0), gated(gate), make(400.0, 20.0), gated(gate)]
            df = cs.sweep(sims, T_END, executor=pool, timeout=TIMEOUT, on_result=lambda i, row: seen.append(i))
        finally:
            gate.set()  # the gated runs finish, and the pool can shut down
    assert len(df) == 4 and sorted(seen) == [0, 2]
    assert df.error[[0, 2]].isna().all() and (df.steps[[0, 2]] == 2000).all()
    assert (df.error[[1, 3]] == cs.sweeps.NOT_FINISHED).all() and df.steps[[1, 3]].isna().all()


@pytest.mark.slow
def test_a_dask_sweep_that_times_out_returns_what_finished(dask_client):
    distributed = pytest.importorskip("distributed")
    gate = distributed.Event("gate-of-the-timeout-test", client=dask_client)
    try:
        df = cs.sweep([make(100.0, 5.0), gated(gate.name)], T_END, executor=dask_client, timeout=TIMEOUT)
    finally:
        gate.set()
    assert pd.isna(df.error[0]) and df.steps[0] == 2000 and df.error[1] == cs.sweeps.NOT_FINISHED


def interrupt_after(n):
    seen = []

    def on_result(i, row):
        seen.append(i)
        if len(seen) == n:
            raise KeyboardInterrupt  # as Ctrl-C in the client while it waits

    return on_result, seen


@pytest.mark.slow
def test_a_sweep_interrupted_from_the_client_returns_what_finished(dask_client):
    for executor in ("pool", dask_client):
        on_result, seen = interrupt_after(2)
        if executor == "pool":
            with process_pool() as pool:
                df = cs.sweep(make, T_END, grid=GRID, executor=pool, on_result=on_result)
        else:
            df = cs.sweep(make, T_END, grid=GRID, executor=executor, on_result=on_result)
        assert len(df) == 6 and list(df.index[df.error.isna()]) == sorted(seen)
        assert (df.steps[seen] == 2000).all() and (df.error.drop(seen) == cs.sweeps.NOT_FINISHED).all()


def test_bad_arguments():
    with pytest.raises(ValueError, match="t_end"):
        cs.sweep([make(100.0, 5.0)])
    with pytest.raises(ValueError, match="grid="):
        cs.sweep(make, T_END)
    with pytest.raises(ValueError, match="grid has 2 points for 1 runs"):
        cs.sweep([make(100.0, 5.0)], T_END, grid=[{}, {}])
    with pytest.raises(ValueError, match=r"runs\[1\]"):
        cs.sweep([make(100.0, 5.0), "x"], T_END)
    with pytest.raises(ValueError, match="chunk"):
        cs.sweep([make(100.0, 5.0)], T_END, chunk=0)
    with pytest.raises(ValueError, match="executor"):
        cs.sweep([make(100.0, 5.0)], T_END, executor=object())
    assert cs.sweeps.grid(a=[1, 2], b="xy") == [dict(a=1, b="x"), dict(a=1, b="y"), dict(a=2, b="x"),
                                                dict(a=2, b="y")]


# ---- Dask: a LocalCluster of 2 worker processes on this machine ----

@pytest.fixture(scope="module")
def dask_client(tmp_path_factory):
    distributed = pytest.importorskip("distributed")
    # dashboard off (no port, no bokeh); loopback only; each worker one thread, so runs overlap as on 2 threads;
    # the workers' own, empty cache of generated libraries, as on another machine
    env = {"COOPSIM_CACHE_DIR": str(tmp_path_factory.mktemp("worker_cache"))}
    # (no warning to filter: with the dashboard off, starting and closing the cluster warns of nothing)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  host="127.0.0.1", silence_logs=logging.ERROR, env=env) as cluster, \
            distributed.Client(cluster, timeout=30) as client:
        client.wait_for_workers(2, timeout=60)
        yield client


@pytest.mark.slow
def test_the_same_grid_gives_identical_metrics_on_threads_a_process_pool_and_dask(dask_client):
    threads = cs.sweep(make, T_END, grid=GRID, threads=2)
    with process_pool() as pool:
        procs = cs.sweep(make, T_END, grid=GRID, executor=pool, timeout=60)
        chunked_procs = cs.sweep(make, T_END, grid=GRID, executor=pool, timeout=60, chunk=4)
    dask = cs.sweep(make, T_END, grid=GRID, executor=dask_client, timeout=60)
    chunked = cs.sweep(make, T_END, grid=GRID, executor=dask_client, timeout=60, chunk=4)  # tasks of 4 runs, 4 + 2
    cols = ["kp", "kd", "error", "simulated_time", "steps"] + metric_columns(threads)
    for df in (procs, chunked_procs, dask, chunked):
        pd.testing.assert_frame_equal(df[cols], threads[cols])
    # the runs really went to the two workers, and were timed there
    pids = {int(w.rsplit(":", 1)[1]) for w in dask.worker}
    assert pids <= set(dask_client.run(os.getpid).values()) and os.getpid() not in pids
    assert (dask.wall_time > 0).all()
    # the task too, with a failure as a row
    tasks = [cs.TaskRun(seed=1), cs.TaskRun(cycles=1, container_shift=(0.1, 0.0, 0.05))]
    local = cs.sweep(tasks, threads=2)
    remote = cs.sweep(tasks, executor=dask_client, timeout=60)
    cols = ["success", "step", "reason", "bar_x", "bar_y", "bar_yaw", "error", "simulated_time", "steps"]
    pd.testing.assert_frame_equal(remote[cols + metric_columns(local)], local[cols + metric_columns(local)])
    from coopsim.tasks import handover as H

    assert H.sweep([1, 2], executor=dask_client) == H.sweep([1, 2], threads=2)  # its dict, the same either way


@pytest.mark.slow
def test_generated_dynamics_compiled_here_reach_the_workers(dask_client, tmp_path, monkeypatch):
    pytest.importorskip("sympy")
    from coopsim import codegen

    monkeypatch.setenv("COOPSIM_CACHE_DIR", str(tmp_path / "client"))
    robot = codegen.compile(cs.robots.scara1())  # built here, at run time: not in the engine, not on the workers
    assert robot.backend == "generated"

    def make_generated(kp, kd):
        sim = cs.Simulation(log_every=10)
        sim.add_robot(robot, cs.PID(kp, kp / 10, kd), TRAJ)
        return sim

    small = dict(kp=[400.0, 6400.0], kd=[80.0])
    here = cs.sweep(make_generated, T_END, grid=small, threads=2)
    remote = cs.sweep(make_generated, T_END, grid=small, executor=dask_client, timeout=60)
    other = tmp_path / "pool"  # a pool whose workers look in another, empty cache
    ctx = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(2, mp_context=ctx, initializer=os.putenv,
                                                initargs=("COOPSIM_CACHE_DIR", str(other))) as pool:
        pooled = cs.sweep(make_generated, T_END, grid=small, executor=pool, timeout=60)
    for df in (here, remote, pooled):
        assert df.error.isna().all(), df.error
    cols = metric_columns(here)
    pd.testing.assert_frame_equal(remote[cols], here[cols])
    pd.testing.assert_frame_equal(pooled[cols], here[cols])
    assert list(other.glob("coopsim_gen_*.so"))  # installed there by the sweep
    # the same metrics as the engine's own generated dynamics of scara1 (make): equal, since both are
    # built by the same compiler with the same flags; against the engine built with sanitizers, whose
    # copy is compiled with theirs, they differ in rounding, which this closed loop amplifies
    if not cs.build_info()["sanitizers"]:
        compiled_in = cs.sweep(make, T_END, grid=small)
        np.testing.assert_allclose(here[cols].to_numpy(float), compiled_in[cols].to_numpy(float), rtol=1e-6,
                                   atol=1e-9)


@pytest.mark.slow
def test_a_worker_killed_mid_sweep_loses_no_row(dask_client):
    # 12 runs of 20 simulated s (about 0.25 s of wall time each) on the 2 workers
    kill_grid = dict(kp=[100.0, 200.0, 400.0, 800.0], kd=[5.0, 10.0, 20.0])
    expected = cs.sweep(make, 20.0, grid=kill_grid, threads=2)
    address, victim = next(iter(dask_client.run(os.getpid).items()))
    finished, lost = [], []

    def kill_at_the_second_result(i, row):
        finished.append(i)
        if len(finished) == 2:  # the other runs are running or queued: one worker dies outright
            lost.extend(dask_client.processing([address])[address])  # the runs it holds
            os.kill(victim, signal.SIGKILL)

    df = cs.sweep(make, 20.0, grid=kill_grid, executor=dask_client, timeout=90, on_result=kill_at_the_second_result)
    assert len(finished) == 12 and len(df) == 12 and df.error.isna().all(), df.error
    cols = ["kp", "kd", "error", "simulated_time", "steps"] + metric_columns(expected)
    pd.testing.assert_frame_equal(df[cols], expected[cols])
    # the killed worker's runs were run again elsewhere: on the survivor or the worker its nanny restarted
    assert victim not in set(dask_client.run(os.getpid).values())
    assert victim not in {int(w.rsplit(":", 1)[1]) for w in df.worker[finished[3:]]}
    assert lost, "the killed worker held no run"
