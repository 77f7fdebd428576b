"""Our URDF export read by the simulators people compare us with: PyBullet (fixed base, inertia
from the file), MuJoCo (MjSpec from the URDF) and Pinocchio give our M and C qd + G to 1e-10
for both SCARAs, and their armature (Pinocchio's model.armature, MuJoCo's joint armature) equals
ours in M and in forward dynamics."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pinocchio as pin
import pybullet
import pytest

import coopsim as cs
from conftest import random_state

NAMES = ["scara1", "scara2"]
ARMATURE = {"scara1": [0.05, 0.03, 0.8, 0.004, 0.002, 0.3], "scara2": [0.04, 0.02, 0.6, 0.003, 0.001, 0.2]}
TOL = 1e-10


def _rel(x, y):
    return np.abs(np.asarray(x) - np.asarray(y)).max() / max(1.0, np.abs(y).max())


def _states(robot, count=10, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q, qd, _ = random_state(robot, rng)
        yield q, qd * 2, rng.normal(size=robot.dof) * 5


def _with_armature(r, Ia):
    return cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, r.joint_types, friction=r.friction_coefficients,
                            q_limits=r.q_limits, tau_limits=r.tau_limits, armature=Ia, name=r.name,
                            boxes=r.boxes, base_position=r.base_position, base_yaw=r.base_yaw)


def _full(A):
    return np.triu(A) + np.triu(A, 1).T


def test_export_has_explicit_zero_inertials_and_boxes():
    """Links without mass carry an explicit zero <inertial> (PyBullet would make them 1 kg), and
    every LinkBox is a <visual> and a <collision> box of its link."""
    r = cs.robots.scara1()
    root = ET.fromstring(r.to_urdf())
    for name in ("world", "base_link", "flange"):
        inertial = root.find(f"link[@name='{name}']/inertial")
        assert float(inertial.find("mass").get("value")) == 0.0
        assert all(float(v) == 0.0 for v in inertial.find("inertia").attrib.values())
    for tag in ("visual", "collision"):
        got = sorted(el.get("name") for el in root.iter(tag))
        assert got == sorted(b.name for b in r.boxes)
        sizes = {el.get("name"): [float(v) for v in el.find("geometry/box").get("size").split()]
                 for el in root.iter(tag)}
        for b in r.boxes:
            np.testing.assert_array_equal(sizes[b.name], 2 * b.half_extents)


def _pybullet(path):
    c = pybullet.connect(pybullet.DIRECT)
    pybullet.setGravity(0, 0, -9.81, physicsClientId=c)
    body = pybullet.loadURDF(str(path), useFixedBase=True, flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
                             physicsClientId=c)
    return c, body


@pytest.mark.parametrize("name", NAMES)
def test_pybullet_reads_our_urdf(name, tmp_path):
    r = getattr(cs.robots, name)(backend="numeric")
    path = tmp_path / f"{name}.urdf"
    path.write_text(r.to_urdf())
    c, body = _pybullet(path)
    try:
        for q, qd, _ in _states(r):
            M = np.array(pybullet.calculateMassMatrix(body, q.tolist(), physicsClientId=c))
            assert _rel(M, r.mass_matrix(q)) <= TOL
            h = np.array(pybullet.calculateInverseDynamics(body, q.tolist(), qd.tolist(), [0.0] * r.dof,
                                                           physicsClientId=c))
            assert _rel(h, r.coriolis(q, qd) + r.gravity(q)) <= TOL
    finally:
        pybullet.disconnect(c)


def _mujoco(text, armature=None):
    spec = mujoco.MjSpec.from_string(text)
    model = spec.compile()
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT  # no limits or contacts: the dynamics alone
    if armature is not None:
        model.dof_armature[:] = armature
    return model, mujoco.MjData(model)


def _mujoco_M(model, data):
    M = np.zeros((model.nv, model.nv))
    try:
        mujoco.mj_fullM(model, data, M)  # MuJoCo >= 3.3 (the sparse M of the data)
    except TypeError:
        mujoco.mj_fullM(model, M, data.qM)
    return M


@pytest.mark.parametrize("name", NAMES)
def test_mujoco_reads_our_urdf(name):
    r = getattr(cs.robots, name)(backend="numeric")
    model, data = _mujoco(r.to_urdf())
    assert model.nv == r.dof
    np.testing.assert_allclose(model.dof_damping, r.friction_coefficients)  # K as the joints' damping
    for q, qd, _ in _states(r):
        data.qpos[:], data.qvel[:] = q, qd
        mujoco.mj_forward(model, data)
        assert _rel(_mujoco_M(model, data), r.mass_matrix(q)) <= TOL
        assert _rel(data.qfrc_bias, r.coriolis(q, qd) + r.gravity(q)) <= TOL


@pytest.mark.parametrize("name", NAMES)
def test_pinocchio_reads_our_urdf(name):
    r = getattr(cs.robots, name)(backend="numeric")
    model = pin.buildModelFromXML(r.to_urdf())
    data = model.createData()
    assert model.nq == model.nv == r.dof  # the SCARAs' revolute joints are limited: no (cos, sin) pairs
    for q, qd, _ in _states(r):
        assert _rel(_full(pin.crba(model, data, q)), r.mass_matrix(q)) <= TOL
        assert _rel(pin.nonLinearEffects(model, data, q, qd), r.coriolis(q, qd) + r.gravity(q)) <= TOL


def test_pinocchio_continuous_joints_have_two_coordinates():
    """An unlimited revolute joint is exported 'continuous': Pinocchio gives it nq = 2 (cos, sin)."""
    r = cs.robots.scara1(backend="numeric")
    free = cs.Robot.from_dh(r.dh, r.com, r.masses, r.inertias, r.joint_types)  # no limits
    model = pin.buildModelFromXML(free.to_urdf())
    assert (model.nq, model.nv) == (r.dof + 4, r.dof)  # four revolute joints, two prismatic
    q = np.array([0.3, -0.5, 0.05, 0.2, 1.0, 0.02])
    pq = np.concatenate([[np.cos(v), np.sin(v)] if t == "R" else [v] for v, t in zip(q, r.joint_types)])
    assert _rel(_full(pin.crba(model, model.createData(), pq)), free.mass_matrix(q)) <= TOL


@pytest.mark.parametrize("name", NAMES)
def test_armature_against_pinocchio_and_mujoco(name):
    """Rotor inertia: Pinocchio's model.armature (CRBA, ABA) and MuJoCo's armature (mj_fullM, qacc
    under applied forces) equal our M and forward dynamics to 1e-10, in both our backends."""
    Ia = np.array(ARMATURE[name])
    r = _with_armature(getattr(cs.robots, name)(backend="numeric"), Ia)
    gen = r.with_generated(name)
    text = r.to_urdf()
    pm = pin.buildModelFromXML(text)
    pm.armature = Ia
    pd = pm.createData()
    mm, md = _mujoco(text, armature=Ia)
    K = r.friction_coefficients
    for q, qd, tau in _states(r):
        M = r.mass_matrix(q)
        assert _rel(M - getattr(cs.robots, name)(backend="numeric").mass_matrix(q), np.diag(Ia)) <= 1e-14
        assert _rel(_full(pin.crba(pm, pd, q)), M) <= TOL
        qdd = r.forward_dynamics(q, qd, tau)
        assert _rel(gen.forward_dynamics(q, qd, tau), qdd) <= TOL
        # Pinocchio's ABA has no damping: our K qd goes into its torque
        assert _rel(pin.aba(pm, pd, q, qd, tau - K * qd), qdd) <= TOL
        md.qpos[:], md.qvel[:], md.qfrc_applied[:] = q, qd, tau  # MuJoCo's damping is K (passive force)
        mujoco.mj_forward(mm, md)
        assert _rel(_mujoco_M(mm, md), M) <= TOL
        assert _rel(md.qacc, qdd) <= TOL
