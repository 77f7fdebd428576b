"""Inverse kinematics (closed form for both SCARAs, numeric for any robot) and
Cartesian planning through it."""
import math

import numpy as np
import pytest

import coopsim as cs
from coopsim.planning import interpolate_poses

ROBOTS = {
    "scara1": cs.robots.scara1,
    "scara2": cs.robots.scara2,
}
# joint index of the prismatic quill and of the elbow, per robot
QUILL = {"scara1": 2, "scara2": 3}


def random_config(robot, rng):
    ql = robot.q_limits
    q = rng.uniform(ql[:, 0], ql[:, 1])
    if robot.ik_kind == "scara2":
        q[2] = q[1]  # the closed form resolves the redundancy with theta2 = theta3
    return q


def angle_diff(a, b):
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


def config_distance(robot, q, p):
    d = np.abs(q - p)
    rev = np.array([c == "R" for c in robot.joint_types])
    d[rev] = angle_diff(q[rev], p[rev])
    return d.max()


def pose_error(robot, q, T):
    F = robot.fk(q)
    pos = np.linalg.norm(F[:3, 3] - T[:3, 3])
    D = T[:3, :3].T @ F[:3, :3]
    # rotation angle from sine and cosine (acos alone loses half the digits near 0)
    v = np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])
    return pos, math.atan2(0.5 * np.linalg.norm(v), 0.5 * (np.trace(D) - 1.0))


def within_limits(robot, q):
    ql = robot.q_limits
    return bool(np.all(q >= ql[:, 0]) and np.all(q <= ql[:, 1]))


def replace_limits(robot, q_limits):
    return cs.Robot.from_dh(dh=robot.dh, com=robot.com, masses=robot.masses, inertias=robot.inertias,
                            joint_types=robot.joint_types, q_limits=q_limits, tool=robot.tool,
                            base_position=robot.base_position, base_yaw=robot.base_yaw)


# ---- closed form ----

@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_round_trip_1000_configurations_both_branches(name):
    # non-default dimensions and a placed base: the solver must read them from the robot
    dims = dict(L1=0.33, L2=0.21, L_base=0.47) if name == "scara1" else dict(L1=0.22, L2=0.16, L3=0.13, L5=0.07)
    robot = ROBOTS[name](base_position=(0.3, -0.2, 0.05), base_yaw=0.7, **dims)
    assert robot.ik_kind == name
    rng = np.random.default_rng(11)
    elbow = 1  # theta2's index, for both robots
    worst, per_branch = 0.0, {}
    for _ in range(1000):
        q = random_config(robot, rng)
        T = robot.fk(q)
        sols = robot.ik_solutions(T, opening=q[5])
        found = None
        for s, b in sols:
            pos, ang = pose_error(robot, s, T)
            worst = max(worst, pos, ang)
            assert within_limits(robot, s)
            assert np.sign(s[elbow]) == np.sign(b) or abs(s[elbow]) < 1e-12
            if name == "scara2":
                assert s[1] == s[2]
            per_branch[b] = per_branch.get(b, 0) + 1
            if config_distance(robot, s, q) < 1e-9:
                found = b
        assert found is not None, f"the generating configuration {q} is not among the solutions"
        # explicit branch: the generating one is returned when asked for its branch
        assert config_distance(robot, robot.ik(T, opening=q[5], branch=found, q_near=q), q) < 1e-9
        # nearest to a given configuration: the generating one
        assert config_distance(robot, robot.ik(T, q_near=q), q) < 1e-9
    assert worst < 1e-9
    # both elbow branches really occur (the other is sometimes beyond a limit)
    assert per_branch[1] > 800 and per_branch[-1] > 800


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_explicit_branch_is_honoured(name):
    robot = ROBOTS[name]()
    rng = np.random.default_rng(3)
    count = 0
    for _ in range(200):
        q = random_config(robot, rng)
        T = robot.fk(q)
        for b in (1, -1):
            try:
                s, info = robot.ik(T, opening=q[5], branch=b, info=True)
            except cs.IKError as e:
                assert "limits" in str(e)
                continue
            count += 1
            assert info["branch"] == b and np.sign(s[1]) in (b, 0)
            assert max(pose_error(robot, s, T)) < 1e-9
    assert count > 300


def test_yaw_and_pitch_of_clamp_pose():
    r1 = cs.robots.scara1(base_yaw=0.4)
    q = np.array([0.3, -0.8, 0.1, 0.5, 0.9, 0.02])
    T = cs.clamp_pose(r1, r1.fk(q)[:3, 3], yaw=0.4 + q[0] + q[1] - q[3], pitch=q[4])
    np.testing.assert_allclose(r1.fk(q), T, atol=1e-12)
    r2 = cs.robots.scara2(base_yaw=-0.2)
    q = np.array([0.3, -0.8, -0.8, 0.1, 0.5, 0.02])
    T = cs.clamp_pose(r2, r2.fk(q)[:3, 3], yaw=-0.2 + q[0] + q[1] + q[2] - q[4])
    np.testing.assert_allclose(r2.fk(q), T, atol=1e-12)
    with pytest.raises(ValueError, match="pitch"):
        cs.clamp_pose(r2, [0.3, 0.0, 0.2], pitch=0.1)


def test_structure_is_checked_before_the_closed_form():
    r = cs.robots.scara1()
    dh = r.dh.copy()
    dh[3, 3] = 0.0  # pitch axis vertical: no longer the decoupled SCARA #1
    other = cs.Robot.from_dh(dh=dh, com=r.com, masses=r.masses, inertias=r.inertias, joint_types=r.joint_types,
                             q_limits=r.q_limits, tool=r.tool)
    assert other.ik_kind is None and "alpha4" in other.ik_kind_reason()
    with pytest.raises(ValueError, match="alpha4"):
        other.ik(other.fk(np.zeros(6)), method="analytic")
    # 'auto' falls back to the numeric solver
    q = np.array([0.2, 0.9, 0.1, 0.3, 0.4, 0.01])
    s = other.ik(other.fk(q), q_near=q + 0.05)
    assert max(pose_error(other, s, other.fk(q))) < 1e-9


# ---- unreachable targets: clear IKError, never NaN ----

def test_ik_error_is_a_value_error():
    assert issubclass(cs.IKError, ValueError)


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_out_of_reach(name):
    robot = ROBOTS[name]()
    T = cs.clamp_pose(robot, [2.0, 0.0, 0.3])
    with pytest.raises(cs.IKError, match="out of reach.*arm reaches"):
        robot.ik(T)
    with pytest.raises(cs.IKError, match="out of reach: it is 2.0.* m from the robot's base.* no point of the robot"):
        robot.ik(T, method="numeric", restarts=3)
    # absurdly far targets too, without overflow into a wrong reason
    T[:2, 3] = 1e200
    for method in ("auto", "numeric"):
        with pytest.raises(cs.IKError, match=r"out of reach.* 1\.41421e\+200 m"):
            robot.ik(T, method=method)


def test_scara2_beyond_the_theta2_equal_theta3_rule():
    # the free arm reaches near the base where theta2 = theta3 cannot:
    # the closed form says so, 'auto' goes on with the numeric solver
    robot = cs.robots.scara2()
    q = np.array([0.3, 2.2, 1.8, 0.1, 0.2, 0.01])  # wrist point 0.028 m from the axis; theta2 = theta3 reaches from 0.043 m
    T = robot.fk(q)
    with pytest.raises(cs.IKError, match="with theta2 = theta3"):
        robot.ik(T, method="analytic")
    with pytest.raises(cs.IKError, match="with theta2 = theta3"):
        robot.ik(T, branch=1)  # a branch is a closed-form notion: no fallback
    s, info = robot.ik(T, opening=q[5], info=True)
    assert info["method"] == "numeric" and s[1] != s[2]
    assert max(pose_error(robot, s, T)) < 1e-9 and within_limits(robot, s)
    # and a plan through such poses
    q2 = q + 0.01
    traj = cs.plan_cartesian(robot, [T, robot.fk(q2)], [0.0, 1.0], opening=[q[5], q2[5]])
    assert max(pose_error(robot, traj.evaluate(1.0)[0], robot.fk(q2))) < 1e-9


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_outside_joint_limit_names_the_joint(name):
    robot = ROBOTS[name]()
    q = np.zeros(6)
    q[1] = 0.8
    if name == "scara2":
        q[2] = 0.8
    T = robot.fk(q)
    T[2, 3] -= 1.0  # far below the quill's stroke
    j = QUILL[name] + 1
    with pytest.raises(cs.IKError, match=rf"joint {j} \(d{j}\).*outside its limits"):
        robot.ik(T)
    with pytest.raises(cs.IKError, match="jaw opening"):
        robot.ik(robot.fk(q), opening=0.2)


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_unreachable_orientation(name):
    robot = ROBOTS[name]()
    q = np.array([0.3, 0.8, 0.1, 0.2, 0.4, 0.0]) if name == "scara1" else np.array([0.3, 0.8, 0.8, 0.1, 0.2, 0.0])
    T = robot.fk(q)
    c, s = math.cos(0.2), math.sin(0.2)
    turn = np.eye(4)
    if name == "scara1":
        turn[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]  # roll about the approach axis
    else:
        turn[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]  # tilt of the approach away from the vertical
    with pytest.raises(cs.IKError, match="orientation not reachable"):
        robot.ik(T @ turn)


def test_singular_target_on_the_first_axis():
    # equal arms and an elbow free to fold completely: the wrist point can sit on joint 1's axis
    base = cs.robots.scara1(L1=0.3, L2=0.3)
    ql = base.q_limits.copy()
    ql[1] = [-math.pi, math.pi]
    robot = replace_limits(base, ql)
    q = np.array([0.0, math.pi, 0.05, 0.0, 0.0, 0.0])
    T = robot.fk(q)
    T[:2, 3] -= robot.frames(q)[4][:2, 3]  # put the wrist point (frame 4) exactly on the axis
    with pytest.raises(cs.IKError, match="singular.*theta1 is undetermined"):
        robot.ik(T)
    q_near = np.array([0.4, 3.0, 0.05, 0.0, 0.0, 0.0])
    s = robot.ik(T, q_near=q_near)
    assert np.all(np.isfinite(s)) and s[0] == pytest.approx(0.4)
    assert max(pose_error(robot, s, T)) < 1e-9


# ---- numeric IK ----

def random_dh_robot(rng, n=6):
    dh = np.column_stack([rng.uniform(-math.pi, math.pi, n), rng.uniform(-0.3, 0.3, n),
                          rng.uniform(0.0, 0.4, n), rng.choice([0.0, math.pi / 2, -math.pi / 2], n)])
    types = "".join(rng.choice(["R", "R", "R", "P"], n))
    ql = np.array([[-math.pi, math.pi] if t == "R" else [-0.3, 0.3] for t in types])
    return cs.Robot.from_dh(dh=dh, com=dh.copy(), masses=np.ones(n), inertias=np.tile(np.eye(3) * 1e-3, (n, 1, 1)),
                            joint_types=types, q_limits=ql)


@pytest.mark.parametrize("name", ["scara1", "scara2"])
def test_numeric_ik_converges_on_scaras(name):
    robot = ROBOTS[name]()
    rng = np.random.default_rng(5)
    for _ in range(60):
        q = rng.uniform(robot.q_limits[:, 0], robot.q_limits[:, 1])  # theta2 != theta3 for SCARA #2 too
        T = robot.fk(q)
        s, info = robot.ik(T, opening=q[5], method="numeric", info=True)
        assert max(pose_error(robot, s, T)) < 1e-9
        assert within_limits(robot, s) and s[5] == q[5]  # the jaw is held
        assert 1 <= info["attempts"] <= 11


def test_numeric_ik_converges_on_random_6dof_robots():
    rng = np.random.default_rng(8)
    converged, total, restarted = 0, 0, 0
    for _ in range(25):
        robot = random_dh_robot(rng)
        assert robot.ik_kind is None
        for _ in range(4):
            q = rng.uniform(robot.q_limits[:, 0], robot.q_limits[:, 1])
            T = robot.fk(q)
            total += 1
            try:
                s, info = robot.ik(T, info=True)
            except cs.IKError:
                continue
            converged += 1
            assert max(pose_error(robot, s, T)) < 1e-9 and within_limits(robot, s)
            if info["attempts"] > 1:
                # the restarts matter: the first attempt alone gets stuck here
                restarted += 1
                with pytest.raises(cs.IKError, match="after 1 attempts"):
                    robot.ik(T, restarts=0)
    assert converged / total >= 0.97, f"{converged}/{total}"
    assert restarted >= 10, restarted


def test_numeric_ik_on_placed_robots_without_limits():
    # the shared random robots: any alpha, negative a, random base placement, unbounded joints
    from conftest import random_robot

    rng = np.random.default_rng(0)
    for seed in range(20):
        robot = random_robot(seed, dof=6)
        prismatic = np.array([c == "P" for c in robot.joint_types])
        for _ in range(3):
            q = rng.uniform(-math.pi, math.pi, 6)
            q[prismatic] *= 0.1
            T = robot.fk(q)
            s = robot.ik(T)
            assert max(pose_error(robot, s, T)) < 1e-9
            # unbounded angles come back as the copy nearest the start point (0)
            assert np.all(np.abs(s[~prismatic]) <= math.pi + 1e-12)


def test_numeric_ik_fails_cleanly_on_unreachable_random_targets():
    rng = np.random.default_rng(9)
    robot = random_dh_robot(rng)
    # beyond any point the robot can reach: |a| + |d| + stroke per link
    reach = np.abs(robot.dh[:, 1:3]).sum() + sum(np.abs(robot.q_limits[i]).max()
                                                 for i, c in enumerate(robot.joint_types) if c == "P")
    T = np.eye(4)
    T[:3, 3] = [reach + 0.5, 0.0, 0.0]
    with pytest.raises(cs.IKError, match="out of reach"):
        robot.ik(T, restarts=4)
    # within that bound but off the plane of a planar arm: the solver tries, then says how close it came
    planar = cs.Robot.from_dh(dh=[[0, 0, 1.0, 0], [0, 0, 1.0, 0]], com=[[0, 0, 0.5, 0], [0, 0, 0.5, 0]],
                              masses=[1.0, 1.0], inertias=np.tile(np.eye(3) * 1e-2, (2, 1, 1)), joint_types="RR")
    T = np.eye(4)
    T[:3, 3] = [0.5, 0.5, 0.5]
    with pytest.raises(cs.IKError, match=r"after 5 attempts: best residual 0\.5 m, .* rad .* unreachable"):
        planar.ik(T, restarts=4, weights="position")


def test_numeric_subset_and_locked_joints():
    rng = np.random.default_rng(10)
    robot = random_dh_robot(rng)
    q = rng.uniform(-1, 1, 6) * 0.25
    T = robot.fk(q)
    T2 = T.copy()
    T2[:3, :3] = np.eye(3)  # orientation left out: only the position must match
    s = robot.ik(T2, weights="position", q_near=q * 0.5)
    assert np.linalg.norm(robot.fk(s)[:3, 3] - T[:3, 3]) < 1e-9
    # a locked joint keeps its start value
    s = robot.ik(T, q_near=q + 0.02, locked=[0], weights="position")
    assert s[0] == q[0] + 0.02


def test_bad_ik_input():
    robot = cs.robots.scara1()
    with pytest.raises(ValueError, match="pose"):
        robot.ik(np.eye(3))
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="pose must be finite"):
        robot.ik(bad)
    with pytest.raises(ValueError, match="branch"):
        robot.ik(robot.fk(np.zeros(6)), branch=3)
    with pytest.raises(ValueError, match="method"):
        robot.ik(robot.fk(np.zeros(6)), method="magic")
    with pytest.raises(ValueError, match="q_near"):
        robot.ik(robot.fk(np.zeros(6)), q_near=np.zeros(5))


# ---- Cartesian planning ----

def scara1_poses(robot):
    return np.array([cs.clamp_pose(robot, [0.40, 0.10, 0.20], yaw=0.3, pitch=1.2),
                     cs.clamp_pose(robot, [0.38, -0.22, 0.10], yaw=-0.6, pitch=0.5),
                     cs.clamp_pose(robot, [0.22, 0.36, 0.25], yaw=1.4, pitch=0.1)])


def test_plan_passes_through_every_given_pose():
    times = np.array([0.0, 1.0, 2.5])
    r1 = cs.robots.scara1()
    r2 = cs.robots.scara2(base_position=(1.0, 0.0, 0.0), base_yaw=math.pi)
    poses2 = np.array([cs.clamp_pose(r2, [0.70, 0.10, 0.20], yaw=0.3),
                       cs.clamp_pose(r2, [0.75, -0.20, 0.15], yaw=-0.5),
                       cs.clamp_pose(r2, [0.60, 0.05, 0.30], yaw=1.0)])
    for robot, poses in ((r1, scara1_poses(r1)), (r2, poses2)):
        for intermediate in (0, 4):
            traj, info = cs.plan_cartesian(robot, poses, times, opening=0.01, intermediate=intermediate,
                                           info=True)
            assert traj.segments == (len(times) - 1) * (intermediate + 1)
            q_given, _, _ = traj.evaluate(times)
            for q, T in zip(q_given, poses):
                assert max(pose_error(robot, q, T)) < 1e-9
            # the inserted knots are on the straight line, too
            q_knots, _, _ = traj.evaluate(info["times"])
            for q, T in zip(q_knots, info["poses"]):
                assert max(pose_error(robot, q, T)) < 1e-9
            # one elbow branch throughout
            assert len(set(np.sign(info["q_points"][:, 1]))) == 1


def test_plan_numeric_robot_passes_through_poses():
    rng = np.random.default_rng(12)
    robot = random_dh_robot(rng)
    q0 = rng.uniform(-0.1, 0.1, 6)
    qs = [q0, q0 + 0.05, q0 + 0.1]  # within the +-0.3 m prismatic limits
    poses = np.array([robot.fk(q) for q in qs])
    traj = cs.plan_cartesian(robot, poses, [0.0, 1.0, 2.0], q_start=q0)
    for q, T in zip(traj.evaluate(np.array([0.0, 1.0, 2.0]))[0], poses):
        assert max(pose_error(robot, q, T)) < 1e-9


def test_more_intermediate_points_follow_the_line_more_closely():
    robot = cs.robots.scara1()
    a, b = cs.clamp_pose(robot, [0.45, -0.1, 0.2], pitch=0.8), cs.clamp_pose(robot, [0.15, 0.35, 0.1], pitch=0.8)
    deviations = []
    for k in (0, 2, 8, 32):
        traj = cs.plan_cartesian(robot, [a, b], [0.0, 2.0], intermediate=k)
        ts = np.linspace(0.0, 2.0, 201)
        q, _, _ = traj.evaluate(ts)
        p = np.array([robot.fk(qi)[:3, 3] for qi in q])
        # distance from the segment a-b
        d = b[:3, 3] - a[:3, 3]
        rel = p - a[:3, 3]
        off = rel - np.outer(rel @ d / (d @ d), d)
        deviations.append(np.linalg.norm(off, axis=1).max())
    assert all(x > y for x, y in zip(deviations, deviations[1:])), deviations
    assert deviations[-1] < 1e-3 < deviations[0]


def test_plan_unwraps_angles():
    base = cs.robots.scara2()
    ql = base.q_limits.copy()
    ql[4] = [-2 * math.pi, 2 * math.pi]  # a yaw joint that may turn through +-180 deg
    robot = replace_limits(base, ql)
    yaws = np.radians([150.0, 180.0, 210.0, 240.0])
    poses = [cs.clamp_pose(robot, [0.35, 0.1, 0.2], yaw=-y) for y in yaws]
    traj, info = cs.plan_cartesian(robot, poses, [0.0, 1.0, 2.0, 3.0], info=True)
    steps = np.diff(info["q_points"], axis=0)
    assert np.abs(steps[:, 4]).max() < math.radians(31.0)  # no 2 pi jump in theta5


def test_straight_line_clamp_interpolation_stays_reachable():
    robot = cs.robots.scara1()
    a, b = scara1_poses(robot)[:2]
    for T in interpolate_poses(a, b, np.linspace(0, 1, 7), mode="clamp"):
        robot.ik(T)  # raises IKError if the orientation left the clamp's yaw-pitch family
    # a geodesic between the same poses does leave it
    mid = interpolate_poses(a, b, [0.5], mode="geodesic")[0]
    with pytest.raises(cs.IKError, match="orientation not reachable"):
        robot.ik(mid)


def test_plan_bad_input():
    robot = cs.robots.scara1()
    poses = scara1_poses(robot)
    with pytest.raises(ValueError, match="same length"):
        cs.plan_cartesian(robot, poses, [0.0, 1.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        cs.plan_cartesian(robot, poses, [0.0, 1.0, 1.0])
    bad = poses.copy()
    bad[1, 0, 3] = np.nan
    with pytest.raises(ValueError, match="finite"):
        cs.plan_cartesian(robot, bad, [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="at least 2"):
        cs.plan_cartesian(robot, poses[:1], [0.0])
    far = poses.copy()
    far[1, :3, 3] = [3.0, 0.0, 0.2]
    with pytest.raises(cs.IKError, match="pose 1.*out of reach"):
        cs.plan_cartesian(robot, far, [0.0, 1.0, 2.0])


# ---- the IK along a path in one call (Robot.ik_path, plan_cartesian's knots) ----

def _path_poses(robot, n, rng, spread=0.05):
    """n poses along a smooth joint path inside the limits, by forward kinematics."""
    lo, hi = robot.q_limits[:, 0], robot.q_limits[:, 1]
    a = lo + (hi - lo) * (0.3 + 0.4 * rng.random(robot.dof))
    b = np.clip(a + spread * (hi - lo) * rng.standard_normal(robot.dof), lo, hi)
    return np.array([robot.fk(a + (b - a) * s) for s in np.linspace(0.0, 1.0, n)])


@pytest.mark.parametrize("name, method", [("scara1", "auto"), ("scara2", "auto"), ("scara1", "numeric")])
def test_ik_path_equals_the_ik_of_each_pose_near_the_one_before(name, method):
    """Robot.ik_path gives, bit for bit, what a loop of Robot.ik calls gives: each pose solved near the solution of
    the one before, the first pose's branch kept (closed forms), no restarts after the first (numeric, local)."""
    robot = getattr(cs.robots, name)()
    rng = np.random.default_rng(5)
    poses = _path_poses(robot, 12, rng)
    openings = np.linspace(0.02, 0.03, len(poses))
    q0 = robot.ik(poses[0], opening=openings[0], method=method)
    later = 0 if method == "numeric" else 10
    Q, branch, failed, error = robot.ik_path(poses, openings=openings, q_start=q0, method=method,
                                             later_restarts=later)
    assert failed is None and error == ""
    q, first = q0, None
    for i, T in enumerate(poses):
        kw = dict(opening=openings[i], q_near=q, method=method)
        if method == "numeric":
            kw["restarts"] = 10 if i == 0 else 0
        else:
            kw.update(branch=first, info=True)
        res = robot.ik(T, **kw)
        if method != "numeric":
            res, info = res
            if i == 0:
                first = info.get("branch")
        np.testing.assert_array_equal(Q[i], res)
        q = res
    assert branch == (first if method != "numeric" else None)


def test_ik_path_stops_at_the_first_pose_out_of_reach_and_names_it():
    robot = cs.robots.scara1()
    rng = np.random.default_rng(2)
    poses = _path_poses(robot, 6, rng)
    far = poses[3].copy()
    far[:3, 3] = [3.0, 0.0, 0.3]          # beyond the arm's reach
    poses[3] = far
    Q, branch, failed, error = robot.ik_path(poses, q_start=robot.ik(poses[0]))
    assert failed == 3 and Q.shape == (3, robot.dof)
    with pytest.raises(cs.IKError) as e:
        robot.ik(far, q_near=Q[-1], branch=branch)
    assert error == str(e.value)
    # plan_cartesian names it among its poses
    with pytest.raises(cs.IKError, match=r"^pose 3 on elbow branch [+-]1: "):
        cs.plan_cartesian(robot, poses, np.arange(6.0), q_start=Q[0])


@pytest.mark.parametrize("kw, match", [
    (dict(openings=[0.02, 0.03]), "openings must have one value per pose \\(4\\), got 2"),
    (dict(later_restarts=-1), "later_restarts must be >= 0, got -1"),
    (dict(poses=np.zeros((2, 3, 3))), "poses"),
])
def test_ik_path_refuses_bad_arguments_in_one_line(kw, match):
    robot = cs.robots.scara1()
    poses = kw.pop("poses", _path_poses(robot, 4, np.random.default_rng(1)))
    with pytest.raises(ValueError, match=match) as e:
        robot.ik_path(poses, **kw)
    assert "\n" not in str(e.value)
