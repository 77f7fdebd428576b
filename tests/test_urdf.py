"""URDF export: parses as XML, carries the same masses, inertias, axes and
limits, and its kinematic chain reproduces the robot's frames."""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import coopsim as cs
from conftest import random_robot


def rpy_matrix(r, p, y):
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return Rz @ Ry @ Rx


def origin(el):
    o = el.find("origin")
    T = np.eye(4)
    if o is not None:
        T[:3, 3] = [float(v) for v in o.get("xyz", "0 0 0").split()]
        T[:3, :3] = rpy_matrix(*[float(v) for v in o.get("rpy", "0 0 0").split()])
    return T


def urdf_link_frames(root, q):
    """World pose of every link by walking the joints (a serial chain)."""
    poses = {"world": np.eye(4)}
    joints = {j.find("child").get("link"): j for j in root.findall("joint")}
    qi = {f"joint{i + 1}": v for i, v in enumerate(q)}

    def pose(link):
        if link in poses:
            return poses[link]
        j = joints[link]
        T = pose(j.find("parent").get("link")) @ origin(j)
        if j.get("type") in ("revolute", "continuous"):
            c, s = math.cos(qi[j.get("name")]), math.sin(qi[j.get("name")])
            T = T @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
        elif j.get("type") == "prismatic":
            T = T @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, qi[j.get("name")]], [0, 0, 0, 1]])
        poses[link] = T
        return T

    for link in root.findall("link"):
        pose(link.get("name"))
    return poses


ROBOTS = [cs.robots.scara1(), cs.robots.scara2(), random_robot(7, dof=5), random_robot(8, dof=7)]


@pytest.mark.parametrize("robot", ROBOTS, ids=[r.name for r in ROBOTS])
def test_urdf_carries_same_parameters(robot):
    root = ET.fromstring(robot.to_urdf())
    assert root.tag == "robot" and root.get("name") == robot.name
    n = robot.dof
    for i in range(n):
        link = root.find(f"link[@name='link{i + 1}']")
        inertial = link.find("inertial")
        assert float(inertial.find("mass").get("value")) == robot.masses[i]
        I = inertial.find("inertia")
        got = np.array([[float(I.get("ixx")), float(I.get("ixy")), float(I.get("ixz"))],
                        [float(I.get("ixy")), float(I.get("iyy")), float(I.get("iyz"))],
                        [float(I.get("ixz")), float(I.get("iyz")), float(I.get("izz"))]])
        np.testing.assert_array_equal(got, robot.inertias[i])
        joint = root.find(f"joint[@name='joint{i + 1}']")
        assert joint.find("axis").get("xyz") == "0 0 1"
        kind = joint.get("type")
        assert kind == ("prismatic" if robot.joint_types[i] == "P" else
                        "continuous" if not np.all(np.isfinite(robot.q_limits[i])) else "revolute")
        lim = joint.find("limit")
        if kind != "continuous":
            # an unbounded prismatic joint is written with +-1e9 m (URDF needs numbers)
            lo, hi = (v if np.isfinite(v) else np.copysign(1e9, v) for v in robot.q_limits[i])
            assert (float(lim.get("lower")), float(lim.get("upper"))) == (lo, hi)
        tl = robot.tau_limits[i]
        assert float(lim.get("effort")) == (tl if np.isfinite(tl) else 1e9)
        assert float(joint.find("dynamics").get("damping")) == robot.friction_coefficients[i]


@pytest.mark.parametrize("robot", ROBOTS, ids=[r.name for r in ROBOTS])
def test_urdf_chain_reproduces_frames_and_coms(robot):
    assert_chain_reproduces(robot, ET.fromstring(robot.to_urdf()))


def assert_chain_reproduces(robot, root):
    rng = np.random.default_rng(1)
    for _ in range(5):
        lim = robot.q_limits
        q = rng.uniform(np.maximum(lim[:, 0], -3), np.minimum(lim[:, 1], 3))
        poses = urdf_link_frames(root, q)
        F = robot.frames(q)
        C = robot.com_frames(q)
        np.testing.assert_allclose(poses["base_link"], F[0], atol=1e-12)
        np.testing.assert_allclose(poses["flange"], F[-1], atol=1e-12)
        for i in range(robot.dof):
            link = root.find(f"link[@name='link{i + 1}']")
            com = poses[f"link{i + 1}"] @ origin(link.find("inertial"))
            np.testing.assert_allclose(com, C[i], atol=1e-12)
            # the joint axis is z of the link frame, equal to z of DH frame i-1
            np.testing.assert_allclose(poses[f"link{i + 1}"][:3, 2], F[i][:3, 2], atol=1e-12)


def test_dimension_keyword_changes_urdf():
    base = ET.fromstring(cs.robots.scara1().to_urdf())
    longer = ET.fromstring(cs.robots.scara1(L1=0.4).to_urdf())
    m0 = float(base.find("link[@name='link1']/inertial/mass").get("value"))
    m1 = float(longer.find("link[@name='link1']/inertial/mass").get("value"))
    assert m1 == pytest.approx(m0 * 0.4 / 0.30, rel=1e-14)   # constant density
    # joint 2 sits L1 along x of link 1
    x0 = float(base.find("joint[@name='joint2']/origin").get("xyz").split()[0])
    x1 = float(longer.find("joint[@name='joint2']/origin").get("xyz").split()[0])
    assert (x0, x1) == (pytest.approx(0.30), pytest.approx(0.40))


def urdf_inertial(root, i):
    inertial = root.find(f"link[@name='link{i}']/inertial")
    I = inertial.find("inertia")
    tensor = np.array([[float(I.get("ixx")), float(I.get("ixy")), float(I.get("ixz"))],
                       [float(I.get("ixy")), float(I.get("iyy")), float(I.get("iyz"))],
                       [float(I.get("ixz")), float(I.get("iyz")), float(I.get("izz"))]])
    return float(inertial.find("mass").get("value")), tensor, origin(inertial)


def urdf_joint(root, name):
    j = root.find(f"joint[@name='{name}']")
    lim = j.find("limit")
    limits = None if lim is None else tuple(float(lim.get(k)) for k in ("lower", "upper", "effort"))
    return origin(j), limits, float(j.find("dynamics").get("damping")) if j.find("dynamics") is not None else None


URDF_KEYWORD_CASES = [("scara1", k) for k in ("L_base", "L1", "L2", "L4", "L5", "quill_length", "jaw_thickness",
                                             "width")] + \
                     [("scara2", k) for k in ("L1", "L3", "L5", "quill_length", "jaw_length", "height")]


@pytest.mark.parametrize("name,key", URDF_KEYWORD_CASES, ids=[f"{n}-{k}" for n, k in URDF_KEYWORD_CASES])
def test_dimension_keywords_reach_every_urdf_element(name, key):
    """The URDF of a robot with one dimension changed carries that robot's
    masses, inertias, joint origins and limits, which differ from the default
    robot's exactly where the box model and the DH/CoM tables say."""
    from test_robots import BOXES, TABLE_ENTRIES

    make = getattr(cs.robots, name)
    r0 = make()
    r = make(**{key: 1.3 * r0.dimensions[key]})
    root, root0 = ET.fromstring(r.to_urdf()), ET.fromstring(r0.to_urdf())
    # with zero theta offsets and d = 0 on the P rows, link i's frame at q = 0
    # is DH frame i-1, so joint i's origin is frame i-2 -> frame i-1
    assert np.all(r.dh[:, 0] == 0) and np.all(r.dh[[c == "P" for c in r.joint_types], 1] == 0)
    F = r.frames(np.zeros(6))
    dh_rows = {i for table, i, _, _ in TABLE_ENTRIES[name][key] if table == "dh"}
    com_rows = {i for table, i, _, _ in TABLE_ENTRIES[name][key] if table == "com"}
    for i in range(1, 7):
        m, I, C = urdf_inertial(root, i)
        m0, I0, C0 = urdf_inertial(root0, i)
        assert m == r.masses[i - 1]
        np.testing.assert_array_equal(I, r.inertias[i - 1])
        # constant density: mass and inertia change iff the link's box holds the keyword
        in_box = key in BOXES[name][i - 1]
        assert (m != m0, not np.array_equal(I, I0)) == (in_box, in_box)
        # the CoM (inertial origin, in the link frame) moves iff its CoM row does
        assert (not np.allclose(C, C0, rtol=0, atol=1e-12)) == (i - 1 in com_rows)
        T, limits, damping = urdf_joint(root, f"joint{i}")
        T0, limits0, damping0 = urdf_joint(root0, f"joint{i}")
        expected = np.eye(4) if i == 1 else np.linalg.inv(F[i - 2]) @ F[i - 1]
        np.testing.assert_allclose(T, expected, rtol=0, atol=1e-14)   # rpy round trip of order-1 values
        # joint i's origin holds the constant part of DH row i-1
        assert (not np.allclose(T, T0, rtol=0, atol=1e-12)) == (i - 2 in dh_rows)
        # limits, efforts and damping do not depend on the dimensions
        assert limits == (*r.q_limits[i - 1], r.tau_limits[i - 1]) == limits0
        assert damping == r.friction_coefficients[i - 1] == damping0
    T, _, _ = urdf_joint(root, "flange_fixed")
    np.testing.assert_allclose(T, np.linalg.inv(F[5]) @ F[6], rtol=0, atol=1e-14)
    assert_chain_reproduces(r, root)


def test_rpy_round_trip():
    from coopsim.urdf import rpy_from_matrix

    rng = np.random.default_rng(0)
    for _ in range(100):
        r, p, y = rng.uniform(-3, 3), rng.uniform(-1.5, 1.5), rng.uniform(-3, 3)
        R = rpy_matrix(r, p, y)
        np.testing.assert_allclose(rpy_matrix(*rpy_from_matrix(R)), R, atol=1e-12)
    R = rpy_matrix(0.3, math.pi / 2, 0.2)  # gimbal lock
    np.testing.assert_allclose(rpy_matrix(*rpy_from_matrix(R)), R, atol=1e-12)
