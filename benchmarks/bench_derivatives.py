"""The dynamics' derivatives: µs per call from Python, coopsim beside Pinocchio, in one run.

Robots: both SCARAs (their exported URDF; coopsim's numeric backend, the recursive algorithm, and the
generated one, whose derivatives are emitted from the symbolic model as C++) and arms of the
example-robot-data wheel (UR5, UR10, Panda with its fingers locked, Z1; the recursive algorithm), each
loaded from the same URDF by both. Rows per robot, at the same random states:

- coopsim ``robot.forward_dynamics_derivatives(q, qd, tau)`` (three new arrays) and the same call writing
  into arrays of the caller's (``out=``), against ``pin.computeABADerivatives`` (both give dqdd/dq,
  dqdd/dqd and M^-1);
- coopsim ``robot.inverse_dynamics_derivatives(q, qd, qdd)`` against ``pin.computeRNEADerivatives``;
- ``cs.forward_dynamics_derivatives_batch`` on one thread: ns per state (N states in one call), into new
  arrays and into the caller's (``out=``, a loop that reuses its buffers: no fresh pages to fault in).

Before anything is timed each pair is compared at the timed states (Pinocchio's results with the
robot's friction added, its armature set alike): a pair that disagrees by more than 1e-9 relative gets
no ratio. Each function is warmed up, then timed in repeats interleaved with the others' (so that a
change of the machine's speed touches all alike), and each figure is the best repeat: on a shared
machine the other loads only ever slow a repeat down. Ratios (Pinocchio's time over coopsim's: > 1
means coopsim is faster) are taken within this run. The last lines set the figures beside the targets
(the generated SCARAs at most 1.5 µs per call and their batch at most 0.5 µs per state, faster than
Pinocchio on every robot): printed, never asserted. The absolute figures move with the machine and its load
(printed first); the ratios less so, and the instruction counts (callgrind) not at all: those are in
docs/planning-and-control.md, with how they are counted.

    python benchmarks/bench_derivatives.py [--quick]
"""
from __future__ import annotations

import argparse
import importlib.metadata
import os
import sys
import tempfile
import time

import numpy as np

import coopsim as cs

ARMS = {
    "ur5": ("ur_description/urdf/ur5_robot.urdf", {}),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", {}),
    "panda": ("panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "z1": ("z1_description/urdf/z1.urdf", {}),
}


def _erd(relative):
    for f in importlib.metadata.files("example-robot-data"):
        if str(f).endswith("robots/" + relative):
            return str(f.locate())
    raise FileNotFoundError(relative)


def pairs(pin):
    """(label, coopsim robot, Pinocchio model) of every robot measured."""
    out = []
    for name in ("scara1", "scara2"):
        robot = getattr(cs.robots, name)(backend="numeric")
        with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
            f.write(robot.to_urdf())
        try:
            model = pin.buildModelFromUrdf(f.name)
        finally:
            os.unlink(f.name)
        out.append((f"{name} numeric", robot, model))
        if robot.has_generated:
            out.append((f"{name} generated", robot.with_backend("generated"), model))
    try:
        importlib.metadata.files("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        print("example-robot-data not installed: the arms are skipped")
        return out
    for name, (rel, locked) in ARMS.items():
        path = _erd(rel)
        robot = cs.Robot.from_urdf(path, locked=locked)
        model = pin.buildModelFromUrdf(path)
        if locked:
            model = pin.buildReducedModel(model, [model.getJointId(j) for j in locked], pin.neutral(model))
        out.append((name, robot, model))
    for _, robot, model in out:
        model.armature[:] = robot.armature
    return out


def states(robot, count, seed=0):
    rng = np.random.default_rng(seed)
    lim = np.clip(robot.q_limits, -np.pi, np.pi)
    n = robot.dof
    return [(rng.uniform(lim[:, 0], lim[:, 1]), rng.normal(size=n), rng.normal(size=n), 5 * rng.normal(size=n))
            for _ in range(count)]


def _rel(x, y):
    return np.abs(np.asarray(x) - np.asarray(y)).max() / np.abs(np.asarray(y)).max()


def agree(pin, robot, model, data, sts):
    """The largest relative difference over the states of both derivatives, Pinocchio's with friction."""
    worst = 0.0
    for q, qd, qdd, tau in sts:
        D = np.diag(robot.friction_coefficients +
                    robot.coulomb / robot.coulomb_width * (1 - np.tanh(qd / robot.coulomb_width) ** 2))
        aq, aqd, Minv = robot.forward_dynamics_derivatives(q, qd, tau)
        pq, pqd, pMinv = pin.computeABADerivatives(model, data, q, qd, tau - robot.friction(qd))
        pMinv = np.triu(pMinv) + np.triu(pMinv, 1).T
        dq, dqd, M = robot.inverse_dynamics_derivatives(q, qd, qdd)
        rq, rqd, _ = pin.computeRNEADerivatives(model, data, q, qd, qdd)
        worst = max(worst, _rel(aq, pq), _rel(aqd, pqd - pMinv @ D), _rel(Minv, pMinv), _rel(dq, rq),
                    _rel(dqd, rqd + D))
    return worst


def interleaved(fns, calls, repeats, warmup=None):
    """Best µs per call of each function over the repeats, the functions timed in turn in each repeat,
    after `warmup` calls of each (default: a tenth of `calls`, at least one)."""
    for fn in fns:
        for _ in range(max(1, calls // 10) if warmup is None else warmup):
            fn()
    times = [[] for _ in fns]
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            for _ in range(calls):
                fn()
            times[i].append((time.perf_counter() - t0) / calls * 1e6)
    return [float(np.min(t)) for t in times]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer calls and repeats")
    args = ap.parse_args(argv)
    calls, repeats, N = (500, 3, 2000) if args.quick else (2000, 25, 20000)
    try:
        import pinocchio as pin
    except ImportError:
        print("Pinocchio is not installed ('pip install pin'): nothing to compare with")
        return 0
    print(f"coopsim {cs.__version__}, build optimised: {cs.build_info()['optimised']}; Pinocchio {pin.__version__}; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    if not cs.build_info()["optimised"]:
        print("figures from a debug build do not count")
    head = (f"{'robot':16} {'dof':>3} {'FD der µs':>9} {'out= µs':>8} {'pin ABA der':>11} {'pin/ours':>8}   "
            f"{'ID der µs':>9} {'pin RNEA der':>12} {'pin/ours':>8}   {'batch ns/state':>14} {'out=':>8}")
    print("\n" + head)
    rows = []
    for label, robot, model in pairs(pin):
        data = model.createData()
        sts = states(robot, 8)
        worst = agree(pin, robot, model, data, sts)
        q, qd, qdd, tau = sts[0]
        tau_pin = tau - robot.friction(qd)
        out = tuple(np.empty((robot.dof, robot.dof)) for _ in range(3))
        fd_ours, fd_out, fd_pin, id_ours, id_pin = interleaved([
            lambda: robot.forward_dynamics_derivatives(q, qd, tau),
            lambda: robot.forward_dynamics_derivatives(q, qd, tau, out=out),
            lambda: pin.computeABADerivatives(model, data, q, qd, tau_pin),
            lambda: robot.inverse_dynamics_derivatives(q, qd, qdd),
            lambda: pin.computeRNEADerivatives(model, data, q, qd, qdd),
        ], calls, repeats)
        big = states(robot, N, seed=1)
        Q, QD, TAU = (np.array([s[i] for s in big]) for i in (0, 1, 3))
        bout = tuple(np.empty((3, N, robot.dof, robot.dof)))
        batch, batch_out = (t * 1e3 / N for t in interleaved([
            lambda: cs.forward_dynamics_derivatives_batch(robot, Q, QD, TAU, threads=1),
            lambda: cs.forward_dynamics_derivatives_batch(robot, Q, QD, TAU, threads=1, out=bout),
        ], 1, max(3, repeats // 2), warmup=1))
        ok = worst <= 1e-9
        r_fd = f"{fd_pin / fd_ours:8.2f}" if ok else "       -"
        r_id = f"{id_pin / id_ours:8.2f}" if ok else "       -"
        print(f"{label:16} {robot.dof:3d} {fd_ours:9.2f} {fd_out:8.2f} {fd_pin:11.2f} {r_fd}   {id_ours:9.2f} "
              f"{id_pin:12.2f} {r_id}   {batch:14.0f} {batch_out:8.0f}")
        if not ok:
            print(f"  {label}: coopsim and Pinocchio differ by {worst:.1e} (relative): no ratio")
        rows.append((label, ok, fd_ours, fd_out, fd_pin, batch, batch_out))
    print("\ntargets (printed, not asserted):")
    gen = [r for r in rows if r[0].endswith("generated")]
    if gen:
        print("  generated SCARAs, FD derivatives per call from Python <= 1.5 µs: " +
              ", ".join(f"{r[0]} {r[2]:.2f} µs ({r[3]:.2f} with out=)" for r in gen))
    slower = [r[0] for r in rows if not r[1] or r[2] >= r[4]]
    print("  faster than pin.computeABADerivatives on every robot: " +
          ("yes" if not slower else "no, not on " + ", ".join(slower)) +
          f" (ratios {min(r[4] / r[2] for r in rows):.2f} to {max(r[4] / r[2] for r in rows):.2f})")
    if gen:
        print("  generated SCARAs, the batch on one thread <= 0.5 µs per state: " +
              ", ".join(f"{r[0]} {r[5] / 1e3:.2f} µs ({r[6] / 1e3:.2f} with out=)" for r in gen))
    print("  the batch on one thread, every robot (µs per state, new arrays / out=): " +
          ", ".join(f"{r[0]} {r[5] / 1e3:.2f} / {r[6] / 1e3:.2f}" for r in rows))
    print("instruction counts of these calls (callgrind, load-independent): docs/planning-and-control.md, "
          "'Linear models: the dynamics' derivatives'")
    return 0


if __name__ == "__main__":
    sys.exit(main())
