"""Sweep throughput: a 64-run gain sweep on 1 thread, 2 threads, a 2-process pool and a 2-worker Dask cluster.

The sweep: SCARA #1 tracking a cubic trajectory under PID, an 8 x 8 grid of
(kp, kd), each run `--t-end` simulated seconds at dt = 0.2 ms, through
``coopsim.sweep`` (threads: one ``run_batch`` call; the pool and Dask: each
run's description pickled to a worker, its row of metrics back). For each
engine: the wall time of the whole sweep (median of repeats), the throughput
in simulated seconds per wall second, and the overhead per run: the sweep's
wall time times its workers less the runs' own wall times (measured where
they ran), over the runs; then the same 64 runs of one step each, whose wall
time per run is the engine's fixed cost. The Dask cluster is a LocalCluster
of 2 worker processes of one thread each on this machine (its start-up time
is printed apart); a last row sends the runs to it in tasks of 8 (``chunk=8``). ``--task N`` adds a sweep of the cooperative task over N
seeds on 2 threads and on the cluster.

    python benchmarks/bench_sweep.py [--quick] [--t-end 2.0] [--task 8]
"""
from __future__ import annotations

import argparse
import concurrent.futures
import logging
import multiprocessing
import statistics
import time

import numpy as np

import coopsim as cs
from bench_simulation import trajectory  # the closed loop's cubic (this folder is on sys.path)

DT = 2e-4


ROBOT = cs.robots.scara1()


def builder(t_end):
    traj = trajectory(ROBOT, t_end)

    def make(kp, kd):
        sim = cs.Simulation(DT, log_every=10)
        sim.add_robot(ROBOT, cs.PID(kp, kp / 10, kd), traj)
        return sim
    return make


GRID = dict(kp=list(np.geomspace(200.0, 12800.0, 8)), kd=list(np.geomspace(10.0, 160.0, 8)))


def time_sweep(make, t_end, workers, repeats, **kw):
    """Median wall time of the sweep, its last table, and the median overhead per run (s)."""
    walls, overheads, df = [], [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        df = cs.sweep(make, t_end, grid=GRID, **kw)
        walls.append(time.perf_counter() - t0)
        assert df.error.isna().all(), df.error.dropna()
        overheads.append((walls[-1] * workers - df.wall_time.sum()) / len(df))
    return statistics.median(walls), df, statistics.median(overheads)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one repeat")
    ap.add_argument("--t-end", type=float, default=2.0, help="simulated seconds per run (default 2)")
    ap.add_argument("--task", type=int, default=0, help="also sweep the cooperative task over this many seeds")
    args = ap.parse_args()
    repeats = 1 if args.quick else 3
    make = builder(args.t_end)
    n = len(GRID["kp"]) * len(GRID["kd"])
    engines = [("1 thread", 1, dict(threads=1)), ("2 threads", 2, dict(threads=2))]
    pool = concurrent.futures.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn"))
    engines.append(("process pool, 2", 2, dict(executor=pool)))
    client = cluster = None
    try:
        import distributed
    except ImportError:
        print("dask distributed is not installed (pip install coopsim[cluster]): no Dask row")
    else:
        t0 = time.perf_counter()
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           dashboard_address=None, host="127.0.0.1", silence_logs=logging.ERROR)
        client = distributed.Client(cluster)
        client.wait_for_workers(2)
        print(f"Dask LocalCluster of 2 workers started in {time.perf_counter() - t0:.2f} s")
        engines.append(("Dask, 2 workers", 2, dict(executor=client)))
        engines.append(("Dask, chunks of 8", 2, dict(executor=client, chunk=8)))
    try:
        # warm-up: worker imports, first pickles
        for _, _, kw in engines:
            cs.sweep(make, DT, grid=GRID, **kw)
        print(f"\n{n}-run gain sweep (8 x 8 kp, kd), SCARA #1 under PID, {args.t_end:g} simulated s per run at "
              f"dt = {DT * 1e3:g} ms, median of {repeats}")
        print(f"{'engine':<18}{'wall s':>9}{'sim s / wall s':>16}{'x 1 thread':>12}{'overhead / run':>16}"
              f"{'1-step run':>12}")
        base = None
        reference = None
        for name, workers, kw in engines:
            wall, df, overhead = time_sweep(make, args.t_end, workers, repeats, **kw)
            tiny_wall, _, _ = time_sweep(make, DT, workers, repeats, **kw)
            metrics = [c for c in df.columns if c.startswith(("rms_error_", "peak_tau_"))]
            if reference is None:
                reference = df[metrics]
            assert (df[metrics].to_numpy() == reference.to_numpy()).all(), f"{name}: metrics differ from 1 thread"
            throughput = n * args.t_end / wall
            base = base or throughput
            print(f"{name:<18}{wall:>9.3f}{throughput:>16.1f}{throughput / base:>12.2f}"
                  f"{overhead * 1e3:>13.2f} ms{tiny_wall / n * 1e3:>9.2f} ms")
        print("(every engine gives the 1-thread metrics bit for bit)")
        if args.task:
            print(f"\ncooperative task over {args.task} seeds (one bar each, score=False)")
            for name, workers, kw in engines[1:2] + engines[3:4]:
                t0 = time.perf_counter()
                df = cs.sweep(cs.TaskRun, grid=dict(seed=range(args.task)), **kw)
                wall = time.perf_counter() - t0
                print(f"{name:<18}{wall:>9.3f} s, {df.simulated_time.sum() / wall:>7.1f} sim s / wall s, "
                      f"{int(df.success.sum())} of {len(df)} succeeded")
    finally:
        pool.shutdown()
        if client is not None:
            client.close()
            cluster.close()


if __name__ == "__main__":
    main()
