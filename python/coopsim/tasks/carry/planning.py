"""The plan of a dual carry: the bar's path over time and both arms' joint references derived from it.

The bar's path (:class:`BarPath`) is the one description of the motion: straight moves of its centre and
turns of its yaw between waypoints, each under the quintic time law (at rest at both ends). Each clamp's
tool pose is the bar's pose times that clamp's grip (its tool pose in the bar's frame), at the same knot
times for both clamps, so the two references agree on the bar they carry: their disagreement between the
knots is the joint cubics' alone (:func:`reference_disagreement`). Inverse kinematics is the closed form on
one elbow branch per robot for the whole run for the SCARAs (``BRANCH``); for the other arms
(:mod:`.pairs`) the numeric IK from the pair's start posture, every later knot solved from the one before it
only (so the arm stays on the branch it started on; a step of more than MAX_KNOT_STEP rad of a joint between
two knots is refused as a flip), and for a redundant arm (the Panda) each knot's null space drawn to the
pair's rest posture first. A pose out of reach is an IKError at planning time naming the robot and the step.
:func:`clearances` measures what the planned motion leaves between the robots' collision shapes, the stands
and the floor.
"""
from __future__ import annotations

import dataclasses
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from ... import _checks
from ..._core import CubicTrajectory, IKError, LinkBox, Robot, shape_clearances
from ...planning import interpolate_poses, plan_cartesian, rotz
from . import scene
from .pairs import Pair, pair as make_pair
from .constants import (CLEAR_ABOVE, CLOSE_SPEED, END, FIXED_GAP, GRIP1, GRIP2, KNOTS, LIFT, OPEN,
                        SQUEEZE, START, START_SHIFT, START_TURN, TIMES)

__all__ = ["BarPath", "Plan", "clearances", "grip_pose", "make_plan", "random_start", "reference_disagreement",
           "STEPS"]

#: the steps of a carry, in order
STEPS = ("approach", "grasp", "lift", "carry", "place", "release", "back off")
ROBOT_NAMES = ("SCARA #1", "SCARA #2")
#: the largest step of an arm joint between two consecutive knots of a numerically solved path (rad): more is
#: the IK leaving the branch it started on
MAX_KNOT_STEP = 0.35
#: the fraction of the way to the rest posture a redundant arm's null-space step takes at each knot
NULL_SPACE_GAIN = 0.5


def _quintic(s):
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclasses.dataclass(frozen=True)
class BarPath:
    """The bar's planned pose over time: waypoints (K, 4) [x, y, z (m), yaw (rad)] at times (K,) s; between
    two waypoints the centre moves on a straight line and the yaw turns at a constant rate, both following
    the quintic time law; before the first time and after the last the bar rests at the end waypoint."""

    times: np.ndarray
    waypoints: np.ndarray

    def state(self, t) -> np.ndarray:
        """[x, y, z, yaw] at time(s) t: (4,) for a scalar, (N, 4) for (N,) times."""
        t = np.asarray(t, float)
        tt = np.atleast_1d(t)
        k = np.clip(np.searchsorted(self.times, tt, side="right") - 1, 0, len(self.times) - 2)
        t0, t1 = self.times[k], self.times[k + 1]
        s = _quintic(np.clip((tt - t0) / (t1 - t0), 0.0, 1.0))
        out = self.waypoints[k] + s[:, None] * (self.waypoints[k + 1] - self.waypoints[k])
        return out[0] if t.ndim == 0 else out

    def pose(self, t) -> np.ndarray:
        """The bar's pose at time(s) t: (4, 4), or (N, 4, 4) for (N,) times."""
        x = np.atleast_2d(self.state(t))
        T = np.zeros((len(x), 4, 4))
        c, s = np.cos(x[:, 3]), np.sin(x[:, 3])
        T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
        T[:, 2, 2] = T[:, 3, 3] = 1.0
        T[:, :3, 3] = x[:, :3]
        return T[0] if np.ndim(t) == 0 else T


def grip_pose(s: float, flip: float, opening: float = OPEN, offset: float = 0.0) -> np.ndarray:
    """A clamp pointing down on the horizontal bar, its tool centre point at the bar's centre height `s` (+
    `offset`) m along the bar from its centre, turned by `flip` (0: tool x along the bar's +x, pi: along
    its -x), open by `opening` m with the fixed jaw FIXED_GAP m from the bar's side (so closing the moving
    jaw does not shove the bar): the tool pose (4, 4) in the bar's frame."""
    R = rotz(flip) @ np.diag([1.0, -1.0, -1.0])
    shift = (opening - 2.0 * scene.BAR_HALF_EXTENTS[1]) / 2.0 - FIXED_GAP   # the TCP off the bar's centre line,
    G = np.eye(4)                                                           # towards the moving jaw
    G[:3, :3] = R
    G[:3, 3] = np.array([s + offset, 0.0, 0.0]) + shift * R[:, 1]
    return G


def random_start(seed: int) -> Tuple[float, float, float, float]:
    """The start (x, y, z, yaw) with its stands shifted by up to START_SHIFT m in x and y and turned by up to
    START_TURN rad, drawn uniformly with a seeded generator."""
    rng = np.random.default_rng(seed)
    dx, dy = rng.uniform(-START_SHIFT, START_SHIFT, 2)
    return (START[0] + dx, START[1] + dy, START[2], START[3] + rng.uniform(-START_TURN, START_TURN))


@dataclasses.dataclass
class Plan:
    """A planned carry.

    bar: the bar's path (:class:`BarPath`, the whole run). grips: each clamp's tool pose in the bar's frame
    when closed on it ((4, 4) each, the bar's x along the bar; what the carry's references hold).
    references: each robot's joint reference (a CubicTrajectory over the whole run). steps: {step: (t0, t1)} s,
    in the order of :data:`STEPS`. t_end: s. start, end: the bar's (x, y, z, yaw) there. q_grasp: each robot's
    q closed on the bar at its grip. model_bar_mass: the bar's mass (kg) the controllers' models take
    (a controller factory reads it; the world's bar has scene.BAR_MASS). knots: each robot's (times, q) knots.
    pair: the arms (:class:`~.pairs.Pair`; the SCARAs unless make_plan was given others).
    """

    bar: BarPath
    grips: Tuple[np.ndarray, np.ndarray]
    references: List[CubicTrajectory]
    steps: Dict[str, Tuple[float, float]]
    t_end: float
    start: Tuple[float, ...]
    end: Tuple[float, ...]
    q_grasp: List[np.ndarray]
    model_bar_mass: float
    knots: List[Tuple[np.ndarray, np.ndarray]]
    grip_offsets: Tuple[float, float] = (0.0, 0.0)
    close: Tuple[bool, bool] = (True, True)
    pair: Optional[Pair] = None

    @property
    def robots(self):
        """The two robots the plan is for."""
        return self.pair.robots


class _Knots:
    """One robot's joint knots, appended move by move."""

    def __init__(self, pair: Pair, index: int, q0: np.ndarray, t0: float):
        self.pair, self.robot, self.i = pair, pair.robots[index], index
        self.t, self.q = [t0], [np.asarray(q0, float)]

    def hold(self, t1: float):
        self.t.append(t1)
        self.q.append(self.q[-1].copy())

    def jaw(self, openings: Sequence[float], times: Sequence[float]):
        for o, t in zip(openings, times):
            q = self.q[-1].copy()
            q[-1] = o
            self.t.append(t)
            self.q.append(q)

    def tool(self, poses, times, opening, step, intermediate=0):
        """Through tool poses (N, 4, 4) at times (N,): poses[0] must be where the robot is now."""
        branch = self.pair.branch[self.i]
        try:
            if branch is not None:
                _, info = plan_cartesian(self.robot, poses, times, opening=opening, q_start=self.q[-1],
                                         branch=branch, intermediate=intermediate, time_law="quintic", info=True)
                self.t.extend(info["times"][1:])
                self.q.extend(info["q_points"][1:])
            else:
                self._numeric(np.asarray(poses, float), np.asarray(times, float), opening, intermediate)
        except IKError as e:
            raise IKError(f"{self.pair.names[self.i]}, {step}: {e}") from None

    def _numeric(self, poses, times, opening, intermediate):
        """The knots of a numerically solved arm: the straight-line poses between the given ones at the quintic
        law's fractions of the way (as plan_cartesian places them), each solved from the knot before it alone
        (no restarts), after the redundant arm's null-space step towards the rest posture."""
        s = np.linspace(0.0, 1.0, intermediate + 2)
        way = _quintic(s)
        for k in range(len(poses) - 1):
            seg = interpolate_poses(poses[k], poses[k + 1], way[1:], "geodesic")
            for j in range(1, len(s)):
                t = times[k] + s[j] * (times[k + 1] - times[k])
                q = solve(self.pair, self.i, seg[j - 1], opening, self.q[-1], what=f"the pose at t = {t:.4g} s")
                self.t.append(float(t))
                self.q.append(q)

    def trajectory(self) -> CubicTrajectory:
        return CubicTrajectory(np.array(self.t), np.array(self.q))


def _up(T, h):
    out = T.copy()
    out[2, 3] += h
    return out


def make_plan(start=START, end=END, *, robots=None, grip_offsets=(0.0, 0.0), close=(True, True),
              mass_factor: float = 1.0) -> Plan:
    """Plans the carry from the bar's `start` to its `end` (each (x, y, z, yaw), m and rad).

    robots: the pair of arms (:func:`~.pairs.pair`: None, the scene's SCARAs; 'scara', 'ur5', 'panda'; a
    :class:`~.pairs.Pair`; two clamped robots; or a factory of them and their bases). grip_offsets: (2,) m, each clamp's approach and grasp
    aimed this far along the bar from its planned grip (a grip error the carry's references do not know: from
    the lift on they follow the plan's grips). close: (2,) whether each clamp's jaw is commanded to close
    (False: it stays open, a forced failure). mass_factor: the controllers' models take the bar's mass times
    this (> 0).

    Returns a :class:`Plan`. Raises IKError naming the robot and the step for a pose out of reach, ValueError
    for a bad argument.
    """
    start, end = _pose4(start, "start"), _pose4(end, "end")
    offsets = np.asarray(grip_offsets, float)
    if offsets.shape != (2,) or not np.all(np.isfinite(offsets)) or np.any(np.abs(offsets) > 0.02):
        raise ValueError(f"grip_offsets must be two finite offsets of at most 0.02 m, got {grip_offsets!r}")
    if len(close) != 2:
        raise ValueError(f"close must be two flags, one per robot, got {close!r}")
    mass_factor = _checks.positive(mass_factor, "mass_factor")
    pair = make_pair(robots)
    robots = pair.robots
    T = TIMES
    # the bar's path: rests on the start stands through the approach and the grasp, lift, carry, place, rests
    t = np.cumsum([0.0, T["start"], T["approach"]])
    t_grasp = t[-1]
    near = 2.0 * scene.BAR_HALF_EXTENTS[1] + 0.002
    t_close = [t_grasp + T["close"], t_grasp + T["close"] + (near - SQUEEZE) / CLOSE_SPEED]
    t_lift = t_close[-1] + T["grasp_settle"]
    t_carry = t_lift + T["lift"]
    t_place = t_carry + T["carry"]
    t_release = t_place + T["place"]
    t_open = t_release + T["open"]
    t_back = t_open + T["release_settle"]
    t_done = t_back + T["back_off"]
    t_end = t_done + T["end_settle"]
    lifted0 = (start[0], start[1], start[2] + LIFT, start[3])
    lifted1 = (end[0], end[1], end[2] + LIFT, end[3])
    bar = BarPath(np.array([0.0, t_lift, t_carry, t_place, t_release, t_end]),
                  np.array([start, start, lifted0, lifted1, end, end], float))
    flip = pair.flip
    grips = (grip_pose(GRIP1, flip[0], SQUEEZE), grip_pose(GRIP2, flip[1], SQUEEZE))
    steps = dict(zip(STEPS, [(0.0, t_grasp), (t_grasp, t_lift), (t_lift, t_carry), (t_carry, t_place),
                             (t_place, t_release), (t_release, t_back), (t_back, t_end)]))
    refs, knots, q_grasp = [], [], []
    B0 = bar.pose(0.0)
    for i, (r, s) in enumerate(zip(robots, (GRIP1, GRIP2))):
        G_open = grip_pose(s, flip[i], OPEN, offsets[i])
        at = B0 @ G_open
        try:
            if pair.branch[i] is not None:
                q0 = r.ik(_up(at, CLEAR_ABOVE), opening=OPEN, branch=pair.branch[i])
            else:
                q0 = solve(pair, i, _up(at, CLEAR_ABOVE), OPEN, None, what="the first pose", first=True)
        except IKError as e:
            raise IKError(f"{pair.names[i]}, approach: {e}") from None
        k = _Knots(pair, i, q0, 0.0)
        k.hold(T["start"])
        k.tool([_up(at, CLEAR_ABOVE), at], [T["start"], t_grasp], OPEN, "approach", KNOTS["approach"])
        q_grasp.append(k.q[-1].copy())
        q_grasp[-1][-1] = 2.0 * scene.BAR_HALF_EXTENTS[1]
        if close[i]:
            k.jaw([near, SQUEEZE], t_close)
        k.hold(t_lift)
        # lift, carry, place: the clamp's tool at the bar's pose times its grip, at the bar's knot times
        opening = SQUEEZE if close[i] else OPEN
        G = grips[i] if close[i] else G_open
        held = (("lift", (t_lift, t_carry)), ("carry", (t_carry, t_place)), ("place", (t_place, t_release)))
        tk = [np.linspace(a, b, KNOTS[step] + 2) for step, (a, b) in held]
        joined = np.concatenate([tk[0]] + [x[1:] for x in tk[1:]])   # a step's first knot is the last one's end
        n0 = len(k.t)
        try:      # the three steps in one call: the same knots, each solved from the one before it
            k.tool(bar.pose(joined) @ G, joined, opening, "lift")
        except IKError:       # step by step, for the error naming the step whose pose is out of reach
            del k.t[n0:], k.q[n0:]
            for (step, _), x in zip(held, tk):
                k.tool(bar.pose(x) @ G, x, opening, step)
        k.jaw([OPEN], [t_open])
        k.hold(t_back)
        here = r.fk(k.q[-1])
        k.tool([here, _up(here, CLEAR_ABOVE)], [t_back, t_done], OPEN, "back off", KNOTS["back_off"])
        k.hold(t_end)
        refs.append(k.trajectory())
        knots.append((np.array(k.t), np.array(k.q)))
    return Plan(bar, grips, refs, steps, float(t_end), tuple(start), tuple(end), q_grasp,
                mass_factor * scene.BAR_MASS, knots, tuple(offsets.tolist()), tuple(bool(c) for c in close), pair)


def reference_disagreement(plan: Plan, robots=None, samples: int = 4000) -> float:
    """The largest distance (m) between where the two references put the bar while both clamps carry it
    (lift to place), sampled at `samples` times: the bar pose of robot 1's reference tool (fk times its grip's
    inverse) against robot 2's."""
    robots = plan.robots if robots is None else robots
    t = np.linspace(plan.steps["lift"][0], plan.steps["place"][1], samples)
    B = [r.fk(ref.evaluate(t)[0]) @ np.linalg.inv(G) for r, ref, G in zip(robots, plan.references, plan.grips)]
    # the two bar poses compared at the bar's ends (a turn shows there in full)
    ends = np.array([[scene.BAR_HALF_EXTENTS[0], 0, 0, 1.0], [-scene.BAR_HALF_EXTENTS[0], 0, 0, 1.0]]).T
    return float(np.linalg.norm((B[0] @ ends - B[1] @ ends)[:, :3, :], axis=1).max())


def _pose4(x, what) -> Tuple[float, float, float, float]:
    try:
        a = np.asarray(x, float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be (x, y, z, yaw) in m and rad, got {x!r}") from None
    if a.shape != (4,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be four finite numbers (x, y, z, yaw) in m and rad, got {x!r}")
    return tuple(float(v) for v in a)


def solve(pair: Pair, i: int, T: np.ndarray, opening: float, q_prev: Optional[np.ndarray], *, what: str,
          first: bool = False) -> np.ndarray:
    """Robot i's joint positions putting its TCP at T (4, 4) with the jaw at `opening` m, by the numeric IK:
    from q_prev alone (no restarts; the first pose from the pair's posture, with the IK's restarts when it has
    none); a redundant arm's start point is first moved along the null space of its arm's Jacobian towards the
    pair's posture (NULL_SPACE_GAIN of the way; the first pose: until it settles). IKError naming `what` for a
    pose out of reach or a joint stepping more than MAX_KNOT_STEP rad from q_prev (a flip of the arm)."""
    r = pair.robots[i]
    rest = None if pair.posture is None else pair.posture[i]
    if first:
        q = r.ik(T, opening=opening, q_near=rest) if rest is not None else r.ik(T, opening=opening)
        if pair.redundant and rest is not None:
            for _ in range(50):
                q_new = r.ik(T, opening=opening, q_near=_toward(r, q, rest, 1.0), restarts=0)
                done = np.abs(q_new - q).max() < 1e-6
                q = q_new
                if done:
                    break
        return q
    start = _toward(r, q_prev, rest, NULL_SPACE_GAIN) if pair.redundant and rest is not None else q_prev
    try:
        q = r.ik(T, opening=opening, q_near=start, restarts=0)
    except IKError as e:
        raise IKError(f"{what}: {e}") from None
    step = np.abs(q[:-1] - q_prev[:-1])
    if step.max() > MAX_KNOT_STEP:
        j = int(np.argmax(step))
        raise IKError(f"{what}: joint {j + 1} would step {step[j]:.2f} rad from the knot before (more than "
                      f"{MAX_KNOT_STEP} rad: the arm would leave its branch)")
    return q


def _toward(r: Robot, q: np.ndarray, rest: np.ndarray, gain: float) -> np.ndarray:
    """q moved `gain` of the way towards `rest` within the null space of the arm's TCP Jacobian (the jaw, the
    last joint, left where it is), kept within the joint limits."""
    J = r.jacobian(q)[:, :-1]
    d = (rest - q)[:-1]
    d = d - np.linalg.pinv(J) @ (J @ d)
    out = q.copy()
    out[:-1] += gain * d
    return np.clip(out, r.q_limits[:, 0], r.q_limits[:, 1])


def clearances(plan: Plan, samples: int = 600) -> dict:
    """What the planned references leave between the robots' collision shapes (``Robot.boxes``: boxes, hulls,
    ...), sampled at `samples` times over the whole plan (m; <= 0 an overlap): robots, the two robots' shapes
    apart; jaws_stands, the jaws' shapes from the four stands; robots_stands, every other shape of the arms (the
    bases', link 0, left out) from the stands; floor, the lowest point of those shapes' bounding boxes;
    self, each robot's shapes on links at least two apart (the pairs the world collides unless they always
    touch) from each other. Returns a dict of those floats and t_robots (s), when the robots come closest."""
    robots = plan.robots
    t = np.linspace(0.0, plan.t_end, samples)
    Q = [ref.evaluate(t)[0] for ref in plan.references]
    P = [r.shapes(q)[0] for r, q in zip(robots, Q)]
    S = [list(r.boxes) for r in robots]
    d_rr = shape_clearances(P[0], S[0], P[1], S[1])[0]
    stands = scene.stands(plan.start, plan.end)
    stand_shapes = [LinkBox(0, he, np.eye(4), name) for name, he, _ in stands]
    stand_poses = np.array([T for _, _, T in stands])
    jaws = plan.pair.jaws
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    jaw_stand, other_stand, floor, own = [], [], [], []
    for r, Pq, Sq in zip(robots, P, S):
        jaw = [k for k, b in enumerate(Sq) if b.name in jaws]
        rest = [k for k, b in enumerate(Sq) if b.name not in jaws and b.link > 0]
        jaw_stand.append(shape_clearances(Pq[:, jaw], [Sq[k] for k in jaw], stand_poses, stand_shapes)[0].min())
        other_stand.append(shape_clearances(Pq[:, rest], [Sq[k] for k in rest], stand_poses, stand_shapes)[0].min())
        H = np.array([b.half_extents for b in Sq])
        floor.append(min(float(((Pq[:, k, 2, :3] @ (corners * H[k]).T).min(axis=1) + Pq[:, k, 2, 3]).min())
                         for k in rest))
        pairs = [(a, b) for a in range(len(Sq)) for b in range(a + 1, len(Sq)) if abs(Sq[a].link - Sq[b].link) > 1]
        own.append(min((shape_clearances(Pq[:, [a]], [Sq[a]], Pq[:, [b]], [Sq[b]])[0].min() for a, b in pairs),
                       default=np.inf))
    j = int(np.argmin(d_rr))
    return dict(robots=float(d_rr[j]), t_robots=float(t[j]), jaws_stands=float(min(jaw_stand)),
                robots_stands=float(min(other_stand)), floor=float(min(floor)), self=float(min(own)))
