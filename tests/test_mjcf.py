"""MJCF in (coopsim.from_mjcf): MuJoCo parses and compiles the file, coopsim reads the compiled model.

The robot's forward dynamics equal MuJoCo's on the same file to 1e-10 relative (|qdd - qacc|_inf <=
1e-10 max(1, |qacc|_inf)): ``mj_forward`` with contacts off (mjDSBL_CONTACT) and MuJoCo's frictionloss, a
constraint, off (mjDSBL_FRICTIONLOSS; coopsim's smooth Coulomb term F_c tanh(qd / v_c) is added back to
the applied torque so that both sides have none), actuators off (mjDSBL_ACTUATION: the torque is
qfrc_applied; a servo's bias would push), the model's gravity set to the robot's, at states
inside the joint ranges (MuJoCo's limits stay on and inactive), with damping and armature, for the numeric
dynamics and for generated code. The files: the project's URDF exports (SCARA #1 and #2, the UR5 and
Panda of example-robot-data) compiled by MjSpec and saved as MJCF with armature and frictionloss
written in, and hand-written ones with ``<default>`` classes, ``childclass``, ``quat`` / ``euler`` /
``axisangle`` / ``xyaxes`` / ``zaxis`` frames, ``fullinertia``, inertias from geoms, degrees, ``ref``,
two joints in one body, a mounted base and parts off the chain. Bad input is one line naming what is
not supported."""
from __future__ import annotations

import importlib.metadata

import numpy as np
import pytest

import coopsim as cs
from coopsim import codegen, mjcf

mujoco = pytest.importorskip("mujoco", reason="mujoco is installed by the test extra")

TOL = 1e-10


def _shipped(path):
    """A file of the example-robot-data wheel (test extra), e.g. 'ur_description/urdf/ur5_robot.urdf'."""
    return next(str(f.locate()) for f in importlib.metadata.files("example-robot-data") if str(f).endswith(path))


def _export(robot, armature, frictionloss):
    """The robot's URDF export compiled by MjSpec and saved as MJCF, with an armature and a frictionloss
    per joint set on the spec (MuJoCo reads neither from URDF)."""
    spec = mujoco.MjSpec.from_string(robot.to_urdf())
    for j, a, f in zip(spec.joints, armature, frictionloss):
        j.armature, j.frictionloss = a, f
    spec.compile()
    return spec.to_xml()


# a 6-joint arm: defaults with classes and childclass, the frames in every MJCF form, fullinertia,
# angles in degrees, a joint ref, two joints in one body, a slide joint, a body without joints merged
HAND_ARM = """
<mujoco model="hand_arm">
  <compiler angle="degree" eulerseq="zyx"/>
  <option gravity="0.3 -0.2 -9.7"/>
  <default>
    <joint damping="0.4" armature="0.02" frictionloss="0.3"/>
    <geom type="box" size="0.03 0.03 0.1" contype="1" conaffinity="1"/>
    <default class="wrist">
      <joint damping="0.05" armature="0.003" range="-170 170"/>
      <geom size="0.02 0.02 0.03"/>
    </default>
    <default class="heavy">
      <joint armature="0.3" frictionloss="1.5"/>
    </default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base" pos="0.2 -0.1 0.05" euler="20 0 0">
      <inertial pos="0 0 0.05" mass="4" diaginertia="0.02 0.02 0.01"/>
      <body name="shoulder" pos="0 0 0.1">
        <joint name="j1" class="heavy" axis="0 0 1" range="-160 160"/>
        <inertial pos="0.01 0.02 0.08" mass="3.1" fullinertia="0.031 0.027 0.012 0.002 -0.003 0.001"/>
        <body name="upper" pos="0 0.05 0.16" quat="0.9238795 0.3826834 0 0">
          <joint name="j2" axis="0 1 0" range="-100 100" ref="15"/>
          <geom name="upper_box" pos="0 0 0.12" size="0.04 0.035 0.13" euler="0 5 0"/>
          <inertial pos="0.005 -0.01 0.14" quat="0.99 0.05 0.1 0.02" mass="2.4"
                    diaginertia="0.024 0.021 0.006"/>
          <body name="fore" pos="0.02 0 0.28" axisangle="1 1 0 30">
            <joint name="j3" axis="0.2 1 0.1" damping="0.7"/>
            <inertial pos="0 0.01 0.1" mass="1.3" fullinertia="0.011 0.010 0.003 0.0005 0.0002 -0.0004"/>
            <body name="slider" pos="0 0 0.2" xyaxes="0 1 0 -1 0 0.2">
              <joint name="j4" type="slide" axis="0 0 1" range="-0.05 0.1" armature="0.5" damping="3"/>
              <geom size="0.02 0.02 0.05" mass="0.6"/>
              <body name="wrist" childclass="wrist" pos="0 0 0.07" zaxis="0.3 0 1">
                <joint name="j5" axis="1 0 0"/>
                <joint name="j6" axis="0 0 1" pos="0.01 0 0.02" range="-120 150"/>
                <geom name="wrist_box" pos="0 0 0.03" mass="0.4"/>
                <body name="flange" pos="0 0 0.06" euler="0 0 90">
                  <inertial pos="0 0 0.01" mass="0.15" diaginertia="0.0001 0.0001 0.00005"/>
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>
    <body name="box" pos="1 0 0.1">
      <freejoint/>
      <geom size="0.05 0.05 0.05" mass="0.5"/>
    </body>
  </worldbody>
</mujoco>
"""

# a 3-joint arm small enough to compile generated code for in seconds: inertias from geoms (capsules and
# boxes), a tilted first axis (a base orientation), a gripper finger off the chain
_HAND_SMALL = """
<mujoco model="hand_small">
  <compiler angle="radian"/>
  <default>
    <default class="link">
      <geom type="capsule" size="0.03" density="800"/>
      <joint damping="0.2" armature="0.01"/>
    </default>
  </default>
  <worldbody>
    <body name="mount" pos="0 0 0.3" euler="0.4 0.2 0">
      <body name="l1" childclass="link">
        <joint name="a" axis="0 0 1" range="-2.5 2.5"/>
        <geom fromto="0 0 0 0.3 0 0.05"/>
        <body name="l2" pos="0.3 0 0.05" quat="0.7071068 0.7071068 0 0">
          <joint name="b" axis="0 0 1" damping="0.1"/>
          <geom type="box" size="0.12 0.02 0.02" pos="0.12 0 0"/>
          <body name="l3" pos="0.25 0 0">
            <joint name="c" type="slide" axis="1 0 0" range="-0.1 0.1" armature="0.2"/>
            <geom fromto="0 0 0 0.15 0 0" size="0.02"/>
{finger}          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="ma" joint="a" gear="2" forcerange="-3 4"/>
    <motor name="mc" joint="c" forcerange="-50 50" gear="1"/>
  </actuator>
</mujoco>
"""
FINGER = """
            <body name="finger" pos="0.15 0 0">
              <joint name="f" type="slide" axis="0 1 0" range="0 0.04"/>
              <geom type="box" size="0.01 0.01 0.02"/>
            </body>
"""
HAND_SMALL = _HAND_SMALL.format(finger=FINGER)
HAND_SMALL_3 = _HAND_SMALL.format(finger="")  # without the finger: MuJoCo's model is the chain alone


def _mujoco(text, gravity):
    model = mujoco.MjSpec.from_string(text).compile()
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_FRICTIONLOSS | off.mjDSBL_ACTUATION
    model.opt.gravity[:] = gravity
    return model, mujoco.MjData(model)


def _full_M(model, data):
    M = np.zeros((model.nv, model.nv))
    try:
        mujoco.mj_fullM(model, data, M)  # MuJoCo >= 3.3 (the sparse M of the data)
    except TypeError:
        mujoco.mj_fullM(model, M, data.qM)
    return M


def _qpos_index(model, robot):
    return np.array([model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, jn)]
                     for jn in robot.joint_names])


def _mismatch(robot, text, count=20, seed=0, scale=1.0):
    """max over random states of |qdd - MuJoCo's qacc|_inf / max(1, |qacc|_inf) (chain dofs), at states
    inside the joint ranges with velocities and applied torques; the rest of the model at qpos0, at rest."""
    model, data = _mujoco(text, robot.gravity_acceleration)
    qi = _qpos_index(model, robot)
    vi = np.array([model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, jn)]
                   for jn in robot.joint_names])
    rng = np.random.default_rng(seed)
    lim = robot.q_limits
    worst = 0.0
    for _ in range(count):
        q = rng.uniform(np.maximum(lim[:, 0], -3.0), np.minimum(lim[:, 1], 3.0))
        qd, tau = rng.normal(size=robot.dof) * 2 * scale, rng.normal(size=robot.dof) * 5
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = model.qpos0, 0.0, 0.0
        data.qpos[qi], data.qvel[vi], data.qfrc_applied[vi] = q, qd, tau
        mujoco.mj_forward(model, data)
        assert data.nefc == 0  # no constraint acts: the smooth dynamics alone
        coulomb = robot.coulomb * np.tanh(qd / robot.coulomb_width)
        qdd = robot.forward_dynamics(q, qd, tau + coulomb)
        worst = max(worst, np.abs(qdd - data.qacc[vi]).max() / max(1.0, np.abs(data.qacc[vi]).max()))
    return worst


def _files():
    rng = np.random.default_rng(3)
    out = {}
    for name in ("scara1", "scara2"):
        r = getattr(cs.robots, name)(backend="numeric")
        out[name] = (_export(r, rng.uniform(0.001, 0.2, r.dof), rng.uniform(0.0, 0.5, r.dof)), {})
    ur5 = cs.Robot.from_urdf(_shipped("ur_description/urdf/ur5_robot.urdf"), tip="tool0")
    out["ur5"] = (_export(ur5, rng.uniform(0.01, 0.5, 6), rng.uniform(0.0, 2.0, 6)), {})
    panda = cs.Robot.from_urdf(_shipped("panda_description/urdf/panda.urdf"),
                               locked={"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0})
    out["panda"] = (_export(panda, rng.uniform(0.01, 0.3, 7), rng.uniform(0.0, 1.0, 7)), {})
    out["hand_arm"] = (HAND_ARM, {"body": "base"})
    out["hand_small"] = (HAND_SMALL_3, {})
    return out


FILES = _files()


@pytest.mark.parametrize("name", sorted(FILES))
def test_forward_dynamics_equal_mujoco(name):
    text, kw = FILES[name]
    robot = cs.from_mjcf(text, **kw)
    assert robot.backend == "numeric"
    assert _mismatch(robot, text) <= TOL
    # fast joints too (the Coulomb term saturated, Coriolis large)
    assert _mismatch(robot, text, count=5, seed=1, scale=10.0) <= TOL


@pytest.mark.parametrize("name", sorted(FILES))
def test_what_is_read_equals_the_compiled_model(name):
    """Damping, frictionloss, armature, ranges and names as MuJoCo compiled them; the mass matrix is
    MuJoCo's; the tool is the tip body's frame."""
    text, kw = FILES[name]
    robot = cs.from_mjcf(text, **kw)
    model, data = _mujoco(text, robot.gravity_acceleration)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, jn) for jn in robot.joint_names]
    assert min(ids) >= 0 and robot.dof == len(ids)
    dofs = model.jnt_dofadr[ids]
    np.testing.assert_array_equal(robot.friction_coefficients, model.dof_damping[dofs])
    np.testing.assert_array_equal(robot.coulomb, model.dof_frictionloss[dofs])
    np.testing.assert_array_equal(robot.armature, model.dof_armature[dofs])
    for i, j in enumerate(ids):
        assert robot.joint_types[i] == ("R" if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE else "P")
        if model.jnt_limited[j]:
            np.testing.assert_array_equal(robot.q_limits[i], model.jnt_range[j])
        else:
            assert np.all(np.isinf(robot.q_limits[i]))
    rng = np.random.default_rng(2)
    qi, vi = _qpos_index(model, robot), model.jnt_dofadr[ids]
    tip = "flange" if name == "hand_arm" else mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody - 1)
    t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, tip)
    for _ in range(5):
        q = rng.uniform(np.maximum(robot.q_limits[:, 0], -3), np.minimum(robot.q_limits[:, 1], 3))
        data.qpos[:] = model.qpos0
        data.qpos[qi] = q
        mujoco.mj_forward(model, data)
        M = _full_M(model, data)
        assert np.abs(robot.mass_matrix(q) - M[np.ix_(vi, vi)]).max() <= TOL * max(1.0, np.abs(M).max())
        T = robot.fk(q)
        assert np.abs(T[:3, 3] - data.xpos[t]).max() <= 1e-12
        assert np.abs(T[:3, :3] - data.xmat[t].reshape(3, 3)).max() <= 1e-12


def test_hand_written_file_read_as_written():
    """The hand-written arm: its names (two joints in one body: a massless link between them), the
    free box and the floor left out, the base where the file mounts it, gravity from <option>, force
    ranges, the colliding boxes on their links."""
    robot = cs.from_mjcf(HAND_ARM, body="base")
    assert robot.name == "hand_arm" and robot.joint_types == "RRRPRR"
    assert robot.joint_names == ["j1", "j2", "j3", "j4", "j5", "j6"]
    assert robot.link_names == ["shoulder", "upper", "fore", "slider", "wrist:j5", "wrist"]
    assert robot.masses[4] == 0.0
    np.testing.assert_allclose(robot.gravity_acceleration, [0.3, -0.2, -9.7])
    np.testing.assert_allclose(robot.q_limits[1], np.radians([-100, 100]))
    np.testing.assert_allclose(robot.q_limits[4], np.radians([-170, 170]))  # from the class "wrist"
    np.testing.assert_array_equal(robot.armature, [0.3, 0.02, 0.02, 0.5, 0.003, 0.003])
    names = sorted(b.name for b in robot.boxes)
    assert names == ["slider_0", "upper_box", "wrist_box"]
    assert {b.name: b.link for b in robot.boxes} == {"upper_box": 2, "slider_0": 4, "wrist_box": 6}
    # the default tip: the end of the only moving chain under base, followed to the fixed flange
    flange = cs.from_mjcf(HAND_ARM, body="base", tip="flange")
    wrist = cs.from_mjcf(HAND_ARM, body="base", tip="wrist")
    q = np.array([0.1, 0.2, -0.3, 0.05, 0.4, -0.5])
    np.testing.assert_array_equal(robot.fk(q), flange.fk(q))
    assert np.linalg.norm(robot.fk(q)[:3, 3] - wrist.fk(q)[:3, 3]) > 0.05
    assert wrist.masses[-1] == robot.masses[-1] == pytest.approx(0.55)  # the fixed flange joins the wrist either way


def test_limits():
    """Force ranges: a single joint actuator's forcerange times its gear (the larger bound's magnitude); a
    joint's actuatorfrcrange (the URDF exports' efforts); limits='ignore' reads neither, nor the ranges."""
    robot = cs.from_mjcf(HAND_SMALL_3)
    np.testing.assert_array_equal(robot.tau_limits, [8.0, np.inf, 50.0])
    np.testing.assert_array_equal(robot.q_limits, [[-2.5, 2.5], [-np.inf, np.inf], [-0.1, 0.1]])
    scara = cs.from_mjcf(FILES["scara1"][0])
    np.testing.assert_allclose(scara.tau_limits, cs.robots.scara1().tau_limits, rtol=1e-6)
    np.testing.assert_allclose(scara.q_limits, cs.robots.scara1().q_limits, rtol=1e-5)
    free = cs.from_mjcf(HAND_SMALL_3, limits="ignore")
    assert np.all(np.isinf(free.tau_limits)) and np.all(np.isinf(free.q_limits))


def test_gravity_and_name_given():
    robot = cs.from_mjcf(HAND_SMALL_3, gravity=(0, 0, -3.0), name="small")
    assert robot.name == "small"
    np.testing.assert_array_equal(robot.gravity_acceleration, [0, 0, -3.0])
    assert _mismatch(robot, HAND_SMALL_3) <= TOL


def test_locked_joint_keeps_its_body():
    """locked= holds the finger at a position: its mass joins l3, and the dynamics equal MuJoCo's with the
    finger held there (its joint's armature and range left out: it does not move)."""
    robot = cs.from_mjcf(HAND_SMALL, locked={"f": 0.03})
    cut = cs.from_mjcf(HAND_SMALL, tip="l3")
    assert robot.dof == cut.dof == 3 and robot.masses[2] > cut.masses[2]
    model = mujoco.MjSpec.from_string(HAND_SMALL).compile()
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    data = mujoco.MjData(model)
    q, qd, tau = np.array([0.3, -0.7, 0.05]), np.array([0.5, -1.0, 0.2]), np.array([1.0, 0.5, -2.0])
    data.qpos[:], data.qvel[:3], data.qfrc_applied[:3] = [*q, 0.03], qd, tau
    mujoco.mj_forward(model, data)
    # MuJoCo's finger is free to slide: compare the chain's rows of M and the bias with the finger's qdd = 0
    M = _full_M(model, data)
    assert np.abs(robot.mass_matrix(q) - M[:3, :3]).max() <= TOL * np.abs(M).max()
    qdd = np.linalg.solve(M[:3, :3], tau - data.qfrc_bias[:3] + data.qfrc_passive[:3])
    assert np.abs(robot.forward_dynamics(q, qd, tau) - qdd).max() <= TOL * max(1.0, np.abs(qdd).max())


def test_generated_code_equals_mujoco(tmp_path):
    """Generated closed-form dynamics of an MJCF robot (compiled at run time) equal MuJoCo's too."""
    robot = cs.from_mjcf(HAND_SMALL_3)
    gen = codegen.compile(robot, cache=tmp_path)
    assert gen.backend == "generated"
    assert _mismatch(gen, HAND_SMALL_3) <= TOL
    assert _mismatch(gen, HAND_SMALL_3, count=5, seed=1, scale=10.0) <= TOL


def test_clamp_on_import():
    robot = cs.from_mjcf(HAND_SMALL, tip="l3", clamp={"opening": 0.04})
    assert robot.joint_types == "RRPP" and robot.joint_names[-1] == "clamp_jaw" and robot.clamp is not None


def test_the_importer_is_the_package_s_and_the_robot_s():
    assert cs.from_mjcf is mjcf.from_mjcf and cs.Robot.from_mjcf is mjcf.from_mjcf


def test_source_forms(tmp_path):
    """A path, text, an MjSpec and an MjModel give the same robot."""
    path = tmp_path / "arm.xml"
    path.write_text(HAND_SMALL)
    spec = mujoco.MjSpec.from_string(HAND_SMALL)
    robots = [cs.from_mjcf(s, tip="l3") for s in (HAND_SMALL, str(path), path, spec, spec.compile())]
    robots.append(cs.Robot.from_mjcf(path, tip="l3"))
    for r in robots[1:]:
        np.testing.assert_array_equal(r.dh, robots[0].dh)
        np.testing.assert_array_equal(r.masses, robots[0].masses)
        np.testing.assert_array_equal(r.inertias, robots[0].inertias)


FREE_BASE = """<mujoco><worldbody><body name="torso"><freejoint name="root"/><geom size="0.1"/>
  <body name="arm"><joint name="h" axis="0 0 1"/><geom size="0.05" pos="0.2 0 0"/></body></body></worldbody></mujoco>"""
BALL = """<mujoco><worldbody><body name="a"><joint name="h" axis="0 0 1"/><geom size="0.1"/>
  <body name="b"><joint name="shoulder" type="ball"/><geom size="0.05" pos="0.2 0 0"/></body></body>
  </worldbody></mujoco>"""
TREE = """<mujoco><worldbody><body name="torso"><geom size="0.1"/>
  <body name="left"><joint name="l" axis="0 0 1"/><geom size="0.05" pos="0.2 0 0"/></body>
  <body name="right"><joint name="r" axis="0 0 1"/><geom size="0.05" pos="-0.2 0 0"/></body></body>
  </worldbody></mujoco>"""
SPRING = """<mujoco><worldbody><body name="a"><joint name="h" axis="0 0 1" stiffness="10"/><geom size="0.1"/>
  </body></worldbody></mujoco>"""
GRAVCOMP = """<mujoco><worldbody><body name="a" gravcomp="1"><joint name="h" axis="0 0 1"/><geom size="0.1"/>
  </body></worldbody></mujoco>"""


@pytest.mark.parametrize("text, kw, match", [
    (FREE_BASE, {}, "joint 'root' of body 'torso' is a free joint: floating bases are not supported"),
    (FREE_BASE, {"tip": "arm"}, "joint 'root' of body 'torso' is a free joint"),
    (FREE_BASE, {"body": "arm"}, "body: the base body 'arm' moves with joint 'root' of body 'torso'; the chain's "
                                "base must be fixed to the world"),
    (BALL, {}, "joint 'shoulder' of body 'b' is a ball joint: ball joints are not supported"),
    (TREE, {}, "body 'torso' has two moving branches .* a tree, not a serial chain; pass tip="),
    (HAND_ARM, {}, "the unnamed joint 6 of body 'box' is a free joint: floating bases are not supported"),
    (SPRING, {}, "joint 'h' has stiffness 10 .* joint springs are not supported"),
    (GRAVCOMP, {}, "body 'a' has gravcomp 1: gravity compensation is not supported"),
    (HAND_SMALL, {"tip": "nowhere"}, "tip: no body named 'nowhere'"),
    (HAND_SMALL, {"body": "mount", "tip": "world"}, "tip: the body 'world' is not below the base body 'mount'"),
    (HAND_SMALL, {"locked": {"zz": 0.0}}, "locked: 'zz' is not a hinge or slide joint"),
    (HAND_SMALL, {"locked": {"f": float("nan")}}, r"locked\['f'\] must be in"),
    (HAND_SMALL, {"limits": "none"}, "limits must be 'file' or 'ignore', got 'none'"),
    (HAND_SMALL, {"body": 3}, "body must be the name of a body"),
    (HAND_SMALL, {"clamp": "yes"}, "clamp must be True, False, None or a dict"),
    ("<mujoco><worldbody><body><joint axis='0 0 0'/><geom size='1'/></body></worldbody></mujoco>", {},
     "source: MuJoCo cannot read or compile it: Error: axis too small"),
    ("<mujoco", {}, "source: MuJoCo cannot read or compile it: XML parse error"),
    ("no/such/file.xml", {}, "source must be MJCF text or the path of an MJCF file; no file"),
    (3.0, {}, "source must be MJCF text, a path, a mujoco.MjSpec or a mujoco.MjModel, got float"),
    ("<mujoco><worldbody><body name='a'><geom size='1'/></body></worldbody></mujoco>", {},
     "no hinge or slide joint under the body 'world'"),
])
def test_bad_input_is_one_line(text, kw, match):
    with pytest.raises(ValueError, match=match) as e:
        cs.from_mjcf(text, **kw)
    assert "\n" not in str(e.value)
