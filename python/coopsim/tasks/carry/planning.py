"""The plan of a dual carry: the bar's path over time and both arms' joint references derived from it.

The bar's path (:class:`BarPath`) is the one description of the motion: straight moves of its centre and
turns of its yaw between waypoints, each under the quintic time law (at rest at both ends). Each clamp's
tool pose is the bar's pose times that clamp's grip (its tool pose in the bar's frame), at the same knot
times for both clamps, so the two references agree on the bar they carry: their disagreement between the
knots is the joint cubics' alone (:func:`reference_disagreement`). Inverse kinematics is the closed form on
one elbow branch per robot for the whole run (``BRANCH``); a pose out of reach is an IKError at planning
time naming the robot and the step.
"""
from __future__ import annotations

import dataclasses
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from ... import _checks
from ..._core import CubicTrajectory, IKError, Robot
from ...planning import plan_cartesian, rotz
from . import scene
from .constants import (BRANCH, CLEAR_ABOVE, CLOSE_SPEED, END, FIXED_GAP, FLIP, GRIP1, GRIP2, KNOTS, LIFT, OPEN,
                        SQUEEZE, START, START_SHIFT, START_TURN, TIMES)

__all__ = ["BarPath", "Plan", "grip_pose", "make_plan", "random_start", "reference_disagreement", "STEPS"]

#: the steps of a carry, in order
STEPS = ("approach", "grasp", "lift", "carry", "place", "release", "back off")
ROBOT_NAMES = ("SCARA #1", "SCARA #2")


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


class _Knots:
    """One robot's joint knots, appended move by move."""

    def __init__(self, robot: Robot, index: int, q0: np.ndarray, t0: float):
        self.robot, self.i = robot, index
        self.t, self.q = [t0], [np.asarray(q0, float)]

    def hold(self, t1: float):
        self.t.append(t1)
        self.q.append(self.q[-1].copy())

    def jaw(self, openings: Sequence[float], times: Sequence[float]):
        for o, t in zip(openings, times):
            q = self.q[-1].copy()
            q[5] = o
            self.t.append(t)
            self.q.append(q)

    def tool(self, poses, times, opening, step, intermediate=0):
        """Through tool poses (N, 4, 4) at times (N,): poses[0] must be where the robot is now."""
        try:
            _, info = plan_cartesian(self.robot, poses, times, opening=opening, q_start=self.q[-1],
                                     branch=BRANCH[self.i], intermediate=intermediate, time_law="quintic", info=True)
        except IKError as e:
            raise IKError(f"{ROBOT_NAMES[self.i]}, {step}: {e}") from None
        self.t.extend(info["times"][1:])
        self.q.extend(info["q_points"][1:])

    def trajectory(self) -> CubicTrajectory:
        return CubicTrajectory(np.array(self.t), np.array(self.q))


def _up(T, h):
    out = T.copy()
    out[2, 3] += h
    return out


def make_plan(start=START, end=END, *, robots=None, grip_offsets=(0.0, 0.0), close=(True, True),
              mass_factor: float = 1.0) -> Plan:
    """Plans the carry from the bar's `start` to its `end` (each (x, y, z, yaw), m and rad).

    robots: (SCARA #1, SCARA #2) (default the scene's). grip_offsets: (2,) m, each clamp's approach and grasp
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
    robots = scene.scaras() if robots is None else tuple(robots)
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
    grips = (grip_pose(GRIP1, FLIP[0], SQUEEZE), grip_pose(GRIP2, FLIP[1], SQUEEZE))
    steps = dict(zip(STEPS, [(0.0, t_grasp), (t_grasp, t_lift), (t_lift, t_carry), (t_carry, t_place),
                             (t_place, t_release), (t_release, t_back), (t_back, t_end)]))
    refs, knots, q_grasp = [], [], []
    B0 = bar.pose(0.0)
    for i, (r, s) in enumerate(zip(robots, (GRIP1, GRIP2))):
        G_open = grip_pose(s, FLIP[i], OPEN, offsets[i])
        at = B0 @ G_open
        try:
            q0 = r.ik(_up(at, CLEAR_ABOVE), opening=OPEN, branch=BRANCH[i])
        except IKError as e:
            raise IKError(f"{ROBOT_NAMES[i]}, approach: {e}") from None
        k = _Knots(r, i, q0, 0.0)
        k.hold(T["start"])
        k.tool([_up(at, CLEAR_ABOVE), at], [T["start"], t_grasp], OPEN, "approach", KNOTS["approach"])
        q_grasp.append(k.q[-1].copy())
        q_grasp[-1][5] = 2.0 * scene.BAR_HALF_EXTENTS[1]
        if close[i]:
            k.jaw([near, SQUEEZE], t_close)
        k.hold(t_lift)
        # lift, carry, place: the clamp's tool at the bar's pose times its grip, at the bar's knot times
        opening = SQUEEZE if close[i] else OPEN
        G = grips[i] if close[i] else G_open
        for step, (a, b) in (("lift", (t_lift, t_carry)), ("carry", (t_carry, t_place)),
                             ("place", (t_place, t_release))):
            tk = np.linspace(a, b, KNOTS[step] + 2)
            k.tool(bar.pose(tk) @ G, tk, opening, step)
        k.jaw([OPEN], [t_open])
        k.hold(t_back)
        here = r.fk(k.q[-1])
        k.tool([here, _up(here, CLEAR_ABOVE)], [t_back, t_done], OPEN, "back off", KNOTS["back_off"])
        k.hold(t_end)
        refs.append(k.trajectory())
        knots.append((np.array(k.t), np.array(k.q)))
    return Plan(bar, grips, refs, steps, float(t_end), tuple(start), tuple(end), q_grasp,
                mass_factor * scene.BAR_MASS, knots, tuple(offsets.tolist()), tuple(bool(c) for c in close))


def reference_disagreement(plan: Plan, robots=None, samples: int = 4000) -> float:
    """The largest distance (m) between where the two references put the bar while both clamps carry it
    (lift to place), sampled at `samples` times: the bar pose of robot 1's reference tool (fk times its grip's
    inverse) against robot 2's."""
    robots = scene.scaras() if robots is None else robots
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
