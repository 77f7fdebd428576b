"""Simulation speed: steps per second and real-time factor of headless runs.

Rows, for each SCARA: one robot tracking a cubic trajectory under PID (with
gravity compensation) and under computed torque, RK4 at 0.2 ms, timed as
``Simulation.run(t_end)`` called from Python (logging every step, the log
returned as numpy arrays), also with the log every 10th step; then a batch
of 16 computed-torque runs on 1 and on 2 threads (``run_batch``). Each
figure is the median over repeats of the wall time; ratios are taken within
this run. Target: >= 150x real time for one SCARA under
computed torque.

    python benchmarks/bench_simulation.py [--quick]
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import coopsim as cs

DT = 2e-4
TARGET_RTF = 150.0


def trajectory(robot, duration):
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    mid, span = (lo + hi) / 2, hi - lo
    pts = np.array([mid + f * span for f in (-0.1, 0.15, -0.2, 0.05)])
    return cs.CubicTrajectory(np.linspace(0.0, duration, 4), pts)


def gains(robot, traj):
    """Per-joint kp, ki, kd from M's diagonal at the start, omega = 50 rad/s (also bench_peers.py's PID)."""
    J = np.maximum(np.diag(robot.mass_matrix(traj.evaluate(0.0)[0])), 0.01)
    w = 50.0
    return J * w * w, J * w ** 3 / 10, 2 * J * w


def pid(robot, traj):
    return cs.PID(*gains(robot, traj))


def make(robot, traj, controller, log_every=1):
    sim = cs.Simulation(DT, log_every=log_every)
    sim.add_robot(robot, controller, traj)
    return sim


def time_run(build, t_end, repeats):
    """Median wall time (s) of build().run(t_end)."""
    times = []
    for _ in range(repeats):
        sim = build()
        t0 = time.perf_counter()
        sim.run(t_end, progress=False)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def time_batch(build, n, t_end, threads, repeats):
    times = []
    for _ in range(repeats):
        sims = [build() for _ in range(n)]
        t0 = time.perf_counter()
        cs.run_batch(sims, t_end, threads=threads)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs, fewer repeats")
    args = ap.parse_args()
    t_end = 1.0 if args.quick else 4.0
    repeats = 3 if args.quick else 7
    steps = round(t_end / DT)

    print(f"# coopsim {cs.__version__}, module built optimised: {cs.build_info()['optimised']}")
    if not cs.build_info()["optimised"]:
        print("# WARNING: not an optimised build; these figures do not count")
    print(f"# {steps} steps of {DT * 1e3:g} ms ({t_end:g} s simulated) per run, median of {repeats}")
    rows = []  # (what, ns per step, steps per s, real-time factor, ratio text)
    ok = True
    for make_robot in (cs.robots.scara1, cs.robots.scara2):
        robot = make_robot()
        traj = trajectory(robot, t_end)
        w_pid = time_run(lambda: make(robot, traj, pid(robot, traj)), t_end, repeats)
        w_ct = time_run(lambda: make(robot, traj, cs.ComputedTorque(900.0, 60.0)), t_end, repeats)
        w_ct10 = time_run(lambda: make(robot, traj, cs.ComputedTorque(900.0, 60.0), 10), t_end, repeats)
        for what, w, ratio in (
            (f"{robot.name} PID, run(), log every step", w_pid, "1.00 (ref)"),
            (f"{robot.name} computed torque, run(), log every step", w_ct, f"{w_ct / w_pid:.2f} x PID time"),
            (f"{robot.name} computed torque, run(), log every 10th", w_ct10, f"{w_ct10 / w_ct:.2f} x full log"),
        ):
            rows.append((what, w / steps * 1e9, steps / w, t_end / w, ratio))
        ok &= t_end / w_ct >= TARGET_RTF

    robot = cs.robots.scara1()
    traj = trajectory(robot, t_end / 4)
    n = 16
    build = lambda: make(robot, traj, cs.ComputedTorque(900.0, 60.0), 10)  # noqa: E731
    w1 = time_batch(build, n, t_end / 4, 1, repeats)
    w2 = time_batch(build, n, t_end / 4, 2, repeats)
    bsteps = n * round(t_end / 4 / DT)
    rows.append((f"batch of {n} scara1 computed torque, 1 thread", w1 / bsteps * 1e9, bsteps / w1,
                 n * t_end / 4 / w1, "1.00 (ref)"))
    rows.append((f"batch of {n} scara1 computed torque, 2 threads", w2 / bsteps * 1e9, bsteps / w2,
                 n * t_end / 4 / w2, f"{w1 / w2:.2f} x throughput"))

    head = ("what", "ns per step", "steps per s", "real-time x", "ratio")
    width = max(len(r[0]) for r in rows)
    print(f"{head[0]:<{width}}  {head[1]:>11}  {head[2]:>12}  {head[3]:>11}  {head[4]}")
    for what, ns, sps, rtf, ratio in rows:
        print(f"{what:<{width}}  {ns:>11.0f}  {sps:>12,.0f}  {rtf:>11.1f}  {ratio}")
    print(f"# target: one SCARA under computed torque >= {TARGET_RTF:g}x real time: "
          f"{'met' if ok else 'NOT met'} on this machine in this run")


if __name__ == "__main__":
    main()
