"""URDF export: the same kinematics and inertial parameters as a coopsim robot.

Layout: a fixed ``world`` link; ``base_link`` (DH frame 0) fixed to it at the
robot's base placement; then for each joint i a link ``link<i>`` whose frame
is DH frame i-1 moved by joint i alone (Rz(q_i) or Tz(q_i)), so the joint
axis is z in every joint frame. The constant part of DH row i-1 becomes the
origin of joint i. The last DH row appears as the fixed frame ``flange``.
The tool centre point has no URDF frame: on the SCARAs it lies midway
between two jaws on two links, so no single link carries it.
"""
from __future__ import annotations

import math
import re
from xml.sax.saxutils import quoteattr

import numpy as np

__all__ = ["to_urdf", "rpy_from_matrix"]

# characters XML 1.0 does not allow (control characters, surrogates, U+FFFE/F)
_XML_ILLEGAL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def rpy_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) with R = Rz(yaw) Ry(pitch) Rx(roll), as URDF reads them."""
    R = np.asarray(R, dtype=float)
    sy = -R[2, 0]
    if abs(sy) < 1.0 - 1e-12:
        pitch = math.asin(sy)
        roll = math.atan2(R[2, 1], R[2, 2])
        yaw = math.atan2(R[1, 0], R[0, 0])
    else:  # gimbal lock: put everything in yaw
        pitch = math.copysign(math.pi / 2, sy)
        roll = 0.0
        yaw = math.atan2(-R[0, 1], R[1, 1])
    return roll, pitch, yaw


def _fmt(x: float) -> str:
    return repr(float(x))


def _origin(T: np.ndarray) -> str:
    r, p, y = rpy_from_matrix(T[:3, :3])
    xyz = " ".join(_fmt(v) for v in T[:3, 3])
    return f'<origin xyz="{xyz}" rpy="{_fmt(r)} {_fmt(p)} {_fmt(y)}"/>'


def _dh(theta, d, a, alpha) -> np.ndarray:
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def to_urdf(robot, name: str | None = None) -> str:
    """URDF text (str) for `robot`, with its kinematics, masses, inertias, axes and limits.

    Revolute joints with infinite limits become ``continuous``; joint effort
    limits are the actuator limits, velocity limits are not modelled and set
    to a large number. Friction K is written as the joint ``damping``.
    """
    n = robot.dof
    dh, com, masses, inertias = robot.dh, robot.com, robot.masses, robot.inertias
    types = robot.joint_types
    qlim, taulim, K = robot.q_limits, robot.tau_limits, robot.friction_coefficients
    rname = name if name is not None and name != "" else robot.name
    if not isinstance(rname, str) or _XML_ILLEGAL.search(rname):
        raise ValueError(f"name must be a string of characters allowed in XML, got {rname!r}")
    out = ['<?xml version="1.0"?>', f"<robot name={quoteattr(rname)}>", '  <link name="world"/>',
           '  <link name="base_link"/>',
           '  <joint name="base_fixed" type="fixed">', '    <parent link="world"/>',
           '    <child link="base_link"/>', f"    {_origin(robot.base)}", "  </joint>"]
    parent = "base_link"

    def rest(i):  # part of DH row i after the joint's own motion
        th, d, a, al = dh[i]
        return _dh(0.0, d, a, al) if types[i] == "R" else _dh(0.0, 0.0, a, al)

    for i in range(n):
        th, d, a, al = dh[i]
        # link frame = DH frame i-1 moved by the constant offsets of row i and
        # then by q_i alone; the joint origin holds the offsets
        if types[i] == "R":
            pre = _dh(th, 0.0, 0.0, 0.0)
            C = _dh(-th, 0.0, 0.0, 0.0) @ _dh(*com[i])
        else:
            pre = _dh(th, d, 0.0, 0.0)
            C = _dh(-th, 0.0, 0.0, 0.0) @ _dh(0.0, -d, 0.0, 0.0) @ _dh(*com[i])
        T = pre if i == 0 else rest(i - 1) @ pre
        lname = f"link{i + 1}"
        I = inertias[i]
        jtype = "prismatic" if types[i] == "P" else (
            "continuous" if not np.all(np.isfinite(qlim[i])) else "revolute")
        out += [f'  <link name="{lname}">', "    <inertial>", f"      {_origin(C)}",
                f'      <mass value="{_fmt(masses[i])}"/>',
                f'      <inertia ixx="{_fmt(I[0, 0])}" ixy="{_fmt(I[0, 1])}" ixz="{_fmt(I[0, 2])}" '
                f'iyy="{_fmt(I[1, 1])}" iyz="{_fmt(I[1, 2])}" izz="{_fmt(I[2, 2])}"/>',
                "    </inertial>", "  </link>",
                f'  <joint name="joint{i + 1}" type="{jtype}">', f'    <parent link="{parent}"/>',
                f'    <child link="{lname}"/>', f"    {_origin(T)}", '    <axis xyz="0 0 1"/>']
        effort = taulim[i] if math.isfinite(taulim[i]) else 1e9
        if jtype == "continuous":
            out.append(f'    <limit effort="{_fmt(effort)}" velocity="1000.0"/>')
        else:
            lo, hi = (float(v) if math.isfinite(v) else math.copysign(1e9, v) for v in qlim[i])
            out.append(f'    <limit lower="{_fmt(lo)}" upper="{_fmt(hi)}" effort="{_fmt(effort)}" '
                       f'velocity="1000.0"/>')
        out += [f'    <dynamics damping="{_fmt(K[i])}" friction="0.0"/>', "  </joint>"]
        parent = lname
    # flange: DH frame n
    F = rest(n - 1)
    out += ['  <link name="flange"/>', '  <joint name="flange_fixed" type="fixed">',
            f'    <parent link="{parent}"/>', '    <child link="flange"/>', f"    {_origin(F)}", "  </joint>",
            "</robot>", ""]
    return "\n".join(out)
