"""What the robots look like in the live page and the replay: parts (boxes, cylinders, meshes) fixed to
link frames. One description, :func:`robot_parts`, feeds both views; the collision boxes (``robot.boxes``)
stay the shapes the world collides, and the views show them on request.

A :class:`Part` is a unit shape scaled along its own axes and placed in the DH frame of its link (0, the
base frame, for the base): ``world pose = robot.frames(q)[part.link] @ part.pose`` (:func:`part_poses`), so
it moves with the link's joint. Shapes: ``box`` (a unit cube centred on the pose; scale = its edge
lengths), ``cylinder`` (diameter 1 and length 1 along the pose's z, centred; scale = (diameter, diameter,
length)), ``mesh`` (a mesh file's triangles in its own units; scale = the file's scale, as a URDF gives
it). ``color`` names the colour it takes: ``'robot'`` the robot's own colour, ``'base'`` and ``'jaw'``
those of :data:`~coopsim.view.COLORS`; every part on a moving link (link > 0) turns the holding green while
its robot holds, as the boxes do.

Which look a robot gets (:func:`look_kind`), decided from the robot's own data, never from its name:

- ``'scara1'`` / ``'scara2'``: the robot is one :func:`coopsim.robots.scara1` / ``scara2`` builds. Its
  joint types are the maker's, its recorded ``dimensions`` are exactly the maker's set of keys, it has a
  clamp, and its DH table equals (to 1e-12) the one the maker builds from those dimensions. Drawn as the
  paper's SCARAs (its Figs. 5 to 7): base plate and column, a cylindrical housing at each revolute joint of
  the arm, segments between them, the quill guide and the quill, the wrist, the clamp body with its jaw
  rail, the fixed and the moving jaw, every size from the dimensions (a longer L1 stretches segment 1
  only: housings keep their size, which follows the robot's width and height).
- ``'urdf'``: a robot :func:`coopsim.urdf.from_urdf` read from a file with ``<visual>`` geometry
  (:func:`coopsim.visuals.visuals`): each link drawn with its visual meshes, boxes and cylinders; a link
  without any, with its own collision boxes.
- ``'boxes'``: any other robot (built from tables): its collision boxes, one box part each.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .._core import dh_transform
from ..robots import _SCARA1, _SCARA2
from ..visuals import visuals

__all__ = ["Part", "robot_parts", "look_kind", "part_poses", "part_corners", "mesh_triangles", "UNIT_CUBE",
           "UNIT_CYLINDER"]

_SHAPES = ("box", "cylinder", "mesh")
_COLORS = ("robot", "base", "jaw")


@dataclass(frozen=True, eq=False)
class Part:
    """A piece of a robot's look: a unit shape scaled along its axes, fixed in the DH frame of `link`.

    name: unique among the robot's parts (e.g. ``segment1``, ``housing2``, ``quill``). link: 0 (base)
    .. n. shape: 'box', 'cylinder' or 'mesh'. scale (3,): a box's edges (m); a cylinder's (diameter,
    diameter, length) (m), its axis along the pose's z; a mesh's scale factors. pose (4, 4): the shape's
    centre and axes in the link's DH frame. color: 'robot', 'base' or 'jaw'. mesh: the mesh file
    (shape 'mesh').
    """

    name: str
    link: int
    shape: str
    scale: np.ndarray
    pose: np.ndarray
    color: str = "robot"
    mesh: Optional[str] = None

    def __post_init__(self):
        if self.shape not in _SHAPES:
            raise ValueError(f"shape must be one of {_SHAPES}, got {self.shape!r}")
        if self.color not in _COLORS:
            raise ValueError(f"color must be one of {_COLORS}, got {self.color!r}")
        s = np.asarray(self.scale, dtype=float).reshape(3)
        if not np.all(np.isfinite(s)) or np.any(s == 0) or (self.shape != "mesh" and np.any(s < 0)):
            raise ValueError(f"part {self.name!r}: scale must be 3 finite sizes > 0, got {self.scale!r}")
        object.__setattr__(self, "scale", s)
        object.__setattr__(self, "pose", np.asarray(self.pose, dtype=float).reshape(4, 4))
        if (self.shape == "mesh") != (self.mesh is not None):
            raise ValueError(f"part {self.name!r}: a mesh file goes with shape 'mesh' and only with it")


# ---- unit shapes (the live page's meshes; the replay draws three.js's box and cylinder of the same sizes) ----

def _unit_cube():
    """A cube of side 1 centred at 0: 24 vertices (4 per face, so that each face shades flat), 12 triangles
    counter-clockwise seen from outside."""
    v, f = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            w = np.cross(n, u)
            c = 0.5 * n
            k = len(v)
            v += [c + 0.5 * (a * u + b * w) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            f += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
    return np.array(v, dtype=np.float32), np.array(f, dtype=np.uint32)


def _unit_cylinder(sides: int = 32):
    """A cylinder of diameter 1 and length 1 along z, centred at 0: the side's vertices shared around it
    (smooth), each cap with its own (flat)."""
    a = 2 * np.pi * np.arange(sides) / sides
    ring = np.column_stack([0.5 * np.cos(a), 0.5 * np.sin(a)])
    v = [np.column_stack([ring, np.full(sides, z)]) for z in (-0.5, 0.5)]            # side: bottom, top rings
    v += [np.column_stack([ring, np.full(sides, z)]) for z in (-0.5, 0.5)]           # caps' rings
    v += [np.array([[0.0, 0.0, -0.5], [0.0, 0.0, 0.5]])]                             # caps' centres
    i = np.arange(sides)
    j = (i + 1) % sides
    side = np.concatenate([np.column_stack([i, j, sides + j]), np.column_stack([i, sides + j, sides + i])])
    c0, c1 = 4 * sides, 4 * sides + 1
    bottom = np.column_stack([np.full(sides, c0), 2 * sides + j, 2 * sides + i])
    top = np.column_stack([np.full(sides, c1), 3 * sides + i, 3 * sides + j])
    return np.concatenate(v).astype(np.float32), np.concatenate([side, bottom, top]).astype(np.uint32)


#: (vertices (24, 3) float32, faces (12, 3) uint32) of the unit cube.
UNIT_CUBE = _unit_cube()
#: (vertices float32, faces uint32) of the unit cylinder (diameter 1, length 1 along z).
UNIT_CYLINDER = _unit_cylinder()


@functools.lru_cache(maxsize=64)
def mesh_triangles(path: str):
    """(vertices (v, 3) float32, faces (f, 3) uint32) of a mesh file (STL, OBJ, DAE, ... as trimesh reads
    them; its parts merged in the file's own frame and units). Needs trimesh (and pycollada for DAE): the
    ``live`` extra."""
    try:
        import trimesh  # the live extra: only for robots drawn with meshes
    except ImportError:
        raise ImportError("drawing a robot's mesh files needs trimesh (and pycollada for .dae): "
                          "pip install 'coopsim[live]' (scripts/setup.sh installs it)") from None
    try:
        m = trimesh.load(path, force="mesh", process=False)
    except Exception as e:       # trimesh raises many kinds for a file it cannot read
        raise ValueError(f"mesh file {path!r} cannot be read: {type(e).__name__}: {e}") from None
    v = np.asarray(m.vertices, dtype=np.float32).reshape(-1, 3)
    f = np.asarray(m.faces, dtype=np.uint32).reshape(-1, 3)
    if not len(f) or not np.all(np.isfinite(v)):
        raise ValueError(f"mesh file {path!r} has no triangles with finite vertices")
    return v, f


# ---- which look ----

def look_kind(robot) -> str:
    """'scara1', 'scara2', 'urdf' or 'boxes': how the views draw `robot` (see the module's docstring)."""
    dims = robot.dimensions
    for spec in (_SCARA1, _SCARA2):          # the makers' own tables
        if robot.joint_types != spec["types"] or set(dims) != set(spec["defaults"]) or robot.clamp is None:
            continue
        dh = np.asarray(spec["geometry"](dims)[0], dtype=float)
        if np.asarray(robot.dh).shape == dh.shape and np.allclose(robot.dh, dh, rtol=0.0, atol=1e-12):
            return spec["name"]
    return "urdf" if visuals(robot) else "boxes"


def robot_parts(robot) -> list:
    """The parts `robot` is drawn with (a list of :class:`Part`), by :func:`look_kind`."""
    kind = look_kind(robot)
    if kind in ("scara1", "scara2"):
        return _scara_parts(robot, kind)
    if kind == "urdf":
        return _urdf_parts(robot)
    return _box_parts(robot, robot.boxes)


def part_poses(robot, parts, q) -> np.ndarray:
    """World poses (m, 4, 4) of the parts at joint positions q (n,): ``robot.frames(q)[link] @ pose``;
    for N states q (N, n), (N, m, 4, 4)."""
    q = np.asarray(q, dtype=float)
    links = np.array([p.link for p in parts], dtype=int)
    local = np.array([p.pose for p in parts]).reshape(-1, 4, 4)
    if q.ndim == 1:
        F = np.asarray(robot.frames(q))
        return np.einsum("kij,kjl->kil", F[links], local)
    F = np.array([robot.frames(x) for x in q])
    return np.einsum("fkij,kjl->fkil", F[:, links], local)


def part_corners(parts, poses) -> np.ndarray:
    """World points (m * 8, 3) that frame the parts at their world poses (m, 4, 4) (or (N, m, 4, 4):
    (N * m * 8, 3)): the corners of each part's box in its own axes (a mesh's: its vertices' bounds)."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    local = []
    for p in parts:
        if p.shape == "mesh":
            v = mesh_triangles(p.mesh)[0] * p.scale
            lo, hi = v.min(axis=0), v.max(axis=0)
            local.append((lo + hi) / 2 + signs * (hi - lo) / 2)
        else:
            local.append(signs * p.scale / 2)
    local = np.array(local).reshape(len(parts), 8, 3)
    W = np.asarray(poses, dtype=float).reshape(-1, len(parts), 4, 4)
    return (np.einsum("fkij,kcj->fkci", W[..., :3, :3], local) + W[:, :, None, :3, 3]).reshape(-1, 3)


# ---- the looks ----

def _box_role(robot, box) -> str:
    """The colour of a collision box, as the views colour boxes: base, jaw, or the robot's."""
    moving = robot.clamp.moving_joint if robot.clamp is not None else -1
    return "base" if box.link == 0 else "jaw" if ("jaw" in box.name or box.link == moving) else "robot"


def _box_parts(robot, boxes) -> list:
    return [Part(f"box_{b.name or k}", b.link, "box", 2 * np.asarray(b.half_extents), np.asarray(b.pose),
                 _box_role(robot, b)) for k, b in enumerate(boxes)]


def _urdf_parts(robot) -> list:
    vis = visuals(robot)
    out, drawn = [], set()
    for k, v in enumerate(vis):
        out.append(Part(f"visual{k}_{v.name}", v.link, v.shape, v.scale, v.pose, "base" if v.link == 0 else "robot",
                        v.path))
        drawn.add(v.link)
    return out + _box_parts(robot, [b for b in robot.boxes if b.link not in drawn])


def _T(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _scara_parts(robot, kind: str) -> list:
    """The paper's SCARA from its dimensions: see the module's docstring. Sizes across the arm follow the
    width w and the link height h; lengths along it follow L_base, L1, L2 (L3), L4, L5, the quill and the
    jaws."""
    d = robot.dimensions
    dh = np.asarray(robot.dh, dtype=float)
    w, h = d["width"], d["height"]
    Lb, ql, Lj, tj = d["L_base"], d["quill_length"], d["jaw_length"], d["jaw_thickness"]
    arm = [1, 2] if kind == "scara1" else [1, 2, 3]         # the horizontal arm's revolute links
    quill = arm[-1] + 1                                     # the prismatic quill's link

    def into(i, T):
        """A pose given in frame i-1 with joint i at zero, in frame i (where link i carries it)."""
        return np.linalg.solve(dh_transform(*dh[i - 1]), T)

    parts = []
    add = lambda *a, **k: parts.append(Part(*a, **k))       # noqa: E731
    # base: a plate on the floor and a column up to the first joint's housing
    tp = 0.25 * w
    add("base_plate", 0, "box", (3.2 * w, 3.2 * w, tp), _T(z=tp / 2), "base")
    housing = (1.3 * w, 1.3 * w, 1.3 * h)
    top = Lb - housing[2] / 2
    if top - tp > 1e-4:
        add("column", 0, "cylinder", (1.6 * w, 1.6 * w, top - tp), _T(z=(top + tp) / 2), "base")
    # the arm: a housing at each joint's axis (in frame i at (-a_i, 0, 0), z_i along the axis), the segment
    # from there to the next joint
    for i in arm:
        a = dh[i - 1, 2]
        add(f"housing{i}", i, "cylinder", housing, _T(-a), "robot")
        add(f"segment{i}", i, "box", (a, 0.75 * w, 0.7 * h), _T(-a / 2), "robot")
    add("quill_guide", arm[-1], "cylinder", (1.1 * w, 1.1 * w, 1.8 * h), _T(), "robot")
    # the quill: its tip at the frame's origin, the shaft up along -z (z points down the quill)
    add("quill", quill, "cylinder", (0.35 * w, 0.35 * w, ql), _T(z=-ql / 2), "jaw")
    # the wrist and the clamp body
    if kind == "scara1":
        L4, L5 = d["L4"], d["L5"]
        add("housing4", 4, "cylinder", (0.6 * w, 0.6 * w, L4), into(4, _T(z=L4 / 2)), "robot")   # yaw, below the quill
        add("housing5", 5, "cylinder", (0.9 * h, 0.9 * h, 1.1 * w), _T(-L5), "robot")             # pitch axis z4 = z5
        add("clamp_body", 5, "box", (L5, 0.8 * w, 0.7 * h), _T(-L5 / 2), "robot")                  # along x5
    else:
        L5 = d["L5"]
        add("housing5", 5, "cylinder", (0.8 * w, 0.8 * w, 0.6 * h), into(5, _T(z=0.3 * h)), "robot")  # yaw, at the quill tip
        add("clamp_body", 5, "box", (0.8 * w, 0.7 * h, L5), into(5, _T(z=L5 / 2)), "robot")           # down to frame 5
    # the clamp (robot.clamp): jaws as plates on each side of the fixed jaw's inner face (x along the jaw, away
    # from the body; z towards the moving jaw), the rail they hang from across the jaws' travel
    c = robot.clamp
    face = np.asarray(c.fixed_face, dtype=float)
    travel = float(robot.q_limits[c.moving_joint - 1, 1])
    travel = travel if math.isfinite(travel) and travel > 0 else 0.0
    add("clamp_rail", c.fixed_link, "box", (tj, 0.6 * w, travel + 2 * tj), face @ _T(-Lj / 2 - tj / 2, 0.0, travel / 2),
        "robot")
    add("fixed_jaw", c.fixed_link, "box", (Lj, w, tj), face @ _T(z=-tj / 2), "jaw")
    add("moving_jaw", c.moving_joint, "box", (Lj, w, tj), into(c.moving_joint, face @ _T(z=tj / 2)), "jaw")
    return parts
