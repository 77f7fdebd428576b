"""Task-space control's cost per step against computed torque on the same run.

Rows (each timed as ``Simulation.run`` over the run below, best of several repeats; dt 0.2 ms, a log
row every 25 steps; real-time factor = simulated time / wall time):

- free SCARA #1 (no world) holding a pose, a 2 N step force at the TCP from the start: ``cs.Impedance``
  (the sensor read and the law every step) against ``cs.ComputedTorque`` (kp 900, kd 60) with the same
  reference and applied force;
- the hybrid press-and-slide task with its world: SCARA #1 holds a 0.2 kg bar on a table, presses it
  with 5 N along z while sliding 5 cm along -x (2.5 s, a Cartesian plan): ``cs.HybridForce`` against
  ``cs.ComputedTorque`` tracking the same joint reference in the same world (the gripping before it is
  not timed);
- the free run again with the impedance law written in Python (a ``cs.TaskController`` subclass with the
  C++ law's arithmetic): the cost of a Python law per update, for information.

"law us/update" is the engine's profile of the controller part of a step (``sim.profile()``, best of
three more runs with profiling on): for a task-space law the sensor's reading, the task state and the law.

Target: the sensor and the task-space law cost at most +50 % over computed torque (ratio <= 1.5).

    nice python benchmarks/bench_task_control.py [--quick]
"""
from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import coopsim as cs  # noqa: E402

DT, LOG_EVERY, G = 2e-4, 25, 9.81
Q0 = np.array([0.3, 0.5, 0.15, 0.2, np.pi / 2, 0.03])        # SCARA #1, clamp down, jaws 3 cm open
BAR_M, BAR_HE = 0.2, np.array([0.09, 0.01, 0.01])
KP, KD = 900.0, 60.0                                         # computed torque; HybridForce's kp, kd defaults
TARGET = 1.5


class PythonImpedance(cs.TaskController):
    """The Impedance law in Python (the same arithmetic as the C++ one)."""

    def __init__(self, K, D, M, **kw):
        super().__init__(**kw)
        self.K, self.D, self.M = float(K), float(D), float(M)

    def compute_task(self, s):
        on = np.array([d in s.commanded for d in cs.TASK_AXES])
        a = np.where(on, s.accel_ref + (s.external + self.D * s.error_rate + self.K * s.error) / self.M, 0.0)
        return self.torques(s, a, s.wrench)


def impedance():
    return cs.Impedance(300.0, 2 * 0.4 * np.sqrt(300.0), 1.0)


def free_run(controller):
    """SCARA #1 without a world holding Q0 under `controller`, a 2 N force along y at the TCP."""
    sim = cs.Simulation(dt=DT, log_every=LOG_EVERY)
    sim.add_robot(cs.robots.scara1(gravity=(0, 0, -G)), controller, cs.SetPoint(Q0))
    sim.set_applied(0, wrenches=[cs.Wrench.at_tool([0.0, 2.0, 0.0, 0.0, 0.0, 0.0])])
    return sim


def press_scene():
    """SCARA #1 has gripped the bar lying on the table (a PID closes the jaws; 0.5 s, not timed). Returns
    the simulation, the bar's Payload (tool frame) and the 2.5 s press-and-slide joint reference."""
    r = cs.robots.scara1(gravity=(0, 0, -G))
    T = r.fk(Q0)
    fixed, _ = r.clamp_faces(Q0)
    P = T.copy()
    P[:3, 3] = fixed[:3, 3] + fixed[:3, 2] * (BAR_HE[1] + 2e-4) + T[:3, 2] * 0.012  # 2 mm beyond the jaw tips
    w = cs.World(gravity=r.gravity_acceleration)
    w.add_free_box("bar", BAR_HE, BAR_M, P, friction=0.5)
    table = np.eye(4)
    table[:3, 3] = [P[0, 3], P[1, 3], P[2, 3] - BAR_HE[2] - 0.01]
    w.add_static_box("table", [0.3, 0.3, 0.01], table, friction=0.5)
    sim = cs.Simulation(dt=DT, world=w, log_every=LOG_EVERY)
    q1 = Q0.copy()
    q1[5] = 0.019
    sim.add_robot(r, cs.PID([400, 400, 2000, 20, 20, 500], 0.0, [40, 40, 100, 2, 2, 20]),
                  cs.CubicTrajectory([0.0, 0.02, 0.12], np.array([Q0, Q0, q1])))
    sim.run(0.5, progress=False)
    assert sim.holding(0) == "bar"
    q, _ = sim.state(0)
    Tq = r.fk(q)
    b = sim.body_state("bar")
    R, Rb = Tq[:3, :3], b.pose[:3, :3]
    pay = cs.Payload(BAR_M, R.T @ (b.position - Tq[:3, 3]),
                     R.T @ Rb @ np.asarray(cs.box_inertia(BAR_M, *(2 * BAR_HE))) @ Rb.T @ R)
    T1 = Tq.copy()
    T1[0, 3] -= 0.05
    t0 = sim.time
    ref = cs.plan_cartesian(r, [Tq, Tq, T1, T1], [t0, t0 + 0.5, t0 + 1.5, t0 + 2.5], q_start=q, opening=q[5],
                            intermediate=12, time_law="quintic", spline=True)
    return sim, pay, ref


def press_run(kind):
    sim, pay, ref = press_scene()
    c = cs.HybridForce(["z"], [-5.0], payload=pay) if kind == "hybrid" else cs.ComputedTorque(kp=KP, kd=KD)
    sim.set_reference(0, ref)
    sim.set_controller(0, c)
    return sim


def hold_run(kind):
    """The press scene's arm holding the gripped bar where it is, pushed with 1 N along y on the bar (the
    impedance felt by pushing the held bar, with its world), under Impedance (payload known) or computed
    torque."""
    sim, pay, _ = press_scene()
    q, _ = sim.state(0)
    c = cs.Impedance(300.0, 2 * 0.4 * np.sqrt(300.0), 1.0, payload=pay) if kind == "impedance" \
        else cs.ComputedTorque(kp=KP, kd=KD)
    sim.set_reference(0, cs.SetPoint(q))
    sim.set_controller(0, c)
    sim.set_body_wrench("bar", [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    return sim


def timed(build, duration, profile=False):
    """Wall time per step (s) of build().run(sim.time + duration), and with profile=True the engine's
    controller part per step (s) instead."""
    sim = build()
    t1 = sim.time + duration
    steps = sim.steps_until(t1)
    sim.set_profiling(profile)
    t = time.perf_counter()
    sim.run(t1, progress=False)
    w = (time.perf_counter() - t) / steps
    return sim.profile().controllers / steps if profile else w


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs, fewer repeats")
    args = ap.parse_args()
    free_t, repeats = (0.5, 2) if args.quick else (2.0, 7)
    press_t = 0.5 if args.quick else 2.5
    rows = [
        ("free SCARA #1", "computed torque", lambda: free_run(cs.ComputedTorque(kp=KP, kd=KD)), free_t),
        ("free SCARA #1", "Impedance (C++)", lambda: free_run(impedance()), free_t),
        ("press and slide, world", "computed torque", lambda: press_run("ct"), press_t),
        ("press and slide, world", "HybridForce (C++)", lambda: press_run("hybrid"), press_t),
        ("held bar pushed, world", "computed torque", lambda: hold_run("ct"), press_t),
        ("held bar pushed, world", "Impedance (C++)", lambda: hold_run("impedance"), press_t),
        ("free SCARA #1", "Impedance in Python", lambda: free_run(PythonImpedance(300.0, 2 * 0.4 * np.sqrt(300.0), 1.0)),
         free_t),
    ]
    print(f"dt {DT * 1e3:g} ms, log every {LOG_EVERY} steps, best of {repeats} (the rows' repeats interleaved)")
    best = {}
    for _ in range(repeats):  # interleaved: a load that comes and goes hits every row alike
        for run, ctl, build, duration in rows:
            s = timed(build, duration)
            best[(run, ctl)] = min(best.get((run, ctl), s), s)
    print(f"{'run':<24}{'controller':<22}{'us/step':>9}{'x real time':>13}{'/ CT':>7}{'law us/update':>15}")
    base, per = {}, {}
    for run, ctl, build, duration in rows:
        s = per[(run, ctl)] = best[(run, ctl)]
        base.setdefault(run, s)
        law = min(timed(build, duration, profile=True) for _ in range(3))
        print(f"{run:<24}{ctl:<22}{s * 1e6:>9.2f}{DT / s:>13.0f}{s / base[run]:>7.2f}{law * 1e6:>15.2f}")
    for run, ctl in (("free SCARA #1", "Impedance (C++)"), ("press and slide, world", "HybridForce (C++)"),
                     ("held bar pushed, world", "Impedance (C++)")):
        r = per[(run, ctl)] / base[run]
        print(f"{run}: {ctl} / computed torque {r:.2f} (target <= {TARGET}: {'met' if r <= TARGET else 'NOT met'})")
    extra = per[("free SCARA #1", "Impedance in Python")] - per[("free SCARA #1", "Impedance (C++)")]
    print(f"a law in Python: +{extra * 1e6:.2f} us per update over the same law in C++")


if __name__ == "__main__":
    main()
