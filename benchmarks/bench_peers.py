"""coopsim against the simulators people would pick instead, in one run.

Same robot (SCARA #1), same states, same job. Peers are loaded from
coopsim's URDF export (PyBullet, MuJoCo, Pinocchio) or built from its DH
table (the Robotics Toolbox); a peer that is not installed is skipped with a
note (``pip install .[peers]`` installs them). Before anything is timed,
every peer's numbers are compared with coopsim's on random states: a peer
that disagrees by more than 1e-9 (relative) gets no ratio, only the reason.

Part 1, dynamics from Python, ns per call: forward dynamics, inverse
dynamics, the mass matrix, one RK4 step (0.2 ms) and batch forward dynamics
(ns per state: coopsim's batch call and MuJoCo's ``mujoco.batch`` on one
thread, Python loops for the others). Friction: coopsim's viscous K is
MuJoCo's joint damping (read from the URDF); Pinocchio, PyBullet and the
Toolbox get K qd in their torques. RK4: MuJoCo's ``mj_step`` with its RK4
integrator; Pinocchio, PyBullet and the Toolbox have none, so theirs is the
classic RK4 written in Python over their forward dynamics (four calls).

Part 2, closed loop: SCARA #1 tracking a cubic under the same PID
(derivative on the measured position, gravity compensation, saturation at
the actuator limits), 5 s at 0.2 ms: coopsim's ``Simulation.run``; MuJoCo
RK4 with the PID in Python driving motor actuators (gravity compensation by
MuJoCo's own ``gravcomp``); MuJoCo RK4 with native actuators (the PID's
proportional and derivative parts with velocity feed-forward as an affine
actuator, no integral: MuJoCo actuators cannot integrate the error) stepped
by ``mujoco.rollout``; PyBullet (semi-implicit Euler, its only integrator)
with the PID in Python. The tracking error is printed beside the speed: it
shows that each did the same job.

Part 3, the cooperative scene: one cycle of the task (``handover.run``,
computed torque, controllers and world at every 0.2 ms RK4 step) against the
same scene in MuJoCo (an MjSpec built from our robots' URDF export and
``coopsim.tasks.scene``: both SCARAs, floor, container walls, the bar free,
a weld per robot switched on and off at coopsim's grasp and release times),
RK4 at 0.2 ms with contacts every step, twice. First under the same
controller: the task's computed torque per robot, tau = sat(M(q) (qdd_ref +
kd (qd_ref - qd) + kp (q_ref - q)) + bias(q, qd) + K qd) with the task's
gains (kp = omega^2, kd = 2 omega, ``handover.OMEGA``), MuJoCo's own M
(d.qM) and bias (d.qfrc_bias; K qd is its joint damping, -d.qfrc_passive),
driving motor actuators, held over each step and clipped at the actuator
limits, on the references of coopsim's run (its log's q_ref, qd_ref and
qdd_ref at every step). MuJoCo has no computed-torque
actuator, so this controller is Python: before each mj_step, MuJoCo's
kinematics, CRB (M), RNE (bias) and passive forces for the present state,
then the torque (in mjcb_control instead, at the first of the four RK4
stages, it needs no recomputation but enters Python four times a step, and
measured about 15 % slower). Before timing, its torque is compared with
coopsim's logged torque in coopsim's states: above 1e-9 (relative) it gets
no ratio, nor does a MuJoCo run whose bar does not end as coopsim's (through
the tube or not). Then replaying coopsim's references under native PD +
feed-forward actuators: MuJoCo at its fastest, a different controller.
Printed: real-time factors, joint tracking errors, where each puts the bar
and the peak weld forces. MuJoCo's friction is the larger of two geoms' and
coopsim's (Bullet's) the product: the MJCF gives the bar 0 and what it
touches the product.

Timings are interleaved (each repeat times every peer in turn) and each
figure is the median over repeats; ratios are taken within this run. The
closed loop and the scene give each run's process CPU time beside its wall
time: on a shared machine other work stretches the one much more than the
other. Set OPENBLAS_NUM_THREADS=1 on a shared machine.

    python benchmarks/bench_peers.py [--quick] [--part dynamics|loop|scene|all] [--repeats N]
"""
from __future__ import annotations

import argparse
import functools
import os
import platform
import statistics
import sys
import tempfile
import time

import numpy as np

import coopsim as cs
from bench_simulation import gains, trajectory  # the closed loop's cubic and PID (this folder is on sys.path)

DT = 2e-4
TOL = 1e-9          # relative agreement required before a ratio is printed
T_LOOP = 5.0        # s simulated in the closed loop
OPS = ["forward dynamics", "inverse dynamics", "mass matrix", "RK4 step", "batch forward dynamics"]
#: per peer, the callables timed in place of the checked ones where the check needs extra arithmetic or copies
TIMED: dict = {}
TARGETS = {"forward dynamics": 0.5, "closed loop": 10.0}  # coopsim <= 0.5x aba and mj_forward; >= 10x MuJoCo RK4


def rel(x, y):
    x, y = np.asarray(x, float), np.asarray(y, float)
    return float(np.abs(x - y).max() / max(1.0, np.abs(y).max()))


def rk4(fd, q, qd, tau, dt=DT):
    """The classic RK4 step on (q, qd) under tau held constant, as coopsim's."""
    k1q, k1v = qd, fd(q, qd, tau)
    k2q, k2v = qd + dt / 2 * k1v, fd(q + dt / 2 * k1q, qd + dt / 2 * k1v, tau)
    k3q, k3v = qd + dt / 2 * k2v, fd(q + dt / 2 * k2q, qd + dt / 2 * k2v, tau)
    k4q, k4v = qd + dt * k3v, fd(q + dt * k3q, qd + dt * k3v, tau)
    return np.concatenate([q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q), qd + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)])


def loop_batch(fd):
    def batch(Q, QD, TAU):
        return np.array([fd(q, qd, tau) for q, qd, tau in zip(Q, QD, TAU)])
    return batch


def urdf_file(robot):
    f = tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False)
    f.write(robot.to_urdf())
    f.close()
    return f.name


# ---------------------------------------------------------------- peers
# Each returns (label, version, {op: fn}) or raises ImportError / names its problem.

def peer_coopsim(robot, label="coopsim"):
    """coopsim's calls; the single-state ones are timed as the bound methods themselves (see TIMED)."""
    TIMED[label] = {"forward dynamics": robot.forward_dynamics, "inverse dynamics": robot.inverse_dynamics,
                    "mass matrix": robot.mass_matrix,
                    "RK4 step": functools.partial(cs.rk4_step, robot, dt=DT, end_stops=False)}
    return {
        "forward dynamics": lambda q, qd, tau: robot.forward_dynamics(q, qd, tau),
        "inverse dynamics": lambda q, qd, qdd: robot.inverse_dynamics(q, qd, qdd),
        "mass matrix": lambda q: robot.mass_matrix(q),
        "RK4 step": lambda q, qd, tau: np.concatenate(cs.rk4_step(robot, q, qd, tau, DT, end_stops=False)),
        "batch forward dynamics": lambda Q, QD, TAU: cs.forward_dynamics_batch(robot, Q, QD, TAU, threads=1),
    }


def mujoco_model(text, *, contacts=False):
    import mujoco
    model = mujoco.MjSpec.from_string(text).compile()
    model.opt.timestep = DT
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    if not contacts:  # the dynamics alone: no collision detection, no limits (the states are inside them)
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    return model


def peer_mujoco(robot):
    import mujoco
    import mujoco.batch
    m = mujoco_model(robot.to_urdf())
    d = mujoco.MjData(m)
    n = m.nv
    M = np.zeros((n, n))

    def fd(q, qd, tau):
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, qd, tau
        mujoco.mj_forward(m, d)
        return d.qacc.copy()

    def inv(q, qd, qdd):
        d.qpos[:], d.qvel[:], d.qacc[:] = q, qd, qdd
        mujoco.mj_inverse(m, d)
        return d.qfrc_inverse.copy()

    def mass(q):
        d.qpos[:] = q
        mujoco.mj_fwdPosition(m, d)
        mujoco.mj_fullM(m, d, M)
        return M.copy()

    def step(q, qd, tau):
        d.time = 0.0
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, qd, tau
        mujoco.mj_step(m, d)
        return np.concatenate([d.qpos, d.qvel])

    batches = {}

    def batch(Q, QD, TAU):
        if len(Q) not in batches:
            b = mujoco.batch.Batch(m, nsim=len(Q), nthread=1)
            batches[len(Q)] = b, b.bind("qacc")  # bound before the calls: refreshed by each
        b, qacc = batches[len(Q)]
        b.qpos, b.qvel, b.qfrc_applied = Q, QD, TAU
        b.forward()
        return qacc.copy()

    def fd_timed(q, qd, tau):  # what a user writes: the state in, mj_forward, qacc read in place
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, qd, tau
        mujoco.mj_forward(m, d)
        return d.qacc

    def inv_timed(q, qd, qdd):
        d.qpos[:], d.qvel[:], d.qacc[:] = q, qd, qdd
        mujoco.mj_inverse(m, d)
        return d.qfrc_inverse

    def step_timed(q, qd, tau):
        d.time = 0.0
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, qd, tau
        mujoco.mj_step(m, d)
        return d.qpos, d.qvel

    TIMED["MuJoCo"] = {"forward dynamics": fd_timed, "inverse dynamics": inv_timed, "RK4 step": step_timed}
    return mujoco.__version__, {"forward dynamics": fd, "inverse dynamics": inv, "mass matrix": mass,
                                "RK4 step": step, "batch forward dynamics": batch}


def peer_pinocchio(robot):
    import pinocchio as pin
    model = pin.buildModelFromXML(robot.to_urdf())
    data = model.createData()
    K = robot.friction_coefficients

    def fd(q, qd, tau):
        return pin.aba(model, data, q, qd, tau - K * qd)

    # timed without the friction term's numpy arithmetic: ABA's own cost from Python
    TIMED["Pinocchio"] = {"forward dynamics": functools.partial(pin.aba, model, data),
                          "inverse dynamics": functools.partial(pin.rnea, model, data),
                          "mass matrix": functools.partial(pin.crba, model, data)}

    return pin.__version__, {
        "forward dynamics": fd,
        "inverse dynamics": lambda q, qd, qdd: pin.rnea(model, data, q, qd, qdd) + K * qd,
        "mass matrix": lambda q: pin.crba(model, data, q),  # upper triangle: compared as such
        "RK4 step": lambda q, qd, tau: rk4(fd, q, qd, tau),
        "batch forward dynamics": loop_batch(fd),
    }


def pybullet_body(robot):
    """A PyBullet client (DIRECT) with our URDF export of `robot` loaded on a fixed base, inertia from the
    file, our gravity: (client id, body id)."""
    import pybullet as pb
    path = urdf_file(robot)
    c = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(*robot.gravity_acceleration, physicsClientId=c)
        body = pb.loadURDF(path, useFixedBase=True, flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=c)
    finally:
        os.unlink(path)
    return c, body


def peer_pybullet(robot):
    import pybullet as pb
    c, body = pybullet_body(robot)
    K = robot.friction_coefficients
    zero = [0.0] * robot.dof

    def fd(q, qd, tau):  # PyBullet has no forward dynamics call: M, C qd + G, and a solve
        q, qd = q.tolist(), qd.tolist()
        M = np.array(pb.calculateMassMatrix(body, q, physicsClientId=c))
        h = np.array(pb.calculateInverseDynamics(body, q, qd, zero, physicsClientId=c))
        return np.linalg.solve(M, tau - K * np.asarray(qd) - h)

    def inv(q, qd, qdd):
        return np.array(pb.calculateInverseDynamics(body, q.tolist(), qd.tolist(), qdd.tolist(),
                                                    physicsClientId=c)) + K * qd

    version = f"{pb.getAPIVersion(physicsClientId=c)} (API)"
    try:
        import importlib.metadata
        version = importlib.metadata.version("pybullet")
    except Exception:  # noqa: BLE001 - a version string only
        pass
    return version, {
        "forward dynamics": fd, "inverse dynamics": inv,
        "mass matrix": lambda q: np.array(pb.calculateMassMatrix(body, q.tolist(), physicsClientId=c)),
        "RK4 step": lambda q, qd, tau: rk4(fd, q, qd, tau),
        "batch forward dynamics": loop_batch(fd),
    }


def rtb_robot(robot):
    """The Robotics Toolbox's DHRobot from coopsim's DH table, CoM vectors and inertias (its convention)."""
    import roboticstoolbox as rtb
    from spatialmath import SE3
    links = []
    for i, (theta, d, a, alpha) in enumerate(robot.dh):
        kw = dict(a=a, alpha=alpha, m=robot.masses[i], r=robot.com_positions[i], I=robot.link_inertias[i],
                  B=robot.friction_coefficients[i], G=1.0, Jm=0.0, Tc=[0.0, 0.0], qlim=robot.q_limits[i])
        if robot.joint_types[i] == "R":
            links.append(rtb.RevoluteDH(d=d, offset=theta, **kw))
        else:
            links.append(rtb.PrismaticDH(theta=theta, offset=d, **kw))
    base = SE3(*robot.base_position) * SE3.Rz(robot.base_yaw)
    return rtb.DHRobot(links, name=robot.name, base=base, gravity=np.asarray(robot.gravity_acceleration))


def peer_rtb(robot):
    import roboticstoolbox as rtb
    r = rtb_robot(robot)

    def fd(q, qd, tau):
        return np.asarray(r.accel(q, qd, tau)).ravel()

    return rtb.__version__, {
        "forward dynamics": fd,
        "inverse dynamics": lambda q, qd, qdd: np.asarray(r.rne(q, qd, qdd)).ravel(),
        "mass matrix": lambda q: np.asarray(r.inertia(q)),
        "RK4 step": lambda q, qd, tau: rk4(fd, q, qd, tau),
        "batch forward dynamics": loop_batch(fd),
    }


PEERS = {  # label: (module to import, the extra's package, builder)
    "MuJoCo": ("mujoco", "mujoco", peer_mujoco),
    "Pinocchio": ("pinocchio", "pin", peer_pinocchio),
    "PyBullet": ("pybullet", "pybullet", peer_pybullet),
    "Robotics Toolbox": ("roboticstoolbox", "roboticstoolbox-python", peer_rtb),
}
CALL_NAMES = {  # what each peer's row calls
    "MuJoCo": {"forward dynamics": "mj_forward", "inverse dynamics": "mj_inverse",
               "mass matrix": "mj_fwdPosition + mj_fullM", "RK4 step": "mj_step (RK4)",
               "batch forward dynamics": "mujoco.batch.Batch.forward"},
    "Pinocchio": {"forward dynamics": "aba", "inverse dynamics": "rnea", "mass matrix": "crba",
                  "RK4 step": "RK4 in Python, 4 aba", "batch forward dynamics": "loop of aba"},
    "PyBullet": {"forward dynamics": "M + ID + solve", "inverse dynamics": "calculateInverseDynamics",
                 "mass matrix": "calculateMassMatrix", "RK4 step": "RK4 in Python, 4 FD",
                 "batch forward dynamics": "loop of M + ID + solve"},
    "Robotics Toolbox": {"forward dynamics": "accel", "inverse dynamics": "rne", "mass matrix": "inertia",
                         "RK4 step": "RK4 in Python, 4 accel", "batch forward dynamics": "loop of accel"},
}


def load_peers(robot, only=None):
    """({label: (version, ops)}, [notes]) for the peers that import; a note for each that does not."""
    peers, notes = {}, []
    for label, (module, package, build) in PEERS.items():
        if only is not None and label not in only:
            continue
        try:
            __import__(module)
        except ImportError as e:
            notes.append(f"{label} skipped: not installed ({e}); pip install {package}, or .[peers]")
            continue
        try:
            peers[label] = build(robot)
        except Exception as e:  # noqa: BLE001 - a peer that cannot load the robot is reported, not fatal
            notes.append(f"{label} skipped: could not load the robot: {type(e).__name__}: {e}")
    return peers, notes


def states(robot, count, seed=0):
    rng = np.random.default_rng(seed)
    lim = robot.q_limits
    out = []
    for _ in range(count):
        q = rng.uniform(lim[:, 0], lim[:, 1])
        out.append((q, rng.normal(size=robot.dof) * 2, rng.normal(size=robot.dof) * 5, rng.normal(size=robot.dof)))
    return out


def inputs(op, state):
    q, qd, tau, qdd = state
    return {"forward dynamics": (q, qd, tau), "inverse dynamics": (q, qd, qdd), "mass matrix": (q,),
            "RK4 step": (q, qd, tau)}[op]


def agreement(robot, ours, peers, count=5, batch=8):
    """{label: {op: relative difference}}: each peer against coopsim on `count` random states (and a batch)."""
    ss = states(robot, count, seed=1)
    Q, QD, TAU, _ = (np.array(x) for x in zip(*states(robot, batch, seed=2)))
    out = {}
    for label, (_, ops) in peers.items():
        out[label] = {}
        for op in OPS:
            try:
                if op == "batch forward dynamics":
                    err = rel(ops[op](Q, QD, TAU), ours[op](Q, QD, TAU))
                else:
                    err = 0.0
                    for s in ss:
                        a, b = ops[op](*inputs(op, s)), ours[op](*inputs(op, s))
                        if op == "mass matrix" and label == "Pinocchio":
                            a, b = np.triu(a), np.triu(b)
                        err = max(err, rel(a, b))
            except Exception as e:  # noqa: BLE001 - a failing call is a disagreement, reported
                err = f"{type(e).__name__}: {e}"
            out[label][op] = err
    return out


def agrees(err):
    return isinstance(err, float) and err <= TOL


def per_call(fn, args, target_s=0.01):
    """How many calls of fn(*args) make about target_s seconds."""
    t0 = time.perf_counter()
    fn(*args)
    one = max(time.perf_counter() - t0, 1e-7)
    return max(1, int(target_s / one))


def interleaved(entries, repeats, target_s):
    """entries: [(key, fn, args, units per call)] -> {key: median ns per unit}, every entry timed in turn per repeat."""
    plan = []
    for key, fn, args, units in entries:
        fn(*args)
        plan.append((key, fn, args, units, per_call(fn, args, target_s)))
    times = {key: [] for key, *_ in plan}
    for r in range(repeats):
        order = plan[r % len(plan):] + plan[:r % len(plan)]  # rotate who goes first
        for key, fn, args, units, calls in order:
            t0 = time.perf_counter()
            for _ in range(calls):
                fn(*args)
            times[key].append((time.perf_counter() - t0) / (calls * units) * 1e9)
    return {k: statistics.median(v) for k, v in times.items()}


def dynamics_part(robot, peers, repeats, batch_n, loop_n, target_s):
    ours = peer_coopsim(robot)
    numeric = peer_coopsim(robot.with_backend("numeric"), "coopsim numeric")
    print(f"\n## Dynamics from Python: {robot.name} ({robot.dof} joints), coopsim backend '{robot.backend}'; "
          f"batches on 1 thread (Python loops: first {loop_n} states)")
    err = agreement(robot, ours, {"coopsim numeric": ("", numeric), **peers})
    print(f"agreement with coopsim before timing (max relative difference; <= {TOL:g} required for a ratio):")
    for label, row in err.items():
        cells = ", ".join(f"{op}: {v:.1e}" if isinstance(v, float) else f"{op}: {v}" for op, v in row.items())
        print(f"  {label:16} {cells}")
    s = states(robot, 1, seed=3)[0]
    Q, QD, TAU, _ = (np.array(x) for x in zip(*states(robot, batch_n, seed=4)))
    Ql, QDl, TAUl = Q[:loop_n], QD[:loop_n], TAU[:loop_n]
    results = {}
    everyone = {"coopsim": ours, "coopsim numeric": numeric, **{k: v[1] for k, v in peers.items()}}
    for op in OPS:
        entries = []
        for label, ops in everyone.items():
            if label in err and not agrees(err[label][op]):
                continue
            if op == "batch forward dynamics":
                native = label in ("coopsim", "coopsim numeric", "MuJoCo")
                args = (Q, QD, TAU) if native else (Ql, QDl, TAUl)
                entries.append((label, ops[op], args, len(args[0])))
            else:
                entries.append((label, TIMED.get(label, {}).get(op, ops[op]), inputs(op, s), 1))
        results[op] = interleaved(entries, repeats, target_s)
    print(f"\n{'what':24} {'peer':18} {'call':34} {'ns':>11} {'x coopsim':>10}")
    for op in OPS:
        base = results[op]["coopsim"]
        for label in everyone:
            call = {"coopsim": "Robot method / cs function", "coopsim numeric": "same, numeric backend"}.get(
                label) or CALL_NAMES[label][op]
            if op == "batch forward dynamics" and label.startswith("coopsim"):
                call = f"forward_dynamics_batch, N={batch_n}"
            if label not in results[op]:
                e = err[label][op]
                why = f"{e:.1e}" if isinstance(e, float) else e
                print(f"{op:24} {label:18} {call:34} no ratio: disagrees ({why})")
                continue
            ns = results[op][label]
            print(f"{op:24} {label:18} {call:34} {ns:11.0f} {ns / base:10.2f}")
    fd = results["forward dynamics"]
    for label in ("Pinocchio", "MuJoCo"):
        if label in fd:
            ratio = fd["coopsim"] / fd[label]
            met = ratio <= TARGETS["forward dynamics"]
            print(f"# target: coopsim forward dynamics <= {TARGETS['forward dynamics']}x "
                  f"{CALL_NAMES[label]['forward dynamics']}: {ratio:.2f}x -> {'met' if met else 'NOT met'}")
            if not met:
                print("#   why: from Python a single call is mostly the call itself (argument checks, conversion "
                      "to and from numpy; see bench_dynamics.py's C++ rows for the dynamics alone), and single "
                      "calls on a loaded machine vary most: more --repeats, or a quieter machine")
    return results


# ---------------------------------------------------------------- closed loop



class PythonPID:
    """coopsim's PID (derivative on the measured position by backward difference, unfiltered; anti-windup;
    saturation), in Python, for the peers; gravity comes from the caller (the peer's own)."""

    def __init__(self, kp, ki, kd, tau_max, h):
        self.kp, self.ki, self.kd, self.tau_max, self.h = kp, ki, kd, tau_max, h
        self.I = np.zeros_like(kp)
        self.q_prev = None
        self.imax = np.where(ki > 0, tau_max / np.where(ki > 0, ki, 1.0), np.inf)

    def __call__(self, q, qd, q_ref, qd_ref, g):
        v = qd if self.q_prev is None else (q - self.q_prev) / self.h
        self.q_prev = q.copy()
        e = q_ref - q
        u0 = self.kp * e + self.kd * (qd_ref - v) + g
        I = self.I + e * self.h
        u = u0 + self.ki * I
        hold = ((u > self.tau_max) & (e > 0)) | ((u < -self.tau_max) & (e < 0))
        I = np.clip(np.where(hold, self.I, I), -self.imax, self.imax)
        self.I = I
        return np.clip(u0 + self.ki * I, -self.tau_max, self.tau_max)


def tracking(Q, Qref, joint_types):
    """Max |q - q_ref| over the run: revolute joints (mrad), prismatic joints (mm)."""
    e = np.abs(np.asarray(Q) - np.asarray(Qref)).max(axis=0) * 1e3
    rev = np.array([t == "R" for t in joint_types])
    return f"{e[rev].max():.3f} mrad / {e[~rev].max():.3f} mm"


def clock():
    """(wall, CPU) seconds now: perf_counter and this process's CPU time (all its threads). The difference of
    two is what a run took; on a shared machine other work stretches the wall time, much less the CPU time."""
    return np.array([time.perf_counter(), time.process_time()])


def loop_coopsim(robot, traj, kp, ki, kd, steps):
    sim = cs.Simulation(DT)
    sim.add_robot(robot, cs.PID(kp, ki, kd), traj)
    t0 = clock()
    log = sim.run(steps * DT, progress=False)
    took = clock() - t0
    return took, log[0].q, log[0].q_ref


def mujoco_spec_with(robot, kind, kp=None, kd=None):
    """The URDF in MjSpec with gravity compensation (gravcomp) and one actuator per joint: 'motor' (ctrl = torque)
    or 'pd' (affine: kp ctrl - kp q - kd qd, with ctrl = q_ref + kd/kp qd_ref), limited to the actuator limits."""
    import mujoco
    spec = mujoco.MjSpec.from_string(robot.to_urdf())
    for b in spec.bodies:
        b.gravcomp = 1.0
    for i, j in enumerate([j for j in spec.joints]):
        a = spec.add_actuator()
        a.name, a.target, a.trntype = f"act_{j.name}", j.name, mujoco.mjtTrn.mjTRN_JOINT
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.forcerange = [-robot.tau_limits[i], robot.tau_limits[i]]
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a.gainprm[0] = 1.0 if kind == "motor" else kp[i]
        if kind == "pd":
            a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            a.biasprm[0], a.biasprm[1], a.biasprm[2] = 0.0, -kp[i], -kd[i]
    m = spec.compile()
    m.opt.timestep = DT
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT  # as coopsim's Simulation without a world
    return m


def loop_mujoco_python(robot, traj, kp, ki, kd, steps):
    import mujoco
    m = mujoco_spec_with(robot, "motor")
    d = mujoco.MjData(m)
    t = np.arange(steps + 1) * DT
    q_ref, qd_ref, _ = traj.evaluate(t)
    d.qpos[:], d.qvel[:] = q_ref[0], qd_ref[0]
    pid = PythonPID(kp, ki, kd, robot.tau_limits, DT)
    zero = np.zeros(robot.dof)
    Q = np.empty((steps + 1, robot.dof))
    t0 = clock()
    for k in range(steps):
        q, qd = d.qpos.copy(), d.qvel.copy()
        Q[k] = q
        d.ctrl[:] = pid(q, qd, q_ref[k], qd_ref[k], zero)  # gravity: MuJoCo's gravcomp
        mujoco.mj_step(m, d)
    Q[steps] = d.qpos
    return clock() - t0, Q, q_ref


def loop_mujoco_rollout(robot, traj, kp, ki, kd, steps):
    import mujoco
    from mujoco import rollout
    m = mujoco_spec_with(robot, "pd", kp, kd)
    d = mujoco.MjData(m)
    t = np.arange(steps + 1) * DT
    q_ref, qd_ref, _ = traj.evaluate(t)
    d.qpos[:], d.qvel[:] = q_ref[0], qd_ref[0]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x0 = np.zeros(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, x0, spec)
    ctrl = (q_ref[:steps] + kd / kp * qd_ref[:steps])[None]
    t0 = clock()
    state, _ = rollout.rollout(m, d, x0[None], ctrl)
    took = clock() - t0
    nq = m.nq
    Q = np.vstack([q_ref[:1], state[0, :, 1:1 + nq]])  # state rows after each step; column 0 is time
    return took, Q, q_ref


def loop_pybullet(robot, traj, kp, ki, kd, steps):
    import pybullet as pb
    c, body = pybullet_body(robot)
    try:
        pb.setPhysicsEngineParameter(fixedTimeStep=DT, numSubSteps=0, physicsClientId=c)
        joints = [j for j in range(pb.getNumJoints(body, physicsClientId=c))
                  if pb.getJointInfo(body, j, physicsClientId=c)[2] != pb.JOINT_FIXED]
        t = np.arange(steps + 1) * DT
        q_ref, qd_ref, _ = traj.evaluate(t)
        for k, j in enumerate(joints):
            pb.resetJointState(body, j, q_ref[0, k], qd_ref[0, k], physicsClientId=c)
        for j in range(-1, pb.getNumJoints(body, physicsClientId=c)):
            pb.changeDynamics(body, j, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        pb.setJointMotorControlArray(body, joints, pb.VELOCITY_CONTROL, forces=[0.0] * len(joints),
                                     physicsClientId=c)  # free the joints of the default motors
        pid = PythonPID(kp, ki, kd, robot.tau_limits, DT)
        zero = [0.0] * robot.dof
        Q = np.empty((steps + 1, robot.dof))
        t0 = clock()
        for k in range(steps):
            js = pb.getJointStates(body, joints, physicsClientId=c)
            q, qd = np.array([s[0] for s in js]), np.array([s[1] for s in js])
            Q[k] = q
            g = np.array(pb.calculateInverseDynamics(body, q.tolist(), zero, zero, physicsClientId=c))
            tau = pid(q, qd, q_ref[k], qd_ref[k], g)
            pb.setJointMotorControlArray(body, joints, pb.TORQUE_CONTROL, forces=tau.tolist(), physicsClientId=c)
            pb.stepSimulation(physicsClientId=c)
        Q[steps] = [s[0] for s in pb.getJointStates(body, joints, physicsClientId=c)]
        return clock() - t0, Q, q_ref
    finally:
        pb.disconnect(c)


def loop_part(robot, peers, repeats, t_end):
    steps = round(t_end / DT)
    traj = trajectory(robot, T_LOOP)  # --quick runs its first second
    kp, ki, kd = gains(robot, traj)
    runs = [("coopsim", "Simulation.run, PID in C++, RK4", loop_coopsim),
            ("coopsim", "the same, ki = 0 (the native actuators' PD)",
             lambda r, tr, kp, ki, kd, n: loop_coopsim(r, tr, kp, 0 * ki, kd, n))]
    if "MuJoCo" in peers:
        runs += [("MuJoCo", "mj_step RK4, PID in Python, motors", loop_mujoco_python),
                 ("MuJoCo", "rollout RK4, native PD+ff actuators", loop_mujoco_rollout)]
    if "PyBullet" in peers:
        runs += [("PyBullet", "stepSimulation (semi-impl. Euler), PID in Python", loop_pybullet)]
    took = {i: [] for i in range(len(runs))}
    errors = {}
    for label, how, fn in runs:  # untimed, once each: first-call costs (loading, first touch) out of the figures
        fn(robot, traj, kp, ki, kd, min(steps, 500))
    for r in range(repeats):
        for i, (label, how, fn) in enumerate(runs):
            t, Q, Qref = fn(robot, traj, kp, ki, kd, steps)
            took[i].append(t)
            errors[i] = tracking(Q, Qref, robot.joint_types)
    print(f"\n## Closed loop: {robot.name} tracking a cubic under PID (gravity compensation), {t_end:g} s at "
          f"{DT * 1e3:g} ms ({steps} steps), median of {repeats}; CPU: the process's CPU time")
    print(f"{'peer':10} {'how':50} {'ms':>8} {'CPU ms':>8} {'real-time x':>12} {'x coopsim':>10} {'CPU':>6}"
          f"  max tracking error")
    med = {i: np.median(v, axis=0) for i, v in took.items()}  # (wall, CPU)
    rtf, cpu = {}, {}
    for i, (label, how, _) in enumerate(runs):
        w, c = med[i]
        rtf[(label, how)], cpu[(label, how)] = t_end / w, c
        print(f"{label:10} {how:50} {w * 1e3:8.1f} {c * 1e3:8.1f} {t_end / w:12.1f} {w / med[0][0]:10.1f} "
              f"{c / med[0][1]:6.1f}  {errors[i]}")
    for (label, how), x in rtf.items():
        if label == "MuJoCo":
            ratio = rtf[runs[0][:2]] / x
            met = ratio >= TARGETS["closed loop"]
            print(f"# target: coopsim >= {TARGETS['closed loop']:g}x the real-time factor of MuJoCo ({how}): "
                  f"{ratio:.1f}x -> {'met' if met else 'NOT met'} (in CPU time {cpu[(label, how)] / med[0][1]:.1f}x)")
            if not met and "rollout" in how:
                us = t_end / x / steps * 1e6
                print(f"#   why: with native actuators and rollout MuJoCo's loop has no Python in it either; what is "
                      f"left is its own cost per step, {us:.1f} us (RK4: four mj_forward with actuation and "
                      f"gravcomp) against coopsim's {t_end / rtf[runs[0][:2]] / steps * 1e6:.1f} us (closed-form "
                      f"dynamics, PID and log)")
    return rtf


# ---------------------------------------------------------------- the cooperative scene

def mujoco_quat(R):
    import mujoco
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, float).ravel())
    return q


def mujoco_scene(robots, gains_kp=None, gains_kd=None):
    """The task's scene as an MjSpec, from our robots and world: both SCARAs from their URDF export
    (prefixes r0_, r1_), the floor, the container's four walls, the bar (a free box), and a weld between
    each robot's last link and the bar, inactive until the grasp. Actuators, one per joint: with gains,
    an affine PD + velocity feed-forward actuator limited to the actuator limits, and gravity compensation
    (gravcomp); without, a motor (force = ctrl, no limits: the controller saturates, as coopsim's) and no
    gravity compensation (a computed-torque controller's bias term carries gravity). Collision groups:
    robots touch the scenery and the bar, not each other (the task fails on any robot-robot contact anyway)."""
    import mujoco
    from coopsim.tasks import scene
    pd = gains_kp is not None
    spec = mujoco.MjSpec()
    spec.option.timestep = DT
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    wb = spec.worldbody
    box = mujoco.mjtGeom.mjGEOM_BOX
    # coopsim's (Bullet's) contact friction is the product of the two bodies' coefficients, MuJoCo's the larger:
    # the bar gets 0 and everything it touches the product with the bar's (only the bar touches anything)
    mu = scene.BAR_FRICTION
    wb.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[3, 3, 0.1],
                friction=[scene.FLOOR_FRICTION * mu, 0.005, 0.0001], contype=2, conaffinity=1)
    for name, he, T in scene.container_walls():
        wb.add_geom(name=name, type=box, size=he, pos=T[:3, 3], quat=mujoco_quat(T[:3, :3]),
                    friction=[scene.CONTAINER["friction"] * mu, 0.005, 0.0001], contype=2, conaffinity=1)
    T = scene.bar_pose()
    bar = wb.add_body(name="bar", pos=T[:3, 3], quat=mujoco_quat(T[:3, :3]))
    bar.add_freejoint()
    bar.add_geom(name="bar", type=box, size=scene.BAR_HALF_EXTENTS, mass=scene.BAR_MASS,
                 friction=[0.0, 0.0, 0.0], contype=3, conaffinity=3)
    for i, r in enumerate(robots):
        child = mujoco.MjSpec.from_string(r.to_urdf())
        for g in child.geoms:
            g.contype, g.conaffinity = 1, 2
            g.friction = [1.0 * mu, 0.005, 0.0001]  # links' default 1
        for b in child.bodies:
            b.gravcomp = 1.0 if pd else 0.0
        spec.attach(child, prefix=f"r{i}_", frame=wb.add_frame())
        for k in range(r.dof):
            a = spec.add_actuator()
            a.name, a.target, a.trntype = f"r{i}_act{k + 1}", f"r{i}_joint{k + 1}", mujoco.mjtTrn.mjTRN_JOINT
            a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            if pd:
                a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
                a.forcerange = [-r.tau_limits[k], r.tau_limits[k]]
                a.gainprm[0] = gains_kp[i][k]
                a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
                a.biasprm[0], a.biasprm[1], a.biasprm[2] = 0.0, -gains_kp[i][k], -gains_kd[i][k]
            else:
                a.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
                a.gainprm[0] = 1.0
                a.biastype = mujoco.mjtBias.mjBIAS_NONE
        eq = spec.add_equality()
        eq.name, eq.type, eq.objtype = f"weld{i}", mujoco.mjtEq.mjEQ_WELD, mujoco.mjtObj.mjOBJ_BODY
        eq.name1, eq.name2, eq.active = f"r{i}_link{r.dof}", "bar", False
    return spec.compile()


def weld_now(m, d, e):
    """Weld e holds its two bodies where they are now: relpose of body2 in body1."""
    import mujoco
    b1, b2 = m.eq_obj1id[e], m.eq_obj2id[e]
    R1 = d.xmat[b1].reshape(3, 3)
    m.eq_data[e, 0:3] = 0.0
    m.eq_data[e, 3:6] = R1.T @ (d.xpos[b2] - d.xpos[b1])
    q1inv = np.zeros(4)
    mujoco.mju_negQuat(q1inv, d.xquat[b1])
    mujoco.mju_mulQuat(m.eq_data[e, 6:10], q1inv, d.xquat[b2])
    d.eq_active[e] = 1


def through(p):
    """Whether a bar centre p has passed the container's lower end (along its axis)."""
    from coopsim.tasks import scene
    axis = scene.container_axes()[:, 0]
    return bool((np.asarray(p) - scene.CONTAINER["mouth"]) @ axis > scene.CONTAINER["length"])


class MujocoComputedTorque:
    """coopsim's ComputedTorque (cpp/src/controller.cpp) for both robots of the MuJoCo scene, in Python: MuJoCo
    has no computed-torque actuator. Per robot tau = sat(M(q) v + bias(q, qd) + B qd), v = qdd_ref +
    kd (qd_ref - qd) + kp (q_ref - q), with MuJoCo's own model: M from d.qM (mj_mulM on the robots' rows;
    the bar's tree is separate, so they are each robot's M), bias = d.qfrc_bias (Coriolis, centrifugal,
    gravity) and B qd = -d.qfrc_passive (the joints' damping, coopsim's viscous friction K qd, which coopsim's
    controller model includes); sat = clip at the actuator limits. control(row) computes them for the present
    state (MuJoCo's kinematics, CRB, RNE and passive forces, called from Python before mj_step, which computes
    them again in its first RK4 stage) and sets d.ctrl, held over the step (control_every=1). The alternative,
    mjcb_control at the first of the four RK4 stages (the others holding), needs no recomputation but enters
    Python four times a step: it measured about 15 % slower on the task's cycle."""

    def __init__(self, m, kp, kd, tau_max, references):
        import mujoco
        self.mj = mujoco
        self.m = m
        adr = [m.joint(f"r{i}_joint1").dofadr[0] for i in range(2)]
        n = sum(len(r[0][0]) for r in references)
        self.dofs = slice(adr[0], adr[0] + n)  # both robots' dofs, contiguous after the bar's
        qadr = m.joint("r0_joint1").qposadr[0]
        self.qpos = slice(qadr, qadr + n)
        assert adr[1] == adr[0] + len(references[0][0][0])
        self.kp, self.kd, self.tau_max = np.concatenate(kp), np.concatenate(kd), np.concatenate(tau_max)
        Q, QD, QDD = (np.hstack([r[j] for r in references]) for j in range(3))
        self.ref = QDD + self.kd * QD + self.kp * Q  # v = ref[k] - kd qd - kp q
        self.vec, self.res = np.zeros(m.nv), np.zeros(m.nv)
        self.v, self.Mv = self.vec[self.dofs], self.res[self.dofs]
        self.t1, self.t2, self.tau = np.zeros(n), np.zeros(n), np.zeros(n)
        self.d = None

    def bind(self, d):
        """Views of d's arrays that the controller reads and writes (in place: numpy's small-array calls cost
        about a microsecond each, the most of this controller's time)."""
        s = self.dofs
        self.d = d
        self.q, self.qd = d.qpos[self.qpos], d.qvel[s]
        self.bias, self.passive, self.ctrl = d.qfrc_bias[s], d.qfrc_passive[s], d.ctrl
        return self

    def control(self, row):
        """The torque for the present state and reference row `row`, into d.ctrl."""
        mj, m, d = self.mj, self.m, self.d
        mj.mj_kinematics(m, d)
        mj.mj_comPos(m, d)
        mj.mj_crb(m, d)  # d.qM
        mj.mj_comVel(m, d)
        mj.mj_passive(m, d)  # d.qfrc_passive
        mj.mj_rne(m, d, 0, d.qfrc_bias)  # as mj_fwdVelocity: C qd + G
        np.multiply(self.kd, self.qd, out=self.t1)
        np.multiply(self.kp, self.q, out=self.t2)
        np.subtract(self.ref[row], self.t1, out=self.v)
        np.subtract(self.v, self.t2, out=self.v)
        mj.mj_mulM(m, d, self.res, self.vec)
        np.add(self.Mv, self.bias, out=self.tau)
        np.subtract(self.tau, self.passive, out=self.tau)
        np.minimum(self.tau, self.tau_max, out=self.tau)
        np.maximum(self.tau, -self.tau_max, out=self.ctrl)


def scene_controller_agreement(m, controller, log, rows):
    """The largest relative difference between MuJoCo's computed torque and coopsim's logged torque (its
    ComputedTorque, saturated) at the given log rows, in coopsim's logged state."""
    import mujoco
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    controller.bind(d)
    err = 0.0
    for k in rows:
        d.qpos[controller.qpos] = np.concatenate([rl.q[k] for rl in log.robots])
        d.qvel[controller.dofs] = np.concatenate([rl.qd[k] for rl in log.robots])
        controller.control(k)
        err = max(err, rel(d.ctrl, np.concatenate([rl.tau[k] for rl in log.robots])))
    return err


def scene_mujoco(m, q0, steps, events, ctrl=None, controller=None, start=0, qd0=None):
    """One run of the scene in MuJoCo from the robots' joints q0 (12,) (at rest, or at qd0), the bar where the
    scene puts it: `steps` mj_step from reference row `start`, the welds switched on and off at {step: (robot,
    'grasp' | 'release')}, the actuators driven by ctrl (rows, 12) or by `controller` (a MujocoComputedTorque)
    before each step. Returns dict(took (wall, CPU) s, Q (steps + 1, 12) the robots' joints at each step, ncon
    the most contacts at once, weld_peak [N, N] (every 10th step), bar (3,) where the bar ends)."""
    import mujoco
    d = mujoco.MjData(m)
    qs = slice(m.joint("r0_joint1").qposadr[0], m.joint("r0_joint1").qposadr[0] + len(q0))
    d.qpos[qs] = q0
    if qd0 is not None:
        d.qvel[m.joint("r0_joint1").dofadr[0]:][:len(q0)] = qd0
    mujoco.mj_forward(m, d)
    q = d.qpos[qs]
    Q = np.empty((steps + 1, len(q0)))
    ncon, weld_peak = 0, [0.0, 0.0]
    EQUALITY = mujoco.mjtConstraint.mjCNSTR_EQUALITY
    if controller is not None:
        controller.bind(d)
    t0 = clock()
    for k in range(steps):
        ev = events.get(k)
        if ev is not None:
            if ev[1] == "grasp":
                mujoco.mj_kinematics(m, d)  # the poses of this state (d's are the last RK4 stage's)
                weld_now(m, d, ev[0])
            else:
                d.eq_active[ev[0]] = 0
        Q[k] = q
        if controller is None:
            d.ctrl[:] = ctrl[start + k]
        else:
            controller.control(start + k)
        mujoco.mj_step(m, d)
        ncon = max(ncon, d.ncon)
        if k % 10 == 0 and d.eq_active.any():  # the welds' forces, every 10th step
            eq = np.flatnonzero(d.efc_type == EQUALITY)
            for e in range(2):
                rows = eq[d.efc_id[eq] == e][:3]
                if len(rows):
                    weld_peak[e] = max(weld_peak[e], float(np.linalg.norm(d.efc_force[rows])))
    took = clock() - t0
    Q[steps] = q
    return dict(took=took, Q=Q, ncon=ncon, weld_peak=weld_peak, bar=d.body("bar").xpos.copy())


def scene_tracking(E, joint_types):
    """One robot's joint tracking error E = q_ref - q (rows, n): 'max a mrad / b mm, RMS c mrad / d mm' over
    its arm's revolute / prismatic joints (RMS per joint over the rows, the largest), then the jaw's (the last
    joint, whose reference squeezes through the bar by design: some 8 mm while it holds one)."""
    rev = np.array([t == "R" for t in joint_types[:-1]])
    mx, rms = np.abs(E).max(axis=0) * 1e3, np.sqrt((E ** 2).mean(axis=0)) * 1e3
    return (f"max {mx[:-1][rev].max():.2f} mrad / {mx[:-1][~rev].max():.2f} mm, "
            f"RMS {rms[:-1][rev].max():.2f} mrad / {rms[:-1][~rev].max():.2f} mm; jaw max {mx[-1]:.2f} mm")


def scene_part(repeats):
    """The cooperative task (one cycle) in coopsim with its controllers and world at every 0.2 ms step, then the
    same scene in MuJoCo (RK4 at 0.2 ms, contacts every step), welding the bar at coopsim's grasp and release
    times, twice: under the task's computed torque (the same controller, in Python) and replaying coopsim's
    references under native PD + feed-forward actuators (MuJoCo at its fastest, a different controller).
    Interleaved repeats; real-time factors, tracking, where the bar ends and the weld forces."""
    from coopsim.tasks import handover as H
    from coopsim.tasks import scene
    r0, r1 = scene.scaras()
    robots = (r0, r1)
    types = [r.joint_types for r in robots]
    walls = {"coopsim": [], "ct": [], "pd": []}
    runs = {}
    m_ct = m_pd = None
    for rep in range(repeats):
        t0 = clock()
        res = H.run(cycles=1, control_every=1, world_every=1, log_every=1, score=False)
        walls["coopsim"].append(clock() - t0)
        if m_ct is None:  # the MuJoCo side from the first run's log (the run is deterministic)
            log, t_sim = res.log, float(res.report["simulated_time"])
            refs = [(rl.q_ref, rl.qd_ref, rl.qdd_ref) for rl in log.robots]   # every step's reference
            steps = len(log.t) - 1
            q0 = np.concatenate([rl.q[0] for rl in log.robots])
            Qref = np.hstack([r[0] for r in refs])
            g = log.grasps
            events = {int(round(t / DT)): (int(rb), ev) for t, rb, ev in zip(g["t"], g["robot"], g["event"])}
            # the task's gains: ComputedTorque(omega^2, 2 omega) (handover._Runner)
            kp, kd = [w * w for w in H.OMEGA], [2 * w for w in H.OMEGA]
            m_ct = mujoco_scene(robots)
            controller = MujocoComputedTorque(m_ct, kp, kd, [r.tau_limits for r in robots], refs)
            agree = scene_controller_agreement(m_ct, controller, log, np.linspace(0, steps, 101).astype(int))
            # PD + ff: the computed torque's bandwidths as PD gains on M's diagonal at the start
            pkp, pkd = [], []
            for r, rl, w in zip(robots, log.robots, H.OMEGA):
                Mii = np.maximum(np.diag(r.mass_matrix(rl.q_ref[0])), 0.01)
                pkp.append(Mii * w * w)
                pkd.append(2 * Mii * w)
            m_pd = mujoco_scene(robots, pkp, pkd)
            ctrl = np.hstack([refs[i][0] + pkd[i] / pkp[i] * refs[i][1] for i in range(2)])
        runs["ct"] = scene_mujoco(m_ct, q0, steps, events, controller=controller)
        runs["pd"] = scene_mujoco(m_pd, q0, steps, events, ctrl=ctrl)
        for key in ("ct", "pd"):
            walls[key].append(runs[key]["took"])
    w, c = ({key: float(np.median(v, axis=0)[j]) for key, v in walls.items()} for j in (0, 1))
    bar_cs = log.bodies["bar"].position[-1]
    ok_cs = through(bar_cs)
    print(f"\n## The cooperative scene: one cycle of the task, {t_sim:.2f} s simulated at {DT * 1e3:g} ms ({steps} "
          f"steps), RK4, contacts every step, median of {repeats} interleaved; CPU: the process's CPU time")
    print(f"agreement before timing: MuJoCo's computed torque against coopsim's logged torque at 101 rows of its "
          f"run, in its state: {agree:.1e} (<= {TOL:g} required for a ratio)")
    rows = [("coopsim", "computed torque in C++ (handover.run, its planning included)", "coopsim"),
            ("MuJoCo", "the same computed torque in Python, motors", "ct"),
            ("MuJoCo", "native PD + ff actuators: a different controller", "pd")]
    print(f"{'peer':8} {'controller':61} {'wall s':>6} {'CPU s':>6} {'real-time x':>11} {'x coopsim':>9} {'CPU':>5}")
    ratios = {}
    for label, how, key in rows:
        bar = bar_cs if key == "coopsim" else runs[key]["bar"]
        same = key == "coopsim" or (through(bar) == ok_cs and (key != "ct" or agrees(agree)))
        ratios[key] = (w[key] / w["coopsim"], c[key] / c["coopsim"]) if same else None
        cell = f"{ratios[key][0]:9.1f} {ratios[key][1]:5.1f}" if same else "  no ratio: " + (
            "the bar ends elsewhere" if through(bar) != ok_cs else f"disagrees ({agree:.1e})")
        print(f"{label:8} {how:61} {w[key]:6.2f} {c[key]:6.2f} {t_sim / w[key]:11.1f} {cell}")
    cs_peak = [float(np.linalg.norm(rl.weld[:, :3], axis=1).max()) for rl in log.robots]
    ncon_cs = len(log.contacts) if log.contacts is not None else 0
    for label, key in (("coopsim", "coopsim"), ("MuJoCo, the same computed torque", "ct"),
                       ("MuJoCo, PD + ff", "pd")):
        if key == "coopsim":
            E = [rl.q_ref - rl.q for rl in log.robots]
            bar, peak = bar_cs, cs_peak
            extra = f"{len(g)} grasp events, {ncon_cs} contact events"
        else:
            r = runs[key]
            E = [Qref[:, :6] - r["Q"][:, :6], Qref[:, 6:] - r["Q"][:, 6:]]
            bar, peak = r["bar"], r["weld_peak"]
            extra = f"at most {r['ncon']} contacts at once"
        print(f"# {label}: joint tracking error #1 {scene_tracking(E[0], types[0])}; #2 "
              f"{scene_tracking(E[1], types[1])}")
        print(f"#   the bar ends at {np.round(bar, 3).tolist()} (through the tube: {through(bar)}); peak weld force "
              f"#1 {peak[0]:.2f} N, #2 {peak[1]:.2f} N{' (every 10th step)' if key != 'coopsim' else ''}; {extra}")
    print("# coopsim's wall time includes its planning and phase sequencing in Python; MuJoCo's a Python loop's few "
          "us per step around mj_step and, for the computed torque, the controller in Python (MuJoCo has no "
          "computed-torque actuator): MuJoCo's kinematics, CRB, RNE and passive forces for the state, then "
          "M v + bias + damping, clipped, before each mj_step")
    ratio = ratios["ct"]
    if ratio is None:
        print("# target: coopsim >= 2x MuJoCo's speed on the same scene under the same controller: no verdict "
              "(MuJoCo's run is not the same job, above)")
    else:
        print(f"# target: coopsim >= 2x MuJoCo's speed on the same scene under the same controller: {ratio[0]:.1f}x -> "
              f"{'met' if ratio[0] >= 2 else 'NOT met'} (in CPU time {ratio[1]:.1f}x)")
    if ratios["pd"] is not None:
        print(f"#   MuJoCo at its fastest (native PD + ff actuators, a different controller): {ratios['pd'][0]:.1f}x "
              f"(in CPU time {ratios['pd'][1]:.1f}x)")
    return ratio


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats, a shorter closed loop")
    ap.add_argument("--part", choices=["dynamics", "loop", "scene", "all"], default="all")
    ap.add_argument("--repeats", type=int, help="repeats of each timing (default 3 with --quick, else 15)")
    args = ap.parse_args(argv)
    repeats = args.repeats or (3 if args.quick else 15)
    robot = cs.robots.scara1()
    print(f"# coopsim {cs.__version__} (optimised build: {cs.build_info()['optimised']}), numpy {np.__version__}, "
          f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} cores, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    peers, notes = load_peers(robot)
    for label, (version, _) in peers.items():
        print(f"# {label} {version}")
    for note in notes:
        print(f"# {note}")
    if args.part in ("dynamics", "all"):
        dynamics_part(robot, peers, repeats, batch_n=2000 if args.quick else 20000,
                      loop_n=200 if args.quick else 1000, target_s=0.005 if args.quick else 0.01)
    if args.part in ("loop", "all"):
        loop_part(robot, peers, 1 if args.quick else max(3, repeats // 3), 1.0 if args.quick else T_LOOP)
    if args.part in ("scene", "all"):
        if "MuJoCo" in peers:
            scene_part(1 if args.quick else 3)
        else:
            print("\n# the cooperative scene needs MuJoCo: skipped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
