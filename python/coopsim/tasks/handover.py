"""The cooperative task (paper section 11.5, Figs. 17-18): two SCARAs hand a bar over and drop it into an
inclined container.

SCARA #2 picks a bar from the floor and carries it under SCARA #1's open clamp; #1 grasps it in the air
(both hold it), #2 lets go, #1 turns the bar onto the container's axis, inserts it, opens and backs
off; the bar slides down the tube by gravity. Both robots return and the next bar follows.

Python sequences the phases; every step runs in the engine. Each phase plans both robots' motions from
the state the previous phase left (the bar's pose in a clamp is measured after each grasp, so a grip
that settled a millimetre off is carried into the plan), installs them with
:meth:`Simulation.set_reference`, and advances the simulation with ``run``; grasps and releases
happen only through the clamp rule (closing the jaws on the bar, opening them). Motions are the
existing closed-form IK and cubic joint trajectories (:func:`coopsim.planning.plan_cartesian` for the
straight tool lines).

A cycle fails, with its step, time and reason, on a forbidden contact (robot-robot, robot-container,
a robot's own links, or a bar touching anything but the jaws, the floor before pick-up, the container
and the floor after release), a grasp that does not happen, a release that does not happen, or a bar
that does not slide down the tube. The run stops at the first failure. :func:`run` returns a
:class:`TaskResult` whose ``report`` holds, per cycle: durations per step, tracking errors (joint and
tool), minimum clearances robot-robot and robot-container, peak weld and internal forces during the
dual hold (the internal force is the part of the two welds' forces that cancels on the bar,
``log.internal_wrench``; with both welds at the bar's centre it is the uneven split of its weight: #1
grasps a bar #2 holds still, so its weld starts unstretched and #2 carries the load until it opens,
giving m g / 2), every contact and grasp event, and success or the step and reason.

Scene values: :mod:`coopsim.tasks.scene`. Planning values (m, rad, s) are the module constants below
(checked against the robots' kinematics in tests/test_task.py): the handover bar centre (0.25, 0.25, 0.20), yaw 285 deg, #1 gripping
0.075 m on one side of the centre and #2 0.125 m on the other; #2 picks the bar 0.125 m from its
centre with the tool centre point 0.015 m above the bar's centre; #1 inserts at a clamp pitch of
65 deg, arriving 0.10 m beside the axis, sliding onto it and pushing 0.20 m in, then backing off
0.06 m along its approach.

Command line: ``python -m coopsim.tasks.handover --out out/`` (``--help`` for the options).
"""
from __future__ import annotations

import dataclasses
import math
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Dict, List, Optional, Sequence

import numpy as np

from .. import _core
from .._core import ComputedTorque, CubicTrajectory, IKError
from ..planning import plan_cartesian, rotz
from ..simulation import Simulation
from . import scene

__all__ = ["REGION", "TaskResult", "TaskError", "default_bars", "random_bar", "run", "sweep"]

DEG = math.pi / 180.0

#: Region of randomised bar starts: centre x, y (m) and yaw (rad), all pickable by SCARA #2.
REGION = dict(x=(0.90, 1.00), y=(0.25, 0.35), yaw=(15 * DEG, 45 * DEG))

# ---- planning values (m, rad, s) ----
HANDOVER_CENTRE = np.array([0.25, 0.25, 0.20])
HANDOVER_YAW = 285 * DEG
GRIP1 = -0.075           # #1's grip along the bar from its centre (the bar's +x end enters the tube first)
GRIP2 = 0.125            # #2's grip along the bar from its centre
PICK_HEIGHT = 0.015      # #2's tool centre point above the bar's centre at pick-up
OPEN = 0.035             # jaw opening while approaching a bar (m)
FIXED_GAP = 0.001        # the fixed jaw's gap to the bar when the clamp arrives (m)
CLOSE_SPEED = 0.02       # mean closing speed of the jaw near the bar (m/s)
SQUEEZE = 0.012          # jaw reference while closing: the jaw stop holds it at the bar's width
CLEAR_ABOVE = 0.08       # height of the approach / retreat above a grip
INSERT_PITCH = 65 * DEG  # #1's clamp pitch theta5 during insertion
BESIDE = 0.10            # #1 arrives this far beside the container's axis (horizontally, towards +x)
BEFORE_MOUTH = 0.03      # the bar's leading end stops this far before the mouth before it goes in
INSERT_DEPTH = 0.20      # how far the leading end goes into the tube
RETREAT2 = 0.04          # #2 rises this far off the bar after letting go (its quill stroke then stays above
                         # 0.03 m, where its clamp body clears its own forearm)
BACK_OFF = 0.06          # #1 backs off along its approach after opening
SLIDE_MIN = 0.05         # a released bar must slide at least this far down the tube's axis (m)
RELEASE_FADE = 0.1       # s: the weld fades out over this after the jaw opens (the simulation's release_time)
SLIDE_BACK = 0.02        # ... and never move back up it faster than this (m/s)
LINE_SPACING = 0.07      # bars lined up for repeated cycles, centre to centre

# durations of the motions (s)
TIMES = dict(approach=1.5, descend=0.6, close=0.2, lift=0.6, carry=2.4, enter=0.8, open=0.2, retreat=0.5,
             home=1.2, to_container=2.4, slide_on=0.6, insert=1.2, back_off=0.5, settle=0.3)
GRASP_TIMEOUT = 1.0      # s for a grasp or a release to happen once the jaws are commanded

#: elbow branches (sign of theta2) of SCARA #1 and #2 throughout: #1's elbow out to the left keeps its
#: forearm clear of #2's quill at the handover; #2's the other way
BRANCH = (-1, +1)
#: SCARA #1's elbow branch for the insertion (the only one that reaches along the container's axis): it
#: turns its elbow over on the way from the handover
INSERT_BRANCH = +1

# gains of the computed-torque controllers: omega (rad/s) per joint
#: (the wrist joints higher: a held bar multiplies their inertia, which the controllers' models leave out)
OMEGA = (np.array([30.0, 30.0, 30.0, 60.0, 60.0, 60.0]), np.array([30.0, 30.0, 30.0, 30.0, 60.0, 60.0]))


class TaskError(RuntimeError):
    """A cycle of the task failed: `step` (name), `t` (s), `reason`, and the bodies involved."""

    def __init__(self, step: str, t: float, reason: str, bodies: Sequence[str] = ()):
        super().__init__(f"{step} at t = {t:.4f} s: {reason}")
        self.step, self.t, self.reason, self.bodies = step, t, reason, tuple(bodies)


@dataclasses.dataclass
class TaskResult:
    """What :func:`run` returns: the report (a dict of plain values, JSON-ready), the simulation and its log."""

    report: dict
    sim: Simulation
    log: object
    series: Optional[dict] = None  # t (rows,), clearance_robots, clearance_container (m), tool_error (rows, 2) m,
    #                                 weld_force (rows, 2) N, internal_force (rows,) N
    timing: Optional[dict] = None  # wall seconds of the run (planning and simulation) and of the scoring; kept out of
    #                                the report, which is the same bit for bit for the same input

    @property
    def success(self) -> bool:
        return bool(self.report["success"])


def _pose(R, p) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


#: the pose (4, 4) of a bar lying on the floor: bar_on_floor(x, y, yaw), centre (x, y) m, yaw rad
bar_on_floor = scene.bar_pose


def default_bars(count: int = 3) -> List[np.ndarray]:
    """`count` bars lined up near SCARA #2: the first at the scene's default, the others side by side,
    LINE_SPACING m apart across the bar (towards SCARA #2's base line)."""
    x, y, yaw = 0.95, 0.30, 30 * DEG
    n = np.array([math.sin(yaw), -math.cos(yaw)])
    return [bar_on_floor(x + k * LINE_SPACING * n[0], y + k * LINE_SPACING * n[1], yaw) for k in range(count)]


def random_bar(seed: int) -> np.ndarray:
    """A bar's start drawn uniformly from :data:`REGION` with a seeded generator: pose (4, 4)."""
    rng = np.random.default_rng(seed)
    return bar_on_floor(rng.uniform(*REGION["x"]), rng.uniform(*REGION["y"]), rng.uniform(*REGION["yaw"]))


def _grip_down(s: float, height: float, opening: float = OPEN) -> np.ndarray:
    """A clamp pointing down over a horizontal bar, s m along it from its centre, its TCP `height` m above
    the bar's centre, open by `opening` m with the fixed jaw FIXED_GAP m from the bar's side (so closing
    the moving jaw does not push the bar across the floor): the TCP pose in the bar's frame (tool x along
    the bar, tool y = -bar y)."""
    shift = (opening - 2.0 * scene.BAR_HALF_EXTENTS[1]) / 2.0 - FIXED_GAP   # the TCP off the bar's centre line
    return _pose(np.diag([1.0, -1.0, -1.0]), [s, -shift, height])


def _yaw_pitch(yaw: float, pitch: float = 0.0) -> np.ndarray:
    """Rotation of a bar: yaw about the vertical, then its axis tilted down by `pitch` (rad)."""
    c, s = math.cos(pitch), math.sin(pitch)
    Ry = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return rotz(yaw) @ Ry


def clearances(PA, HA, PB, HB):
    """The smallest distance between two sets of boxes in each of N rows (m; < 0: overlap depth) and the
    pair that has it.

    PA: (N, ka, 4, 4) poses, HA: (ka, 3) half extents; PB: (N, kb, 4, 4) or (kb, 4, 4) for boxes that do
    not move, HB: (kb, 3). Returns (d (N,), ia (N,), ib (N,)). Exact (box_distance, Bullet's GJK) on the
    pairs that bounding spheres and separating axes cannot rule out (``coopsim.box_clearances``).
    """
    return _core.box_clearances(PA, HA, PB, HB)


class _Runner:
    """The task on one simulation: plans and runs the phases of every cycle, and scores them."""

    def __init__(self, bars, *, dt, log_every, world_every, control_every, mouth, slope, handover_yaw, t_limit,
                 container_shift=None, grip1_turn=0.0):
        self.r1, self.r2 = scene.scaras()
        self.bars = [np.asarray(b, float) for b in bars]
        self.names = scene.bar_names(len(self.bars))
        self.mouth = scene.CONTAINER["mouth"] if mouth is None else np.asarray(mouth, float)
        self.slope = scene.CONTAINER["slope"] if slope is None else float(slope)
        self.handover_yaw = HANDOVER_YAW if handover_yaw is None else float(handover_yaw)
        self.axes = scene.container_axes(self.slope)
        placed = self.mouth if container_shift is None else self.mouth + np.asarray(container_shift, float)
        self.walls = scene.container_walls(placed, self.slope)
        self.grip1_turn = float(grip1_turn)
        w = scene.world(self.bars, mouth=placed, slope=self.slope)
        self.sim = Simulation(dt=dt, world=w, log_every=log_every, world_every=world_every,
                              control_every=control_every)
        self.t_limit = t_limit
        # start: #1 waiting above its handover grip, #2 above its first pick
        self.q1_wait = self._ik(0, self._wait1_pose(), OPEN)
        for k, T in enumerate(self.bars):   # every bar pickable where it lies: checked before the run
            self.step = f"planning the pick of {self.names[k]}"
            self.pick_grip(T)
        self.q2_home = self._ik(1, self._above(*self.pick_grip(self.bars[0])), OPEN)
        self.sim.add_robot(self.r1, ComputedTorque(OMEGA[0] ** 2, 2.0 * OMEGA[0]), self.q1_wait)
        self.sim.add_robot(self.r2, ComputedTorque(OMEGA[1] ** 2, 2.0 * OMEGA[1]), self.q2_home)
        self.cycles: List[dict] = []
        self.step = "start"
        self.contact_seen = 0
        self.state = {name: "floor" for name in self.names}   # floor -> grasped -> held (lifted) -> released
        self.label: Dict[str, np.ndarray] = {}   # the task's frame of each bar in its body frame
        self.outcome: Dict[str, str] = {}

    # ---- geometry ----

    def _handover_bar(self) -> np.ndarray:
        return _pose(rotz(self.handover_yaw), HANDOVER_CENTRE)

    def _wait1_pose(self) -> np.ndarray:
        T = self._handover_bar() @ _grip_down(GRIP1, 0.0)
        T[2, 3] += CLEAR_ABOVE
        return T

    @staticmethod
    def _reachable(i, T) -> np.ndarray:
        """The clamp pose nearest T that robot i can take: the jaw axis (tool y) horizontal for both, the
        approach (tool z) straight down for #2. Poses planned from a measured grip carry the bar's slight
        tilt in the jaws (its weight, the weld's sag), which the clamps cannot follow."""
        R = T[:3, :3]
        y = np.array([R[0, 1], R[1, 1], 0.0])
        y /= np.linalg.norm(y)
        z = np.array([0.0, 0.0, -1.0]) if i == 1 else R[:, 2] - y * (y @ R[:, 2])
        z /= np.linalg.norm(z)
        out = T.copy()
        out[:3, :3] = np.column_stack([np.cross(y, z), y, z])
        return out

    @staticmethod
    def _above(bar, G):
        """The TCP pose CLEAR_ABOVE m above the grip G on a bar at `bar`."""
        T = bar @ G
        T[2, 3] += CLEAR_ABOVE
        return T

    def _ik(self, i, T, opening, q_near=None, branch=None):
        r = (self.r1, self.r2)[i]
        T = self._reachable(i, T)
        try:
            return r.ik(T, opening=opening, q_near=q_near, branch=BRANCH[i] if branch is None else branch)
        except IKError as e:
            raise IKError(f"{('SCARA #1', 'SCARA #2')[i]}, {self.step}: {e}") from None

    # ---- running ----

    def q_ref(self, i) -> np.ndarray:
        return self.sim.references[i].evaluate(self.sim.time)[0]

    def move_joints(self, i, points, durations):
        """Robot i through joint points (each (6,)) from its present reference, at rest at each."""
        q0 = self.q_ref(i)
        t0 = self.sim.time
        times = [t0] + list(t0 + np.cumsum(durations))
        self.sim.set_reference(i, CubicTrajectory(times, np.vstack([q0] + [np.asarray(p, float) for p in points])))
        return times[-1]

    def move_line(self, i, poses, durations, opening, intermediate=4, branch=None):
        """Robot i's tool along straight lines through `poses` from its present pose (opening: jaw, m)."""
        r = (self.r1, self.r2)[i]
        q0 = self.q_ref(i)
        t0 = self.sim.time
        times = [t0] + list(t0 + np.cumsum(durations))
        P = [r.fk(q0)] + [self._reachable(i, T) for T in poses]
        op = [q0[5]] + [opening] * len(poses)
        try:
            traj, info = plan_cartesian(r, P, times, opening=op, q_start=q0, intermediate=intermediate, info=True,
                                        branch=BRANCH[i] if branch is None else branch)
        except IKError as e:
            raise IKError(f"{('SCARA #1', 'SCARA #2')[i]}, {self.step}: {e}") from None
        Q = info["q_points"]
        Q[0] = q0
        self.sim.set_reference(i, CubicTrajectory(info["times"], Q))
        return times[-1]

    def jaw(self, i, opening, duration):
        q = self.q_ref(i).copy()
        q[5] = opening
        return self.move_joints(i, [q], [duration])

    def bar(self, name) -> np.ndarray:
        """A bar's pose now in the task's frame for it (see pick_grip), (4, 4)."""
        return self.sim.body_state(name)["pose"] @ self.label.get(name, np.eye(4))

    def pick_grip(self, bar):
        """How #2 takes a bar lying at `bar` (4, 4): the bar's frame relabelled so that #2's grip is GRIP2
        along +x (the bar is symmetric: either end may become its +x end), and #2's TCP in that frame
        (tool x along +x or -x). Of the four, the one within the joint limits at the pick and at the
        handover with the least joint travel between them."""
        best, cost_best, why = None, math.inf, []
        hand = self._handover_bar()
        for label in (0.0, math.pi):
            Tb = bar @ _pose(rotz(label), np.zeros(3))
            for flip in (0.0, math.pi):
                G = _grip_down(GRIP2, PICK_HEIGHT) @ _pose(rotz(flip), np.zeros(3))
                try:
                    qa = self._ik(1, Tb @ G, OPEN)
                    qb = self._ik(1, hand @ _grip_down(GRIP2, PICK_HEIGHT) @ _pose(rotz(flip), np.zeros(3)), OPEN,
                                  q_near=qa)
                except IKError as e:
                    why.append(str(e).split(": ", 2)[-1])
                    continue
                cost = float(np.abs(qb - qa)[[0, 1, 2, 4]].sum())
                if cost < cost_best:
                    best, cost_best = (Tb, G), cost
        if best is None:
            raise IKError(f"SCARA #2, {self.step}: no grip on the bar at {np.round(bar[:3, 3], 4).tolist()} is "
                          f"reachable both there and at the handover ({why[0] if why else ''})")
        return best

    def close(self, i):
        """Robot i's jaw closes fast to 2 mm over the bar's width, then slowly (CLOSE_SPEED) on to SQUEEZE:
        the moving jaw meets the bar at a speed the clamp rule takes as 'moving with the clamp'."""
        q = self.q_ref(i)
        near = q.copy()
        near[5] = 2.0 * scene.BAR_HALF_EXTENTS[1] + 0.002
        shut = q.copy()
        shut[5] = SQUEEZE
        return self.move_joints(i, [near, shut], [TIMES["close"], (near[5] - SQUEEZE) / CLOSE_SPEED])

    def run_to(self, t_end):
        if t_end > self.t_limit:
            raise TaskError(self.step, self.sim.time, f"the task would run past its time limit of {self.t_limit} s")
        # the engine's run without building the log (Simulation.run returns one): phases end hundreds of
        # times per cycle, and a log of the whole run built at each would cost more than the steps
        self.sim._core.run(t_end, None)
        self.check_contacts()

    def wait_for(self, predicate, timeout, what):
        """Runs in 10 ms chunks until predicate() holds, at most `timeout` s; TaskError with `what` if not."""
        t_end = self.sim.time + timeout
        while not predicate():
            if self.sim.time >= t_end - 1e-12:
                raise TaskError(self.step, self.sim.time, what)
            self.run_to(min(self.sim.time + 0.01, t_end))

    def wait_grasp(self, i, name):
        """Runs until robot i holds `name` (GRASP_TIMEOUT s at most); else TaskError naming the clamp
        rule's conditions that failed at the end."""
        try:
            self.wait_for(lambda: self.sim.holding(i) == name, GRASP_TIMEOUT, "")
        except TaskError as e:
            if e.reason:   # something else went wrong while waiting (a forbidden contact): that is the reason
                raise
            c = self.sim.grasp_check(i, name)
            failed = [k for k in ("closing", "aligned", "touching", "in_pads", "slow") if not c[k]]
            detail = (f"angle {c['angle'] / DEG:.1f} deg, gaps {c['gap_fixed'] * 1e3:.1f} and "
                      f"{c['gap_moving'] * 1e3:.1f} mm, speed {c['speed']:.3f} m/s")
            raise TaskError(self.step, self.sim.time, f"SCARA #{i + 1} did not grasp {name}: the clamp rule's "
                            f"{', '.join(failed) or 'hold time'} failed ({detail})") from None

    # ---- contacts ----

    def allowed(self, a: str, b: str) -> bool:
        """Whether a contact between bodies a and b is allowed now."""
        for x, y in ((a, b), (b, a)):
            if x in self.state:
                st = self.state[x]
                if y in self.state:   # bar on bar: both already dropped
                    return st == "released" and self.state[y] == "released"
                if y.endswith("/fixed_jaw") or y.endswith("/link6"):
                    return True
                if y == "floor":
                    return st in ("floor", "grasped", "released")
                if y.startswith("container"):
                    return st == "released"
                return False
        return False

    def check_contacts(self):
        ev = self.sim._core.contact_events()
        if not ev:
            return
        n = len(ev["a"])
        for k in range(self.contact_seen, n):
            a, b = ev["a"][k], ev["b"][k]
            if not self.allowed(a, b):
                raise TaskError(self.step, float(ev["begin"][k]), f"forbidden contact between {a} and {b}", (a, b))
        self.contact_seen = n

    # ---- one cycle ----

    def cycle(self, k):
        name, sim = self.names[k], self.sim
        steps: Dict[str, list] = {}

        def mark(step):
            self.step = step
            steps[step] = [sim.time, None]

        def done():
            steps[self.step][1] = sim.time

        T = TIMES
        # 1. #2 above the bar, down to it, closes: the clamp rule grasps
        mark("pick")
        bar0, G = self.pick_grip(sim.body_state(name)["pose"])
        self.label[name] = np.linalg.solve(sim.body_state(name)["pose"], bar0)
        grip = bar0 @ G
        above = grip.copy()
        above[2, 3] += CLEAR_ABOVE
        q_above = self._ik(1, above, OPEN, q_near=self.q_ref(1))
        t = self.move_joints(1, [q_above], [T["approach"]])
        self.run_to(t)
        self.run_to(self.move_line(1, [grip], [T["descend"]], OPEN))
        self.close(1)
        self.wait_grasp(1, name)
        self.state[name] = "grasped"   # still on the floor until lifted
        done()
        # 2. lift, carry under #1's open clamp
        mark("carry")
        G2 = np.linalg.solve(self.r2.fk(sim.state(1)[0]), self.bar(name))   # bar in #2's tool
        lifted = self.bar(name)
        lifted[2, 3] += CLEAR_ABOVE
        hand = self._handover_bar()
        pre = hand.copy()
        pre[:3, 3] += np.array([0.10, -0.10, 0.0])
        self.run_to(self.move_line(1, [lifted @ np.linalg.inv(G2)], [T["lift"]], SQUEEZE))
        self.state[name] = "held"
        q_pre = self._ik(1, pre @ np.linalg.inv(G2), SQUEEZE, q_near=self.q_ref(1))
        self.run_to(self.move_joints(1, [q_pre], [T["carry"]]))
        self.run_to(self.move_line(1, [hand @ np.linalg.inv(G2)], [T["enter"]], SQUEEZE))
        self.run_to(sim.time + T["settle"])
        done()
        # 3. #1 descends onto the bar as it is held and closes: both hold
        mark("grasp by #1")
        held = self.bar(name)
        g1 = held @ _grip_down(GRIP1, 0.0) @ _pose(rotz(self.grip1_turn), np.zeros(3))
        self.run_to(self.move_line(0, [g1], [T["descend"]], OPEN))
        self.close(0)
        self.wait_grasp(0, name)
        self.run_to(sim.time + T["settle"])
        done()
        # 4. #2 opens and leaves
        mark("release by #2")
        self.jaw(1, OPEN, T["open"])
        self.wait_for(lambda: sim.holding(1) is None, GRASP_TIMEOUT, "SCARA #2 did not let go")
        up = self.r2.fk(self.q_ref(1))
        up[2, 3] += RETREAT2
        self.run_to(self.move_line(1, [up], [T["retreat"]], OPEN))
        nxt = self.names[k + 1] if k + 1 < len(self.names) else None
        home = self._above(*self.pick_grip(sim.body_state(nxt)["pose"] if nxt else self.bars[0]))
        self.run_to(self.move_joints(1, [self._ik(1, home, OPEN, q_near=self.q_ref(1))], [T["home"]]))
        done()
        # 5. #1 turns the bar onto the container's axis, beside it, then slides onto it
        mark("to container")
        G1 = np.linalg.solve(self.r1.fk(sim.state(0)[0]), self.bar(name))
        a = self.axes[:, 0]
        R_axis = _yaw_pitch(math.atan2(a[1], a[0]), self.slope)
        lead = scene.BAR_HALF_EXTENTS[0]
        on_axis = _pose(R_axis, self.mouth - a * (lead + BEFORE_MOUTH))
        beside = on_axis.copy()
        beside[:3, 3] += np.array([BESIDE, 0.0, 0.0])
        lifted = self.bar(name)
        lifted[2, 3] += 0.06
        self.run_to(self.move_line(0, [lifted @ np.linalg.inv(G1)], [T["lift"]], SQUEEZE))
        q_beside = self._ik(0, beside @ np.linalg.inv(G1), SQUEEZE, q_near=self.q_ref(0), branch=INSERT_BRANCH)
        self.run_to(self.move_joints(0, [q_beside], [T["to_container"]]))
        self.run_to(self.move_line(0, [on_axis @ np.linalg.inv(G1)], [T["slide_on"]], SQUEEZE, branch=INSERT_BRANCH))
        done()
        # 6. insert along the axis
        mark("insert")
        inside = on_axis.copy()
        inside[:3, 3] += a * (BEFORE_MOUTH + INSERT_DEPTH)
        self.run_to(self.move_line(0, [inside @ np.linalg.inv(G1)], [T["insert"]], SQUEEZE, intermediate=8,
                                   branch=INSERT_BRANCH))
        done()
        # 7. open, back off along the approach, return
        mark("release")
        self.jaw(0, OPEN, T["open"])
        self.wait_for(lambda: sim.holding(0) is None, GRASP_TIMEOUT, "SCARA #1 did not let go")
        self.state[name] = "released"
        T1 = self.r1.fk(self.q_ref(0))
        T1[:3, 3] -= T1[:3, 2] * BACK_OFF
        self.run_to(self.move_line(0, [T1], [T["back_off"]], OPEN, branch=INSERT_BRANCH))
        done()
        mark("return")
        t_release = sim.time
        self.run_to(self.move_joints(0, [self.q1_wait], [T["home"]]))
        done()
        self.step = "slide"
        self.check_slide(name, steps["release"][0])
        return steps

    def check_slide(self, name, t_release):
        """The bar, since its release (once the weld has faded out), slid down the tube: its centre within the tube's section while in it,
        never moving back up the axis faster than SLIDE_BACK m/s, at least SLIDE_MIN m further down, and
        now inside the tube or out of its lower mouth."""
        b = self.sim.log.bodies[name]
        k = b.t >= t_release + RELEASE_FADE
        rel = b.position[k] - self.mouth
        a = self.axes[:, 0]
        s = rel @ a
        lateral = np.linalg.norm(rel - s[:, None] * a, axis=1)
        v = b.velocity[k] @ a
        L = scene.CONTAINER["length"]
        inside = (s >= 0.0) & (s <= L)
        t = b.t[k]
        if np.any(lateral[inside] > scene.CONTAINER["inner"] / 2):
            j = int(np.argmax(inside & (lateral > scene.CONTAINER["inner"] / 2)))
            raise TaskError("slide", float(t[j]), f"{name} left the tube's section: its centre {lateral[j] * 1e3:.1f} mm "
                            f"off the axis")
        if np.any(v[inside] < -SLIDE_BACK):
            j = int(np.argmax(inside & (v < -SLIDE_BACK)))
            raise TaskError("slide", float(t[j]), f"{name} moved back up the tube at {-v[j]:.3f} m/s")
        if s[-1] - s[0] < SLIDE_MIN:
            raise TaskError("slide", float(t[-1]), f"{name} did not slide down the tube: it moved "
                            f"{(s[-1] - s[0]) * 1e3:.1f} mm along the axis")
        if s[-1] < 0.0:
            raise TaskError("slide", float(t[-1]), f"{name} ended above the tube's upper mouth")
        self.outcome[name] = "inside the container" if s[-1] <= L else "out of the lower mouth"


def _cycle_window(log, t0, t1):
    return (log.t >= t0 - 1e-12) & (log.t <= t1 + 1e-12)


def _score(runner: "_Runner", results: List[dict]) -> dict:
    """Per-cycle scores from the log (see the module's docstring); also the series behind the plots."""
    sim, log = runner.sim, runner.sim.log
    robots = (runner.r1, runner.r2)
    shapes, halves = zip(*(r.shapes(rl.q) for r, rl in zip(robots, log.robots)))
    names = [[f"{r.name}/{b.name}" for b in r.boxes] for r in robots]
    walls = [w[0] for w in runner.walls]
    PW = np.array([w[2] for w in runner.walls])
    HW = np.array([w[1] for w in runner.walls])
    # the three clearance series at once: the engine releases the GIL
    with ThreadPoolExecutor(max_workers=3) as pool:
        jobs = [pool.submit(clearances, shapes[0], halves[0], shapes[1], halves[1])]
        jobs += [pool.submit(clearances, P, H, PW, HW) for P, H in zip(shapes, halves)]
        (d_rr, i_rr, j_rr), *cont = [j.result() for j in jobs]
    d_rc = np.minimum(cont[0][0], cont[1][0])
    tcp_err = np.column_stack([np.linalg.norm(r.fk(rl.q)[:, :3, 3] - r.fk(rl.q_ref)[:, :3, 3], axis=1)
                               for r, rl in zip(robots, log.robots)])
    weld = np.column_stack([np.linalg.norm(rl.weld[:, :3], axis=1) for rl in log.robots])
    internal = np.linalg.norm(log.internal_wrench(0, 1)[:, :3], axis=1)
    grasps, contacts = log.grasps, log.contacts
    for c in results:
        m = _cycle_window(log, c["t_start"], c["t_end"])
        c["duration"] = c["t_end"] - c["t_start"]
        if not m.any():
            continue
        c["tracking"] = [dict(robot=rl.name, rms_joint=np.sqrt((rl.error[m] ** 2).mean(axis=0)).tolist(),
                              max_joint=np.abs(rl.error[m]).max(axis=0).tolist(),
                              rms_tool=float(np.sqrt((tcp_err[m, i] ** 2).mean())),
                              max_tool=float(tcp_err[m, i].max()))
                         for i, rl in enumerate(log.robots)]
        k = np.flatnonzero(m)[np.argmin(d_rr[m])]
        c["clearance_robots"] = dict(min=float(d_rr[k]), t=float(log.t[k]), between=[names[0][i_rr[k]],
                                                                                     names[1][j_rr[k]]])
        k = np.flatnonzero(m)[np.argmin(d_rc[m])]
        r = 0 if cont[0][0][k] <= cont[1][0][k] else 1
        c["clearance_container"] = dict(min=float(d_rc[k]), t=float(log.t[k]),
                                        between=[names[r][cont[r][1][k]], walls[cont[r][2][k]]])
        c["peak_weld_force"] = [float(weld[m, i].max()) for i in range(2)]
        both = m & (log[0].holding != "") & (log[0].holding == log[1].holding)
        c["dual_hold"] = float(both.sum() * (log.t[1] - log.t[0])) if len(log.t) > 1 else 0.0
        c["peak_internal_force"] = float(internal[both].max()) if both.any() else 0.0
        g = grasps[(grasps.t >= c["t_start"]) & (grasps.t <= c["t_end"])]
        c["grasp_events"] = [dict(t=float(e.t), robot=int(e.robot), body=e.body, event=e.event, reason=e.reason)
                             for e in g.itertuples()]
        e = contacts[(contacts.begin >= c["t_start"] - 1e-12) & (contacts.begin <= c["t_end"])]
        c["contact_events"] = [dict(a=x.a, b=x.b, kind=x.kind, begin=float(x.begin),
                                    end=None if np.isnan(x.end) else float(x.end), peak_force=float(x.peak_force))
                               for x in e.itertuples()]
        c["outcome"] = runner.outcome.get(c["bar"])
    series = dict(t=log.t, clearance_robots=d_rr, clearance_container=d_rc, tool_error=tcp_err, weld_force=weld,
                  internal_force=internal)
    return series


def run(bars=None, *, cycles: Optional[int] = None, seed: Optional[int] = None, dt: float = 2e-4,
        log_every: int = 25, world_every: int = 5, control_every: int = 5, mouth=None, slope=None,
        handover_yaw=None, t_limit: float = 120.0, score: bool = True, container_shift=None,
        grip1_turn: float = 0.0) -> TaskResult:
    """Runs the task and scores it.

    bars: list of (4, 4) start poses of the bars on the floor (default: :func:`default_bars` of
    `cycles`, 3), or None with `seed`: one bar drawn from :data:`REGION`. cycles: how many bars to
    move (default: all). dt (s), log_every, world_every, control_every: the simulation's (by default
    the robots are integrated at 5 kHz, the paper's 0.2 ms, and the controllers, with their torques held
    in between, and the world with its contacts run at 1 kHz, a servo rate; with the controllers at
    every step the scores agree to 0.01 mm, see benchmarks/bench_task.py). mouth (3,) m, slope (rad): the
    container (default scene.CONTAINER). handover_yaw (rad): the bar's yaw at the handover. t_limit:
    simulated seconds after which a cycle fails. score: compute the per-cycle scores (clearances,
    tracking errors, forces, events; a little slower than the run itself).

    Faults, to see failures reported: container_shift (3,) m moves the container in the world by that
    much while the plan still aims at the container where it should be; grip1_turn (rad) turns SCARA
    #1's clamp about its approach when it comes down on the bar at the handover.

    Returns a :class:`TaskResult`. Raises coopsim.IKError, naming the bar and what is out of reach,
    when a bar cannot be picked where it lies (checked before the run starts).
    """
    if bars is None:
        bars = [random_bar(seed)] if seed is not None else default_bars(3 if cycles is None else cycles)
    cycles = len(bars) if cycles is None else int(cycles)
    if not 0 < cycles <= len(bars):
        raise ValueError(f"cycles must be 1 .. {len(bars)} (one per bar), got {cycles}")
    runner = _Runner(bars, dt=dt, log_every=log_every, world_every=world_every, control_every=control_every,
                     mouth=mouth, slope=slope, handover_yaw=handover_yaw, t_limit=t_limit,
                     container_shift=container_shift, grip1_turn=grip1_turn)
    results = []
    t_wall = time.perf_counter()
    for k in range(cycles):
        t0 = runner.sim.time
        c = dict(cycle=k, bar=runner.names[k], success=True, t_start=t0)
        results.append(c)
        try:
            c["steps"] = runner.cycle(k)
            c["t_end"] = runner.sim.time
        except TaskError as e:
            c.update(success=False, t_end=runner.sim.time, failed_step=e.step, failed_at=e.t, reason=e.reason,
                     bodies=list(e.bodies))
            break
        except (IKError, _core.DivergenceError) as e:
            c.update(success=False, t_end=runner.sim.time, failed_step=runner.step, failed_at=runner.sim.time,
                     reason=f"{type(e).__name__}: {e}", bodies=[])
            break
    t_run = time.perf_counter() - t_wall
    series = _score(runner, results) if score else None
    timing = dict(run=t_run, scoring=time.perf_counter() - t_wall - t_run)
    report = dict(success=len(results) == cycles and all(c["success"] for c in results), cycles_planned=cycles,
                  cycles=results, bars=[np.round(b, 12).tolist() for b in runner.bars[:cycles]],
                  simulated_time=runner.sim.time, dt=dt, world_every=world_every, control_every=control_every)
    return TaskResult(report, runner.sim, runner.sim.log, series, timing)


def sweep(seeds: Sequence[int], *, threads: int = 2, executor=None, **options) -> dict:
    """The task once per seed, each with one bar drawn from :data:`REGION` (:func:`random_bar`), by
    :func:`coopsim.sweep` (which gives the same as a table): on `threads` threads (the engine releases
    the GIL while it steps), or through `executor` (any concurrent.futures executor or a Dask
    distributed.Client). options go to :func:`run` (score=False by default: the success and failure
    reasons only).

    Returns dict(success_rate, runs=[dict(seed, bar=[x, y, yaw], success, step, reason, simulated_time)],
    failures=[the runs that failed]).
    """
    from ..sweeps import TaskRun, sweep as _sweep

    options.setdefault("score", False)
    seeds = [int(s) for s in seeds]
    # one mechanism for both: coopsim.sweep (threads here, or the executor), its rows read back per seed
    df = _sweep([TaskRun(seed=s, **options) for s in seeds], executor=executor,
                threads=None if executor is not None else max(1, int(threads)))
    runs = []
    for s, r in zip(seeds, df.itertuples()):
        bar = random_bar(s)
        entry = dict(seed=s, bar=[float(bar[0, 3]), float(bar[1, 3]), float(math.atan2(bar[1, 0], bar[0, 0]))])
        if r.step == "planning" or not isinstance(r.success, (bool, np.bool_)):
            # a planning error, or a run the executor lost (its error says why)
            runs.append(dict(entry, success=False, step=r.step if r.step == "planning" else "lost",
                             reason=r.reason if r.step == "planning" else r.error, simulated_time=0.0))
        else:
            runs.append(dict(entry, success=bool(r.success), step=r.step, reason=r.reason,
                             simulated_time=float(r.simulated_time)))
    return dict(success_rate=sum(r["success"] for r in runs) / max(1, len(runs)), runs=runs,
                failures=[r for r in runs if not r["success"]])


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def write_report(report: dict, path) -> str:
    """The report as JSON, written atomically (a temporary file renamed into place); returns the path."""
    import json

    from ..log import _atomic_write

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(_jsonable(report), f, indent=1)

    return _atomic_write(path, ".json", write)


def summary(report: dict) -> str:
    """A few lines per cycle: outcome, duration, tracking, clearances and forces, or the failure."""
    lines = []
    for c in report["cycles"]:
        head = f"cycle {c['cycle']} ({c['bar']}): "
        if not c["success"]:
            lines.append(head + f"FAILED in {c['failed_step']} at t = {c['failed_at']:.3f} s: {c['reason']}")
            continue
        lines.append(head + f"success in {c['duration']:.2f} s, the bar {c.get('outcome')}")
        if "tracking" in c:
            tr = ", ".join(f"{x['robot']} {x['rms_tool'] * 1e3:.2f} / {x['max_tool'] * 1e3:.2f} mm"
                           for x in c["tracking"])
            lines.append(f"  tool tracking error RMS / max: {tr}")
            cr, cc = c["clearance_robots"], c["clearance_container"]
            lines.append(f"  min clearance robot-robot {cr['min'] * 1e3:.1f} mm ({' - '.join(cr['between'])}, "
                         f"t = {cr['t']:.2f} s), robot-container {cc['min'] * 1e3:.1f} mm "
                         f"({' - '.join(cc['between'])})")
            lines.append(f"  dual hold {c['dual_hold']:.3f} s; peak weld force #1 {c['peak_weld_force'][0]:.2f} N, "
                         f"#2 {c['peak_weld_force'][1]:.2f} N; peak internal force {c['peak_internal_force']:.2f} N; "
                         f"{len(c['grasp_events'])} grasp events, {len(c['contact_events'])} contact events")
    ok = sum(c["success"] for c in report["cycles"])
    lines.append(f"{ok} of {report['cycles_planned']} cycles succeeded")
    return "\n".join(lines)


def plot_report(result: TaskResult, out_dir) -> List[str]:
    """The plots of a run into out_dir: joints with references (one PNG per robot), tracking errors, and
    clearances with forces over time. Returns the paths."""
    import os

    import matplotlib.pyplot as plt

    from ..plotting import plot_log

    os.makedirs(out_dir, exist_ok=True)
    log, series, paths = result.log, result.series, []
    for i, rl in enumerate(log.robots):
        fig, axes = plt.subplots(rl.dof, 1, figsize=(9, 1.6 * rl.dof), sharex=True)
        plot_log(log, robot=i, quantity="q", axes=axes, title=f"{rl.name}: joints (solid) and references (dashed)")
        p = os.path.join(out_dir, f"joints_{rl.name}.png")
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)
    cycles = [(c["t_start"], c.get("t_end", c["t_start"])) for c in result.report["cycles"]]

    def save(fig, axes, title, name):
        """Legends, the cycles' bounds and a title on a figure of panels over time, written as name."""
        for ax in axes:
            ax.legend(loc="upper right")
            for t0, _ in cycles[1:]:
                ax.axvline(t0, color="0.6", lw=0.8, ls=":")
        fig.suptitle(title)
        p = os.path.join(out_dir, name)
        fig.savefig(p, dpi=90)
        plt.close(fig)
        paths.append(p)

    fig, axes = plt.subplots(2, 1, figsize=(9, 5), sharex=True)
    for i, rl in enumerate(log.robots):
        axes[0].plot(series["t"], series["tool_error"][:, i] * 1e3, label=rl.name)
        axes[1].plot(log.t, np.abs(rl.error).max(axis=1), label=rl.name)
    axes[0].set_ylabel("tool position error (mm)")
    axes[1].set_ylabel("largest joint error\n(rad or m)")
    axes[1].set_xlabel("t (s)")
    save(fig, axes, "Tracking errors", "tracking.png")

    fig, axes = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    axes[0].plot(series["t"], series["clearance_robots"] * 1e3, label="robot - robot")
    axes[0].plot(series["t"], series["clearance_container"] * 1e3, label="robot - container")
    axes[0].set_ylabel("clearance (mm)")
    axes[0].set_ylim(0, 300)
    for i, rl in enumerate(log.robots):
        axes[1].plot(series["t"], series["weld_force"][:, i], label=f"weld force, {rl.name}")
    axes[1].plot(series["t"], series["internal_force"], label="internal force (dual hold)", color="k", lw=1)
    axes[1].set_ylabel("force (N)")
    axes[1].set_xlabel("t (s)")
    save(fig, axes, "Clearances and grasp forces", "clearance_forces.png")
    return paths


def main(argv=None) -> int:
    """``python -m coopsim.tasks.handover``: runs the task, writes its outputs, prints the summary."""
    import argparse
    import os

    ap = argparse.ArgumentParser(prog="python -m coopsim.tasks.handover", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out", help="folder for the outputs (default out/)")
    ap.add_argument("--cycles", type=int, default=3, help="bars moved, one per cycle (default 3)")
    ap.add_argument("--seed", type=int, default=None, help="one bar drawn from the stated region with this seed")
    ap.add_argument("--sweep", type=int, default=0, metavar="N", help="also run seeds 0 .. N-1 and report the rate")
    ap.add_argument("--threads", type=int, default=2, help="threads for the sweep (default 2)")
    ap.add_argument("--no-video", action="store_true", help="skip the animation (MP4) and the browser replay")
    ap.add_argument("--speed", type=float, default=2.0, help="simulated seconds per video second (default 2)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    res = run(seed=args.seed) if args.seed is not None else run(cycles=args.cycles)
    rep, wall = res.report, res.timing["run"]
    print(summary(rep))
    print(f"simulated {rep['simulated_time']:.2f} s in {wall:.2f} s of wall time: {rep['simulated_time'] / wall:.1f}x "
          f"real time (scoring {res.timing['scoring']:.2f} s more)")
    paths = [write_report(rep, os.path.join(args.out, "report.json")),
             res.log.to_csv(os.path.join(args.out, "task.csv")),
             res.log.to_excel(os.path.join(args.out, "task.xlsx"))]
    paths += plot_report(res, args.out)
    if not args.no_video:
        from .. import view

        paths.append(view.replay_html(res.sim, os.path.join(args.out, "task_replay.html"),
                                      title="coopsim: the cooperative bar handover"))
        anim = view.animate(res.sim, speed=args.speed, fps=20, path=os.path.join(args.out, "task.mp4"))
        paths.append(anim.path)
    if args.sweep:
        t1 = time.perf_counter()
        sw = sweep(range(args.sweep), threads=args.threads)
        print(f"sweep of {args.sweep} seeds in {time.perf_counter() - t1:.1f} s: success rate "
              f"{sw['success_rate'] * 100:.0f} %")
        for f in sw["failures"]:
            print(f"  seed {f['seed']} (bar at {np.round(f['bar'], 3).tolist()}): {f['step']}: {f['reason']}")
        paths.append(write_report(sw, os.path.join(args.out, "sweep.json")))
    print("wrote " + ", ".join(paths))
    return 0 if rep["success"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
