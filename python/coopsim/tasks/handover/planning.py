"""Where the clamps go: the bars' starts, the grips on a bar, the clamp poses each robot can take and their
joint positions (closed-form IK on the task's elbow branches)."""
from __future__ import annotations

import math
from typing import List

import numpy as np

from ..._core import IKError
from ...planning import rotz
from .. import scene
from .constants import BRANCH, CLEAR_ABOVE, DEG, FIXED_GAP, GRIP1, GRIP2, HANDOVER_CENTRE, HANDOVER_YAW, \
    LINE_SPACING, OPEN, PICK_HEIGHT, REGION


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


_DOWN = np.array([0.0, 0.0, -1.0])   # #2's approach: straight down
#: the bar's frame as it is and turned end for end (pick_grip: either end may be its +x end)
_TURNS = tuple(_pose(rotz(label), np.zeros(3)) for label in (0.0, math.pi))
#: #2's grip at the pick in the bar's frame, its tool x along +x and along -x
_PICK_GRIPS = tuple(_grip_down(GRIP2, PICK_HEIGHT) @ _pose(rotz(flip), np.zeros(3)) for flip in (0.0, math.pi))


class Planner:
    """The task's geometry for the two SCARAs of the scene: the handover pose of the bar (yaw `handover_yaw`
    rad, default HANDOVER_YAW), the grips and the inverse kinematics, its errors naming the robot and
    :attr:`step` (the phase being planned)."""

    def __init__(self, handover_yaw=None):
        self.r1, self.r2 = scene.scaras()
        self.handover_yaw = HANDOVER_YAW if handover_yaw is None else float(handover_yaw)
        self.step = "start"
        self._picks = {}        # pick_grip's answers by the bar's pose (its bytes)
        self._at_hand = None    # _hand_grips'

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
        # numpy's norm (sqrt of the dot product) and cross product (each component's two products, then their
        # difference) written out on the three components: the same operations, the same bits, without the
        # general functions' overhead (called about 40 times per cycle)
        y = np.array([T[0, 1], T[1, 1], 0.0])
        y /= math.sqrt(y.dot(y))
        if i == 1:
            z = _DOWN
        else:
            z = T[:3, 2] - y * (y @ T[:3, 2])
            z /= math.sqrt(z.dot(z))
        (y0, y1, y2), (z0, z1, z2) = y.tolist(), z.tolist()
        out = T.copy()
        out[:3, :3] = ((y1 * z2 - y2 * z1, y0, z0), (y2 * z0 - y0 * z2, y1, z1), (y0 * z1 - y1 * z0, y2, z2))
        return out

    @staticmethod
    def _above(bar, G):
        """The TCP pose CLEAR_ABOVE m above the grip G on a bar at `bar`."""
        T = bar @ G
        T[2, 3] += CLEAR_ABOVE
        return T

    def _ik(self, i, T, opening, q_near=None, branch=None):
        return self._ik_reachable(i, self._reachable(i, T), opening, q_near, branch)

    def _ik_reachable(self, i, T, opening, q_near=None, branch=None):
        """Robot i's joint positions at T, a pose it can take (_reachable's)."""
        r = (self.r1, self.r2)[i]
        try:
            return r.ik(T, opening=opening, q_near=q_near, branch=BRANCH[i] if branch is None else branch)
        except IKError as e:
            raise IKError(f"{('SCARA #1', 'SCARA #2')[i]}, {self.step}: {e}") from None

    def pick_grip(self, bar):
        """How #2 takes a bar lying at `bar` (4, 4): the bar's frame relabelled so that #2's grip is GRIP2
        along +x (the bar is symmetric: either end may become its +x end), and #2's TCP in that frame
        (tool x along +x or -x). Of the four, the one within the joint limits at the pick and at the
        handover with the least joint travel between them. A pure function of the bar's pose (and the
        handover's): the answer for a pose met before (bit for bit: a bar lying still) is the one found then."""
        key = np.asarray(bar, float).tobytes()
        found = self._picks.get(key)
        if found is None:
            found = self._picks[key] = self._pick_grip(bar)
        return found[0].copy(), found[1].copy()

    def _pick_grip(self, bar):
        best, cost_best, why = None, math.inf, []
        at_hand = self._hand_grips()
        for turn in _TURNS:
            Tb = bar @ turn
            for G, hand in zip(_PICK_GRIPS, at_hand):
                try:
                    qa = self._ik(1, Tb @ G, OPEN)
                    qb = self._ik_reachable(1, hand, OPEN, q_near=qa)
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

    def _hand_grips(self):
        """#2's reachable TCP poses at the handover for each of _PICK_GRIPS' two ways round (the handover's pose
        is fixed: computed once; the products in pick_grip's order)."""
        if self._at_hand is None:
            hand = self._handover_bar()
            self._at_hand = [self._reachable(1, hand @ _grip_down(GRIP2, PICK_HEIGHT) @ _pose(rotz(flip), np.zeros(3)))
                             for flip in (0.0, math.pi)]
        return self._at_hand
