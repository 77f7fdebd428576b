"""The world's cost: both SCARAs under computed torque in the cooperative task's scene
(floor, the container of four walls, the bar), RK4 at 0.2 ms.

Rows: the robots alone (the reference), then with the world every step and
every 5th step (contacts and their torques held in between). For each: the
median wall time of a run, the real-time factor, and the time per step
split into controllers, world (Bullet: collision detection and solver),
contact mapping (penalty forces, J^T) and robots (RK4), measured with the
simulation's own profiler in a separate run. A last row has SCARA #1 holding
a box (the clamp grasp) with the world every step, and the grasp's own cost
(rule checking and the weld) within the world's. Target: >= 50x real time
with the world at least every 5th step.

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


def build_holding(duration):
    """The task's world plus a box held by SCARA #1 (closed on it from a pedestal, as in
    tests/test_grasp.py, then lifted), SCARA #2 moving as in the other rows; world every step."""
    r1, r2 = scene.scaras()
    (_, ref2) = references(duration)[1]
    q0 = np.array([0.3, 0.5, 0.15, 0.2, np.pi / 2, 0.03])
    T = r1.fk(q0)
    fixed, _ = r1.clamp_faces(q0)
    he = np.array([0.05, 0.01, 0.01])
    P = T.copy()
    P[:3, 3] = fixed[:3, 3] + fixed[:3, 2] * (he[1] + 2e-4)
    w = scene.world()
    w.add_free_box("box", he, 0.1, P, friction=0.5)
    ped = np.eye(4)
    top = P[2, 3] - he[2]
    ped[:3, 3] = [P[0, 3], P[1, 3], top / 2]
    w.add_static_box("pedestal", [0.004, 0.004, top / 2], ped)
    sim = cs.Simulation(DT, log_every=10, world=w)
    q1 = q0.copy()
    q1[5] = 0.019
    q2 = q1.copy()
    q2[2] -= 0.05
    sim.add_robot(r1, cs.PID([400, 400, 2000, 20, 20, 500], [0] * 6, [40, 40, 100, 2, 2, 20]),
                  cs.CubicTrajectory([0.0, 0.02, 0.12, 0.2, 0.5, duration], np.array([q0, q0, q1, q1, q2, q2])))
    sim.add_robot(r2, cs.ComputedTorque(400.0, 40.0), ref2)
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
        sim.set_profiling(True)
        sim.run(t_end, progress=False)
        p = sim.profile()
        split = ", ".join(f"{p[k] / steps * 1e6:.2f}" for k in ("controllers", "world", "contacts", "robots"))
        if every is not None:
            events = sim.log.contacts
            assert set(events["kind"]) <= {"body-scenery"}, events  # the scene is collision-free
        rtf = t_end / wall
        rows[label] = rtf
        print(f"{label:<28}{wall:9.3f}{rtf:13.1f}{wall / steps * 1e6:9.2f}   {split}")
    # the grasp's cost beside the world's: SCARA #1 holding a box for the whole run
    walls = []
    for _ in range(repeats):
        sim = build_holding(t_end)
        t0 = time.perf_counter()
        sim.run(t_end, progress=False)
        walls.append(time.perf_counter() - t0)
    wall = statistics.median(walls)
    sim = build_holding(t_end)
    sim.set_profiling(True)
    sim.run(t_end, progress=False)
    assert sim.holding(0) == "box", "the benchmark's grasp failed"
    p = sim.profile()
    print(f"{'one SCARA holding a box':<28}{wall:9.3f}{t_end / wall:13.1f}{wall / steps * 1e6:9.2f}   "
          + ", ".join(f"{p[k] / steps * 1e6:.2f}" for k in ("controllers", "world", "contacts", "robots"))
          + f"; of the world's, the grasp (rule and weld) {p.grasp / steps * 1e6:.2f}")
    ok = rows["world every 5th step"] >= TARGET_RTF
    extra = (1 / rows["world every step"] - 1 / rows["robots only"]) / steps * t_end * 1e6
    print(f"target >= {TARGET_RTF:g}x real time with the world every 5th step: "
          f"{'met' if ok else 'NOT met'} ({rows['world every 5th step']:.1f}x); the world every step adds "
          f"{extra:.2f} us per step to the robots alone")


if __name__ == "__main__":
    main()
