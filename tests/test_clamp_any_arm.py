"""A clamp on any serial arm (cs.robots.add_clamp, Robot.from_urdf(clamp=...)) and IK with its jaw: the UR5
and the Panda of the example-robot-data wheel with SCARA #1's clamp, checked against Pinocchio assembling the
same parts, the tool centre point between the jaws, the grasp rule, the sensor, task-space and object-level
control, the numeric IK with the jaw locked at an opening, and bad input."""
from __future__ import annotations

import importlib.metadata

import numpy as np
import pinocchio as pin
import pytest

import coopsim as cs

G = 9.81
D = cs.robots.CLAMP_DEFAULTS


def shipped(relative: str) -> str:
    """Path of a file of the example-robot-data wheel, e.g. 'ur_description/urdf/ur5_robot.urdf'."""
    return next(str(f.locate()) for f in importlib.metadata.files("example-robot-data")
                if str(f).endswith("robots/" + relative))


UR5 = shipped("ur_description/urdf/ur5_robot.urdf")
PANDA = shipped("panda_description/urdf/panda.urdf")
ARMS = {"ur5": lambda: cs.Robot.from_urdf(UR5),
        "panda": lambda: cs.Robot.from_urdf(PANDA, tip="panda_link8")}  # the arm to its flange, fingers cut
# a mount neither identity nor along an axis: turned about z and x, moved off the flange's centre
MOUNT = cs.dh_transform(0.4, 0.01, 0.02, 0.3)
DOWN = np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]])  # TCP axes: x along world x, approach pointing down


def pose(R, p):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def in_clamp(frame, point):
    """A point (3,) given in the clamp frame, in the frame `frame` (4, 4) is given in."""
    return frame[:3, :3] @ point + frame[:3, 3]


@pytest.mark.parametrize("which", list(ARMS))
def test_the_last_link_with_the_clamp_is_the_assembly_pinocchio_builds(which):
    """Exported to URDF and read by Pinocchio, the clamped arm's last body is the arm's last body (Pinocchio
    reading the arm's own export) plus the clamp body and the fixed jaw as boxes at the mount, and its new
    body the moving jaw at the opening: mass, centre of mass and inertia to 1e-10. The exported URDF has
    the jaw as a prismatic joint, and M(q) equals Pinocchio's CRBA on it."""
    arm = ARMS[which]()
    c = cs.robots.add_clamp(arm, mount=MOUNT, body_mass=0.3)
    n = arm.dof
    m0, m1 = pin.buildModelFromXML(arm.to_urdf()), pin.buildModelFromXML(c.to_urdf())
    d0, d1 = m0.createData(), m1.createData()
    assert m1.nq == n + 1 and m1.names[n + 1] == "clamp_jaw" and '<joint name="clamp_jaw" type="prismatic">' in \
        c.to_urdf()
    L5, Lj, tj, w, h, mj = (D[k] for k in ("body_length", "jaw_length", "jaw_thickness", "width", "height",
                                            "jaw_mass"))
    rng = np.random.default_rng(5)
    for _ in range(5):
        q, opening = rng.uniform(-2, 2, n), rng.uniform(0, D["opening"])
        pin.forwardKinematics(m0, d0, q)
        pin.forwardKinematics(m1, d1, np.r_[q, opening])
        C = arm.fk(q) @ MOUNT  # the clamp frame in the world

        def box(mass, centre, size):
            return pin.SE3(C[:3, :3], in_clamp(C, centre)).act(pin.Inertia.FromBox(mass, *size))

        expected = [d0.oMi[n].act(m0.inertias[n]) + box(0.3, [0, 0, L5 / 2], (w, h, L5))
                    + box(mj, [0, -tj / 2, L5 + Lj / 2], (w, tj, Lj)),
                    box(mj, [0, opening + tj / 2, L5 + Lj / 2], (w, tj, Lj))]
        for k, want in zip((n, n + 1), expected):
            got = d1.oMi[k].act(m1.inertias[k])
            assert got.mass == pytest.approx(want.mass, rel=1e-10)
            np.testing.assert_allclose(got.lever, want.lever, rtol=0, atol=1e-10)
            np.testing.assert_allclose(got.inertia, want.inertia, rtol=0, atol=1e-10 * np.abs(want.inertia).max())
        Mp = pin.crba(m1, d1, np.r_[q, opening])
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        np.testing.assert_allclose(c.mass_matrix(np.r_[q, opening]), Mp, rtol=0, atol=1e-10 * np.abs(Mp).max())


@pytest.mark.parametrize("which", list(ARMS))
def test_the_tcp_lies_between_the_jaws_and_the_arm_is_unchanged(which):
    """The TCP is midway between the jaws' inner faces, which stand `opening` apart along the clamp's y;
    it has the clamp frame's axes, body_length + jaw_length / 2 out along the approach. Frames 0..n-1, the
    arm's masses and dynamics with the jaw's row left out are the arm's."""
    arm = ARMS[which]()
    c = cs.robots.add_clamp(arm, mount=MOUNT)
    n = arm.dof
    assert c.dof == n + 1 and c.joint_types == arm.joint_types + "P" and c.backend == "numeric"
    assert c.clamp.fixed_link == n and c.clamp.moving_joint == n + 1
    np.testing.assert_array_equal(c.q_limits[-1], [0.0, D["opening"]])
    assert [b.name for b in c.boxes][-3:] == ["clamp_body", "fixed_jaw", "moving_jaw"]
    rng = np.random.default_rng(2)
    for _ in range(5):
        q, opening = rng.uniform(-2, 2, n), rng.uniform(0, D["opening"])
        qc = np.r_[q, opening]
        C = arm.fk(q) @ MOUNT
        T = c.fk(qc)
        np.testing.assert_allclose(T[:3, :3], C[:3, :3], atol=1e-14)
        np.testing.assert_allclose(T[:3, 3], in_clamp(C, [0, opening / 2, D["body_length"] + D["jaw_length"] / 2]),
                                   atol=1e-14)
        fixed, moving = c.clamp_faces(qc)
        np.testing.assert_allclose((fixed[:3, 3] + moving[:3, 3]) / 2, T[:3, 3], atol=1e-14)
        np.testing.assert_allclose(moving[:3, 3] - fixed[:3, 3], opening * C[:3, 1], atol=1e-14)
        np.testing.assert_allclose(fixed[:3, 2], C[:3, 1], atol=1e-14)  # the face's normal: the jaw axis
        np.testing.assert_allclose(np.array(c.frames(qc))[:n], np.array(arm.frames(q))[:n], atol=1e-14)
    np.testing.assert_array_equal(c.masses[:n - 1], arm.masses[:n - 1])
    assert c.masses[n - 1] == pytest.approx(arm.masses[n - 1] + D["body_mass"] + D["jaw_mass"], rel=1e-15)
    assert c.masses[n] == D["jaw_mass"]


def test_from_urdf_with_clamp_is_add_clamp_on_import():
    """clamp=True: add_clamp's defaults; a dict: its keywords; the tip's visuals follow the turned frame."""
    arm = cs.Robot.from_urdf(UR5)
    for clamp, kw in ((True, {}), (dict(mount=MOUNT, opening=0.04, jaw_mass=0.08), dict(mount=MOUNT, opening=0.04,
                                                                                         jaw_mass=0.08))):
        a, b = cs.Robot.from_urdf(UR5, clamp=clamp), cs.robots.add_clamp(arm, **kw)
        for field in ("dh", "com", "masses", "inertias", "q_limits", "tau_limits"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
        assert a.joint_names == b.joint_names
    q = np.r_[np.linspace(-1, 1, 6), 0.02]
    vis = cs.urdf.visuals(a)
    assert vis and {v.link for v in vis} >= {6}
    last = [v for v in vis if v.name == "wrist_3_link"]
    np.testing.assert_allclose(a.frames(q)[6] @ last[0].pose,
                               arm.frames(q[:6])[6] @ cs.urdf.visuals(arm)[-1].pose, atol=1e-14)
    with pytest.raises(ValueError, match="^clamp must be True, False, None or a dict"):
        cs.Robot.from_urdf(UR5, clamp="yes")


@pytest.mark.parametrize("which", list(ARMS))
def test_ik_with_an_opening_reaches_the_pose_with_the_jaw_at_it(which):
    """robot.ik(T, opening=...) on a clamped arm: the numeric solver with the jaw locked at the opening
    reaches poses the arm was put in (to 1e-9) with the jaw at exactly the opening; out of reach, the
    IKError names the robot and the pose; the arm without a clamp refuses an opening."""
    arm = ARMS[which]()
    c = cs.robots.add_clamp(arm, mount=MOUNT)
    rng = np.random.default_rng(11)
    lim = np.clip(c.q_limits[:-1], -2.5, 2.5)
    for opening in (0.0, 0.03, D["opening"]):
        T = c.fk(np.r_[rng.uniform(lim[:, 0], lim[:, 1]), 0.01])
        q, info = c.ik(T, opening=opening, info=True)
        assert info["method"] == "numeric" and q[-1] == opening
        assert np.abs(c.fk(q) - T).max() < 1e-9
        assert np.all(q >= c.q_limits[:, 0]) and np.all(q <= c.q_limits[:, 1])
    far = pose(DOWN, [3.0, 0.5, 0.3])
    with pytest.raises(cs.IKError, match=rf"out of reach.*robot '{c.name}', target TCP position \[3, 0.5, 0.3\] m"):
        c.ik(far, opening=0.03)
    with pytest.raises(cs.IKError, match=r"jaw opening \(joint \d\) = 0.06 m is outside its limits \[0, 0.05\]"):
        c.ik(T, opening=0.06)
    with pytest.raises(ValueError, match="opening applies to robots with a clamp"):
        arm.ik(arm.fk(np.zeros(arm.dof)), opening=0.03)


def test_the_scaras_closed_forms_stay():
    r = cs.robots.scara1()
    T = r.fk(np.array([0.3, 0.5, 0.15, 0.2, np.pi / 2, 0.03]))
    q, info = r.ik(T, opening=0.02, info=True)
    assert info["method"] == "scara1" and q[5] == 0.02


def grip(robot, centre, opening=0.03, he=0.01, q_near=None):
    """Joints putting the clamp pointing down with its fixed jaw 0.2 mm from the side of a body of half
    width `he` (along y) centred at `centre`, the jaws `opening` apart."""
    tcp = np.asarray(centre, dtype=float) + (opening / 2 - he - 2e-4) * DOWN[:, 1]
    return robot.ik(pose(DOWN, tcp), opening=opening, q_near=q_near)


def lift_plan(r, q, lift, close=0.019, dt=(0.02, 0.12, 0.17, 0.67)):
    """A cubic trajectory: hold, close the jaw to `close`, then move the TCP up by `lift` (IK, jaw held)."""
    b = q.copy()
    b[-1] = close
    T = r.fk(b)
    T[2, 3] += lift
    up = r.ik(T, opening=close, q_near=b)
    return cs.CubicTrajectory([0.0, *dt], np.array([q, q, b, b, up]))


def box_world(centre, he, mass):
    """A free box on a thin pedestal (the jaws close around it), gravity on."""
    w = cs.World(gravity=(0, 0, -G))
    w.add_free_box("box", he, mass, pose(np.eye(3), centre), friction=0.5)
    top = centre[2] - he[2]
    w.add_static_box("pedestal", [0.004, 0.004, top / 2], pose(np.eye(3), [centre[0], centre[1], top / 2]),
                     friction=0.5)
    return w


def test_a_clamped_ur5_grasps_and_holds_a_box_at_rest_with_weld_m_g():
    """The UR5 with the clamp closes on a 0.1 kg box by the grasp rule, lifts it 5 cm and holds it: at rest
    the weld carries m g (1e-3 relative) and nothing sideways; the force/torque sensor at the TCP reads
    m g upwards and the weight's moment about the TCP (1e-3 of m g)."""
    # (its collision meshes left out: at this grip the wrist's mesh cuts the pedestal and the clamp's boxes)
    r = cs.Robot.from_urdf(UR5, clamp=True, collision_meshes=False)
    centre, he, m = np.array([0.45, 0.1, 0.25]), np.array([0.02, 0.01, 0.01]), 0.1
    q = grip(r, centre)
    sim = cs.Simulation(dt=2e-4, world=box_world(centre, he, m), log_every=50)
    sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), lift_plan(r, q, 0.05))
    sim.run(1.5, progress=False)
    assert sim.holding(0) == "box"
    assert sim.body_state("box").position[2] > centre[2] + 0.045
    F = sim.weld_wrench(0)
    assert F[2] == pytest.approx(m * G, rel=1e-3)
    assert np.abs(F[:2]).max() < 1e-3 * m * G
    s = sim.sensor(0)
    np.testing.assert_allclose(s.pose, r.fk(sim.state(0)[0]), rtol=0, atol=1e-12)  # the sensor frame: the TCP
    c, p, f = sim.body_state("box").position, s.pose[:3, 3], np.array([0.0, 0.0, m * G])
    np.testing.assert_allclose(s.ft_world, np.r_[f, np.cross(c - p, f)], rtol=0, atol=1e-3 * m * G)


def test_impedance_on_a_clamped_arm_gives_the_commanded_stiffness():
    """cs.Impedance on the clamped UR5 (six arm joints, the jaw held by its own PD): a 2 N push at the TCP
    moves it F / K along the push (0.5 %), the other directions stay (2 %)."""
    r = cs.Robot.from_urdf(UR5, clamp=True, gravity=(0, 0, -G))
    q0 = grip(r, [0.45, 0.1, 0.3])
    K = 200.0
    sim = cs.Simulation(dt=2e-4, log_every=5)
    sim.add_robot(r, cs.Impedance(K, 2 * 0.7 * np.sqrt(K * 2.0), 2.0), cs.SetPoint(q0))
    sim.run(0.2, progress=False)
    before = r.fk(sim.state(0)[0])[:3, 3]
    sim.set_applied(0, wrenches=np.array([0, 2.0, 0, 0, 0, 0]))
    sim.run(2.2, progress=False)
    d = r.fk(sim.state(0)[0])[:3, 3] - before
    assert d[1] == pytest.approx(2.0 / K, rel=5e-3)
    assert np.abs(d[[0, 2]]).max() < 0.02 * 2.0 / K


def test_two_clamped_ur5s_carry_a_bar_under_object_control():
    """Two UR5s with clamps facing each other grip a 0.3 kg bar 0.1 m either side of its centre, lift it
    under computed torque, then cs.ObjectControl holds it: the welds carry m g between them in the commanded
    shares (1 %) with the commanded squeeze."""
    # (collision meshes left out: at these grips the wrists' meshes cut the pedestal and the clamps' boxes)
    a = cs.Robot.from_urdf(UR5, clamp=True, collision_meshes=False)
    b = a.with_base((1.0, 0.0, 0.0), np.pi)
    centre, he, m = np.array([0.5, 0.0, 0.25]), np.array([0.175, 0.01, 0.01]), 0.3
    sim = cs.Simulation(dt=2e-4, world=box_world(centre, he, m), log_every=10)
    for r, x in ((a, -0.1), (b, 0.1)):
        sim.add_robot(r, cs.ComputedTorque(400.0, 40.0), lift_plan(r, grip(r, centre + [x, 0, 0]), 0.03))
    sim.run(1.0, progress=False)
    assert sim.holding(0) == "box" and sim.holding(1) == "box"
    for i in (0, 1):
        sim.set_reference(i, cs.SetPoint(sim.state(i)[0]))
    c = cs.ObjectControl(m, cs.box_inertia(m, *(2 * he)), load_share=0.6, squeeze=2.0)
    sim.add_cooperative(c, [0, 1])
    sim.run(3.0, progress=False)
    co = sim.log.cooperation(0, 1)
    np.testing.assert_allclose(co["load_share"][-1], [0.6, 0.4], rtol=0.01)
    assert co["squeeze"][-1] == pytest.approx(2.0, rel=0.01)
    assert sim.weld_wrench(0)[2] + sim.weld_wrench(1)[2] == pytest.approx(m * G, rel=1e-3)
    # the last update (at the state the run ended in), at the TCPs p0, p1: the clamps' wrenches are the
    # least-norm solution of the distribution (arms that command all six directions take it through the Gram
    # matrix): it meets the force, share and squeeze rows, and lies in the rows' span: both clamps take the
    # same moment m, and f0 - f1 - m x (p0 - p1) lies in the plane of the vertical and the line p0 -> p1
    (f0, m0), (f1, m1) = [(w[:3], w[3:]) for w in c.clamp_wrenches]
    p0, p1 = [r.fk(sim.state(i)[0])[:3, 3] for i, r in enumerate((a, b))]
    e, z = (p1 - p0) / np.linalg.norm(p1 - p0), np.array([0.0, 0.0, 1.0])
    n = np.cross(z, e) / np.linalg.norm(np.cross(z, e))
    np.testing.assert_allclose(f0 + f1, c.object_wrench[:3], rtol=0, atol=1e-12)
    assert 0.4 * f0[2] - 0.6 * f1[2] == pytest.approx(0.0, abs=1e-12)
    assert 0.5 * e @ (f0 - f1) == pytest.approx(2.0, abs=1e-12)
    np.testing.assert_allclose(m0, m1, rtol=0, atol=1e-12)
    assert abs(n @ (f0 - f1 - np.cross(m0, p0 - p1))) < 1e-12


@pytest.mark.parametrize("call,match", [
    (lambda arm: cs.robots.add_clamp(cs.robots.scara1()), r"^robot 'scara1' already has a clamp"),
    (lambda arm: cs.robots.add_clamp(cs.robots.add_clamp(arm)), r"^robot 'ur5' already has a clamp"),
    (lambda arm: cs.robots.add_clamp(arm, mount=2 * np.eye(4)), r"^mount must be a (rigid|homogeneous) transform"),
    (lambda arm: cs.robots.add_clamp(arm, mount=np.diag([1.0, 1, -1, 1])), r"^mount must be a rigid transform"),
    (lambda arm: cs.robots.add_clamp(arm, mount=np.eye(3)), r"^.*mount.*\(4, 4\)"),
    (lambda arm: cs.robots.add_clamp(arm, mount=np.full((4, 4), np.nan)), r"^mount must be finite"),
    (lambda arm: cs.robots.add_clamp(arm, jaw_length=-0.04), r"^jaw_length must be finite and > 0 m, got -0.04"),
    (lambda arm: cs.robots.add_clamp(arm, opening=0.0), r"^opening must be finite and > 0 m, got 0"),
    (lambda arm: cs.robots.add_clamp(arm, jaw_mass=0.0), r"^jaw_mass must be finite and > 0 kg, got 0"),
    (lambda arm: cs.robots.add_clamp(arm, body_mass=float("nan")), r"^body_mass must be finite and >= 0 kg"),
    (lambda arm: cs.robots.add_clamp(arm, width="wide"), r"^width must be"),
    (lambda arm: cs.robots.add_clamp("ur5"), r"^robot must be a coopsim.Robot, got str"),
])
def test_bad_input_is_one_line_naming_what_is_wrong(call, match):
    arm = cs.Robot.from_urdf(UR5)
    with pytest.raises(ValueError, match=match) as e:
        call(arm)
    assert "\n" not in str(e.value)


def test_unknown_keywords_are_named():
    with pytest.raises(TypeError, match=r"unknown keyword\(s\) \['jaw_width'\]"):
        cs.robots.add_clamp(cs.Robot.from_urdf(UR5), jaw_width=0.05)


def test_plan_cartesian_takes_an_opening_on_a_clamped_arm():
    """cs.plan_cartesian(..., opening=...) on a clamped UR5: every knot reached with the jaw at the opening
    interpolated between the poses'; the arm without a clamp refuses an opening, naming itself."""
    arm = ARMS["ur5"]()
    c = cs.robots.add_clamp(arm, mount=MOUNT)
    q0 = np.r_[0.3, -1.2, 1.5, -1.9, -1.5, 0.2, 0.02]
    T0 = c.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.05, -0.03, 0.04]
    traj, info = cs.plan_cartesian(c, [T0, T1], [0.0, 1.0], opening=[0.03, 0.01], q_start=q0, intermediate=4,
                                   info=True)
    for t, T in zip(info["times"], info["poses"]):
        q = traj.evaluate(t)[0]
        assert np.abs(c.fk(q) - T).max() < 1e-8
    assert traj.evaluate(0.0)[0][-1] == pytest.approx(0.03, abs=1e-12)
    assert traj.evaluate(1.0)[0][-1] == pytest.approx(0.01, abs=1e-12)
    with pytest.raises(ValueError, match=rf"opening applies to a robot with a clamp; robot '{arm.name}' has none"):
        cs.plan_cartesian(arm, [arm.fk(np.zeros(arm.dof))] * 2, [0.0, 1.0], opening=0.03)
