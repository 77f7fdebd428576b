"""The pairs of arms that carry the bar: ``scara`` (the handover's two SCARAs, the carry's own), ``ur5`` (two UR5s
of example-robot-data with the paper's clamp, facing each other across the bar's path) and ``panda`` (two 7-dof
Franka Emika Pandas with the clamp on their flanges, facing each other; their redundancy resolved in the null
space of the plan's IK), or a pair of one's own (:class:`Pair`, or a factory returning the two clamped robots
and their bases).

A :class:`Pair` is everything the carry needs to know of its arms beyond the robots themselves: their names in
the reports, how the plan's IK stays on one branch (the SCARAs' closed-form elbow branch; a numeric arm's start
posture, from which every knot is solved near the previous one), the rest posture a redundant arm's null space
is drawn to, the gains of the baseline computed torque, the boxes of the jaws (which may touch the bar) and the
simulation's rates. :func:`pair` resolves ``run(robots=...)``: a name of :data:`PAIRS`, a Pair, or a factory.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import xml.etree.ElementTree as ET
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from ..._core import Robot
from ...robots import add_clamp
from .. import scene as handover_scene
from .constants import BRANCH, END, FLIP, OMEGA, START
from .controllers import load_callable

__all__ = ["PAIRS", "Pair", "facing", "pair", "panda", "scara", "ur5"]


@dataclasses.dataclass(frozen=True)
class Pair:
    """Two arms with clamps, placed, as the carry drives them.

    robots: (robot #1, robot #2), each with a clamp (:func:`coopsim.robots.add_clamp` or the SCARAs'), at their
    bases in the world; robot #1 grips the bar on its +x side (GRIP1), #2 on its -x side. name: the pair's name
    in the report. names: the robots' names in messages and reports. branch: each robot's closed-form elbow
    branch (+1 / -1) for the whole run, or None for a robot solved numerically. posture: each robot's joint
    positions (n,) near which the numeric IK starts the approach (None: the IK's own start and restarts); with
    `redundant`, also the rest posture the null space of the arm's Jacobian is drawn to at every knot. omega:
    each robot's baseline computed-torque gains, rad/s per joint (n,): kp = omega^2, kd = 2 omega. jaws: the
    names of the boxes of a clamp that may touch the bar (the fixed and the moving jaw). simulation: the
    simulation's dt (s), world_every and control_every for this pair (run's defaults; the world's step is
    dt * world_every). object_gains: this pair's values over OBJECT_GAINS for the object-level laws (``object``,
    ``object-impedance``; a run's controller options over them)."""

    robots: Tuple[Robot, Robot]
    name: str = "pair"
    names: Tuple[str, str] = ("robot #1", "robot #2")
    branch: Tuple[Optional[int], Optional[int]] = (None, None)
    posture: Optional[Tuple[np.ndarray, np.ndarray]] = None
    redundant: bool = False
    omega: Optional[Tuple[np.ndarray, np.ndarray]] = None
    jaws: Tuple[str, ...] = ("fixed_jaw", "moving_jaw")
    flip: Tuple[float, float] = FLIP
    object_gains: Dict[str, float] = dataclasses.field(default_factory=dict)
    simulation: Dict[str, float] = dataclasses.field(
        default_factory=lambda: dict(dt=2e-4, world_every=5, control_every=5))

    def __post_init__(self):
        robots = tuple(self.robots) if isinstance(self.robots, (list, tuple)) else self.robots
        if not isinstance(robots, tuple) or len(robots) != 2 or not all(isinstance(r, Robot) for r in robots):
            raise ValueError(f"robots must be two coopsim.Robot, got {self.robots!r}")
        for i, r in enumerate(robots):
            if r.clamp is None:
                raise ValueError(f"robot #{i + 1} ({r.name!r}) has no clamp: put one on with "
                                 f"coopsim.robots.add_clamp or Robot.from_urdf(..., clamp=True)")
        object.__setattr__(self, "robots", robots)
        omega = self.omega
        if omega is None:
            omega = tuple(default_omega(r) for r in robots)
        omega = tuple(np.asarray(w, float) for w in omega)
        for r, w in zip(robots, omega):
            if w.shape != (r.dof,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
                raise ValueError(f"omega must give each robot's gains as ({r.dof},) rad/s > 0 for {r.name!r}, "
                                 f"got {w!r}")
        object.__setattr__(self, "omega", omega)
        if self.posture is not None:
            posture = tuple(np.asarray(p, float) for p in self.posture)
            for r, p in zip(robots, posture):
                if p.shape != (r.dof,) or not np.all(np.isfinite(p)):
                    raise ValueError(f"posture must be each robot's ({r.dof},) joint positions for {r.name!r}, "
                                     f"got {p!r}")
            object.__setattr__(self, "posture", posture)

    def jaw_boxes(self, i: int):
        """Indices of robot i's boxes that are its jaws."""
        return [k for k, b in enumerate(self.robots[i].boxes) if b.name in self.jaws]


def default_omega(robot: Robot) -> np.ndarray:
    """Baseline gains of an arm with a clamp (rad/s per joint): 30 for the arm's joints, 60 for the last arm
    joint and the jaw (as the SCARAs' wrist and jaw)."""
    w = np.full(robot.dof, 30.0)
    w[-2:] = 60.0
    return w


def scara() -> Pair:
    """The carry's own pair: the handover's two SCARAs (``coopsim.tasks.scene.scaras``), on their closed-form
    elbow branches BRANCH."""
    r1, r2 = handover_scene.scaras()
    return Pair((r1, r2), name="scara", names=("SCARA #1", "SCARA #2"), branch=BRANCH, omega=OMEGA,
                jaws=("fixed_jaw", "link6"))


def path_frame(start=START, end=END) -> Tuple[np.ndarray, np.ndarray]:
    """The bar's path's centre (3,) m (the mean of its start and end centres, on the floor) and its mean axis
    (3,), a horizontal unit vector along the bar's +x."""
    c = (np.asarray(start[:3], float) + np.asarray(end[:3], float)) / 2.0
    yaw = (start[3] + end[3]) / 2.0
    return np.array([c[0], c[1], 0.0]), np.array([math.cos(yaw), math.sin(yaw), 0.0])


def facing(robot: Robot, distance: float, start=START, end=END) -> Tuple[Robot, Robot]:
    """Two copies of `robot` facing each other across the bar's path: #1 at `distance` m from the path's centre
    along the bar's +x (its grip's side), #2 as far along its -x, each turned so that its base's x axis points at
    the centre. Returns (robot #1, robot #2)."""
    c, u = path_frame(start, end)
    out = []
    for s in (1.0, -1.0):
        p = c + s * distance * u
        yaw = math.atan2(-s * u[1], -s * u[0])
        out.append(robot.with_base(tuple(p), yaw))
    return tuple(out)


def _shipped(relative: str) -> str:
    """A URDF of the example-robot-data package (e.g. 'ur_description/urdf/ur5_robot.urdf')."""
    import importlib.metadata   # what it costs to import, only when a pair is read
    try:
        files = importlib.metadata.files("example-robot-data") or []
    except importlib.metadata.PackageNotFoundError:
        raise ValueError("the 'ur5' and 'panda' pairs read their URDFs from the example-robot-data package: "
                         "pip install example-robot-data") from None
    for f in files:
        if str(f).endswith("robots/" + relative):
            return str(f.locate())
    raise ValueError(f"example-robot-data has no {relative!r}")


#: the meshes' hulls keep this many vertices (Robot.from_urdf's hull_points): the world collides them at every
#: step, and 24 points hold a link's hull within a few millimetres
HULL_POINTS = 24


#: the Panda's clamp on its flange (panda_link8, z its normal), turned a quarter turn about it: both arms then
#: grip the bar with their last joint near the middle of its range (1.65 and -1.27 rad at the approach)
PANDA_MOUNT = np.array([[0.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


@functools.lru_cache(maxsize=None)
def _arm(which: str) -> Robot:
    """The clamped arm, read once per process (reading the meshes takes a second or more)."""
    if which == "ur5":
        arm = Robot.from_urdf(_shipped("ur_description/urdf/ur5_robot.urdf"), name="ur5", hull_points=HULL_POINTS)
        return add_clamp(arm, mount=flange_mount(arm))
    arm = Robot.from_urdf(_panda_without_hand(), tip="panda_link8", name="panda", hull_points=HULL_POINTS)
    return add_clamp(arm, mount=PANDA_MOUNT)


@functools.lru_cache(maxsize=None)
def _placed(which: str, distance: float) -> Tuple[Robot, Robot]:
    """The two clamped arms of `which` facing each other `distance` m from the path's centre (:func:`facing`),
    built once per process and distance: every run's simulation holds copies of the same robots, which share
    what the engine computes once per robot (its self-collision exclusions)."""
    return facing(_arm(which), distance)


def flange_mount(arm: Robot) -> np.ndarray:
    """The mount (4, 4, in the arm's tool frame) of a clamp on the arm's flange: its approach (z) along the last
    joint's axis, pointing away from the wrist, its origin on that axis at the face of the last link's shapes
    (their farthest point along it), its x the tool's x made normal to the approach."""
    n = arm.dof
    q = np.zeros(n)
    F = np.array(arm.frames(q))
    o, a = F[n - 1][:3, 3], F[n - 1][:3, 2]
    P, _ = arm.shapes(q)
    pts = []
    for k, b in enumerate(arm.boxes):
        if b.link == n:
            local = np.asarray(b.points) if b.kind == "hull" else \
                np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * b.half_extents
            pts.append(local @ P[k][:3, :3].T + P[k][:3, 3])
    pts = np.concatenate(pts) if pts else np.zeros((1, 3))
    along = (pts - o) @ a
    sign = 1.0 if along.mean() >= 0 else -1.0
    face = o + sign * a * (sign * along).max()
    T = arm.fk(q)
    z = T[:3, :3].T @ (sign * a)
    x = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = x - (x @ z) * z
    x /= np.linalg.norm(x)
    M = np.eye(4)
    M[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    M[:3, 3] = T[:3, :3].T @ (face - T[:3, 3])
    return M


def _panda_without_hand() -> str:
    """The Panda's URDF with its hand and fingers taken off (the clamp takes the hand's place on the flange,
    panda_link8), its meshes named by absolute paths."""
    path = _shipped("panda_description/urdf/panda.urdf")
    root = ET.parse(path).getroot()
    gone = {"panda_hand", "panda_hand_tcp", "panda_leftfinger", "panda_rightfinger"}
    for el in list(root):
        child = el.find("child")
        if (el.tag == "link" and el.get("name") in gone) or \
                (el.tag == "joint" and child is not None and child.get("link") in gone):
            root.remove(el)
    robots = path[:path.index("/robots/panda_description/")]
    for mesh in root.iter("mesh"):
        mesh.set("filename", mesh.get("filename").replace("package://example-robot-data", robots))
    return ET.tostring(root, encoding="unicode")


#: object-level control of arms that command all six directions: no integral on the clamps' wrench errors. The
#: integral acts on the moment about the bar's own axis too, where the welds hold the thin bar softly (their
#: stiffness scales with its roll inertia, 1e-5 kg m^2): it rocked the bar about that axis in a growing
#: oscillation (the Pandas: 108 mrad at its peak, 31 mrad RMS; the UR5s 15 mrad), without it 4 and 0.8 mrad. These
#: arms command the vertical force through their whole Jacobian and meet a commanded load share without it
#: (0.298 for 0.3, the Pandas)
ARM_OBJECT_GAINS = dict(ki_force=0.0)
#: the UR5s' and Pandas' simulation: robots, controllers and world all at 1 kHz (the SCARAs' world and
#: controllers run at 1 kHz too, their robots at 5 kHz): the arms' slowest-damped modes (the controllers' 60 rad/s,
#: the welds' and contacts' 0.2 / dt) are well inside RK4's step at 1 ms
SIMULATION = dict(dt=1e-3, world_every=1, control_every=1)

#: the named pairs' placement and postures: distance of each base from the path's centre (m), the start
#: posture (arm joints, rad; the jaw at the approach's opening)
UR5 = dict(distance=0.50, posture=(0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0))
PANDA = dict(distance=0.65, posture=(0.0, 0.35, 0.0, -2.2, 0.0, 2.55, 0.785))


def ur5() -> Pair:
    """Two UR5s of example-robot-data with the paper's clamp on their tool flanges (its defaults), facing each
    other UR5["distance"] m either side of the bar's path, the approach solved from UR5["posture"] (elbow up,
    the wrist above the clamp) and every later knot near the one before."""
    q = np.r_[UR5["posture"], 0.035]
    return Pair(_placed("ur5", float(UR5["distance"])), name="ur5", names=("UR5 #1", "UR5 #2"), posture=(q, q),
                simulation=dict(SIMULATION), object_gains=dict(ARM_OBJECT_GAINS))


def panda() -> Pair:
    """Two Franka Emika Pandas of example-robot-data (to the flange, panda_link8; the hand's hull stays on the
    last link) with the paper's clamp, facing each other PANDA["distance"] m either side of the bar's path.
    Seven arm joints for a six-dimensional pose: the plan's IK draws each knot's null space to PANDA["posture"]
    (:func:`~.planning.make_plan`)."""
    q = np.r_[PANDA["posture"], 0.035]
    return Pair(_placed("panda", float(PANDA["distance"])), name="panda", names=("Panda #1", "Panda #2"), posture=(q, q),
                redundant=True, simulation=dict(SIMULATION), object_gains=dict(ARM_OBJECT_GAINS))


#: the pairs by name (``run(robots=NAME)``, the command line's ``--robots``)
PAIRS: Dict[str, Callable[[], Pair]] = {"scara": scara, "ur5": ur5, "panda": panda}


def pair(spec=None) -> Pair:
    """The Pair of `spec`: None (the SCARAs), a name of :data:`PAIRS`, a :class:`Pair`, two clamped robots
    placed where they stand, or a factory ``() -> `` one of those or ``((robot #1, robot #2), (base #1,
    base #2))`` with each base ``(position (3,) m, yaw rad)`` (the robots moved there with ``with_base``); a
    factory may be named as ``"module:factory"`` or ``"path/to/file.py:factory"`` (imported where the run runs).
    The robots of a factory are solved by the numeric IK from the IK's own start (:class:`Pair` sets a start
    posture). ValueError, one line, for anything else."""
    if spec is None:
        return scara()
    if isinstance(spec, Pair):
        return spec
    if isinstance(spec, str):
        if spec in PAIRS:
            return PAIRS[spec]()
        if ":" not in spec:
            raise ValueError(f"unknown robots {spec!r}: choose from {', '.join(PAIRS)} (or name a factory of two "
                             f"clamped robots and their bases as module:factory or path/to/file.py:factory)")
        spec = load_callable(spec, "robots", "() -> the two robots and their bases")
    made = spec() if callable(spec) and not isinstance(spec, Robot) else spec
    if isinstance(made, Pair):
        return made
    name = getattr(spec, "__name__", "pair") if callable(spec) else "pair"
    try:
        robots, bases = _robots_and_bases(made)
    except (TypeError, ValueError):
        raise ValueError(f"robots must be a name ({', '.join(PAIRS)}), a Pair, two clamped robots or a factory "
                         f"returning them and their bases ((r1, r2), ((position, yaw), (position, yaw))), "
                         f"got {made!r}") from None
    if bases is not None:
        robots = tuple(r.with_base(tuple(np.asarray(p, float)), float(y)) for r, (p, y) in zip(robots, bases))
    names = tuple(f"{r.name} #{i + 1}" for i, r in enumerate(robots))
    closed = all(r.ik_kind is not None for r in robots)     # SCARAs: their closed forms on the carry's branches
    return Pair(robots, name=name, names=names, branch=BRANCH if closed else (None, None),
                jaws=("fixed_jaw", "moving_jaw", "link6") if closed else ("fixed_jaw", "moving_jaw"))


def _robots_and_bases(made) -> Tuple[Sequence[Robot], Optional[Sequence]]:
    if isinstance(made, (list, tuple)) and len(made) == 2 and all(isinstance(r, Robot) for r in made):
        return tuple(made), None
    robots, bases = made
    if not (len(robots) == 2 and all(isinstance(r, Robot) for r in robots) and len(bases) == 2):
        raise ValueError("not two robots and two bases")
    for p, y in bases:
        if np.shape(p) != (3,) or not np.all(np.isfinite(np.asarray(p, float))) or not math.isfinite(float(y)):
            raise ValueError("a base is not (position (3,), yaw)")
    return tuple(robots), bases
