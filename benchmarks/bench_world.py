"""The world's cost: both SCARAs under computed torque in the cooperative task's scene
(floor, the container of four walls, the bar), RK4 at 0.2 ms.

Rows: the robots alone (the reference), then with the world every step and
every 5th step (contacts and their torques held in between). For each: the
median wall time of a run, the real-time factor, and the time per step
split into controllers, world (Bullet: collision detection and solver),
contact mapping (penalty forces, J^T) and robots (RK4), measured with the
simulation's own profiler in a separate run. Target: >= 50x real time with
the world at least every 5th step.

    python benchmarks/bench_world.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

# numpy's OpenBLAS threads spin after each call and take a core from the run being timed
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402
from coopsim.tasks import scene  # noqa: E402

DT = 2e-4
TARGET_RTF = 50.0


def references(duration):
    r1, r2 = scene.scaras()
    q1 = np.array([-1.2, 0.8, 0.15, 0.0, np.pi / 2, 0.03])
    q2 = np.array([0.3, 0.6, -0.5, 0.2, 0.0, 0.03])
    t = np.linspace(0.0, duration, 5)
    wave = np.sin(np.linspace(0, 2 * np.pi, 5))[:, None]
    d1 = np.array([0.3, -0.3, 0.05, 0.5, 0.2, 0.01])
    d2 = np.array([0.3, -0.3, 0.3, 0.05, 0.5, 0.01])
    return [(r1, cs.CubicTrajectory(t, q1 + wave * d1)), (r2, cs.CubicTrajectory(t, q2 + wave * d2))]


def build(duration, world_every=None):
    world = None if world_every is None else scene.world()
    kw = {} if world is None else dict(world=world, world_every=world_every)
    sim = cs.Simulation(DT, log_every=10, **kw)
    for robot, ref in references(duration):
        sim.add_robot(robot, cs.ComputedTorque(400.0, 40.0), ref)
    return sim


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs, fewer repeats")
    args = ap.parse_args()
    t_end, repeats = (1.0, 3) if args.quick else (4.0, 5)
    steps = int(round(t_end / DT))
    print(f"both SCARAs, computed torque, RK4 dt = {DT * 1e3:g} ms, {t_end:g} s runs ({steps} steps), "
          f"median of {repeats}")
    print(f"{'scene':<28}{'wall s':>9}{'x real time':>13}{'us/step':>9}   split per step (us): "
          f"controllers, world, contacts, robots")
    rows = {}
    for label, every in (("robots only", None), ("world every step", 1), ("world every 5th step", 5)):
        walls = []
        for _ in range(repeats):
            sim = build(t_end, every)
            t0 = time.perf_counter()
            sim.run(t_end, progress=False)
            walls.append(time.perf_counter() - t0)
        wall = statistics.median(walls)
        sim = build(t_end, every)
        sim._core.set_profiling(True)
        sim.run(t_end, progress=False)
        p = sim._core.profile()
        split = ", ".join(f"{p[k] / steps * 1e6:.2f}" for k in ("controllers", "world", "contacts", "robots"))
        if every is not None:
            events = sim.log.contacts
            assert set(events["kind"]) <= {"body-scenery"}, events  # the scene is collision-free
        rtf = t_end / wall
        rows[label] = rtf
        print(f"{label:<28}{wall:9.3f}{rtf:13.1f}{wall / steps * 1e6:9.2f}   {split}")
    ok = rows["world every 5th step"] >= TARGET_RTF
    extra = (1 / rows["world every step"] - 1 / rows["robots only"]) / steps * t_end * 1e6
    print(f"target >= {TARGET_RTF:g}x real time with the world every 5th step: "
          f"{'met' if ok else 'NOT met'} ({rows['world every 5th step']:.1f}x); the world every step adds "
          f"{extra:.2f} us per step to the robots alone")


if __name__ == "__main__":
    main()
