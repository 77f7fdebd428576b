"""benchmarks/bench_peers.py cannot rot: every peer that is installed loads coopsim's URDF export (or DH
table) and computes coopsim's numbers before anything is timed, and the closed-loop runs track the
same cubic under the same PID (a short run, no timing asserted)."""
from __future__ import annotations

import importlib.util
import os
import sys

import numpy as np
import pytest

import coopsim as cs

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "benchmarks"))
import bench_peers  # noqa: E402


@pytest.fixture(scope="module")
def robot():
    return cs.robots.scara1()


@pytest.fixture(scope="module")
def peers(robot):
    peers, notes = bench_peers.load_peers(robot)
    for label, (module, _, _) in bench_peers.PEERS.items():
        if importlib.util.find_spec(module) is not None:  # installed: it must load, not be skipped
            assert label in peers, notes
        else:
            assert any(n.startswith(label + " skipped") for n in notes)
    return peers


def test_every_installed_peer_agrees_before_timing(robot, peers):
    ours = bench_peers.peer_coopsim(robot)
    numeric = bench_peers.peer_coopsim(robot.with_backend("numeric"), "coopsim numeric")
    err = bench_peers.agreement(robot, ours, {"coopsim numeric": ("", numeric), **peers}, count=2, batch=3)
    for label, row in err.items():
        assert set(row) == set(bench_peers.OPS)
        for op, e in row.items():
            assert bench_peers.agrees(e), (label, op, e)


def test_a_disagreeing_peer_gets_no_ratio(robot):
    ours = bench_peers.peer_coopsim(robot)
    off = {op: (lambda f: lambda *a: f(*a) * (1 + 1e-6))(fn) for op, fn in ours.items()}
    err = bench_peers.agreement(robot, ours, {"off": ("", off)}, count=1, batch=2)
    assert not any(bench_peers.agrees(e) for e in err["off"].values())


def test_timing_is_interleaved_medians():
    out = bench_peers.interleaved([("a", lambda: None, (), 1), ("b", lambda x: x, (1,), 2)], 3, 1e-4)
    assert set(out) == {"a", "b"} and all(v > 0 for v in out.values())


def test_closed_loops_do_the_same_job(robot, peers):
    """0.1 s of the closed loop: coopsim and each installed peer follow the same reference, and the
    PID-in-Python peers land on coopsim's trajectory (the same controller; integrators differ)."""
    steps = 500
    traj = bench_peers.trajectory(robot, bench_peers.T_LOOP)
    kp, ki, kd = bench_peers.gains(robot, traj)
    _, Q0, R0 = bench_peers.loop_coopsim(robot, traj, kp, ki, kd, steps)
    runs = []
    if "MuJoCo" in peers:
        runs += [(bench_peers.loop_mujoco_python, 1e-6), (bench_peers.loop_mujoco_rollout, 2e-3)]
    if "PyBullet" in peers:
        runs += [(bench_peers.loop_pybullet, 1e-4)]
    for fn, tol in runs:
        _, Q, R = fn(robot, traj, kp, ki, kd, steps)
        assert Q.shape == Q0.shape == (steps + 1, robot.dof)
        np.testing.assert_allclose(R, R0, atol=1e-12)
        assert np.abs(Q - Q0).max() <= tol, fn.__name__


@pytest.mark.skipif(importlib.util.find_spec("mujoco") is None, reason="the scene is compared in MuJoCo only")
def test_the_scene_in_mujoco_welds_where_it_grasps():
    """The task's scene as MJCF: both SCARAs (12 actuated joints), the bar free (7 coordinates), the floor and
    the container's four walls; a weld switched on holds the bar where it is (no residual)."""
    import mujoco
    from coopsim.tasks import scene
    r0, r1 = scene.scaras()
    m = bench_peers.mujoco_scene((r0, r1), [np.full(6, 100.0)] * 2, [np.full(6, 10.0)] * 2)
    assert (m.nu, m.nq, m.neq) == (12, 19, 2)
    assert {"floor", "container_bottom", "container_top", "container_left", "container_right", "bar"} <= {
        m.geom(i).name for i in range(m.ngeom)}
    d = mujoco.MjData(m)
    d.joint("r1_joint1").qpos[0], d.joint("r1_joint2").qpos[0] = 0.3, 0.7
    mujoco.mj_forward(m, d)
    bench_peers.weld_now(m, d, 1)
    mujoco.mj_forward(m, d)
    rows = d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert rows.sum() == 6 and np.abs(d.efc_pos[rows]).max() < 1e-12
    assert bench_peers.through(scene.CONTAINER["mouth"] + scene.container_axes()[:, 0] * 0.5)
    assert not bench_peers.through(scene.bar_pose()[:3, 3])


@pytest.mark.skipif(importlib.util.find_spec("mujoco") is None, reason="the scene is compared in MuJoCo only")
def test_the_scene_in_mujoco_runs_the_tasks_controller():
    """The task's references as its log keeps them (q_ref, qd_ref, qdd_ref at every step); MuJoCo's computed
    torque gives coopsim's logged torques in coopsim's states; and 0.1 s of the task in MuJoCo under that
    controller, from coopsim's state as SCARA #2 starts down to the bar (robots in free space), follows
    coopsim's joints: the same controller, references, dt and integrator."""
    from coopsim.tasks import handover as H
    from coopsim.tasks import scene
    res = H.run(cycles=1, control_every=1, world_every=1, log_every=1, score=False)
    log = res.log
    refs = [(rl.q_ref, rl.qd_ref, rl.qdd_ref) for rl in log.robots]     # as scene_part takes them
    assert all(np.isfinite(r).all() for ref in refs for r in ref)
    t = np.asarray(log.t)
    for rl, ref in zip(log.robots, res.sim.references):   # the last reference each robot was given, over its rows
        mine = t > ref.times[0] + 1e-12
        assert mine.sum() > 100
        for logged, evaluated in zip((rl.q_ref, rl.qd_ref, rl.qdd_ref), ref.evaluate(t[mine])):
            np.testing.assert_allclose(logged[mine], evaluated, rtol=0, atol=1e-12)
    robots = scene.scaras()
    m = bench_peers.mujoco_scene(robots)
    assert (m.nu, m.ngravcomp) == (12, 0) and not m.actuator_forcelimited.any()
    ctl = bench_peers.MujocoComputedTorque(m, [w * w for w in H.OMEGA], [2 * w for w in H.OMEGA],
                                           [r.tau_limits for r in robots], refs)
    rows = np.linspace(0, len(log.t) - 1, 9).astype(int)
    assert bench_peers.agrees(bench_peers.scene_controller_agreement(m, ctl, log, rows))
    off = bench_peers.MujocoComputedTorque(m, [w * w * 1.001 for w in H.OMEGA], [2 * w for w in H.OMEGA],
                                           [r.tau_limits for r in robots], refs)
    assert not bench_peers.agrees(bench_peers.scene_controller_agreement(m, off, log, rows))  # would get no ratio
    k0, steps = round(H.TIMES["approach"] / bench_peers.DT), 500
    q0, qd0 = (np.concatenate([getattr(rl, x)[k0] for rl in log.robots]) for x in ("q", "qd"))
    run = bench_peers.scene_mujoco(m, q0, steps, {}, controller=ctl, start=k0, qd0=qd0)
    assert run["ncon"] <= 4  # the bar lying on the floor, nothing else
    Q = np.hstack([rl.q[k0:k0 + steps + 1] for rl in log.robots])
    assert np.abs(run["Q"][-1] - run["Q"][0]).max() > 1e-2  # SCARA #2 moves
    assert np.abs(run["Q"] - Q).max() < 1e-6
