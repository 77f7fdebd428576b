"""URDF import: round trips of our own export, real robots nobody here wrote (the UR5 and the
Panda of the example-robot-data wheel) against Pinocchio loading the same file, general joint
origins and axes, the URDF's damping, friction and rotor inertia, and clear errors."""
from __future__ import annotations

import importlib.metadata
import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import coopsim as cs
from conftest import random_fleet, random_state


def example_robot_data(relative: str) -> str:
    """Path of a file shipped in the example-robot-data wheel (PyPI), e.g. 'ur_description/urdf/ur5_robot.urdf'."""
    for f in importlib.metadata.files("example-robot-data"):
        if str(f).endswith("robots/" + relative):
            return str(f.locate())
    raise FileNotFoundError(relative)


UR5 = example_robot_data("ur_description/urdf/ur5_robot.urdf")
PANDA = example_robot_data("panda_description/urdf/panda.urdf")
PANDA_FINGERS = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}

ROUND_TRIP = [cs.robots.scara1(backend="numeric"), cs.robots.scara2(backend="numeric")] + random_fleet()


def _rel(x, y):
    return np.abs(np.asarray(x) - np.asarray(y)).max() / max(1.0, np.abs(y).max())


@pytest.mark.parametrize("robot", ROUND_TRIP, ids=[r.name for r in ROUND_TRIP])
def test_round_trip_same_dynamics_and_kinematics(robot):
    """Exported and imported back: M, C, G, FD, ID, the flange pose (the imported tool: a URDF
    has no frame for the SCARAs' TCP between two jaws) and Jacobians of every CoM and of the
    flange agree to 1e-12; limits, damping, masses and boxes come back too."""
    back = cs.Robot.from_urdf(robot.to_urdf())
    assert back.joint_types == robot.joint_types and back.name == robot.name
    np.testing.assert_array_equal(back.q_limits, robot.q_limits)
    np.testing.assert_array_equal(back.friction_coefficients, robot.friction_coefficients)
    np.testing.assert_array_equal(back.masses, robot.masses)
    assert sorted(b.name for b in back.boxes) == sorted(b.name for b in robot.boxes)
    rng = np.random.default_rng(len(robot.name))
    for _ in range(4):
        q, qd, qdd = random_state(robot, rng)
        tau = rng.normal(size=robot.dof) * 3
        checks = {
            "M": (back.mass_matrix(q), robot.mass_matrix(q)),
            "C": (back.coriolis(q, qd), robot.coriolis(q, qd)),
            "C_matrix": (back.coriolis_matrix(q, qd), robot.coriolis_matrix(q, qd)),
            "G": (back.gravity(q), robot.gravity(q)),
            "FD": (back.forward_dynamics(q, qd, tau), robot.forward_dynamics(q, qd, tau)),
            "ID": (back.inverse_dynamics(q, qd, qdd), robot.inverse_dynamics(q, qd, qdd)),
            "FK": (back.fk(q), robot.frames(q)[-1]),
            "J_tool": (back.tool_jacobian(q), robot.jacobian(q, -1)),
            "J_com": ([back.jacobian(q, i + 1, back.com_positions[i]) for i in range(robot.dof)],
                      [robot.jacobian(q, i + 1, robot.com_positions[i]) for i in range(robot.dof)]),
            "CoM": (back.com_frames(q)[:, :3, 3], robot.com_frames(q)[:, :3, 3]),
        }
        for k, (x, y) in checks.items():
            assert _rel(x, y) <= 1e-12, (k, _rel(x, y))
        order = {b.name: i for i, b in enumerate(back.boxes)}
        idx = [order[b.name] for b in robot.boxes]
        assert _rel(back.shapes(q)[0][idx], robot.shapes(q)[0]) <= 1e-12


def test_round_trip_armature_and_friction():
    """Armature through the transmission's drake:rotor_inertia, Coulomb through dynamics friction."""
    r = cs.robots.scara1(backend="numeric")
    Ia, Fc = np.array([0.05, 0.03, 0.8, 0.004, 0.0, 0.3]), np.array([1.5, 0.0, 6.0, 0.1, 0.05, 2.0])
    r = cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, r.joint_types, friction=r.friction_coefficients,
                         q_limits=r.q_limits, armature=Ia, coulomb=Fc)
    text = r.to_urdf()
    assert 'xmlns:drake="http://drake.mit.edu"' in text and text.count("<transmission") == 5
    back = cs.Robot.from_urdf(text, coulomb_width=r.coulomb_width[0])
    np.testing.assert_array_equal(back.armature, Ia)
    np.testing.assert_array_equal(back.coulomb, Fc)
    q, qd, qdd = np.full(6, 0.1), np.linspace(-1, 1, 6), np.ones(6)
    assert _rel(back.inverse_dynamics(q, qd, qdd), r.inverse_dynamics(q, qd, qdd)) <= 1e-12
    # a gear ratio multiplies the rotor's inertia by its square; the prefix need not be declared
    g = text.replace('<drake:gear_ratio value="1.0"/>', '<drake:gear_ratio value="3.0"/>')
    g = g.replace(' xmlns:drake="http://drake.mit.edu"', "")
    np.testing.assert_allclose(cs.Robot.from_urdf(g).armature, 9 * Ia, rtol=1e-15)


def _pin_model(path, locked=()):
    m = pin.buildModelFromUrdf(path)
    if locked:
        m = pin.buildReducedModel(m, [m.getJointId(j) for j in locked], pin.neutral(m))
    return m


@pytest.mark.parametrize("which", ["ur5", "panda"])
def test_real_robots_against_pinocchio(which):
    """The UR5 and the Panda arm as shipped in example-robot-data (the Panda's fingers locked at 0,
    as Pinocchio's reduced model holds them): M, nonlinear effects C qd + G and forward dynamics
    (Pinocchio's ABA) agree to 1e-10 relative at random states."""
    path, locked = (UR5, {}) if which == "ur5" else (PANDA, PANDA_FINGERS)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # these tensors keep the triangle inequality
        r = cs.Robot.from_urdf(path, locked=locked)
    assert r.dof == (6 if which == "ur5" else 7) and r.joint_types == "R" * r.dof
    m = _pin_model(path, locked)
    d = m.createData()
    lim = np.clip(r.q_limits, -np.pi, np.pi)
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(lim[:, 0], lim[:, 1])
        qd, tau = rng.normal(size=r.dof) * 2, rng.normal(size=r.dof) * 10
        Mp = pin.crba(m, d, q)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        assert _rel(r.mass_matrix(q), Mp) <= 1e-10
        h = pin.nonLinearEffects(m, d, q, qd)
        assert _rel(r.coriolis(q, qd) + r.gravity(q), h) <= 1e-10
        # the URDF's damping is our viscous K; Pinocchio's ABA leaves it out
        a = pin.aba(m, d, q, qd, tau)
        assert _rel(r.forward_dynamics(q, qd, tau + r.friction(qd)), a) <= 1e-10
        # the tool is the tip link's frame
        tip = "wrist_3_link" if which == "ur5" else "panda_hand"
        pin.framesForwardKinematics(m, d, q)
        # (1e-10: the import reads the UR5's 1.57079632679 as pi/2, see test_snap_...)
        assert _rel(r.fk(q), d.oMf[m.getFrameId(tip)].homogeneous) <= 1e-10


def test_panda_tip_and_cut_fingers():
    """tip= ends the chain at a link; movable joints off the path (the fingers) are cut with their
    links, locked ones are merged with their mass; without either, the branching is an error."""
    with pytest.raises(ValueError, match="branch .*tip=.*locked="):
        cs.Robot.from_urdf(PANDA)
    cut = cs.Robot.from_urdf(PANDA, tip="panda_hand_tcp")
    kept = cs.Robot.from_urdf(PANDA, locked=PANDA_FINGERS)
    np.testing.assert_allclose(kept.masses[-1] - cut.masses[-1], 2 * 0.015, rtol=1e-12)  # two fingers
    np.testing.assert_array_equal(kept.masses[:-1], cut.masses[:-1])
    q = np.linspace(-1, 1, 7)
    # the TCP lies 0.1034 m along the hand's z
    np.testing.assert_allclose(cut.fk(q), kept.fk(q) @ cs.dh_transform(0, 0.1034, 0, 0), atol=1e-15)
    ur5_tool = cs.Robot.from_urdf(UR5, tip="tool0")
    m = _pin_model(UR5)
    d = m.createData()
    pin.framesForwardKinematics(m, d, q[:6])
    np.testing.assert_allclose(ur5_tool.fk(q[:6]), d.oMf[m.getFrameId("tool0")].homogeneous, atol=1e-10)


GENERAL = """<?xml version="1.0"?>
<robot name="bent">
  <link name="ground"><inertial><mass value="9"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <joint name="mount" type="fixed"><parent link="ground"/><child link="plate"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.2 0.7"/></joint>
  <link name="plate"/>
  <joint name="j1" type="revolute"><parent link="plate"/><child link="a"/>
    <origin xyz="0.05 0.02 0.1" rpy="0.4 0.1 -0.3"/><axis xyz="0.2 -1 0.3"/>
    <limit lower="-2" upper="2.5" effort="40" velocity="2"/><dynamics damping="0.4" friction="0.7"/></joint>
  <link name="a"><inertial><origin xyz="0.1 0.02 -0.05" rpy="0.5 0.2 0.1"/><mass value="2.5"/>
    <inertia ixx="0.03" ixy="0.001" ixz="-0.002" iyy="0.04" iyz="0.003" izz="0.05"/></inertial></link>
  <joint name="j2" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="0.3 0.1 -0.05" rpy="-0.6 0.3 1.1"/><axis xyz="0 0 -1"/>
    <limit lower="-0.1" upper="0.4" effort="300" velocity="1"/></joint>
  <link name="b"><inertial><origin xyz="0.0 0.05 0.2"/><mass value="1.2"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.025" iyz="0" izz="0.01"/></inertial></link>
  <joint name="j3" type="continuous"><parent link="b"/><child link="c"/>
    <origin xyz="0 0.2 0.25" rpy="1.2 0 0"/><axis xyz="1 0 0"/></joint>
  <link name="c"><inertial><origin xyz="0.15 0 0"/><mass value="0.8"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="j4" type="revolute"><parent link="c"/><child link="d"/>
    <origin xyz="0.3 0 0"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <link name="d"><inertial><origin xyz="0.05 0.01 0"/><mass value="0.3"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
  <joint name="tip_fixed" type="fixed"><parent link="d"/><child link="tip"/><origin xyz="0.1 0 0.02" rpy="0 0.5 0"/></joint>
  <link name="tip"><inertial><origin xyz="0.01 0 0"/><mass value="0.2"/>
    <inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0001" iyz="0" izz="0.0001"/></inertial></link>
</robot>
"""


def _pin_general():
    m = pin.buildModelFromXML(GENERAL)
    return m, m.createData()


def _pin_q(m, q):
    """Pinocchio's configuration for our q: (cos, sin) for the continuous joint j3."""
    out = []
    for j, v in zip(m.joints[1:], q):
        out += [math.cos(v), math.sin(v)] if j.nq == 2 else [v]
    return np.array(out)


def test_general_origins_axes_and_tilted_first_axis_against_pinocchio():
    """Joint origins with any rpy, axes in any direction (a tilted first axis: a base
    orientation; a prismatic axis along -z), a continuous joint (Pinocchio: nq = 2) and fixed
    links merged: M, C qd + G, ABA and the tip's pose agree with Pinocchio to 1e-12."""
    r = cs.Robot.from_urdf(GENERAL)
    assert r.joint_types == "RPRR" and r.name == "bent"
    assert not np.allclose(r.base_orientation, np.eye(3))
    np.testing.assert_array_equal(r.q_limits, [[-2, 2.5], [-0.1, 0.4], [-np.inf, np.inf], [-1, 1]])
    np.testing.assert_array_equal(r.tau_limits, [40, 300, np.inf, 10])
    np.testing.assert_array_equal(r.friction_coefficients, [0.4, 0, 0, 0])
    np.testing.assert_array_equal(r.coulomb, [0.7, 0, 0, 0])
    assert [b.link for b in r.boxes] == [0]  # the ground's box, on the base
    np.testing.assert_allclose(r.masses, [2.5, 1.2, 0.8, 0.5])
    m, d = _pin_general()
    rng = np.random.default_rng(2)
    for _ in range(20):
        q, qd, _ = random_state(r, rng)
        tau = rng.normal(size=4) * 3
        pq = _pin_q(m, q)
        Mp = pin.crba(m, d, pq)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        assert _rel(r.mass_matrix(q), Mp) <= 1e-12
        assert _rel(r.coriolis(q, qd) + r.gravity(q), pin.nonLinearEffects(m, d, pq, qd)) <= 1e-12
        assert _rel(r.forward_dynamics(q, qd, tau + r.friction(qd)), pin.aba(m, d, pq, qd, tau)) <= 1e-12
        pin.framesForwardKinematics(m, d, pq)
        assert _rel(r.fk(q), d.oMf[m.getFrameId("tip")].homogeneous) <= 1e-12


@pytest.mark.slow  # sympy and g++: about 15 s
def test_generated_dynamics_for_an_imported_robot(tmp_path):
    """codegen.compile builds closed-form dynamics for an imported robot; they equal the numeric
    backend's (which equals Pinocchio's above)."""
    from coopsim import codegen

    r = cs.Robot.from_urdf(GENERAL)
    g = codegen.compile(r, cache=tmp_path)
    assert g.backend == "generated"
    rng = np.random.default_rng(4)
    for _ in range(10):
        q, qd, qdd = random_state(r, rng)
        tau = rng.normal(size=4)
        assert _rel(g.mass_matrix(q), r.mass_matrix(q)) <= 1e-12
        assert _rel(g.inverse_dynamics(q, qd, qdd), r.inverse_dynamics(q, qd, qdd)) <= 1e-12
        assert _rel(g.forward_dynamics(q, qd, tau), r.forward_dynamics(q, qd, tau)) <= 1e-10


def _joint(name, kind, parent, child, extra=""):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<axis xyz="0 0 1"/>{extra}</joint>')


def _urdf(*parts, links=("a", "b", "c")):
    body = "".join(f'<link name="{ln}"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" '
                   f'iyz="0" izz="0.01"/></inertial></link>' for ln in links)
    return f'<robot name="t">{body}{"".join(parts)}</robot>'


@pytest.mark.parametrize("text,match", [
    ("<robot><link name=\"a\"></robot>", "not well-formed XML"),
    ("<model/>", "not URDF"),
    (_urdf(_joint("j", "floating", "a", "b"), _joint("k", "revolute", "b", "c")), "floating bases"),
    (_urdf(_joint("j", "planar", "a", "b")), "planar"),
    (_urdf(_joint("j", "spherical", "a", "b")), "unsupported type 'spherical'"),
    (_urdf(_joint("j", "revolute", "a", "b"), _joint("k", "revolute", "a", "c")), "branch"),
    (_urdf(_joint("j", "revolute", "a", "b"), _joint("k", "revolute", "b", "c"), _joint("l", "fixed", "a", "c")),
     "closed loop"),
    (_urdf(_joint("j", "revolute", "a", "b")), "exactly one root link"),
    (_urdf(_joint("j", "fixed", "a", "b"), _joint("k", "fixed", "b", "c")), "no movable joint"),
    (_urdf(_joint("j", "revolute", "a", "b"), _joint("k", "revolute", "b", "c", '<mimic joint="j"/>')), "mimic"),
    (_urdf(_joint("j", "revolute", "a", "b", '<limit lower="1" upper="0" effort="1" velocity="1"/>'),
           _joint("k", "revolute", "b", "c")), "lower must be below upper"),
    (_urdf(_joint("j", "revolute", "a", "x"), _joint("k", "revolute", "b", "c")), "must name a parent and a child"),
])
def test_import_errors_are_clear(text, match):
    with pytest.raises(ValueError, match=match):
        cs.Robot.from_urdf(text)


@pytest.mark.parametrize("text", [
    _urdf(_joint("j", "revolute", "a", "b"), _joint("k", "revolute", "c", "c")),  # a joint from a link to itself
    _urdf(_joint("j", "revolute", "a", "d"), _joint("k", "revolute", "b", "c"), _joint("l", "revolute", "c", "b"),
          links=("a", "b", "c", "d")),  # a loop of two joints apart from the chain
])
@pytest.mark.parametrize("tip", [None, "b", "c"])
def test_a_cycle_of_joints_apart_from_the_root_is_an_error_not_a_hang(text, tip):
    """Every link but the root has one parent, so a link the root does not reach hangs from a cycle
    of joints: following its parents never ended (from_urdf hung; found by fuzzing)."""
    with pytest.raises(ValueError, match=r"form a closed loop \(a cycle of links\) apart from the root 'a'"):
        cs.Robot.from_urdf(text, tip=tip)


def test_import_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="no file"):
        cs.Robot.from_urdf(str(tmp_path / "missing.urdf"))
    with pytest.raises(ValueError, match="source must be URDF text or a path"):
        cs.Robot.from_urdf(42)
    with pytest.raises(ValueError, match="tip: no link named 'nowhere'"):
        cs.Robot.from_urdf(UR5, tip="nowhere")
    with pytest.raises(ValueError, match="locked: 'ee_fixed_joint' is not a movable joint"):
        cs.Robot.from_urdf(UR5, locked={"ee_fixed_joint": 0.0})
    path = tmp_path / "ur5.urdf"
    path.write_text(Path(UR5).read_text())
    # a PathLike too (the copy's package:// collision meshes are not found from tmp_path: not read)
    assert cs.Robot.from_urdf(path, collision_meshes=False).dof == 6


SCARA1 = cs.robots.scara1().to_urdf()


@pytest.mark.parametrize("old, new, match", [
    # inf in an inertia went through numpy's matmul (a RuntimeWarning) into NaN inertias
    ('ixx="0.0012999999999999997"', 'ixx="inf"', r"link 'link1' inertia: ixx must be finite and at most 1e\+12"),
    # huge finite numbers overflowed in the frame changes, or were taken as a 1e300 kg link
    ('ixx="0.0012999999999999997"', 'ixx="1e308"', r"ixx must be finite and at most 1e\+12"),
    ('<mass value="2.2"/>', '<mass value="1e300"/>', r"link 'link2' inertial mass: value must be finite and at most"),
    ('<origin xyz="0.3 0.0 0.42"', '<origin xyz="1e300 0.0 0.42"',
     r"joint 'joint2' origin xyz: numbers must be at most 1e\+12 in magnitude"),
    ('damping="0.8"', 'damping="-inf"', r"joint 'joint2': damping must be finite"),  # was the engine's "friction"
])
def test_import_refuses_numbers_too_large_to_compute_with(old, new, match):
    assert old in SCARA1
    with pytest.raises(ValueError, match=match):
        cs.Robot.from_urdf(SCARA1.replace(old, new))


def test_import_reads_infinite_or_huge_limits_and_efforts_as_none():
    text = SCARA1.replace('lower="-2.530727415391778" upper="2.530727415391778" effort="20.0"',
                          'lower="-inf" upper="1e300" effort="inf"')
    r = cs.Robot.from_urdf(text)
    assert np.all(np.isinf(r.q_limits[1])) and np.isinf(r.tau_limits[1])


@pytest.mark.parametrize("kw, match", [
    (dict(snap="a"), "snap must be in"), (dict(snap=None), "snap must be in"), (dict(snap=np.nan), "snap must be in"),
    (dict(tip=5), r"tip must be the name of a link \(str\) or None, got int"),
    (dict(tip=["link3"]), "tip must be the name of a link"),
    (dict(locked=["joint6"]), r"locked must be a dict \{joint name: position\}, got list"),
    (dict(locked={"joint6": "a"}), r"locked: the position of 'joint6' must be a finite number \(rad or m\), got 'a'"),
    (dict(locked={"joint6": None}), "locked: the position of 'joint6' must be a finite number"),
    (dict(locked={"joint6": 1e300}), "locked: the position of 'joint6' must be a finite number"),
])
def test_import_arguments_name_what_is_wrong(kw, match):
    # these gave float()'s "could not convert string to float: 'a'", a TypeError, "unhashable type:
    # 'list'" or dict()'s "dictionary update sequence element #0 ...", none naming the argument
    with pytest.raises(ValueError, match=match):
        cs.Robot.from_urdf(SCARA1, **kw)


def test_text_that_no_xml_holds_is_a_clear_error(tmp_path):
    # a lone surrogate gave the parser's UnicodeEncodeError, a file that is not UTF-8 the
    # UnicodeDecodeError of open(), naming neither the source nor the file
    with pytest.raises(ValueError, match="source is not well-formed XML"):
        cs.Robot.from_urdf('<robot name="\udcff"/>')
    path = tmp_path / "latin1.urdf"
    path.write_bytes(SCARA1.replace('name="scara1"', 'name="scara\xe9"').encode("latin-1"))
    with pytest.raises(ValueError, match=f"the file '{path}' is not UTF-8 text"):
        cs.Robot.from_urdf(path)


def test_snap_reads_eleven_digit_right_angles():
    """The UR5's URDF writes pi/2 as 1.57079632679: read as pi/2 by default (snap = 1e-9 rad), so
    the DH and CoM angles come out as exact multiples of pi/2 (CoMs on their axes, to rounding,
    have none); snap=0 reads the angles as written. Both equal Pinocchio's dynamics to 1e-10."""
    exact, raw = cs.Robot.from_urdf(UR5), cs.Robot.from_urdf(UR5, snap=0.0)
    for angles in (exact.dh[:, [0, 3]], exact.com[:, [0, 3]]):
        k = angles / (np.pi / 2)
        assert np.abs(k - np.round(k)).max() <= 1e-12  # structural for generated code (codegen.exact_angle)
    assert np.abs(raw.dh[:, [0, 3]] / (np.pi / 2) - np.round(raw.dh[:, [0, 3]] / (np.pi / 2))).max() > 1e-12
    m = _pin_model(UR5)
    d = m.createData()
    q, qd = np.linspace(-1, 1, 6), np.linspace(0.5, -0.5, 6)
    for r in (exact, raw):
        assert _rel(r.mass_matrix(q), _full_pin(pin.crba(m, d, q))) <= 1e-10
        assert _rel(r.coriolis(q, qd) + r.gravity(q), pin.nonLinearEffects(m, d, q, qd)) <= 1e-10
    with pytest.raises(ValueError, match="snap must be in"):
        cs.Robot.from_urdf(UR5, snap=-1.0)


def _full_pin(A):
    return np.triu(A) + np.triu(A, 1).T


def test_com_on_the_axis_to_rounding_has_no_angle():
    """A CoM off its joint axis by rounding noise only (1e-17 m) is on the axis: a_c = 0 and the
    CoM row's theta is the DH row's, not an angle of the noise (axis z0 is y of frame 1 here)."""
    dh = np.array([[0.3, 0.1, 0.0, np.pi / 2], [0.0, 0.0, 0.4, 0.0]])
    com = np.array([[1e-17, 0.05, -2e-17], [-0.2, 0.0, 0.0]])
    r = cs.Robot.from_dh(dh, com, [1.0, 2.0], np.array([np.eye(3) * 0.01] * 2), "RR")
    np.testing.assert_array_equal(r.com[:, 2], [0.0, 0.2])
    np.testing.assert_array_equal(r.com[:, 0], [0.3, 0.0])


# ------------------------------------------------------------ names and placeholder limits

def test_urdf_robots_keep_their_joint_and_link_names_in_the_order_of_q():
    """q[i] is the joint named joint_names[i]: Pinocchio's order of the same file (its q), and the
    link each joint moves is the body Pinocchio hangs on that joint."""
    for path, locked in ((UR5, ()), (PANDA, ("panda_finger_joint1", "panda_finger_joint2"))):
        r = cs.Robot.from_urdf(path, locked={j: 0.0 for j in locked})
        m = _pin_model(path, locked)
        assert r.joint_names == list(m.names)[1:]
        for i, link in enumerate(r.link_names):
            f = m.frames[m.getFrameId(link)]
            assert f.type == pin.FrameType.BODY and f.parentJoint == i + 1, (link, i)
    ur5 = cs.Robot.from_urdf(UR5)
    assert ur5.joint_names[:3] == ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint"]
    assert ur5.link_names[0] == "shoulder_link" and ur5.link_names[-1] == "wrist_3_link"
    # moving joint i alone moves link i and what follows, never the links before it
    q = np.zeros(6)
    q[2] = 0.7
    moved = [not np.allclose(a, b) for a, b in zip(ur5.frames(np.zeros(6)), ur5.frames(q))]
    assert moved[ur5.link_names.index("forearm_link") + 1] and not moved[ur5.link_names.index("upper_arm_link") + 1]


def test_robots_from_tables_have_default_names_and_copies_keep_names():
    import pickle

    r = cs.robots.scara1()
    assert r.joint_names == [f"joint{i}" for i in range(1, 7)] and r.link_names == [f"link{i}" for i in range(1, 7)]
    ur5 = cs.Robot.from_urdf(UR5)
    for copy in (ur5.with_base((0.1, 0.2, 0.0), 0.3), ur5.with_gravity((0, 0, -1.0)), ur5.with_backend("numeric"),
                 ur5.with_base_orientation(np.eye(3)), ur5.with_geometry(ur5.boxes, None),
                 pickle.loads(pickle.dumps(ur5))):
        assert copy.joint_names == ur5.joint_names and copy.link_names == ur5.link_names
    sim = cs.Simulation()
    sim.add_robot(ur5, cs.PID(1.0, 0.0, 0.1), np.zeros(6))
    assert sim.robots[0].joint_names == ur5.joint_names
    # the export writes the names, so a round trip keeps them
    back = cs.Robot.from_urdf(ur5.to_urdf())
    assert back.joint_names == ur5.joint_names and back.link_names == ur5.link_names
    named = r.with_names([f"j{i}" for i in range(6)], [f"l{i}" for i in range(6)])
    assert named.joint_names[0] == "j0" and named.link_names[5] == "l5" and r.joint_names[0] == "joint1"
    with pytest.raises(ValueError, match="joint_names must hold 6 names, got 2"):
        r.with_names(["a", "b"], r.link_names)
    with pytest.raises(ValueError, match="link_names must be unique: 'x' appears twice"):
        r.with_names(r.joint_names, ["x"] * 6)
    with pytest.raises(ValueError, match=r"joint_names\[0\] must not be empty"):
        r.with_names([""] + r.joint_names[1:], r.link_names)


def test_names_the_export_needs_for_its_own_frames_fall_back_to_the_defaults():
    r = cs.robots.scara1().with_names([f"j{i}" for i in range(6)], ["world"] + [f"l{i}" for i in range(5)])
    back = cs.Robot.from_urdf(r.to_urdf())
    assert back.joint_names == [f"j{i}" for i in range(6)] and back.link_names == [f"link{i}" for i in range(1, 7)]


# what CAD exporters write for a joint they know no limits of
PLACEHOLDER = '<limit lower="0" upper="0" effort="0" velocity="0"/>'


def test_placeholder_limits_are_refused_naming_the_joint_the_values_and_the_option():
    old = 'lower="-2.530727415391778" upper="2.530727415391778" effort="20.0" velocity="1000.0"/>'
    assert SCARA1.count(old) == 1
    text = SCARA1.replace("<limit " + old, PLACEHOLDER)
    with pytest.raises(ValueError, match=r"joint 'joint2': its <limit> has lower = upper = 0 \(effort 0\).*"
                                         r"placeholder.*limits='ignore'"):
        cs.Robot.from_urdf(text)
    # lower above upper is refused too, pointing at the option
    with pytest.raises(ValueError, match="lower must be below upper.*limits='ignore'"):
        cs.Robot.from_urdf(SCARA1.replace("<limit " + old, '<limit lower="1" upper="-1" effort="1" velocity="1"/>'))
    with pytest.raises(ValueError, match="limits must be 'file' or 'ignore', got 'none'"):
        cs.Robot.from_urdf(text, limits="none")


def test_limits_ignore_loads_a_cad_export_without_limits_and_with_the_same_dynamics():
    # a hand-written chain as a CAD exporter writes it: every joint with placeholder limits
    links = "".join(f'<link name="{ln}"><inertial><origin xyz="0.1 0 0"/><mass value="{m}"/>'
                    f'<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>'
                    for ln, m in (("base", 1.0), ("upper", 2.0), ("lower", 1.5), ("slider", 0.5)))
    joints = "".join(f'<joint name="{jn}" type="{kind}"><parent link="{p}"/><child link="{c}"/>'
                     f'<origin xyz="{x} 0 0.1"/><axis xyz="{ax}"/>{PLACEHOLDER}</joint>'
                     for jn, kind, p, c, x, ax in (("shoulder", "revolute", "base", "upper", 0.0, "0 0 1"),
                                                   ("elbow", "revolute", "upper", "lower", 0.3, "0 1 0"),
                                                   ("slide", "prismatic", "lower", "slider", 0.25, "1 0 0")))
    text = f'<robot name="cad">{links}{joints}</robot>'
    with pytest.raises(ValueError, match="joint 'shoulder'.*limits='ignore'"):
        cs.Robot.from_urdf(text)
    r = cs.Robot.from_urdf(text, limits="ignore")
    assert r.joint_types == "RRP" and r.joint_names == ["shoulder", "elbow", "slide"]
    assert r.link_names == ["upper", "lower", "slider"]
    assert np.all(np.isinf(r.q_limits)) and np.all(np.isinf(r.tau_limits))
    # the same file with real limits: the same dynamics, only the limits differ
    real = cs.Robot.from_urdf(text.replace(PLACEHOLDER, '<limit lower="-1" upper="1" effort="5" velocity="1"/>'))
    np.testing.assert_array_equal(real.q_limits, np.tile([-1.0, 1.0], (3, 1)))
    q, qd = np.array([0.3, -0.4, 0.05]), np.array([0.2, 0.1, -0.3])
    np.testing.assert_array_equal(r.mass_matrix(q), real.mass_matrix(q))
    np.testing.assert_array_equal(r.inverse_dynamics(q, qd, qd), real.inverse_dynamics(q, qd, qd))
    # limits='ignore' on a file with real limits drops them too
    assert np.all(np.isinf(cs.Robot.from_urdf(UR5, limits="ignore").q_limits))
