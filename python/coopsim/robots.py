"""The two SCARA robots of the paper, built from DH and centre-of-mass tables.

The paper gives the joint structure (Tables 1 and 2) but no numbers; the
defaults below are coopsim's (listed with their units in the README's table
"The two SCARAs"). Every dimension is
a keyword argument. Changing one rebuilds the tables, and the mass properties
follow it: each link is a uniform box whose mass scales with its volume
(constant density), unless ``masses`` is given, and whose inertia tensor is
the box's about its centre of mass.

Clamp model (both robots): a fixed jaw on the clamp body (link 5) and a moving
jaw (link 6) on a prismatic joint whose variable is the opening d6 between the
jaws' inner faces. Jaws are plates of ``jaw_length`` x ``width`` x
``jaw_thickness``. The tool centre point (TCP) is midway between the jaws'
inner faces, halfway along the jaws; the tool frame has z along the approach
(out of the clamp), y along the jaw axis (fixed jaw towards moving jaw).

Shapes (``robot.boxes``, ``robot.shapes(q)``): each link's box is the uniform
box of its mass properties, centred on its centre of mass with the axes of
its CoM frame (named ``link1`` ... ``link6``; ``link6`` is the moving jaw);
the fixed jaw is a second box on link 5 (``fixed_jaw``), the mirror of the
moving one across the fixed jaw's inner face; the base is a column
(``base``) of square section 2 ``width`` standing on the floor of frame 0
(z = 0) up to the underside of link 1 (``L_base - height / 2``).
``robot.clamp`` describes the jaws (``coopsim.Clamp``). Boxes that touch
at every pose: each link with the next (they meet at their joint), the
base column with link 1, and on both robots the fixed jaw with the clamp
body (its own link) and with the moving jaw when the clamp is closed
(d6 = 0, faces in contact); the world's collision filter leaves adjacent
links out (``tests/test_robots.py::test_scara_boxes_overlap_only_where_they_touch``).

The same clamp on any serial arm: ``add_clamp(robot, mount=...)`` (defaults
CLAMP_DEFAULTS, SCARA #1's clamp).

Units: m, kg, rad, N, N m.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from . import _checks
from ._core import Clamp, LinkBox, Robot, Tool, box_inertia, compiled_generated_names, dh_transform
from .visuals import _follow_visuals

__all__ = ["scara1", "scara2", "SCARA1_DEFAULTS", "SCARA2_DEFAULTS", "SCARA1_BOUNDS", "SCARA2_BOUNDS", "Bound",
           "add_clamp", "CLAMP_DEFAULTS"]

DEG = math.pi / 180.0

#: SCARA #1 (RRPRRP) defaults: lengths in m, masses in kg.
SCARA1_DEFAULTS = dict(
    L_base=0.42,        # base height: floor to joint 2's plane
    L1=0.30,            # first arm segment
    L2=0.25,            # second arm segment
    L4=0.05,            # wrist: quill tip to the pitch axis
    L5=0.08,            # clamp body: pitch axis to the jaws
    quill_length=0.30,  # vertical quill (joint 3 strokes 0 .. 0.25 down)
    jaw_length=0.04,
    jaw_thickness=0.01,
    width=0.06,         # robot width w
    height=0.04,        # link height h
)


class Bound(NamedTuple):
    """The range a dimension of a built-in SCARA may take (m, both ends included) and why."""
    low: float
    high: float
    why: str


# Why the ranges below. The robots' actuators (tau_limits), joint limits and strokes (q_limits) stay the
# defaults' whatever the dimensions, and each link is a uniform box whose mass follows its volume: the
# bounds keep a rebuilt robot one those actuators can move and the drawn parts can form.
_ARM = "an arm segment: at least a joint housing (1.3 x the default width) long; at most where the arm's " \
       "inertia about joint 1 is about 8x the default's for the same joint-1 torque limit"
_ACROSS = "the links' cross-section: at least 2 cm; at most where the quill's force limit (joint 3 of " \
          "SCARA #1, joint 4 of #2) still holds the links it carries, the longest quill included"
_JAW = "the clamp's jaw plates: from a 2 mm plate to a 10 cm jaw; the opening strokes 0 .. 5 cm"
_BASE = "the base height: link 1 above the base plate; at most a 1 m column, a bench robot"
_WRIST = "the wrist and clamp body: 1 .. 30 cm, carried by the quill (its force limit)"

#: SCARA #1's dimension bounds (m): Bound(low, high, why) per keyword of SCARA1_DEFAULTS; a dimension
#: outside is refused by scara1() with a ValueError naming the range.
SCARA1_BOUNDS = dict(
    L_base=Bound(0.10, 1.00, _BASE),
    L1=Bound(0.08, 0.60, _ARM),
    L2=Bound(0.08, 0.60, _ARM),
    L4=Bound(0.01, 0.30, _WRIST),
    L5=Bound(0.01, 0.30, _WRIST),
    quill_length=Bound(0.25, 0.60, "the quill: at least its stroke (0.25 m, q_limits), at most 0.6 m (its "
                                   "weight on the joint-3 force limit)"),
    jaw_length=Bound(0.01, 0.10, _JAW),
    jaw_thickness=Bound(0.002, 0.03, _JAW),
    width=Bound(0.02, 0.10, _ACROSS),
    height=Bound(0.02, 0.08, _ACROSS),
)
_SCARA1_MASSES = np.array([3.0, 2.2, 0.8, 0.3, 0.25, 0.05])
_SCARA1_K = np.array([1.0, 0.8, 4.0, 0.05, 0.05, 2.0])
_SCARA1_QLIM = np.array([[-160 * DEG, 160 * DEG], [-145 * DEG, 145 * DEG], [0.0, 0.25],
                         [-180 * DEG, 180 * DEG], [-10 * DEG, 120 * DEG], [0.0, 0.05]])
_SCARA1_TAU = np.array([30.0, 20.0, 100.0, 2.0, 2.0, 15.0])

#: SCARA #2 (RRRPRP) defaults.
SCARA2_DEFAULTS = dict(
    L_base=0.40,
    L1=0.20,
    L2=0.18,
    L3=0.15,
    L5=0.06,            # clamp body, vertical, below the quill tip
    quill_length=0.30,  # joint 4 strokes 0 .. 0.30 down
    jaw_length=0.04,
    jaw_thickness=0.01,
    width=0.05,
    height=0.04,
)

#: SCARA #2's dimension bounds (m), as SCARA1_BOUNDS (three arm segments: shorter ones).
SCARA2_BOUNDS = dict(
    L_base=Bound(0.10, 1.00, _BASE),
    L1=Bound(0.07, 0.40, _ARM),
    L2=Bound(0.07, 0.40, _ARM),
    L3=Bound(0.07, 0.40, _ARM),
    L5=Bound(0.01, 0.30, _WRIST),
    quill_length=Bound(0.30, 0.60, "the quill: at least its stroke (0.30 m, q_limits), at most 0.6 m (its "
                                   "weight on the joint-4 force limit)"),
    jaw_length=Bound(0.01, 0.10, _JAW),
    jaw_thickness=Bound(0.002, 0.03, _JAW),
    width=Bound(0.02, 0.10, _ACROSS),
    height=Bound(0.02, 0.08, _ACROSS),
)
_SCARA2_MASSES = np.array([2.0, 1.6, 1.2, 0.6, 0.25, 0.05])
_SCARA2_K = np.array([0.8, 0.6, 0.4, 3.0, 0.05, 2.0])
_SCARA2_QLIM = np.array([[-170 * DEG, 170 * DEG], [-150 * DEG, 150 * DEG], [-150 * DEG, 150 * DEG],
                         [0.0, 0.30], [-180 * DEG, 180 * DEG], [0.0, 0.05]])
_SCARA2_TAU = np.array([25.0, 15.0, 8.0, 80.0, 1.5, 15.0])


def _check_dims(dims: dict, defaults: dict, name: str, bounds: dict) -> dict:
    unknown = set(dims) - set(defaults)
    if unknown:
        raise TypeError(f"{name}() got unknown dimension(s) {sorted(unknown)}; known: {sorted(defaults)}")
    out = dict(defaults)
    for key, value in dims.items():
        v = _checks.positive(value, key, unit="m", text=True)
        b = bounds[key]
        if not b.low <= v <= b.high:
            raise ValueError(f"{key} of {name} must be {b.low:g} .. {b.high:g} m ({b.why}), got {value!r}")
        out[key] = v
    return out


def _masses(boxes, default_boxes, default_masses, masses, n):
    """Masses at constant density (volume ratio), or the given ones."""
    if masses is not None:
        try:
            raw = np.asarray(masses)
            if raw.dtype.kind not in "biuf":
                raise TypeError
            m = raw.astype(float)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"masses must be an array of {n} real numbers in kg, got {masses!r}") from None
        if m.shape != (n,):
            raise ValueError(f"wrong shape for masses: expected ({n},), got {m.shape}")
        return m
    vol = np.array([np.prod(b) for b in boxes])
    vol0 = np.array([np.prod(b) for b in default_boxes])
    return default_masses * vol / vol0


def _box_inertia(masses, k: int, box) -> np.ndarray:
    """Link k+1's inertia, a solid box; the engine's rule of a link's mass (finite and >= 0 kg: a link
    that carries nothing may be massless), its message naming the argument."""
    try:
        return box_inertia(masses[k], *box)
    except ValueError as e:
        raise ValueError(f"masses[{k}] (link {k + 1}): {e}") from None


def _make(spec, dims, masses, friction, base_position, base_yaw, gravity, backend) -> Robot:
    """Robot of one of the built-in specs: tables from the dimensions, boxes
    for the mass properties, then the dynamics backend."""
    if backend not in ("generated", "numeric"):
        raise ValueError(f"backend must be 'generated' or 'numeric', got {backend!r}")
    d = _check_dims(dims, spec["defaults"], spec["name"], spec["bounds"])
    if isinstance(base_yaw, (bool, str, complex)) or np.ndim(base_yaw) != 0:
        raise ValueError(f"base_yaw must be a number in radians, got {base_yaw!r}")
    dh, com, boxes, tool, jaw = spec["geometry"](d)
    boxes0 = spec["geometry"](spec["defaults"])[2]
    n = len(spec["types"])
    m = _masses(boxes, boxes0, spec["masses"], masses, n)
    inertias = np.array([_box_inertia(m, k, b) for k, b in enumerate(boxes)])
    robot = Robot.from_dh(
        dh=np.array(dh, dtype=float), com=np.array(com, dtype=float), masses=m, inertias=inertias,
        joint_types=spec["types"], friction=spec["friction"] if friction is None else friction,
        q_limits=spec["q_limits"], tau_limits=spec["tau_limits"], gravity=gravity, base_position=base_position,
        base_yaw=base_yaw, tool=tool, name=spec["name"], boxes=_shapes(dh, com, boxes, jaw, d),
        clamp=_clamp(jaw, d), dimensions=d)
    if robot.name in compiled_generated_names():
        robot = robot.with_generated(robot.name)
    return robot.with_backend(backend if robot.has_generated else "numeric")


def _shapes(dh, com, boxes, face, d):
    """LinkBox list: each link's mass box on its CoM frame, the fixed jaw, the base column."""
    w, h = d["width"], d["height"]
    col = d["L_base"] - h / 2
    # no column when link 1 reaches down to the floor
    out = [LinkBox(0, [w, w, col / 2], _translation([0.0, 0.0, col / 2]), "base")] if col > 1e-4 else []
    for i, (row, crow, box) in enumerate(zip(dh, com, boxes)):
        # CoM frame in the link's DH frame: constant, q enters both rows in the same slot
        pose = np.linalg.solve(dh_transform(*row), dh_transform(*crow))
        pose[3] = [0.0, 0.0, 0.0, 1.0]
        out.append(LinkBox(i + 1, np.array(box) / 2, pose, f"link{i + 1}"))
    Lj, tj = d["jaw_length"], d["jaw_thickness"]
    centre = face[:3, 3] - face[:3, 2] * tj / 2  # behind the inner face, away from the moving jaw
    half = np.abs(face[:3, :3]) @ [Lj / 2, w / 2, tj / 2]  # face axes (along, across, normal) in frame 5
    out.append(LinkBox(5, half, _translation(centre), "fixed_jaw"))
    return out


def _clamp(face, d):
    return Clamp(fixed_link=5, fixed_face=face, moving_joint=6, jaw_length=d["jaw_length"], pad_width=d["width"])


def _translation(p):
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _scara1_geometry(d):
    w, h, Lj, tj = d["width"], d["height"], d["jaw_length"], d["jaw_thickness"]
    dh = [  # theta, d, a, alpha
        [0.0, d["L_base"], d["L1"], 0.0],
        [0.0, 0.0, d["L2"], math.pi],
        [0.0, 0.0, 0.0, 0.0],             # P: d3, quill down
        [0.0, d["L4"], 0.0, math.pi / 2],  # R: theta4, clamp yaw about the vertical
        [0.0, 0.0, d["L5"], 0.0],         # R: theta5, clamp pitch; body along x5
        [0.0, 0.0, 0.0, 0.0],             # P: d6, moving jaw along z5
    ]
    com = [
        [0.0, d["L_base"], d["L1"] / 2, 0.0],
        [0.0, 0.0, d["L2"] / 2, 0.0],
        [0.0, -d["quill_length"] / 2, 0.0, 0.0],  # d3 - Lc3: CoM Lc3 above the quill tip
        [0.0, d["L4"] / 2, 0.0, 0.0],
        [0.0, 0.0, d["L5"] / 2, 0.0],
        [0.0, tj / 2, Lj / 2, 0.0],               # jaw plate beyond the clamp tip
    ]
    boxes = [(d["L1"], w, h), (d["L2"], w, h), (w, h, d["quill_length"]), (w, h, d["L4"]),
             (d["L5"], w, h), (Lj, w, tj)]
    # tool frame in frame 5: z along x5 (approach), y along z5 (jaw), x = y5
    R = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = [Lj / 2, 0.0, 0.0]
    tool = Tool(link=5, offset=T, second_link=6, second_point=[Lj / 2, 0.0, 0.0])
    # fixed jaw's inner face in frame 5: centre on the jaw axis z5, x5 along the jaw
    face = _translation([Lj / 2, 0.0, 0.0])
    return dh, com, boxes, tool, face


def _scara2_geometry(d):
    w, h, Lj, tj = d["width"], d["height"], d["jaw_length"], d["jaw_thickness"]
    dh = [
        [0.0, d["L_base"], d["L1"], 0.0],
        [0.0, 0.0, d["L2"], 0.0],
        [0.0, 0.0, d["L3"], math.pi],
        [0.0, 0.0, 0.0, 0.0],             # P: d4, quill down
        [0.0, d["L5"], 0.0, math.pi / 2],  # R: theta5, clamp yaw; z5 horizontal
        [0.0, 0.0, 0.0, 0.0],             # P: d6, moving jaw along z5
    ]
    com = [
        [0.0, d["L_base"], d["L1"] / 2, 0.0],
        [0.0, 0.0, d["L2"] / 2, 0.0],
        [0.0, 0.0, d["L3"] / 2, 0.0],
        [0.0, -d["quill_length"] / 2, 0.0, 0.0],  # d4 - Lc4 (paper Table 2, corrected)
        [0.0, d["L5"] / 2, 0.0, 0.0],
        [math.pi / 2, tj / 2, Lj / 2, 0.0],       # jaw plate hanging along y5 (down)
    ]
    boxes = [(d["L1"], w, h), (d["L2"], w, h), (d["L3"], w, h), (w, h, d["quill_length"]),
             (w, h, d["L5"]), (Lj, w, tj)]
    # tool frame in frame 5: z along y5 (down, approach), y along z5 (jaw), x = -x5
    R = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = [0.0, Lj / 2, 0.0]
    tool = Tool(link=5, offset=T, second_link=6, second_point=[0.0, Lj / 2, 0.0])
    # fixed jaw's inner face in frame 5: x along y5 (down the jaw), z = z5, y = -x5
    face = _translation([0.0, Lj / 2, 0.0])
    face[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    return dh, com, boxes, tool, face


def scara1(*, base_position=(0.0, 0.0, 0.0), base_yaw=0.0, masses=None, friction=None,
           gravity=(0.0, 0.0, -9.81), backend="generated", **dims) -> Robot:
    """SCARA #1 of the paper: RRP positioning plus a 3-joint clamp (RRPRRP).

    Joints: theta1, theta2 (horizontal arm, rad), d3 (quill, m, down),
    theta4 (clamp yaw about the vertical), theta5 (clamp pitch; 0 horizontal,
    pi/2 pointing down), d6 (jaw opening, m).

    Keyword dimensions (m): L_base, L1, L2, L4, L5, quill_length, jaw_length,
    jaw_thickness, width, height; see SCARA1_DEFAULTS, each within
    SCARA1_BOUNDS (outside: ValueError naming the range). base_position (3,) m
    and base_yaw (rad) place frame 0 in the world. masses (6,) kg overrides
    the volume-scaled masses; friction (6,) the viscous K. backend selects
    'generated' closed-form dynamics when compiled in, else 'numeric'.
    """
    return _make(_SCARA1, dims, masses, friction, base_position, base_yaw, gravity, backend)


def scara2(*, base_position=(0.0, 0.0, 0.0), base_yaw=0.0, masses=None, friction=None,
           gravity=(0.0, 0.0, -9.81), backend="generated", **dims) -> Robot:
    """SCARA #2 of the paper: over-actuated RRRPRP (Tables 1 and 2, corrected).

    Joints: theta1, theta2, theta3 (horizontal arm, rad), d4 (quill, m, down),
    theta5 (clamp yaw about the vertical), d6 (jaw opening, m).

    Keyword dimensions (m): L_base, L1, L2, L3, L5, quill_length, jaw_length,
    jaw_thickness, width, height; see SCARA2_DEFAULTS, each within
    SCARA2_BOUNDS. Other keywords as for
    scara1.
    """
    return _make(_SCARA2, dims, masses, friction, base_position, base_yaw, gravity, backend)


_SCARA1 = dict(name="scara1", types="RRPRRP", defaults=SCARA1_DEFAULTS, bounds=SCARA1_BOUNDS,
               geometry=_scara1_geometry,
               masses=_SCARA1_MASSES, friction=_SCARA1_K, q_limits=_SCARA1_QLIM, tau_limits=_SCARA1_TAU)
_SCARA2 = dict(name="scara2", types="RRRPRP", defaults=SCARA2_DEFAULTS, bounds=SCARA2_BOUNDS,
               geometry=_scara2_geometry,
               masses=_SCARA2_MASSES, friction=_SCARA2_K, q_limits=_SCARA2_QLIM, tau_limits=_SCARA2_TAU)


# ------------------------------------------------------------------ a clamp on any serial arm

#: add_clamp's defaults: SCARA #1's clamp. Lengths in m, masses in kg, the jaw's force limit in N and its
#: viscous friction in N s/m.
CLAMP_DEFAULTS = dict(
    opening=0.05,        # the jaw's stroke: the opening q of the jaw joint spans 0 .. opening
    jaw_length=SCARA1_DEFAULTS["jaw_length"],
    jaw_thickness=SCARA1_DEFAULTS["jaw_thickness"],
    width=SCARA1_DEFAULTS["width"],       # the pads' width (across the jaws) and the body's
    height=SCARA1_DEFAULTS["height"],     # the body's size along the jaw axis
    body_length=SCARA1_DEFAULTS["L5"],    # the clamp body, from the mount to the jaws
    body_mass=float(_SCARA1_MASSES[4]),
    jaw_mass=float(_SCARA1_MASSES[5]),    # each jaw plate, the fixed and the moving one
    jaw_force=float(_SCARA1_TAU[5]),
    jaw_friction=float(_SCARA1_K[5]),
)


def _common_normal(f, u, theta):
    """DH row [theta, d, a, alpha] from z of a frame (through its origin) to the line through f along the
    unit vector u (both in that frame): the common normal's foot on z at d, its length a >= 0 along x at
    angle theta about z (kept when the lines meet on z's axis), then alpha about x turns z onto u."""
    z = np.array([0.0, 0.0, 1.0])
    n = np.cross(z, u)
    if np.linalg.norm(n) > 1e-9:
        x = n / np.linalg.norm(n)
        d, a, _ = np.linalg.solve(np.column_stack([z, x, -u]), f)
        if a < 0:
            x, a = -x, -a
    else:  # parallel axes: the normal from z to the line, any when they coincide
        r = f - (f @ z) * z
        a = float(np.linalg.norm(r))
        x = r / a if a > 1e-12 else np.array([math.cos(theta), math.sin(theta), 0.0])
        a = a if a > 1e-12 else 0.0
        d = float(f @ z)
    y = np.cross(z, x)
    return np.array([math.atan2(x[1], x[0]), d, a, math.atan2(-(u @ y), u @ z)])


def _combine(parts):
    """One rigid body of [(mass, CoM (3,), inertia about the CoM (3, 3))] in one frame (parallel axes)."""
    m = sum(p[0] for p in parts)
    c = sum(p[0] * p[1] for p in parts) / m if m > 0 else parts[0][1]
    inertia = np.zeros((3, 3))
    for mk, ck, Ik in parts:
        r = ck - c
        inertia += Ik + mk * ((r @ r) * np.eye(3) - np.outer(r, r))
    return m, c, inertia


def _mount(mount) -> np.ndarray:
    """The mount as a (4, 4) array, checked by the engine's rule of a rigid pose (a Tool's offset)."""
    try:
        Tool(-1, mount)
    except (TypeError, ValueError) as e:
        raise ValueError(str(e).replace("offset", "mount", 1)) from None
    return np.asarray(mount, dtype=float)


def add_clamp(robot: Robot, *, mount=None, **values) -> Robot:
    """A copy of `robot` with the paper's parallel-jaw clamp (SCARA #1's) on its last link.

    The clamp frame C is `mount` (4, 4; default identity) in the robot's tool frame (its fk before the
    clamp: the flange, or the URDF's tip link): z along the approach (out of the flange), y the jaw axis
    (fixed jaw towards the moving one), origin on the mounting face. The clamp body, a ``width`` x
    ``height`` x ``body_length`` box along C's x, y, z, spans z = 0 .. body_length; the jaws, plates
    ``width`` x ``jaw_thickness`` x ``jaw_length``, lie beyond it (z = body_length .. body_length +
    jaw_length). The fixed jaw's inner face is centred on C's z axis, its plate behind it (y < 0); the
    moving jaw is a new prismatic joint n + 1 (named ``clamp_jaw``, link ``moving_jaw``) along y, its
    variable the opening between the inner faces, 0 .. ``opening`` m, force limit ``jaw_force`` N,
    viscous friction ``jaw_friction`` N s/m. The tool centre point is midway between the faces' centres,
    with C's axes (z the approach, y the jaw axis), as on the SCARAs.

    Mass: the body (``body_mass``) and the fixed jaw (``jaw_mass``) are fixed to the last link: its mass,
    centre of mass and inertia become those of the three (parallel axis theorem); the moving jaw
    (``jaw_mass``) is link n + 1. The last DH row is turned so that z_n is the jaw axis (the frame of link
    n, its CoM and inertia, its boxes and the tool re-expressed in it; the kinematics of joints 1..n do not
    change). Boxes: the robot's, plus ``clamp_body`` and ``fixed_jaw`` on link n and ``moving_jaw`` on
    n + 1; ``robot.clamp`` describes the jaws. The copy uses the numeric dynamics (its structure is new).

    Keywords and defaults (CLAMP_DEFAULTS, SCARA #1's clamp): opening 0.05, jaw_length 0.04,
    jaw_thickness 0.01, width 0.06, height 0.04, body_length 0.08 (m); body_mass 0.25, jaw_mass 0.05 (kg);
    jaw_force 15 (N), jaw_friction 2 (N s/m). Each must be finite and > 0 (body_mass and jaw_friction
    >= 0). A robot with a clamp already, with a tool on another link or between two points, or with
    kMaxDof joints, and a mount that is not a rigid transform, are refused with a ValueError.
    """
    unknown = set(values) - set(CLAMP_DEFAULTS)
    if unknown:
        raise TypeError(f"add_clamp() got unknown keyword(s) {sorted(unknown)}; known: mount, "
                        f"{', '.join(CLAMP_DEFAULTS)}")
    if not isinstance(robot, Robot):
        raise ValueError(f"robot must be a coopsim.Robot, got {type(robot).__name__}")
    v = dict(CLAMP_DEFAULTS)
    for key, x in values.items():
        v[key] = _checks.positive(x, key, zero=key in ("body_mass", "jaw_friction"),
                                  unit="N s/m" if key == "jaw_friction" else "N" if key == "jaw_force"
                                  else "kg" if key.endswith("mass") else "m")
    n = robot.dof
    if robot.clamp is not None:
        raise ValueError(f"robot {robot.name!r} already has a clamp (on link {robot.clamp.fixed_link}, "
                         f"jaw joint {robot.clamp.moving_joint}): add_clamp puts one on an arm without one")
    tool = robot.tool
    if tool.link not in (-1, n) or tool.second_link not in (-1, n) \
            or not np.allclose(tool.second_point, tool.offset[:3, 3], rtol=0, atol=1e-12):
        raise ValueError(f"robot {robot.name!r} must have a fixed tool on its last link for add_clamp (the "
                         "clamp is mounted on it), got one between two points or on another link")
    M = _mount(np.eye(4) if mount is None else mount)
    L5, Lj, tj, w, h = v["body_length"], v["jaw_length"], v["jaw_thickness"], v["width"], v["height"]
    dh = np.array(robot.dh, dtype=float)
    A_old = dh_transform(*dh[-1])
    C = A_old @ tool.offset @ M                       # the clamp frame in DH frame n-1 (q_n = 0)
    f = C[:3, :3] @ [0.0, 0.0, L5 + Lj / 2] + C[:3, 3]  # the fixed face's centre
    row = _common_normal(f, C[:3, 1], dh[-1, 0])
    A_new = dh_transform(*row)
    stroke = (f - A_new[:3, 3]) @ C[:3, 1]            # from frame n's origin to the face, along z_n
    X = np.linalg.solve(A_new, A_old)                 # old frame n -> new frame n
    Cn = np.linalg.solve(A_new, C)                    # the clamp frame in the new frame n
    Cj = Cn.copy()
    Cj[2, 3] -= stroke                                # ... in frame n + 1 (frame n moved along z_n)
    R = Cn[:3, :3]

    def part(mass, centre, size, frame):
        return mass, frame[:3, :3] @ centre + frame[:3, 3], R @ box_inertia(mass, *size) @ R.T

    body = ([0.0, 0.0, L5 / 2], (w, h, L5))
    fixed_jaw = ([0.0, -tj / 2, L5 + Lj / 2], (w, tj, Lj))
    moving_jaw = ([0.0, tj / 2, L5 + Lj / 2], (w, tj, Lj))
    com, inertias = np.array(robot.com_positions), np.array(robot.link_inertias)
    last = (robot.masses[-1], X[:3, :3] @ com[-1] + X[:3, 3], X[:3, :3] @ inertias[-1] @ X[:3, :3].T)
    m_n, c_n, I_n = _combine([last, part(v["body_mass"], *body, Cn), part(v["jaw_mass"], *fixed_jaw, Cn)])
    m_j, c_j, I_j = part(v["jaw_mass"], *moving_jaw, Cj)
    face = Cn @ [[0.0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, L5 + Lj / 2], [0, 0, 0, 1]]  # x: approach, z: jaw axis
    tcp = Cn.copy()
    tcp[:3, 3] = face[:3, 3]
    boxes = [b if b.link != n else b.moved(n, X @ b.pose) for b in robot.boxes]
    parts = [(link, size, frame @ _translation(centre), name)
             for link, (centre, size), frame, name in ((n, body, Cn, "clamp_body"), (n, fixed_jaw, Cn, "fixed_jaw"),
                                                       (n + 1, moving_jaw, Cj, "moving_jaw"))]
    boxes += [LinkBox(link, np.array(size) / 2, pose, name) for link, size, pose, name in parts]
    jn, ln = list(robot.joint_names), list(robot.link_names)

    def fresh(name, taken):
        return next(x for x in (name, *(f"{name}_{k}" for k in range(2, n + 3))) if x not in taken)

    out = Robot.from_dh(
        dh=np.vstack([dh[:-1], row, [0.0, stroke, 0.0, 0.0]]), com=np.vstack([com[:-1], c_n, c_j]),
        masses=np.r_[robot.masses[:-1], m_n, m_j], inertias=np.concatenate([inertias[:-1], [I_n, I_j]]),
        joint_types=robot.joint_types + "P", friction=np.r_[robot.friction_coefficients, v["jaw_friction"]],
        armature=np.r_[robot.armature, 0.0], coulomb=np.r_[robot.coulomb, 0.0],
        coulomb_width=np.r_[robot.coulomb_width, robot.coulomb_width[-1]],
        q_limits=np.vstack([robot.q_limits, [0.0, v["opening"]]]), tau_limits=np.r_[robot.tau_limits, v["jaw_force"]],
        gravity=robot.gravity_acceleration, base_position=robot.base_position, base_yaw=robot.base_yaw,
        base_orientation=robot.base_orientation,
        tool=Tool(link=n, offset=tcp, second_link=n + 1, second_point=(Cj @ [0.0, 0.0, L5 + Lj / 2, 1.0])[:3]),
        name=robot.name, end_stop_frequency=robot.end_stop_frequency,
        end_stop_damping_ratio=robot.end_stop_damping_ratio, boxes=boxes,
        clamp=Clamp(fixed_link=n, fixed_face=face, moving_joint=n + 1, jaw_length=Lj, pad_width=w),
        dimensions=robot.dimensions, inertia_check="ignore")
    out = out.with_names(jn + [fresh("clamp_jaw", jn)], ln + [fresh("moving_jaw", ln)])
    _follow_visuals(robot, out, X, parts)  # an imported arm's look follows it
    return out
