"""URDF in and out: a coopsim robot as URDF that peers read right, and any
serial URDF chain as a coopsim robot.

Export layout: a fixed ``world`` link; ``base_link`` (DH frame 0) fixed to it
at the robot's base placement; then for each joint i (named
``Robot.joint_names[i]``, ``joint<i>`` by default) a link
(``Robot.link_names[i]``, ``link<i>``) whose frame is DH frame i-1 moved by
joint i alone (Rz(q_i) or Tz(q_i)), so the joint axis is z in every joint
frame. The constant part of DH row i-1
becomes the origin of joint i. The last DH row appears as the fixed frame
``flange``. The tool centre point has no URDF frame: on the SCARAs it lies
midway between two jaws on two links, so no single link carries it.

Every link has an explicit ``<inertial>``, zero for links without mass
(``world``, ``base_link``, ``flange``): PyBullet gives a link without one
1 kg and unit inertia, which would load the last joint. Each link's boxes
(``Robot.boxes``) are its ``<visual>`` and ``<collision>`` boxes. Revolute
joints without limits are ``continuous``: Pinocchio represents those by
(cos q, sin q), so its model has nq = 2 per such joint (nv stays 1). The
viscous K is the joint ``damping``, the Coulomb F_c its ``friction``; the
armature J_m G^2 goes in a ``<transmission>`` with Drake's
``drake:rotor_inertia`` (gear ratio 1), which PyBullet, MuJoCo and
Pinocchio ignore (set theirs from ``Robot.armature``) and ``from_urdf``
reads back.
"""
from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Optional
from xml.sax.saxutils import quoteattr

import numpy as np

from . import _checks
from ._core import Robot
from .urdf_shapes import _collision_shapes
from .robots import add_clamp
from .visuals import Visual, _register_visuals, visuals

__all__ = ["to_urdf", "from_urdf", "rpy_from_matrix", "Visual", "visuals"]

# characters XML 1.0 does not allow (control characters, surrogates, U+FFFE/F)
_XML_ILLEGAL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")
_DRAKE_NS = "http://drake.mit.edu"


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


def _matrix_from_rpy(r: float, p: float, y: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


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


_ZERO_INERTIAL = ['    <inertial>', '      <origin xyz="0 0 0" rpy="0 0 0"/>', '      <mass value="0.0"/>',
                  '      <inertia ixx="0.0" ixy="0.0" ixz="0.0" iyy="0.0" iyz="0.0" izz="0.0"/>', '    </inertial>']


def _boxes(boxes, frame):
    """<visual> and <collision> of LinkBoxes whose poses are given in `frame`'s coordinates
    (frame: 4x4 from the URDF link frame to the box's link DH frame): boxes, spheres and cylinders as
    such, a convex hull as its bounding box (half_extents; a mesh file cannot be written inline)."""
    out = []
    for b in boxes:
        if b.kind == "sphere":
            geometry = f'<sphere radius="{_fmt(b.radius)}"/>'
        elif b.kind == "cylinder":
            geometry = f'<cylinder radius="{_fmt(b.radius)}" length="{_fmt(b.length)}"/>'
        else:
            geometry = '<box size="' + " ".join(_fmt(2.0 * h) for h in b.half_extents) + '"/>'
        nm = f" name={quoteattr(b.name)}" if b.name and not _XML_ILLEGAL.search(b.name) else ""
        for tag in ("visual", "collision"):
            out += [f"    <{tag}{nm}>", f"      {_origin(frame @ b.pose)}",
                    f"      <geometry>{geometry}</geometry>", f"    </{tag}>"]
    return out


_RESERVED_LINKS = {"world", "base_link", "flange"}
_RESERVED_JOINTS = {"base_fixed", "flange_fixed"}


def _export_names(robot):
    """The robot's joint and link names for the URDF, or joint1.. / link1.. where one cannot stand in it
    (characters XML does not allow, or a name the export gives its own frames)."""
    n = robot.dof
    jn, ln = list(robot.joint_names), list(robot.link_names)
    if any(_XML_ILLEGAL.search(x) for x in jn) or _RESERVED_JOINTS & set(jn):
        jn = [f"joint{i + 1}" for i in range(n)]
    if any(_XML_ILLEGAL.search(x) for x in ln) or _RESERVED_LINKS & set(ln):
        ln = [f"link{i + 1}" for i in range(n)]
    return jn, ln


def to_urdf(robot, name: str | None = None) -> str:
    """URDF text (str) for `robot`, with its kinematics, masses, inertias, axes, limits and boxes.

    Revolute joints with infinite limits become ``continuous`` (Pinocchio:
    nq = 2 for each, cos and sin); joint effort limits are the actuator
    limits, velocity limits are not modelled and set to a large number.
    Friction: viscous K as the joint ``damping`` (N m s/rad or N s/m),
    Coulomb F_c as its ``friction`` (N m or N; its width v_c has no URDF
    field). The armature goes in a ``<transmission>`` as Drake's
    ``drake:rotor_inertia`` with ``drake:gear_ratio`` 1. Links without mass
    carry an explicit zero ``<inertial>``. The link shapes (``Robot.boxes``)
    are written as ``<visual>`` and ``<collision>``: boxes, spheres and
    cylinders as such; a convex hull (from a mesh) as its bounding box
    (``LinkBox.half_extents`` about its pose), since the text holds no mesh
    file: a robot read back collides as boxes there. See the module's docstring.
    """
    n = robot.dof
    dh, com, masses, inertias = robot.dh, robot.com, robot.masses, robot.inertias
    types = robot.joint_types
    qlim, taulim, K = robot.q_limits, robot.tau_limits, robot.friction_coefficients
    Fc, Ia = robot.coulomb, robot.armature
    rname = name if name is not None and name != "" else robot.name
    if not isinstance(rname, str) or _XML_ILLEGAL.search(rname):
        raise ValueError(f"name must be a string of characters allowed in XML, got {rname!r}")
    ns = f' xmlns:drake="{_DRAKE_NS}"' if np.any(Ia > 0) else ""
    boxes = robot.boxes
    jnames, lnames = _export_names(robot)
    out = ['<?xml version="1.0"?>', f"<robot name={quoteattr(rname)}{ns}>", '  <link name="world">',
           *_ZERO_INERTIAL, "  </link>", '  <link name="base_link">', *_ZERO_INERTIAL,
           *_boxes([b for b in boxes if b.link == 0], np.eye(4)), "  </link>",
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
        lname = lnames[i]
        I = inertias[i]
        jtype = "prismatic" if types[i] == "P" else (
            "continuous" if not np.all(np.isfinite(qlim[i])) else "revolute")
        out += [f'  <link name={quoteattr(lname)}>', "    <inertial>", f"      {_origin(C)}",
                f'      <mass value="{_fmt(masses[i])}"/>',
                f'      <inertia ixx="{_fmt(I[0, 0])}" ixy="{_fmt(I[0, 1])}" ixz="{_fmt(I[0, 2])}" '
                f'iyy="{_fmt(I[1, 1])}" iyz="{_fmt(I[1, 2])}" izz="{_fmt(I[2, 2])}"/>',
                "    </inertial>", *_boxes([b for b in boxes if b.link == i + 1], rest(i)), "  </link>",
                f'  <joint name={quoteattr(jnames[i])} type="{jtype}">', f'    <parent link={quoteattr(parent)}/>',
                f'    <child link={quoteattr(lname)}/>', f"    {_origin(T)}", '    <axis xyz="0 0 1"/>']
        effort = taulim[i] if math.isfinite(taulim[i]) else 1e9
        if jtype == "continuous":
            out.append(f'    <limit effort="{_fmt(effort)}" velocity="1000.0"/>')
        else:
            lo, hi = (float(v) if math.isfinite(v) else math.copysign(1e9, v) for v in qlim[i])
            out.append(f'    <limit lower="{_fmt(lo)}" upper="{_fmt(hi)}" effort="{_fmt(effort)}" '
                       f'velocity="1000.0"/>')
        out += [f'    <dynamics damping="{_fmt(K[i])}" friction="{_fmt(Fc[i])}"/>', "  </joint>"]
        parent = lname
    # flange: DH frame n
    F = rest(n - 1)
    out += ['  <link name="flange">', *_ZERO_INERTIAL, "  </link>", '  <joint name="flange_fixed" type="fixed">',
            f'    <parent link={quoteattr(parent)}/>', '    <child link="flange"/>', f"    {_origin(F)}", "  </joint>"]
    for i in range(n):
        if Ia[i] > 0:
            out += [f'  <transmission name="transmission{i + 1}">',
                    "    <type>transmission_interface/SimpleTransmission</type>",
                    f'    <joint name={quoteattr(jnames[i])}><hardwareInterface>EffortJointInterface</hardwareInterface>'
                    "</joint>",
                    f'    <actuator name="motor{i + 1}">', "      <mechanicalReduction>1</mechanicalReduction>",
                    f'      <drake:rotor_inertia value="{_fmt(Ia[i])}"/>', '      <drake:gear_ratio value="1.0"/>',
                    "    </actuator>", "  </transmission>"]
    out += ["</robot>", ""]
    return "\n".join(out)


def _mesh_path(filename: str, base_dir: Optional[str]) -> Optional[str]:
    """The file a URDF mesh filename names, or None when it is not found: ``package://pkg/rest`` in a
    directory of ROS_PACKAGE_PATH or a parent of the URDF's directory named pkg (or holding pkg),
    ``file://`` and plain paths as they are or relative to the URDF's directory."""
    cands = []
    if filename.startswith("package://"):
        pkg, _, rest = filename[len("package://"):].partition("/")
        roots = [r for r in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if r]
        if base_dir is not None:
            d = os.path.abspath(base_dir)
            while True:
                roots.append(d)
                up = os.path.dirname(d)
                if up == d:
                    break
                d = up
        for r in roots:
            cands += [os.path.join(r, rest)] if os.path.basename(os.path.normpath(r)) == pkg else []
            cands.append(os.path.join(r, pkg, rest))
    else:
        path = filename[len("file://"):] if filename.startswith("file://") else filename
        cands.append(path if os.path.isabs(path) or base_dir is None else os.path.join(base_dir, path))
    return next((os.path.abspath(c) for c in cands if os.path.isfile(c)), None)


def _visual(sh, ln, body, X, base_dir, snap):
    """A Visual of one <visual> element of link ln (X: the link frame in the body's DH frame), or None for
    geometry the views do not draw (spheres, a mesh file not found)."""
    what = f"link {ln!r} visual"
    g = sh.find("geometry")
    if g is None:
        return None
    T = X @ _pose(sh, what, snap)
    mesh, box, cyl = g.find("mesh"), g.find("box"), g.find("cylinder")
    if mesh is not None:
        fn = mesh.get("filename")
        path = _mesh_path(fn, base_dir) if fn else None
        if path is None:
            return None
        scale = _floats(mesh.get("scale", "1 1 1"), 3, f"{what} mesh scale")
        if any(s == 0 for s in scale):
            raise ValueError(f"{what}: mesh scale must not be 0, got {scale}")
        return Visual(body, T, "mesh", np.array(scale), path, ln)
    if box is not None:
        size = _floats(box.get("size"), 3, f"{what} box size")
        return Visual(body, T, "box", np.array(size), None, ln) if min(size) > 0 else None
    if cyl is not None:
        r, length = _attr(cyl, "radius", what), _attr(cyl, "length", what)
        return Visual(body, T, "cylinder", np.array([2 * r, 2 * r, length]), None, ln) if r > 0 and length > 0 \
            else None
    return None


# ------------------------------------------------------------------ import

# numbers read from a URDF (lengths, angles, masses, inertias, damping ...) are at most this large in
# magnitude, so that combining them (inertias moved to another frame, DH rows of far or nearly parallel
# axes) cannot overflow; joint limits and efforts may be anything, 1e9 or more standing for none
_MAX_NUMBER = 1e12


def _floats(text, count, what):
    try:
        v = [float(x) for x in (text or "").split()]
    except ValueError:
        raise ValueError(f"{what}: expected {count} numbers, got {text!r}") from None
    if len(v) != count or not all(math.isfinite(x) for x in v):
        raise ValueError(f"{what}: expected {count} finite numbers, got {text!r}")
    if any(abs(x) > _MAX_NUMBER for x in v):
        raise ValueError(f"{what}: numbers must be at most {_MAX_NUMBER:g} in magnitude, got {text!r}")
    return v


def _pose(el, what, snap=0.0) -> np.ndarray:
    """4x4 of an element's <origin> (identity when absent); rpy angles within `snap` rad of a
    multiple of pi/12 taken as that multiple."""
    T = np.eye(4)
    o = el.find("origin") if el is not None else None
    if o is not None:
        T[:3, 3] = _floats(o.get("xyz", "0 0 0"), 3, f"{what} origin xyz")
        rpy = _floats(o.get("rpy", "0 0 0"), 3, f"{what} origin rpy")
        T[:3, :3] = _matrix_from_rpy(*(_snap_angle(v, snap) for v in rpy))
    return T


def _is_real(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _attr(el, key, what, default=None, bounded=True):
    """The number in attribute `key` of `el` (`default` when absent): finite and at most _MAX_NUMBER
    in magnitude, or with bounded=False any number but NaN (limits, efforts)."""
    v = el.get(key) if el is not None else None
    if v is None:
        if default is None:
            raise ValueError(f"{what} lacks the attribute {key!r}")
        return default
    try:
        x = float(v)
    except ValueError:
        raise ValueError(f"{what}: {key} must be a number, got {v!r}") from None
    if math.isnan(x):
        raise ValueError(f"{what}: {key} must be a number, got {v!r}")
    if bounded and not abs(x) <= _MAX_NUMBER:
        raise ValueError(f"{what}: {key} must be finite and at most {_MAX_NUMBER:g} in magnitude, got {v!r}")
    return x


def _inertial(link, snap):
    """(mass, CoM (3,), inertia about the CoM (3, 3)) of a <link>, in the link frame."""
    what = f"link {link.get('name')!r}"
    el = link.find("inertial")
    if el is None:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    T = _pose(el, f"{what} inertial", snap)
    m = _attr(el.find("mass"), "value", f"{what} inertial mass", default=0.0)
    i = el.find("inertia")
    if m < 0 or not math.isfinite(m):
        raise ValueError(f"{what}: mass must be finite and >= 0, got {m}")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    v = {k: _attr(i, k, f"{what} inertia", default=0.0) for k in keys} if i is not None else dict.fromkeys(keys, 0.0)
    I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]])
    R = T[:3, :3]
    return m, T[:3, 3].copy(), R @ I @ R.T


def _combine(parts):
    """One rigid body of [(mass, CoM, inertia about CoM)] in one frame."""
    m = sum(p[0] for p in parts)
    if m <= 0:
        return 0.0, np.zeros(3), sum((p[2] for p in parts), np.zeros((3, 3)))
    c = sum(p[0] * p[1] for p in parts) / m
    I = np.zeros((3, 3))
    for mi, ci, Ii in parts:
        r = ci - c
        I += Ii + mi * (r @ r * np.eye(3) - np.outer(r, r))
    return m, c, 0.5 * (I + I.T)


def _unit(v):
    return v / np.linalg.norm(v)


def _snap_angle(x, tol=1e-12):
    k = round(x / (math.pi / 12))
    return k * math.pi / 12 if abs(x - k * math.pi / 12) <= tol else x


def _dh_from_axes(points, axes):
    """Standard DH frames 0..n (origin, x, z) at q = 0 for joint axes through points[i] along
    axes[i] (base coordinates), then the DH rows [theta, d, a, alpha] at q = 0."""
    n = len(axes)
    z = [axes[0]]
    o = [points[0] - (points[0] @ axes[0]) * axes[0]]  # on axis 1, nearest the root's origin
    ref = np.array([1.0, 0.0, 0.0])
    if np.linalg.norm(np.cross(ref, z[0])) < 1e-6:
        ref = np.array([0.0, 1.0, 0.0])
    x = [_unit(ref - (ref @ z[0]) * z[0])]
    for i in range(1, n + 1):
        zp, op, xp = z[i - 1], o[i - 1], x[i - 1]
        if i == n:  # the last frame: frame n-1 turned or slid by q_n alone
            z.append(zp), o.append(op), x.append(xp)
            break
        zi, p = axes[i], points[i]
        c = np.cross(zp, zi)
        if np.linalg.norm(c) > 1e-9:  # skew or intersecting: the common normal
            w = op - p
            b, dd, e = zp @ zi, zp @ w, zi @ w
            den = 1.0 - b * b
            with np.errstate(all="ignore"):
                t, s = (b * e - dd) / den, (e - b * dd) / den
            if not (math.isfinite(t) and math.isfinite(s)):
                raise ValueError(f"the axes of joints {i} and {i + 1} are out of range: their common normal "
                                 f"cannot be computed (points {points[i - 1]}, {p}, axes {zp}, {zi})")
            f1, f2 = op + t * zp, p + s * zi
            xi = _unit(c)
            if (f2 - f1) @ xi < 0:
                xi = -xi
            oi = f2
        else:  # parallel: the normal through o_(i-1) (d_i = 0)
            f2 = p + ((op - p) @ zi) * zi
            v = f2 - op
            v = v - (v @ zp) * zp
            xi = _unit(v) if np.linalg.norm(v) > 1e-12 else xp
            oi = f2
        xi = _unit(xi - (xi @ zi) * zi)
        z.append(zi), o.append(oi), x.append(xi)
    rows = []
    for i in range(1, n + 1):
        v = o[i] - o[i - 1]
        theta = math.atan2(z[i - 1] @ np.cross(x[i - 1], x[i]), x[i - 1] @ x[i])
        alpha = math.atan2(x[i] @ np.cross(z[i - 1], z[i]), z[i - 1] @ z[i])
        rows.append([_snap_angle(theta), z[i - 1] @ v, x[i] @ v, _snap_angle(alpha)])
    R0 = np.column_stack([x[0], np.cross(z[0], x[0]), z[0]])
    return np.array(rows), o[0], R0


@dataclass(frozen=True)
class _Frames:
    """A chain's standard DH rows (n, 4), its base (position (3,) m, yaw rad, orientation (3, 3) or
    None) and its DH frames 0..n at q = 0 (n + 1 4x4 poses in the root's coordinates)."""
    dh: np.ndarray
    base_position: np.ndarray
    base_yaw: float
    base_orientation: Optional[np.ndarray]
    F: list


def _chain_frames(points, axes) -> _Frames:
    """The DH frames of joint axes through points[i] along axes[i] ((3,) each, root coordinates, at
    q = 0); the base a yaw when z0 is the root's z, else a base orientation."""
    dh, o0, R0 = _dh_from_axes([np.asarray(p, dtype=float) for p in points],
                               [np.asarray(a, dtype=float) for a in axes])
    if np.linalg.norm(R0[:, 2] - [0, 0, 1]) < 1e-12:
        yaw, Rb = math.atan2(R0[1, 0], R0[0, 0]), None
        R0 = _dh(yaw, 0, 0, 0)[:3, :3]
    else:
        yaw, Rb = 0.0, R0
    F = [np.eye(4)]
    F[0][:3, :3], F[0][:3, 3] = R0, o0
    for row in dh:
        F.append(F[-1] @ _dh(*row))  # DH frames at q = 0, rebuilt from the rows
    return _Frames(dh, o0, yaw, Rb, F)


def _moved(X, m, c, I):
    """(mass, CoM, inertia about the CoM) given in a frame at pose X (4x4) of another frame, in that
    other frame."""
    R = X[:3, :3]
    return m, R @ c + X[:3, 3], R @ I @ R.T


def _chain_robot(frames: _Frames, types: str, parts, tool, *, joint_names, link_names, boxes, name, **kw):
    """The Robot of a chain whose importer has read the file: `parts[b]` the (mass, CoM, inertia
    about the CoM) of every piece of body b (0 the base, i the link joint i moves) in DH frame b,
    combined into one link each; `tool` (4x4) in DH frame n; `boxes` LinkBoxes (None or empty:
    the default ones); `kw` from_dh's friction, coulomb, armature, limits, gravity, ... ."""
    bodies = [_combine(p) for p in parts[1:]]
    robot = Robot.from_dh(frames.dh, np.array([b[1] for b in bodies]), np.array([b[0] for b in bodies]),
                          np.array([b[2] for b in bodies]), types, base_position=frames.base_position,
                          base_yaw=frames.base_yaw, base_orientation=frames.base_orientation, tool=tool,
                          name=name, boxes=boxes or None, **kw)
    return robot.with_names(list(joint_names), list(link_names))


def _with_clamp(robot, clamp):
    """The importers' clamp= (None/False: the robot; True: add_clamp's defaults; a dict: its keywords)."""
    if clamp is None or clamp is False:
        return robot
    if clamp is not True and not isinstance(clamp, Mapping):
        raise ValueError(f"clamp must be True, False, None or a dict of add_clamp's keywords, got {clamp!r}")
    return add_clamp(robot, **({} if clamp is True else dict(clamp)))


def _read(source):
    """(root element, the file's directory or None for text)."""
    base_dir = None
    if isinstance(source, os.PathLike) or (isinstance(source, str) and not source.lstrip().startswith("<")):
        path = os.fspath(source)
        base_dir = os.path.dirname(os.path.abspath(path))
        if not os.path.isfile(path):
            raise ValueError(f"source must be URDF text or the path of a URDF file; no file {path!r}")
        try:
            with open(path, encoding="utf-8") as f:
                source = f.read()
        except UnicodeDecodeError as e:
            raise ValueError(f"source: the file {path!r} is not UTF-8 text ({e})") from None
    if not isinstance(source, str):
        raise ValueError(f"source must be URDF text or a path, got {type(source).__name__}")
    # a drake: prefix used without its namespace declaration still parses
    if "drake:" in source and "xmlns:drake" not in source:
        source = re.sub(r"<robot\b", f'<robot xmlns:drake="{_DRAKE_NS}"', source, count=1)
    try:
        root = ET.fromstring(source)
    except (ET.ParseError, UnicodeError) as e:  # UnicodeError: a lone surrogate, which no XML text holds
        raise ValueError(f"source is not well-formed XML: {e}") from None
    if root.tag != "robot":
        raise ValueError(f"source is not URDF: its root element is <{root.tag}>, expected <robot>")
    return root, base_dir


_MOVABLE = {"revolute": "R", "continuous": "R", "prismatic": "P"}
# limits and efforts this large stand for none (to_urdf writes +-1e9 where URDF needs a number)
_UNBOUNDED = 1e9


def from_urdf(source, *, tip: str | None = None, locked: dict | None = None, name: str | None = None,
              gravity=(0.0, 0.0, -9.81), coulomb_width=0.01, inertia_check: str = "warn", snap: float = 1e-9,
              limits: str = "file", clamp=None, hull_points: int = 64, collision_meshes: bool = True):
    """A coopsim.Robot from a URDF serial chain (text, or the path of a .urdf file).

    Joints: revolute, continuous (unbounded) and prismatic ones make the
    chain, in order from the root link; fixed joints merge their child link
    (mass, CoM, inertia, boxes) into its parent. The robot keeps their names:
    ``robot.joint_names[i]`` is the URDF joint whose position is q[i] (and
    whose torque is tau[i]), ``robot.link_names[i]`` the child link it moves
    (the one Robot link i + 1 stands for, with the links fixed to it). Each joint's origin and axis
    (any direction) become a standard DH row; frame 0 lies on the first axis
    (z0 along it, nearest the root's origin) and is the robot's base
    (position, yaw and, for a first axis that is not the root's z, a
    base_orientation); the tip link's frame is the tool (Robot.tool offset
    from DH frame n). q = 0 is the URDF's zero and q has the URDF's sign.
    Inertials are carried over as CoM vectors and link-frame inertias;
    links without one have no mass. Limits: lower/upper (rad or m), effort
    as tau_limits (none or 0: unbounded; limits and efforts of 1e9 or more,
    which to_urdf writes for none, too); dynamics damping as the viscous K,
    friction as Coulomb F_c (with `coulomb_width` v_c, rad/s or m/s); a
    ``<transmission>`` actuator's ``drake:rotor_inertia`` times
    ``drake:gear_ratio`` squared as the armature. ``<collision>`` shapes (or
    ``<visual>`` ones when a link has no collision) become the robot's
    shapes (``Robot.boxes``, LinkBox): boxes, spheres and cylinders as such
    (Bullet's own shapes in the world), collision meshes (read with trimesh,
    their scale applied) as the convex hull of at most `hull_points` of their
    hull's vertices (trimesh's convex hull, then farthest-point sampling:
    the vertex farthest from the centroid first, then each time the one
    farthest from those kept); a mesh that cannot be read is left out with a
    RuntimeWarning naming its file (a robot without any shape gets the
    default boxes).
    The ``<visual>`` meshes (files found: ``package://`` through
    ROS_PACKAGE_PATH or the URDF file's parent directories), boxes and
    cylinders are kept in Python for the views (:func:`visuals`; the live
    page and the replay draw them, :mod:`coopsim.view.parts`).

    tip: the last link of the chain (default: the end of the only chain of
        movable joints, followed down single fixed joints). Movable joints
        off the root-to-tip path are cut with their subtrees (e.g. gripper
        fingers).
    locked: {joint name: position} joints held fixed at that position (rad
        or m) and merged like fixed joints (e.g. fingers kept with their mass).
    name: the robot's name (default the URDF's). gravity: (3,) m/s^2 in the
        root link's frame. inertia_check: as Robot.from_dh.
    limits: 'file' (default) takes each joint's lower/upper and effort from
        its ``<limit>``; 'ignore' takes none (q and tau unbounded), for
        files whose limits are placeholders, as CAD exporters write them
        (lower = upper = 0, effort = 0), which 'file' refuses, naming the
        joint and this option.
    clamp: None or False (default) for the chain as it is; True puts the paper's parallel-jaw clamp on
        its last link (coopsim.robots.add_clamp with its defaults, mounted on the tip's frame), a dict
        of add_clamp's keywords (mount, opening, jaw_length, ...) sets them. The tip link's visuals
        are kept, moved into the turned last frame.
    hull_points: the most points (4 .. 4096, default 64) a collision mesh's convex hull keeps (see
        above): a hull's cost in the world's contacts grows with it. collision_meshes=False leaves the
        meshes out (the robot's other shapes, or the default boxes).
    snap: origin angles (rpy, rad) within `snap` of a multiple of pi/12 are
        read as that multiple: URDFs often write pi/2 as 1.57079632679, whose
        5e-12 rad would make every derived angle general (and generated code
        larger); 0 reads them as written.

    Raises ValueError naming the element for malformed URDF, a link that is
    the child of two joints (a closed loop), several roots, floating or
    planar joints, mimic joints in the chain, branches of movable joints (a
    tree; pass tip= or locked=) or no movable joint.
    """
    if limits not in ("file", "ignore"):
        raise ValueError(f"limits must be 'file' or 'ignore', got {limits!r}")
    if not _is_real(snap) or not 0.0 <= snap < 0.1:
        raise ValueError(f"snap must be in [0, 0.1) rad, got {snap!r}")
    snap = float(snap)
    hull_points = _checks.integer(hull_points, "hull_points", 4, 4096)
    if tip is not None and not isinstance(tip, str):
        raise ValueError(f"tip must be the name of a link (str) or None, got {type(tip).__name__}")
    if locked is not None and not isinstance(locked, Mapping):
        raise ValueError(f"locked must be a dict {{joint name: position}}, got {type(locked).__name__}")
    root, base_dir = _read(source)
    links = {}
    for el in root.findall("link"):
        ln = el.get("name")
        if not ln:
            raise ValueError("a <link> has no name")
        if ln in links:
            raise ValueError(f"link {ln!r} is defined twice")
        links[ln] = el
    locked = dict(locked or {})
    joints, child_of = {}, {}
    for el in root.findall("joint"):
        jn, jt = el.get("name"), el.get("type")
        if not jn:
            raise ValueError("a <joint> has no name")
        if jn in joints:
            raise ValueError(f"joint {jn!r} is defined twice")
        par, ch = el.find("parent"), el.find("child")
        if par is None or ch is None or par.get("link") not in links or ch.get("link") not in links:
            raise ValueError(f"joint {jn!r} must name a parent and a child link that exist")
        if jt in ("floating", "planar"):
            raise ValueError(f"joint {jn!r} is {jt}: floating bases and planar joints are not supported "
                             "(a serial arm on a fixed base is)")
        if jt not in _MOVABLE and jt != "fixed":
            raise ValueError(f"joint {jn!r} has the unsupported type {jt!r} (revolute, continuous, prismatic, "
                             "fixed)")
        c = ch.get("link")
        if c in child_of:
            raise ValueError(f"link {c!r} is the child of joints {child_of[c]!r} and {jn!r}: a closed loop, not a "
                             "serial chain")
        child_of[c] = jn
        joints[jn] = el
    for jn, v in locked.items():
        if jn not in joints or joints[jn].get("type") not in _MOVABLE:
            raise ValueError(f"locked: {jn!r} is not a movable joint of this URDF")
        if not _is_real(v) or not abs(v) <= _MAX_NUMBER:
            raise ValueError(f"locked: the position of {jn!r} must be a finite number (rad or m), got {v!r}")
    roots = [ln for ln in links if ln not in child_of]
    if len(roots) != 1:
        raise ValueError(f"a URDF robot needs exactly one root link, got {sorted(roots)!r}")
    base = roots[0]
    children = {ln: [] for ln in links}
    for jn, el in joints.items():
        children[el.find("parent").get("link")].append(jn)
    # every link has one parent at most, so a link the root does not reach hangs from a cycle of joints
    reached, todo = {base}, [base]
    while todo:
        for jn in children[todo.pop()]:
            c = joints[jn].find("child").get("link")
            if c not in reached:
                reached.add(c)
                todo.append(c)
    if len(reached) != len(links):
        cycle = sorted(jn for jn, el in joints.items() if el.find("child").get("link") not in reached)
        raise ValueError(f"joints {cycle!r} form a closed loop (a cycle of links) apart from the root {base!r}: "
                         "not a serial chain")

    def movable(jn):
        return joints[jn].get("type") in _MOVABLE and jn not in locked

    def path_to(ln):  # joints from the root to link ln
        out = []
        while ln in child_of:
            jn = child_of[ln]
            out.append(jn)
            ln = joints[jn].find("parent").get("link")
        return out[::-1]

    if tip is None:
        mov = [jn for jn in joints if movable(jn)]
        if not mov:
            raise ValueError("the URDF has no movable joint (revolute, continuous or prismatic)")
        ends = [jn for jn in mov if not any(jn in path_to(joints[m].find("child").get("link"))[:-1] for m in mov)]
        if len(ends) > 1:
            raise ValueError(f"the movable joints branch (a tree, not a chain): {sorted(ends)!r} end branches; "
                             "pass tip= to keep one chain (cutting the rest) or locked= to hold joints fixed")
        tip = joints[ends[0]].find("child").get("link")
        while len(children[tip]) == 1 and joints[children[tip][0]].get("type") == "fixed":
            tip = joints[children[tip][0]].find("child").get("link")
    elif tip not in links:
        raise ValueError(f"tip: no link named {tip!r}")
    chain = [jn for jn in path_to(tip) if movable(jn)]
    if not chain:
        raise ValueError(f"no movable joint between the root {base!r} and the tip {tip!r}")
    for jn in chain:
        if joints[jn].find("mimic") is not None:
            raise ValueError(f"joint {jn!r} mimics another: mimic joints are not supported (lock it with locked=)")

    # world poses at q = 0 (locked joints at their position) of every link, from the root down
    def motion(jn, value):
        el = joints[jn]
        ax = el.find("axis")
        u = np.array(_floats(ax.get("xyz"), 3, f"joint {jn!r} axis")) if ax is not None else np.array([1.0, 0, 0])
        if np.linalg.norm(u) < 1e-12:
            raise ValueError(f"joint {jn!r}: its axis must not be zero")
        u = _unit(u)
        T = np.eye(4)
        if el.get("type") == "prismatic":
            T[:3, 3] = value * u
        else:
            k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
            T[:3, :3] = np.eye(3) + math.sin(value) * k + (1 - math.cos(value)) * k @ k
        return T, u

    pose = {base: np.eye(4)}
    axes, points = [], []
    cut = set()
    order = [base]
    for ln in order:
        for jn in children[ln]:
            el = joints[jn]
            c = el.find("child").get("link")
            T = pose[ln] @ _pose(el, f"joint {jn!r}", snap)
            if el.get("type") in _MOVABLE:
                M, u = motion(jn, float(locked.get(jn, 0.0)))
                if movable(jn) and jn not in chain:
                    cut.add(c)
                    continue
                if jn in chain:
                    axes.append(T[:3, :3] @ u)
                    points.append(T[:3, 3].copy())
                T = T @ M
            pose[c] = T
            order.append(c)
    # bodies: the base and each chain joint's child, each with the links fixed to it
    body_of = {base: 0}
    for ln in order[1:]:
        jn = child_of[ln]
        body_of[ln] = chain.index(jn) + 1 if jn in chain else body_of[joints[jn].find("parent").get("link")]
    n = len(chain)
    frames = _chain_frames(points, axes)
    F = frames.F
    types = "".join(_MOVABLE[joints[jn].get("type")] for jn in chain)
    parts = [[] for _ in range(n + 1)]
    box_list, visual_list = [], []
    for ln in order:
        b = body_of[ln]
        X = np.linalg.inv(F[b]) @ pose[ln]  # link frame in the body's DH frame (frame 0 for the base)
        parts[b].append(_moved(X, *_inertial(links[ln], snap)))
        box_list += _collision_shapes(links[ln], ln, b, X, base_dir, snap, hull_points if collision_meshes else 0,
                                      (_attr, _floats, _mesh_path, _pose))
        for sh in links[ln].findall("visual"):
            v = _visual(sh, ln, b, X, base_dir, snap)
            if v is not None:
                visual_list.append(v)
    qlim = np.tile([-np.inf, np.inf], (n, 1))
    tau, K, Fc, Ia = np.full(n, np.inf), np.zeros(n), np.zeros(n), np.zeros(n)
    for i, jn in enumerate(chain):
        el = joints[jn]
        lim = el.find("limit")
        what = f"joint {jn!r}"
        if lim is not None and limits == "file":
            e = _attr(lim, "effort", what, 0.0, bounded=False)
            if el.get("type") != "continuous" and (lim.get("lower") is not None or lim.get("upper") is not None):
                qlim[i] = [_attr(lim, key, what, 0.0, bounded=False) for key in ("lower", "upper")]
                qlim[i] = np.where(np.abs(qlim[i]) >= _UNBOUNDED, np.copysign(np.inf, qlim[i]), qlim[i])
                if qlim[i, 0] == qlim[i, 1]:
                    raise ValueError(f"{what}: its <limit> has lower = upper = {qlim[i, 0]:g} (effort {e:g}), "
                                     "which leaves the joint no motion: placeholder values, as CAD exporters "
                                     "write them? Pass limits='ignore' to load the robot without the file's "
                                     "joint and effort limits")
                if not qlim[i, 0] < qlim[i, 1]:
                    raise ValueError(f"{what}: limit lower must be below upper, got {qlim[i].tolist()} "
                                     "(limits='ignore' loads the robot without the file's limits)")
            tau[i] = e if 0 < e < _UNBOUNDED else np.inf
        dyn = el.find("dynamics")
        if dyn is not None:
            K[i], Fc[i] = _attr(dyn, "damping", what, 0.0), _attr(dyn, "friction", what, 0.0)
    for tr in root.findall("transmission"):
        names = [j.get("name") for j in tr.findall("joint")]
        for act in tr.findall("actuator"):
            vals = {el.tag.split("}")[-1]: el for el in act}
            if "rotor_inertia" in vals:
                Jm = _attr(vals["rotor_inertia"], "value", f"transmission {tr.get('name')!r} rotor_inertia")
                G = _attr(vals.get("gear_ratio"), "value", "gear_ratio", 1.0) if "gear_ratio" in vals else 1.0
                for jn in names:
                    if jn in chain:
                        Ia[chain.index(jn)] += Jm * G * G
    tool = np.linalg.inv(F[n]) @ pose[tip] if tip not in cut else np.eye(4)
    robot = _chain_robot(frames, types, parts, tool, joint_names=chain,
                         link_names=[joints[jn].find("child").get("link") for jn in chain],
                         friction=K, coulomb=Fc, armature=Ia, q_limits=qlim, tau_limits=tau, boxes=box_list,
                         name=name or root.get("name") or "robot", gravity=gravity, coulomb_width=coulomb_width,
                         inertia_check=inertia_check)
    _register_visuals(robot, visual_list)
    return _with_clamp(robot, clamp)  # add_clamp: the visuals follow (_follow_visuals)
