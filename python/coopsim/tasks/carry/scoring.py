"""The scores of a carry, from its log: the bar's pose against its planned path, the welds' wrenches and
stretch (slip), the joint torques, tracking, clearances, the force sensors against the welds, and every grasp
and contact event."""
from __future__ import annotations

from typing import List

import numpy as np

from ..._core import box_clearances
from . import scene
from .planning import ROBOT_NAMES


def _angles(R) -> np.ndarray:
    """Rotation angles (N,) rad of rotations (N, 3, 3)."""
    return np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else 0.0


def _max(x) -> float:
    return float(np.max(x)) if len(x) else 0.0


def clamp_link_frames(robot, q) -> np.ndarray:
    """The world poses (rows, 4, 4) of the clamp's link (the fixed jaw's) at joint positions q (rows, n): the
    tool pose with the jaw at a fixed opening times that link's constant offset from it (one forward
    kinematics call for all rows)."""
    q = np.array(q, float)
    q0 = q[0].copy()
    q[:, -1] = q0[-1]
    O = np.linalg.solve(robot.fk(q0), robot.frames(q0)[robot.clamp.fixed_link])
    return robot.fk(q) @ O


def weld_stretch(robot, q, bar_poses, anchor) -> np.ndarray:
    """The weld's stretch (m) per row: the distance between its point carried by the clamp's link (at joint
    positions q (rows, n)) and carried by the bar (poses (rows, 4, 4)); anchor: the point in both
    (``{'link': (3,), 'body': (3,)}``, recorded at the grasp). The clamp rule lets go beyond 5 mm."""
    F = clamp_link_frames(robot, q)
    by_link = F[:, :3, :3] @ anchor["link"] + F[:, :3, 3]
    by_body = bar_poses[:, :3, :3] @ anchor["body"] + bar_poses[:, :3, 3]
    return np.linalg.norm(by_link - by_body, axis=1)


def score(runner, report: dict) -> dict:
    """Adds report['scores'] from the run's log and returns the series behind the figures (numpy arrays over the
    log's rows): t, bar_planned (rows, 4, 4), bar (rows, 4, 4), position_error (m), angle_error (rad),
    weld (rows, 2, 6) N and N m, weld_stretch (rows, 2) m, tau (2 lists of (rows, n)), holding (rows, 2) bool,
    clearance_robots (m)."""
    log, plan, robots = runner.sim.log, runner.plan, runner.robots
    t = log.t
    body = log.bodies[scene.BAR]
    bar = body.poses() if len(body.t) == len(t) else _resample(body, t)
    planned = plan.bar.pose(t)
    pos_err = np.linalg.norm(bar[:, :3, 3] - planned[:, :3, 3], axis=1)
    ang_err = _angles(np.swapaxes(planned[:, :3, :3], 1, 2) @ bar[:, :3, :3])
    holding = np.column_stack([rl.holding == scene.BAR for rl in log.robots])
    both = holding.all(axis=1)
    carried = both & (t >= plan.steps["lift"][0]) & (t <= plan.steps["place"][1])
    weld = np.stack([rl.weld for rl in log.robots], axis=1)
    stretch = np.zeros((len(t), 2))
    for i, (r, rl) in enumerate(zip(robots, log.robots)):
        a = runner.anchors[i]
        if a is not None and holding[:, i].any():
            rows = np.flatnonzero(holding[:, i])
            stretch[rows, i] = weld_stretch(r, rl.q[rows], bar[rows], a)
    shapes = [r.shapes(rl.q) for r, rl in zip(robots, log.robots)]
    d_rr = box_clearances(shapes[0][0], shapes[0][1], shapes[1][0], shapes[1][1])[0]
    # the tool's tracking error with the jaw where it is (closed on the bar the jaw stops at the bar's width,
    # short of its squeezing reference, and the tool centre point midway between the jaws would count that)
    tcp_err = np.column_stack([np.linalg.norm(r.fk(rl.q)[:, :3, 3] - r.fk(_jaw_as(rl.q_ref, rl.q))[:, :3, 3], axis=1)
                               for r, rl in zip(robots, log.robots)])
    s = dict(
        # the bar against its planned path while both clamps carry it (lift, carry, place)
        bar_position_error_mm=dict(rms=_rms(pos_err[carried]) * 1e3, max=_max(pos_err[carried]) * 1e3),
        bar_angle_error_mrad=dict(rms=_rms(ang_err[carried]) * 1e3, max=_max(ang_err[carried]) * 1e3),
        dual_hold=float(both.sum() * (t[1] - t[0])) if len(t) > 1 else 0.0,
        robots=[])
    for i, (r, rl) in enumerate(zip(robots, log.robots)):
        h = holding[:, i]
        tau = np.abs(rl.tau)
        s["robots"].append(dict(
            robot=ROBOT_NAMES[i],
            # the raw weld wrench on the bar, world axes, moment about the weld's point
            peak_weld_force=_max(np.linalg.norm(weld[h, i, :3], axis=1)),
            peak_weld_moment=_max(np.linalg.norm(weld[h, i, 3:], axis=1)),
            max_slip_mm=_max(stretch[h, i]) * 1e3,
            peak_torque=tau.max(axis=0).tolist(),
            peak_torque_held=(tau[both].max(axis=0) if both.any() else np.zeros(r.dof)).tolist(),
            torque_limit_fraction=float((tau / r.tau_limits).max()),
            tool_error_mm=dict(rms=_rms(tcp_err[:, i]) * 1e3, max=_max(tcp_err[:, i]) * 1e3),
            # the force sensor's reading against the weld's force it measures while holding (nothing else
            # touches the clamp then): its noise and filter
            sensed_force_error=dict(rms=_rms(np.linalg.norm(rl.ft_world[h, :3] - weld[h, i, :3], axis=1)),
                                    max=_max(np.linalg.norm(rl.ft_world[h, :3] - weld[h, i, :3], axis=1)))))
    # ---- internal force: it plugs in here ----
    # The internal (squeezing, twisting) part of the two weld wrenches needs the welds' points: they are
    # `weld_points` below, per row (the anchors carried by the clamps' links). Until the engine's internal-force
    # computation lands, the score carries the raw weld wrenches per robot (above, and `weld` in the series).
    k = np.flatnonzero(np.isfinite(d_rr))
    j = k[np.argmin(d_rr[k])] if len(k) else 0
    s["clearance_robots"] = dict(min=float(d_rr[j]), t=float(t[j])) if len(k) else None
    g = log.grasps
    s["grasp_events"] = [dict(t=float(e.t), robot=int(e.robot), body=e.body, event=e.event, reason=e.reason)
                         for e in g.itertuples()]
    c = log.contacts
    s["contact_events"] = [dict(a=x.a, b=x.b, kind=x.kind, begin=float(x.begin),
                                end=None if np.isnan(x.end) else float(x.end), peak_force=float(x.peak_force))
                           for x in c.itertuples()]
    report["scores"] = s
    weld_points = np.full((len(t), 2, 3), np.nan)
    for i, r in enumerate(robots):
        a = runner.anchors[i]
        if a is not None:
            rows = np.flatnonzero(holding[:, i])
            if len(rows):
                F = clamp_link_frames(r, log.robots[i].q[rows])
                weld_points[rows, i] = F[:, :3, :3] @ a["link"] + F[:, :3, 3]
    return dict(t=t, bar=bar, bar_planned=planned, position_error=pos_err, angle_error=ang_err, weld=weld,
                weld_points=weld_points, weld_stretch=stretch, holding=holding, carried=carried,
                tau=[rl.tau for rl in log.robots], clearance_robots=d_rr, tool_error=tcp_err)


def _jaw_as(q_ref, q) -> np.ndarray:
    out = np.array(q_ref, float)
    out[:, -1] = q[:, -1]
    return out


def _resample(body, t) -> np.ndarray:
    """The body's poses at times t (the log's rows), from its own rows (the nearest at or before)."""
    k = np.clip(np.searchsorted(body.t, t + 1e-12, side="right") - 1, 0, len(body.t) - 1)
    return body.poses()[k]
