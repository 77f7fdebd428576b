"""MJCF in: a serial chain of a MuJoCo model as a coopsim robot.

MuJoCo reads and compiles the file (``mujoco.MjSpec``: defaults, ``childclass``, ``quat`` / ``euler`` /
``axisangle`` / ``xyaxes`` / ``zaxis`` frames, ``fullinertia``, inertias from geoms, ``compiler angle``,
``meshdir``, includes), so coopsim has no MJCF parser of its own. This module reads the compiled model:
MuJoCo's forward kinematics at q = 0 gives every body's frame, principal inertia frame, joint anchor and
axis in world coordinates, and the importers' common path of coopsim.urdf (``_chain_frames``: the joint axes
as standard DH rows with a base; ``_chain_robot``: the bodies combined into links) makes the robot, as
``from_urdf`` does for URDF.
"""
from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np

from . import _checks
from .urdf import _chain_frames, _chain_robot, _moved, _with_clamp, _UNBOUNDED
from ._core import LinkBox

__all__ = ["from_mjcf"]

_HINGE, _SLIDE, _BALL, _FREE = 3, 2, 1, 0   # mujoco.mjtJoint
_KIND = {_FREE: "a free joint", _BALL: "a ball joint"}


def _mujoco():
    try:
        import mujoco
    except ImportError:
        raise ImportError("from_mjcf needs the mujoco package (pip install 'mujoco>=3.2'; it is in coopsim's "
                          "test extra)") from None
    return mujoco


def _one_line(e) -> str:
    return " ".join(str(e).split())


def _model(source):
    """The compiled MjModel of a path, MJCF text or an MjSpec / MjModel."""
    mujoco = _mujoco()
    if isinstance(source, mujoco.MjModel):
        return source
    try:
        if isinstance(source, mujoco.MjSpec):
            return source.compile()
        if isinstance(source, os.PathLike) or (isinstance(source, str) and not source.lstrip().startswith("<")):
            path = os.fspath(source)
            if not os.path.isfile(path):
                raise ValueError(f"source must be MJCF text or the path of an MJCF file; no file {path!r}")
            return mujoco.MjSpec.from_file(path).compile()
        if not isinstance(source, str):
            raise ValueError(f"source must be MJCF text, a path, a mujoco.MjSpec or a mujoco.MjModel, "
                             f"got {type(source).__name__}")
        return mujoco.MjSpec.from_string(source).compile()
    except ValueError as e:
        if str(e).startswith("source "):
            raise
        raise ValueError(f"source: MuJoCo cannot read or compile it: {_one_line(e)}") from None


def from_mjcf(source, *, body: str | None = None, tip: str | None = None, locked: dict | None = None,
              name: str | None = None, gravity=None, coulomb_width=0.01, inertia_check: str = "warn",
              limits: str = "file", clamp=None):
    """A coopsim.Robot from a fixed-base serial chain of an MJCF model.

    source: the path of an MJCF file, MJCF text, a ``mujoco.MjSpec`` or a compiled ``mujoco.MjModel``
    (MuJoCo parses and compiles it: the ``mujoco`` package, in the test extra).

    The chain: the bodies from ``body`` (its base, fixed to the world: no joint on its path from the
    world) down to ``tip`` (its last body), each body's hinge (R) and slide (P) joints in the file's
    order, so q[i] is MuJoCo's qpos of ``robot.joint_names[i]`` (same zero, sign and units: rad, m;
    a joint's ``ref`` is MuJoCo's qpos0, not coopsim's zero) and ``robot.link_names[i]`` the body it
    moves (``body:joint`` for all but the last of a body's several joints, a link without mass).
    Bodies without joints merge into their parent (mass, centre of mass, inertia, box geoms). The
    robot is placed in the world's coordinates: DH frame 0 on the first axis is its base (position,
    yaw, and a base_orientation for a first axis that is not the world's z); the tip body's frame is
    the tool. Bodies of the base's subtree that are off the path and move (fingers, objects) are cut
    with their subtrees; ``locked`` keeps them, or joints on the path, fixed at a position.

    Read from the compiled model: masses, centres of mass and principal inertias in their frames,
    joint anchors and axes; ``dof_damping`` as the viscous K, ``dof_frictionloss`` as Coulomb F_c
    (smooth, v_c = ``coulomb_width`` rad/s or m/s; MuJoCo's is a constraint), ``dof_armature`` as the
    armature; ``jnt_range`` of limited joints as q_limits; tau_limits from the joint's
    ``actuatorfrcrange`` or else a single joint actuator's ``forcerange`` times its gear (the larger
    bound's magnitude); box geoms that collide (contype or conaffinity not 0) as the robot's boxes
    (other shapes are left out; a robot without boxes gets the default ones). Not read: actuator
    dynamics and gains, tendons, equality constraints, contacts, fluid forces, sites.

    body: the base body (default the world body). tip: the last body (default the end of the only
    chain of moving bodies under ``body``, followed down single children without joints).
    locked: {joint name: position (rad or m)} hinge or slide joints held fixed.
    name: the robot's name (default the model's). gravity: (3,) m/s^2 in the world (default the
    file's ``<option gravity>``). coulomb_width, inertia_check: as Robot.from_dh.
    limits: 'file' (default) takes joint ranges and force ranges; 'ignore' none.
    clamp: as from_urdf: True or a dict of coopsim.robots.add_clamp's keywords puts the paper's
    clamp on the last link, mounted on the tip body's frame.

    Raises ValueError naming what is not supported: a free joint (a floating base), a ball joint,
    a tree (a body with two moving branches under ``body``, when ``tip`` is not given), a base that
    moves, joint springs (``stiffness``) or gravity compensation (``gravcomp``) in the chain; and
    for unknown bodies or joints, or a file MuJoCo cannot read (its message, on one line).
    """
    mujoco = _mujoco()
    _checks.one_of(limits, "limits", ("file", "ignore"))
    for what, v in (("body", body), ("tip", tip)):
        if v is not None and not isinstance(v, str):
            raise ValueError(f"{what} must be the name of a body (str) or None, got {type(v).__name__}")
    if locked is not None and not isinstance(locked, Mapping):
        raise ValueError(f"locked must be a dict {{joint name: position}}, got {type(locked).__name__}")
    m = _model(source)
    obj = mujoco.mjtObj

    def body_name(b):
        return mujoco.mj_id2name(m, obj.mjOBJ_BODY, b) or f"body{b}"

    def joint_name(j):
        return mujoco.mj_id2name(m, obj.mjOBJ_JOINT, j) or f"joint{j}"

    def said(j):  # a joint as a message names it
        nm = mujoco.mj_id2name(m, obj.mjOBJ_JOINT, j)
        return f"joint {nm!r}" if nm else f"the unnamed joint {j}"

    def body_id(nm, what):
        b = mujoco.mj_name2id(m, obj.mjOBJ_BODY, nm)
        if b < 0:
            raise ValueError(f"{what}: no body named {nm!r}")
        return b

    locked = dict(locked or {})
    lock = {}
    for jn, v in locked.items():
        j = mujoco.mj_name2id(m, obj.mjOBJ_JOINT, jn) if isinstance(jn, str) else -1
        if j < 0 or m.jnt_type[j] not in (_HINGE, _SLIDE):
            raise ValueError(f"locked: {jn!r} is not a hinge or slide joint of this model")
        lock[j] = _checks.number(v, f"locked[{jn!r}]", -1e12, 1e12)

    parent = m.body_parentid
    children = [[] for _ in range(m.nbody)]
    for b in range(1, m.nbody):
        children[parent[b]].append(b)

    def joints(b):  # the body's joints that move (locked ones do not)
        return [j for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]) if j not in lock]

    def path(b, top):  # bodies below top down to b, in order
        out = []
        while b != top:
            out.append(b)
            b = parent[b]
        return out[::-1]

    def unsupported(b):
        for j in joints(b):
            if m.jnt_type[j] in (_FREE, _BALL):
                why = ("floating bases are not supported (a serial arm on a fixed base is: pass body= the body "
                       "it is mounted on)" if m.jnt_type[j] == _FREE else
                       "ball joints are not supported (hinge and slide joints are)")
                raise ValueError(f"{said(j)} of body {body_name(b)!r} is {_KIND[m.jnt_type[j]]}: {why}")

    base = 0 if body is None else body_id(body, "body")
    for b in path(base, 0):  # the world's bodies down to the base, which must not move
        if joints(b):
            raise ValueError(f"body: the base body {body_name(base)!r} moves with {said(joints(b)[0])} of body "
                             f"{body_name(b)!r}; the chain's base must be fixed to the world")
    subtree, todo = [], [base]
    while todo:
        b = todo.pop()
        subtree.append(b)
        todo.extend(reversed(children[b]))
    if tip is None:
        moving = [b for b in subtree if b != base and joints(b)]
        if not moving:
            raise ValueError(f"no hinge or slide joint under the body {body_name(base)!r}")
        for b in moving:
            unsupported(b)
        ends = [b for b in moving if not any(c != b and b in path(c, base) for c in moving)]
        if len(ends) > 1:
            fork = [b for b in path(ends[0], base) if b in path(ends[1], base)]
            at = fork[-1] if fork else base
            raise ValueError(f"body {body_name(at)!r} has two moving branches (to {body_name(ends[0])!r} and "
                             f"{body_name(ends[1])!r}): a tree, not a serial chain; pass tip= to keep one chain "
                             "(cutting the others) or locked= to hold joints fixed")
        t = ends[0]
        while len(children[t]) == 1 and not m.body_jntnum[children[t][0]]:
            t = children[t][0]
    else:
        t = body_id(tip, "tip")
        if t not in subtree or t == base:
            raise ValueError(f"tip: the body {tip!r} is not below the base body {body_name(base)!r}")
    on_path = path(t, base)
    for b in on_path:
        unsupported(b)
    chain = [j for b in on_path for j in joints(b)]
    if not chain:
        raise ValueError(f"no hinge or slide joint between the base body {body_name(base)!r} and the tip "
                         f"{body_name(t)!r}")

    # MuJoCo's kinematics at q = 0 (locked joints at their position, others of the model at qpos0)
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    for j in chain:
        d.qpos[m.jnt_qposadr[j]] = 0.0
    for j, v in lock.items():
        d.qpos[m.jnt_qposadr[j]] = v
    mujoco.mj_kinematics(m, d)
    frames = _chain_frames([d.xanchor[j].copy() for j in chain], [d.xaxis[j].copy() for j in chain])
    F = frames.F
    n = len(chain)

    def pose(p, R):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = np.asarray(R).reshape(3, 3), p
        return T

    # link of each body: the base 0, a body on the path its last chain joint's, a fixed body its parent's
    link = {base: 0}
    last = {b: chain.index(joints(b)[-1]) + 1 for b in on_path if joints(b)}
    for b in subtree[1:]:
        if b in last:
            link[b] = last[b]
        elif parent[b] in link and (b in on_path or not joints(b)):
            link[b] = link[parent[b]]
    parts = [[] for _ in range(n + 1)]
    boxes = []
    for b in subtree:
        if b not in link:
            continue
        i = link[b]
        if i and m.body_gravcomp[b] != 0:
            raise ValueError(f"body {body_name(b)!r} has gravcomp {m.body_gravcomp[b]:g}: gravity compensation "
                             "is not supported")
        Finv = np.linalg.inv(F[i])
        R = d.ximat[b].reshape(3, 3)
        parts[i].append(_moved(Finv, float(m.body_mass[b]), d.xipos[b].copy(), R @ np.diag(m.body_inertia[b]) @ R.T))
        for k, g in enumerate(range(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b])):
            if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX and (m.geom_contype[g] or m.geom_conaffinity[g]):
                gname = mujoco.mj_id2name(m, obj.mjOBJ_GEOM, g) or f"{body_name(b)}_{k}"
                boxes.append(LinkBox(i, m.geom_size[g].copy(), Finv @ pose(d.geom_xpos[g], d.geom_xmat[g]), gname))

    qlim = np.tile([-np.inf, np.inf], (n, 1))
    tau = np.full(n, np.inf)
    dofs = [m.jnt_dofadr[j] for j in chain]
    for i, j in enumerate(chain):
        if m.jnt_stiffness[j] != 0:
            raise ValueError(f"{said(j)} has stiffness {m.jnt_stiffness[j]:g} (a spring): joint springs are not "
                             "supported")
        if limits == "file":
            if m.jnt_limited[j]:
                qlim[i] = m.jnt_range[j]
            bound = None
            if m.jnt_actfrclimited[j]:
                bound = np.abs(m.jnt_actfrcrange[j]).max()
            else:
                acts = [a for a in range(m.nu) if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                        and m.actuator_trnid[a, 0] == j]
                if len(acts) == 1 and m.actuator_forcelimited[acts[0]]:
                    a = acts[0]
                    bound = abs(m.actuator_gear[a, 0]) * np.abs(m.actuator_forcerange[a]).max()
            if bound is not None and 0 < bound < _UNBOUNDED:
                tau[i] = bound
    names = [joint_name(j) for j in chain]
    link_names = [body_name(m.jnt_bodyid[j]) if j == joints(m.jnt_bodyid[j])[-1]
                  else f"{body_name(m.jnt_bodyid[j])}:{joint_name(j)}" for j in chain]
    model_name = bytes(m.names).split(b"\0", 1)[0].decode() or "robot"
    robot = _chain_robot(frames, "".join("R" if m.jnt_type[j] == _HINGE else "P" for j in chain), parts,
                         np.linalg.inv(F[n]) @ pose(d.xpos[t], d.xmat[t]), joint_names=names, link_names=link_names,
                         boxes=boxes, name=name or model_name,
                         gravity=np.array(m.opt.gravity) if gravity is None else gravity,
                         friction=m.dof_damping[dofs], coulomb=m.dof_frictionloss[dofs], armature=m.dof_armature[dofs],
                         q_limits=qlim, tau_limits=tau, coulomb_width=coulomb_width, inertia_check=inertia_check)
    return _with_clamp(robot, clamp)
